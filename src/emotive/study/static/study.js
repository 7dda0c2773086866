// The participant page of `emotive study serve` (the API: docs/study-protocol.md).
//
// Screens, in order: consent ("I agree" joins the study), instructions, one screen per item of
// the participant's plan (the stimulus looping at a fixed camera, the questions below it,
// "Next" once every question is answered), and the completion code. The participant's token
// is kept in localStorage under the study's origin and title, so a reload resumes where it
// stopped; it travels only in the Authorization header. A submission carries an
// Idempotency-Key made for its item and kept in localStorage until the server acknowledges
// it: a retry (after a network failure, a 5xx, a 429, or a reload) sends the same key and
// body, so the server stores it once.
//
// window.study is a read-only view of the page, for tests and the console:
//   ready            true once the study is loaded and the first screen shown
//   screen           "loading" | "consent" | "instructions" | "item" | "done" | "error"
//   title            the study's title
//   participant      the participant's public id, or null before joining
//   render           the plan's render (mannequin | sticks | effectors), or null
//   items            items in the plan (0 before joining)
//   answered         item numbers answered so far
//   item             the item shown: {item, stimulus, index (1-based), instruction}, or null
//   loaded           true once the item's stimulus has been drawn
//   framesRendered   frames the view has drawn in all; stimulusFrames: of this stimulus
//   time             the loop's time of the stimulus shown (seconds), or null
//   framing          [minX, minY, maxX, maxY] of the walk's box on the view (-1..1), or null
//   answers          the answers given to the item shown, by question id
//   canSubmit        whether "Next" is enabled
//   saving           true while a submission awaits its reply; retrying: after a failed try
//   status           the text of the saving line; statuses: every text it has shown
//   completionCode   the code, once shown
//   errors           every error message shown so far

import { ApiError, call, jsonOptions, randomKey, reasonOf, request } from "./api.js";
import { questionWidget } from "./questions.js";
import { Stage } from "./stage.js";

const $ = (id) => document.getElementById(id);
const SCREENS = ["loading", "consent", "instructions", "item", "done", "error"];

const state = {
  ready: false,
  screen: "loading",
  study: null,
  token: null,
  storageKey: null,
  plan: null,
  answered: new Set(),
  current: null,
  widgets: [],
  answers: {},
  loaded: false,
  shownAt: null,
  saving: false,
  retrying: false,
  status: "",
  statuses: [],
  completionCode: null,
  errors: [],
  glbs: new Map(),
  stage: null,
};

// --- storage --------------------------------------------------------------------------------

/** {token, pending: {item, key, body} | null, code} of this study in this browser. */
function stored() {
  try {
    return JSON.parse(localStorage.getItem(state.storageKey)) ?? {};
  } catch {
    return {};
  }
}

function store(changes) {
  try {
    localStorage.setItem(state.storageKey, JSON.stringify({ ...stored(), ...changes }));
  } catch {
    // Private browsing without storage: the page still works, a reload starts over.
  }
}

function forget() {
  try {
    localStorage.removeItem(state.storageKey);
  } catch {
    // nothing kept
  }
}

// --- screens --------------------------------------------------------------------------------

function show(screen) {
  state.screen = screen;
  for (const name of SCREENS) $(`screen-${name}`).hidden = name !== screen;
  if (screen !== "item") $("progress").textContent = "";
  document.body.dataset.screen = screen;
}

function report(message) {
  state.errors.push(message);
}

/** The error screen; `restart` offers to forget this browser's participant. */
function fail(message, restart = false) {
  report(message);
  $("error-text").textContent = message;
  $("restart").hidden = !restart;
  show("error");
}

function paragraphs(target, text) {
  target.replaceChildren(...text.trim().split(/\n\s*\n/).map((part) => {
    const p = document.createElement("p");
    p.textContent = part.trim();
    return p;
  }));
}

function saveStatus(text, isError = false) {
  state.status = text;
  if (text) state.statuses.push(text);
  const line = $("save-status");
  line.textContent = text;
  line.classList.toggle("error", isError);
  if (isError) report(text);
}

// --- the server -----------------------------------------------------------------------------

const auth = (method, body, headers = {}) => jsonOptions(method, body, state.token, headers);

function connecting(what) {
  return () => { $("loading-text").textContent = `${what}... (retrying)`; };
}

/** GET /api/plan into state; false when the server does not know the token. */
async function loadPlan() {
  const response = await request("/api/plan", auth("GET"), { onRetry: connecting("Loading") });
  if (response.status === 401) return false;
  if (!response.ok) throw new ApiError(response.status, await reasonOf(response));
  state.plan = await response.json();
  state.answered = new Set(state.plan.answered);
  return true;
}

/** The bytes of a stimulus GLB, fetched once (retried while the network fails). */
function glb(url) {
  if (!state.glbs.has(url)) {
    const bytes = (async () => {
      const response = await request(url, {}, {
        onRetry: () => { $("stage-status").textContent = "Loading the animation... (retrying)"; },
      });
      if (!response.ok) throw new ApiError(response.status, await reasonOf(response));
      return response.arrayBuffer();
    })();
    bytes.catch(() => state.glbs.delete(url));
    state.glbs.set(url, bytes);
  }
  return state.glbs.get(url);
}

// --- consent and instructions ---------------------------------------------------------------

function showConsent() {
  paragraphs($("consent-text"), state.study.consent);
  show("consent");
  $("agree").focus();
}

async function agree() {
  const button = $("agree");
  button.disabled = true;
  try {
    const response = await request("/api/participants", jsonOptions("POST", { consent: true }),
                                   { retry: false });
    if (!response.ok) {
      const reason = await reasonOf(response);
      report(reason);
      $("consent-status")?.remove();
      const line = document.createElement("p");
      line.id = "consent-status";
      line.className = "error";
      line.setAttribute("role", "alert");
      line.textContent = `${reason}. Please try again.`;
      $("screen-consent").append(line);
      return;
    }
    const joined = await response.json();
    state.token = joined.token;
    store({ token: joined.token, pending: null, code: null });
    if (!(await loadPlan())) throw new ApiError(401, "the server did not accept the new token");
    showInstructions();
  } catch (err) {
    fail(err.message);
  } finally {
    button.disabled = false;
  }
}

function showInstructions() {
  paragraphs($("instructions-text"), state.study.instructions || "Answer every question.");
  const n = state.plan.items.length;
  $("instructions-count").textContent = `There are ${n} animations to rate.`;
  show("instructions");
  $("start").focus();
}

// --- items ----------------------------------------------------------------------------------

function updateNext() {
  const ready = state.widgets.every((w) => w.value !== null);
  $("next").disabled = !ready || state.saving;
}

async function nextItem() {
  const plan = state.plan;
  const item = plan.items.find((it) => !state.answered.has(it.item));
  if (!item) {
    await finish();
    return;
  }
  const index = plan.items.indexOf(item) + 1;
  state.current = { ...item, index };
  state.answers = {};
  state.loaded = false;
  state.shownAt = null;
  $("progress").textContent = `Item ${state.answered.size + 1} of ${plan.items.length}`;
  const instruction = $("instruction");
  instruction.hidden = item.instruction === null;
  instruction.textContent = item.instruction ?? "";
  state.widgets = state.study.questions.map((q) => questionWidget(q, (id, value) => {
    state.answers[id] = value;
    updateNext();
  }));
  $("questions").replaceChildren(...state.widgets.map((w) => w.element));
  saveStatus("");
  updateNext();
  // The last item's figure must not play beside this item's questions.
  state.stage.clear();
  $("stage").setAttribute("aria-busy", "true");
  $("stage-status").textContent = "Loading the animation...";
  $("stage-status").hidden = false;
  show("item");
  window.scrollTo(0, 0);
  state.widgets[0]?.focus({ preventScroll: true });
  try {
    const bytes = await glb(item.url);
    if (state.current?.item !== item.item) return;
    await state.stage.show(bytes, plan.render, plan.seconds, item.effectors);
    state.glbs.delete(item.url);
  } catch (err) {
    fail(`The animation ${item.stimulus} could not be shown: ${err.message}`);
    return;
  }
  // Fetch the next one while this one is watched.
  const following = plan.items.find((it) => !state.answered.has(it.item) && it !== item);
  if (following) glb(following.url).catch(() => {});
}

function firstFrame() {
  state.loaded = true;
  state.shownAt = performance.now();
  $("stage").setAttribute("aria-busy", "false");
  $("stage-status").hidden = true;
}

async function submit(event) {
  event?.preventDefault();
  if (state.saving || $("next").disabled || !state.current) return;
  const item = state.current;
  const body = { item: item.item, stimulus: item.stimulus, answers: { ...state.answers } };
  if (state.shownAt !== null) body.rt_ms = Math.round(performance.now() - state.shownAt);
  const old = stored().pending;
  const key = old && old.item === item.item ? old.key : randomKey();
  const pending = { item: item.item, key, body };
  store({ pending });
  await deliver(pending);
}

/**
 * Send a submission until the server answers it; then on to the next item (or the end).
 * Network failures, 5xx and 429 are retried with the same key and body.
 */
async function deliver(pending, first = "saving...") {
  state.saving = true;
  updateNext();
  saveStatus(first);
  try {
    const response = await request("/api/responses",
                                   auth("POST", pending.body, { "Idempotency-Key": pending.key }),
                                   { onRetry: () => {
                                     state.retrying = true;
                                     saveStatus("saving... (retrying)");
                                   } });
    let accepted = response.ok;
    if (response.status === 409) {
      // Already answered (another tab, or a reply lost before a reload)?
      const reason = await reasonOf(response);
      if (!(await loadPlan())) {
        fail("This browser's place in the study is no longer known to the server.", true);
        return;
      }
      accepted = state.answered.has(pending.item);
      if (!accepted) {
        store({ pending: null });
        saveStatus(reason, true);
        return;
      }
    } else if (response.status === 401) {
      fail("This browser's place in the study is no longer known to the server.", true);
      return;
    } else if (!accepted) {
      // Refused: nothing was stored, so a corrected submission may take a new key.
      store({ pending: null });
      saveStatus(await reasonOf(response), true);
      return;
    }
    store({ pending: null });
    state.answered.add(pending.item);
    saveStatus("");
    state.saving = false;
    state.retrying = false;
    await nextItem();
  } catch (err) {
    fail(err.message);
  } finally {
    state.saving = false;
    state.retrying = false;
    updateNext();
  }
}

// --- the end --------------------------------------------------------------------------------

async function finish() {
  state.current = null;
  state.stage.clear();
  $("loading-text").textContent = "Saving...";
  show("loading");
  const response = await request("/api/complete", auth("POST", {}),
                                  { onRetry: connecting("Saving") });
  if (response.status === 409) {
    // An item is still unanswered after all: show it.
    if (await loadPlan()) await nextItem();
    return;
  }
  if (!response.ok) {
    fail(await reasonOf(response), response.status === 401);
    return;
  }
  const { completion_code: code } = await response.json();
  state.completionCode = code;
  store({ code, pending: null });
  $("code").textContent = code;
  show("done");
  $("copy").focus();
}

async function copyCode() {
  const code = state.completionCode;
  let copied = false;
  try {
    await navigator.clipboard.writeText(code);
    copied = true;
  } catch {
    // No clipboard API (plain http): select the code for the participant to copy.
  }
  if (!copied) {
    const range = document.createRange();
    range.selectNodeContents($("code"));
    const selection = getSelection();
    selection.removeAllRanges();
    selection.addRange(range);
    try {
      copied = document.execCommand("copy");
    } catch {
      copied = false;
    }
  }
  $("copy-status").textContent = copied ? "Copied." : "Select the code and copy it.";
}

// --- start ----------------------------------------------------------------------------------

/** Continue a participant of this browser: pending submission, next item or the code. */
async function resume() {
  if (!(await loadPlan())) {
    // The server does not know this token (a new database): join again.
    forget();
    state.token = null;
    showConsent();
    return;
  }
  const pending = stored().pending;
  if (pending && !state.answered.has(pending.item)
      && state.plan.items.some((it) => it.item === pending.item)) {
    // Answers given before the reload, maybe stored, maybe not: send them again with the same
    // key (the server stores them once), then go on.
    await nextItem();
    state.retrying = true;
    deliver(pending, "saving... (retrying)").catch((e) => fail(e.message));
    return;
  }
  store({ pending: null });
  if (state.plan.completed || state.answered.size === state.plan.items.length) {
    await finish();
  } else if (state.answered.size === 0) {
    showInstructions();
  } else {
    await nextItem();
  }
}

async function boot() {
  state.stage = new Stage($("stage"));
  state.stage.onFirstFrame = firstFrame;
  $("agree").addEventListener("click", agree);
  $("start").addEventListener("click", () => { nextItem().catch((e) => fail(e.message)); });
  $("answers").addEventListener("submit", (event) => {
    submit(event).catch((e) => fail(e.message));
  });
  $("copy").addEventListener("click", copyCode);
  $("reload").addEventListener("click", () => location.reload());
  $("restart").addEventListener("click", () => { forget(); location.reload(); });

  state.study = await call("/api/study", {}, { onRetry: connecting("Loading") });
  document.title = state.study.title;
  $("title").textContent = state.study.title;
  state.storageKey = `emotive-study:${location.origin}:${state.study.title}`;
  state.token = stored().token ?? null;
  if (state.token) await resume();
  else showConsent();
  state.ready = true;
}

addEventListener("error", (event) => report(`page error: ${event.message}`));
addEventListener("unhandledrejection", (event) => report(`page error: ${event.reason}`));

const copyOf = (value) => (value === null || value === undefined ? value
  : JSON.parse(JSON.stringify(value)));

window.study = Object.freeze({
  get ready() { return state.ready; },
  get screen() { return state.screen; },
  get title() { return state.study?.title ?? null; },
  get participant() { return state.plan?.participant ?? null; },
  get render() { return state.plan?.render ?? null; },
  get items() { return state.plan?.items.length ?? 0; },
  get answered() { return [...state.answered].sort((a, b) => a - b); },
  get item() {
    const c = state.current;
    return c ? { item: c.item, stimulus: c.stimulus, index: c.index,
                 instruction: c.instruction } : null;
  },
  get loaded() { return state.loaded; },
  get framesRendered() { return state.stage?.framesRendered ?? 0; },
  get stimulusFrames() { return state.stage?.stimulusFrames ?? 0; },
  get time() { return state.stage?.time ?? null; },
  get framing() { return state.stage?.framing() ?? null; },
  get answers() { return copyOf(state.answers); },
  get canSubmit() { return !$("next").disabled; },
  get saving() { return state.saving; },
  get retrying() { return state.retrying; },
  get status() { return state.status; },
  get statuses() { return [...state.statuses]; },
  get completionCode() { return state.completionCode; },
  get errors() { return [...state.errors]; },
});

boot().catch((err) => fail(`The study could not be loaded: ${err.message}`));
