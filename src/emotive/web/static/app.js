// The browser runtime of `emotive export web`: gait agents stepped in the page by
// onnxruntime-web (engine.js), shown with the served app's view, figures, mouse input,
// cameras, panel, emotion controls and WebXR buttons (its modules, copied into the export).
// No emotive server: any static file server of the exported folder will do.
//
// URL parameters: `?demo=1` starts with four walking agents; `?paused=1` starts with the
// clock stopped (the agents step only through the test hook or the Pause button). With a
// scene (exported with --scene, crowd.js): `?avoidance=0` runs it with navigation agents
// that do not see each other (the baseline), `?seed=N` seeds its random draws (default 0).
//
// window.emotiveWeb (hook.js) is a read-only view of the page's state for tests and the
// console, with the test functions that feed the page the inputs a test feeds Python.

import { LabelSliders, MAIN_LABELS, ValenceArousalDisc } from "./emotion-controls.js";
import { createView } from "./scene-setup.js";
import { listenToGround } from "./ground-input.js";
import { AgentFigures, dropUnseen, figuresOf, loadMannequin } from "./agent-figures.js";
import { FollowCamera } from "./follow-camera.js";
import {
  AgentList, Rates, cameraButtons, collapsiblePanel, figureButtons, mouseModeButtons,
  sticksOnly, toaster,
} from "./panel.js";
import { AgentEngine, Lock } from "./engine.js";
import { installHook } from "./hook.js";
import { GroundPath, circlePath, waypointPath } from "./paths.js";
import { emotionWeights, pointOf, weightsFromPoint, weightsObject } from "./emotion.js";
import { RuntimeError, loadMetadata, loadRuntime, requireWasmSimd } from "./runtime.js";
import { CrowdRunner, loadSceneDocument } from "./crowd.js";
import { drawScene } from "./crowd-view.js";

const params = new URLSearchParams(location.search);

// Radius of the circle a placed agent walks, metres.
const PLACED_RADIUS = 1.5;
// Steps the clock may run at once to catch up after a slow frame; beyond, time is dropped.
const MAX_CATCH_UP = 4;

const $ = (id) => document.getElementById(id);
const errors = [];
const toast = toaster(errors);

const view = createView($("view"));
collapsiblePanel();
const cameras = new FollowCamera(view);
const lock = new Lock();

const app = {
  meta: null, engine: null, crowd: null, ort: null, session: null, template: null,
  status: "loading", error: null, ready: false, running: params.get("paused") !== "1",
  figureMode: "mannequin", cameraMode: "fixed", mouseMode: "place",
  views: new Map(), selected: null, drawnPath: [], shownFrame: null,
  framesRendered: 0, renderFps: 0, stepsPerSecond: 0,
};

/** Stop the agents with `message` on screen; the view and the controls keep working. */
function fail(message) {
  app.status = "error";
  app.error = message;
  errors.push(message);
  $("runtime-error").textContent = message;
  $("runtime-error").hidden = false;
  $("stat-status").textContent = "agents not running (see the message)";
}

/** The engine, or null after a toast saying why there is none. */
function running() {
  if (app.engine) return app.engine;
  toast(app.error ? `no agents: ${app.error}` : "the agents' runtime is still loading");
  return null;
}

// --- agents on screen ----------------------------------------------------------------------

/** One agent's figures, placed from the latest frame of the engine. */
class AgentView extends AgentFigures {
  constructor(id) {
    super(id, app.meta.skeleton, app.template, view.world, app.figureMode);
  }

  /** Pose from row `b` of `frame` (hidden while the agent takes its start steps). */
  update(frame, b, agent) {
    this.group.visible = frame.walking[b] === 1;
    if (!this.group.visible) return;
    const { J, P } = app.engine;
    this.pose(frame.root_position.subarray(3 * b, 3 * b + 3),
              pointOf(app.meta.emotion, agent.emotion),
              frame.world.subarray(3 * P * b, 3 * P * (b + 1)),
              frame.rotations.subarray(4 * J * b, 4 * J * (b + 1)));
  }
}

const agentList = new AgentList((id) => select(id));

/** Bring the figures to the engine's latest frame. */
function showFrame(frame) {
  app.shownFrame = frame;
  const seen = new Set();
  frame.ids.forEach((id, b) => {
    const agent = app.engine.agent(id);
    if (!agent) return;
    seen.add(id);
    figuresOf(app.views, id, (i) => new AgentView(i)).update(frame, b, agent);
  });
  dropUnseen(app.views, seen, (id) => { if (app.selected === id) select(null); });
  agentList.update(app.views, app.selected);
  const selected = app.views.get(app.selected);
  if (selected) disc.show(selected.va);
}

// --- selection and emotion editing ---------------------------------------------------------

const disc = new ValenceArousalDisc($("va-disc"), ({ valence, arousal }) => {
  if (app.selected === null || !app.engine) return;
  const weights = weightsFromPoint(app.meta.emotion, valence, arousal);
  app.engine.setEmotion(app.selected, weights);
  sliders?.set(weightsObject(app.meta.emotion, weights), true);
});
let sliders = null;

function onSliders(weights) {
  const total = Object.values(weights).reduce((a, b) => a + b, 0);
  // All-zero weights name no emotion: wait for a non-zero one.
  if (app.selected !== null && app.engine && total > 0) {
    app.engine.setEmotion(app.selected, emotionWeights(app.meta.emotion, weights));
  }
}

function select(id) {
  const agent = id === null ? null : app.engine?.agent(id);
  app.selected = agent ? id : null;
  $("selected-name").textContent = agent ? `Agent ${id}` : "none";
  $("remove-agent").disabled = !agent;
  disc.enabled = Boolean(agent);
  disc.reset();
  const v = app.views.get(app.selected);
  if (v) disc.show(v.va);
  if (sliders) sliders.set(agent ? weightsObject(app.meta.emotion, agent.emotion) : null, Boolean(agent));
  agentList.mark(app.selected);
  view.setLine(view.selectedPathLine, agent ? agent.path.outline() : []);
}

$("remove-agent").addEventListener("click", () => {
  if (app.selected === null || !app.engine) return;
  app.engine.remove([app.selected]);
  select(null);
});

// --- mouse on the ground: place, pick, draw --------------------------------------------------

// An agent added with the mouse is selected once it shows.
let pendingSelect = null;

async function addAgent(path) {
  const engine = running();
  if (!engine) return;
  const emotion = emotionWeights(app.meta.emotion, { neutral: 1 });
  [pendingSelect] = await engine.add([{ path, emotion, phase: Math.random() * 2 * Math.PI }]);
}

async function onPathDrawn(points) {
  app.drawnPath = points;
  let path;
  try {
    path = waypointPath(points);
  } catch (err) {
    toast(`that path cannot be walked: ${err.message}`);
    return;
  }
  if (app.selected !== null && app.engine) {
    const id = app.selected;
    await app.engine.setPath(id, path);
    if (app.selected === id) view.setLine(view.selectedPathLine, path.outline());
  } else {
    await addAgent(path);
  }
}

listenToGround(view, app, app.views, {
  select,
  place: (x, z) => addAgent(circlePath(x, z, PLACED_RADIUS)),
  drawn: onPathDrawn,
});

// --- toggles -----------------------------------------------------------------------------------

mouseModeButtons(app, view);
figureButtons(app, app.views, () => { if (app.shownFrame) showFrame(app.shownFrame); });
cameraButtons(app, cameras, app.views, select);

function setRunning(on) {
  app.running = on;
  $("pause").textContent = on ? "Pause" : "Run";
  $("pause").classList.toggle("on", !on);
}
$("pause").addEventListener("click", () => setRunning(!app.running));
setRunning(app.running);

// --- the clock: fixed steps at the model's frame rate ----------------------------------------

/** One frame: the scene's crowd when there is one (it steps the engine), else the engine. */
function advance() {
  return app.crowd ? app.crowd.step() : app.engine.step();
}

let backlog = 0;
let lastTick = performance.now();

/** Step the agents at `fps` from a fixed-timestep accumulator, independently of rendering. */
async function tick() {
  const engine = app.engine;
  const h = 1 / engine.fps;
  const now = performance.now();
  if (app.running) backlog = Math.min(backlog + (now - lastTick) / 1000, MAX_CATCH_UP * h);
  else backlog = 0;
  lastTick = now;
  try {
    while (app.running && backlog >= h) {
      await advance();
      backlog -= h;
    }
  } catch (err) {
    fail(`the agents stopped: a step failed (${err.message})`);
    return;
  }
  setTimeout(tick, Math.max(1, (h - backlog) * 1000));
}

// --- render loop and stats ---------------------------------------------------------------------

const rates = new Rates();

/** Before each frame is drawn, `dt` seconds after the last: the engine's latest frame shows. */
function beforeRender(dt) {
  const frame = app.engine?.frame;
  if (frame && frame !== app.shownFrame) showFrame(frame);
  cameras.update(app.views.get(app.selected), dt);
  if (pendingSelect !== null && app.views.get(pendingSelect)?.group.visible) {
    select(pendingSelect);
    pendingSelect = null;
  }
  const selected = app.views.get(app.selected);
  view.ringAt(selected?.group.visible ? selected.position : null);
  app.framesRendered++;
}

function everySecond() {
  const { rendered, steps } = rates.sample({ rendered: app.framesRendered,
                                            steps: app.engine?.frames ?? 0 });
  app.renderFps = rendered;
  app.stepsPerSecond = steps;
  $("stat-fps").textContent = app.renderFps.toFixed(0);
  $("stat-steps").textContent = app.engine ? app.stepsPerSecond.toFixed(0) : "-";
  const ms = app.engine?.medianMs();
  $("stat-step-ms").textContent = ms == null ? "-" : ms.toFixed(1);
  agentList.refresh(app.views);
}

// --- the hook for tests and the console ----------------------------------------------------------

installHook({ app, view, errors, lock, running, setRunning, advance });

// --- start ---------------------------------------------------------------------------------------

/** Four agents walking loops, as the served app's `?demo=1`. */
function startDemo() {
  const ellipse = (cx, cz, rx, rz) => new GroundPath(Array.from({ length: 400 }, (_, i) => {
    const a = (i / 400) * 2 * Math.PI;
    return [cx + rx * Math.cos(a), cz + rz * Math.sin(a)];
  }), true, "loop");
  const info = app.meta.emotion;
  app.engine.add([
    { path: circlePath(-3, -1, 1.8), emotion: emotionWeights(info, "happy"), phase: 0.3 },
    { path: ellipse(3, -1.5, 2.2, 1.4), emotion: emotionWeights(info, "sad"), phase: 2.1 },
    { path: circlePath(2.5, 3, 1.5), emotion: emotionWeights(info, "angry"), phase: 4.0 },
    { path: ellipse(-2.5, 3, 1.6, 1.2), emotion: weightsFromPoint(info, 0.5, -0.6), phase: 5.2 },
  ]);
}

async function start() {
  view.animate(beforeRender);
  setInterval(everySecond, 1000);
  await view.setUpXR($("xr"));
  requireWasmSimd();
  const meta = await loadMetadata();
  app.meta = meta;
  sliders = new LabelSliders($("sliders"), meta.emotion.labels, onSliders);
  disc.setLabels(Object.fromEntries(Object.entries(meta.emotion.points)
    .filter(([label]) => MAIN_LABELS.includes(label))));
  const mannequinUrl = new URL(meta.mannequin, location.href).href;
  const [{ ort, session }, template] = await Promise.all([loadRuntime(meta),
                                                          loadMannequin(mannequinUrl, toast)]);
  Object.assign(app, { ort, session, template });
  if (!template) sticksOnly(app);
  app.engine = new AgentEngine(ort, session, meta.step, lock);
  let scene = "";
  if (meta.scene) {
    const doc = await loadSceneDocument(meta.scene);
    drawScene(view, doc);
    app.crowd = await CrowdRunner.create(doc, meta, app.engine, {
      avoidance: params.get("avoidance") !== "0", seed: Number(params.get("seed") ?? 0),
    });
    scene = `; scene ${doc.name}${app.crowd.avoidance ? "" : " without avoidance"}`;
  }
  app.status = "running";
  app.ready = true;
  $("stat-status").textContent = `running: ${meta.emotion.labels.length} emotions, ${meta.step.fps} fps${scene}`;
  tick();
  if (params.get("demo") === "1") startDemo();
}

start().catch((err) => fail(err instanceof RuntimeError ? err.message
                                                        : `the page could not start: ${err.message}`));
