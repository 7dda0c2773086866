// The admin page of `emotive study serve`: progress and participants (refreshed every
// REFRESH_MS), a toggle per participant to exclude or include them, and the CSV export.
//
// The admin token is asked for once and kept in sessionStorage (gone with the tab); it travels
// only in the Authorization header, which is why the export is fetched and saved from a blob
// rather than linked.
//
// window.studyAdmin is a read-only view for tests: {ready, refreshes (done so far), rows
// (participants shown), status (the status line), errors}.

import { call, jsonOptions, request, reasonOf } from "./api.js";

const REFRESH_MS = 5000;
const TOKEN_KEY = "emotive-study-admin-token";
const $ = (id) => document.getElementById(id);

const state = { token: null, timer: null, busy: false, refreshes: 0, errors: [], ready: false };

function status(text, isError = false) {
  const line = $("admin-status");
  line.textContent = text;
  line.classList.toggle("error", isError);
  if (isError) state.errors.push(text);
}

const auth = (method = "GET", body = undefined) => jsonOptions(method, body, state.token);

function cell(text, className = "") {
  const td = document.createElement("td");
  td.textContent = text;
  if (className) td.className = className;
  return td;
}

function when(iso) {
  const date = new Date(iso);
  return Number.isNaN(date.getTime()) ? iso : date.toLocaleString();
}

function showProgress(progress) {
  const totals = [["participants", progress.participants], ["completed", progress.completed],
                  ["responses (values)", progress.responses]];
  $("totals").replaceChildren(...totals.map(([label, value]) => {
    const div = document.createElement("div");
    const b = document.createElement("b");
    b.textContent = String(value);
    div.append(b, label);
    return div;
  }));
  $("conditions").tBodies[0].replaceChildren(...Object.entries(progress.conditions)
    .map(([name, c]) => {
      const tr = document.createElement("tr");
      tr.append(cell(name), cell(String(c.joined), "number"), cell(String(c.completed), "number"),
                cell(String(c.responses), "number"));
      return tr;
    }));
}

/** One row a participant, updated in place (a reason being typed is left alone). */
function showParticipants(rows) {
  const body = $("participants").tBodies[0];
  const old = new Map([...body.rows].map((tr) => [tr.dataset.participant, tr]));
  const ordered = rows.map((p) => {
    let tr = old.get(p.participant);
    if (!tr) {
      tr = document.createElement("tr");
      tr.dataset.participant = p.participant;
      const reason = document.createElement("input");
      reason.type = "text";
      reason.placeholder = "reason";
      reason.setAttribute("aria-label", `reason to exclude ${p.participant}`);
      const toggle = document.createElement("input");
      toggle.type = "checkbox";
      toggle.setAttribute("aria-label", `exclude ${p.participant}`);
      toggle.addEventListener("change", () => exclude(tr, toggle, reason));
      const label = document.createElement("label");
      label.className = "toggle";
      label.append(toggle, "excluded");
      const reasonCell = document.createElement("td");
      reasonCell.className = "keep";
      reasonCell.append(reason);
      const toggleCell = document.createElement("td");
      toggleCell.className = "keep";
      toggleCell.append(label);
      tr.append(cell(""), cell(""), cell(""), cell(""), cell("", "number"), cell("", "number"),
                reasonCell, toggleCell);
    }
    const [id, condition, joined, completed, answered, failed] = tr.cells;
    id.textContent = p.participant;
    condition.textContent = p.condition;
    joined.textContent = when(p.joined);
    completed.textContent = p.completed ? "yes" : "no";
    answered.textContent = `${p.answered} / ${p.items}`;
    failed.textContent = String(p.failed_checks);
    const reason = tr.querySelector('input[type="text"]');
    if (document.activeElement !== reason) reason.value = p.reason ?? "";
    const toggle = tr.querySelector('input[type="checkbox"]');
    if (!toggle.disabled) toggle.checked = p.excluded;
    // What the server holds (the box may show a change on its way).
    tr.dataset.excluded = String(p.excluded);
    tr.classList.toggle("excluded", p.excluded);
    return tr;
  });
  body.replaceChildren(...ordered);
}

async function refresh() {
  if (!state.token || state.busy) return;
  state.busy = true;
  try {
    const [progress, people] = await Promise.all([
      call("/api/admin/progress", auth(), { retry: false }),
      call("/api/admin/participants", auth(), { retry: false }),
    ]);
    showProgress(progress);
    showParticipants(people.participants);
    $("data").hidden = false;
    $("updated").textContent = `Updated ${new Date().toLocaleTimeString()}`;
    status("");
    state.refreshes++;
  } catch (err) {
    if (err.status === 403) {
      stop();
      status(`The server refused the token: ${err.message}`, true);
    } else {
      status(`Could not refresh (${err.message}); trying again in ${REFRESH_MS / 1000} s.`,
             true);
    }
  } finally {
    state.busy = false;
  }
}

async function exclude(tr, toggle, reason) {
  const excluded = toggle.checked;
  toggle.disabled = true;
  try {
    await call("/api/admin/exclusions", auth("POST", {
      participant: tr.dataset.participant, excluded,
      reason: excluded ? (reason.value.trim() || "excluded by the admin") : "",
    }), { retry: false });
    await refresh();
  } catch (err) {
    toggle.checked = tr.dataset.excluded === "true";
    status(`Could not change ${tr.dataset.participant}: ${err.message}`, true);
  } finally {
    toggle.disabled = false;
  }
}

async function download() {
  const button = $("download");
  button.disabled = true;
  try {
    const response = await request("/api/admin/export.csv", auth(), { retry: false });
    if (!response.ok) throw new Error(await reasonOf(response));
    const url = URL.createObjectURL(await response.blob());
    const link = document.createElement("a");
    link.href = url;
    link.download = "responses.csv";
    document.body.append(link);
    link.click();
    link.remove();
    setTimeout(() => URL.revokeObjectURL(url), 60000);
    status("Downloaded responses.csv.");
  } catch (err) {
    status(`Could not download the export: ${err.message}`, true);
  } finally {
    button.disabled = false;
  }
}

function stop() {
  clearInterval(state.timer);
  state.timer = null;
}

function start(token) {
  state.token = token;
  try {
    sessionStorage.setItem(TOKEN_KEY, token);
  } catch {
    // no session storage: the token lasts as long as the page
  }
  stop();
  state.timer = setInterval(() => { if (!document.hidden) refresh(); }, REFRESH_MS);
  return refresh();
}

$("login").addEventListener("submit", (event) => {
  event.preventDefault();
  const token = $("token").value.trim();
  if (token) start(token);
});
$("forget").addEventListener("click", () => {
  stop();
  state.token = null;
  try { sessionStorage.removeItem(TOKEN_KEY); } catch { /* nothing kept */ }
  $("token").value = "";
  $("data").hidden = true;
  status("Token forgotten.");
});
$("refresh").addEventListener("click", () => refresh());
$("download").addEventListener("click", () => download());

window.studyAdmin = Object.freeze({
  get ready() { return state.ready; },
  get refreshes() { return state.refreshes; },
  get rows() { return $("participants").tBodies[0].rows.length; },
  get status() { return $("admin-status").textContent; },
  get errors() { return [...state.errors]; },
});

let saved = null;
try { saved = sessionStorage.getItem(TOKEN_KEY); } catch { saved = null; }
if (saved) {
  $("token").value = saved;
  start(saved).finally(() => { state.ready = true; });
} else {
  state.ready = true;
  $("token").focus();
}
