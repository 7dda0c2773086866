// The browser runtime of `emotive export web`: gait agents stepped in the page by
// onnxruntime-web (engine.js), drawn with the served app's figures, emotion controls and
// WebXR buttons. No emotive server: any static file server of the exported folder will do.
//
// URL parameters: `?demo=1` starts with four walking agents; `?paused=1` starts with the
// clock stopped (the agents step only through the test hook or the Pause button).
//
// window.emotiveWeb (hook.js) is a read-only view of the page's state for tests and the
// console, with the test functions that feed the page the inputs a test feeds Python.

import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { Mannequin, StickFigure, emotionColor } from "./figures.js";
import { LabelSliders, MAIN_LABELS, ValenceArousalDisc } from "./emotion-controls.js";
import { setUpXR } from "./xr.js";
import { createView } from "./scene.js";
import { AgentEngine, Lock } from "./engine.js";
import { installHook } from "./hook.js";
import { GroundPath, circlePath, waypointPath } from "./paths.js";
import { emotionWeights, pointOf, weightsFromPoint, weightsObject } from "./emotion.js";
import { RuntimeError, loadMetadata, loadRuntime, requireWasmSimd } from "./runtime.js";

const params = new URLSearchParams(location.search);

// A click within this distance (metres, on the ground) of an agent selects it.
const PICK_RADIUS = 0.8;
// Drawn paths keep a point every this many metres.
const PATH_SPACING = 0.2;
// A press that moves less than this (pixels) is a click.
const CLICK_PIXELS = 5;
// Radius of the circle a placed agent walks, metres.
const PLACED_RADIUS = 1.5;
// Steps the clock may run at once to catch up after a slow frame; beyond, time is dropped.
const MAX_CATCH_UP = 4;
// Follow camera: offset behind and above the agent (metres) and smoothing rates (1/s).
const FOLLOW_BACK = 4.5;
const FOLLOW_UP = 2.2;
const FOLLOW_RATE = 2.5;
const LOOK_RATE = 6;

const $ = (id) => document.getElementById(id);
const round = (v) => Math.round(v * 1000) / 1000;
const errors = [];

function toast(text) {
  errors.push(text);
  const div = document.createElement("div");
  div.className = "toast";
  div.textContent = text;
  $("toasts").append(div);
  setTimeout(() => div.remove(), 5000);
}

const view = createView($("view"));
const { renderer, camera, controls, world, selectionRing } = view;
const lock = new Lock();

const app = {
  meta: null, engine: null, ort: null, session: null, template: null,
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
class AgentView {
  constructor(id) {
    const skeleton = app.meta.skeleton;
    this.id = id;
    this.group = new THREE.Group();
    this.sticks = new StickFigure(skeleton);
    this.mannequin = app.template ? new Mannequin(app.template, skeleton) : null;
    this.group.add(this.sticks.object);
    if (this.mannequin) this.group.add(this.mannequin.object);
    this.position = new THREE.Vector3();
    this.heading = new THREE.Vector3(0, 0, 1);
    this.color = new THREE.Color();
    this.va = { valence: 0, arousal: 0 };
    this.points = null;
    world.add(this.group);
    this.showMode();
  }

  showMode() {
    const mannequin = app.figureMode === "mannequin" && this.mannequin !== null;
    this.sticks.object.visible = !mannequin;
    if (this.mannequin) this.mannequin.object.visible = mannequin;
  }

  /** Pose from row `b` of `frame` (hidden while the agent takes its start steps). */
  update(frame, b, agent) {
    this.group.visible = frame.walking[b] === 1;
    if (!this.group.visible) return;
    const { J, P } = app.engine;
    const mover = frame.root_position.subarray(3 * b, 3 * b + 3);
    const step = new THREE.Vector3(mover[0] - this.position.x, 0, mover[2] - this.position.z);
    // Heading from the walking direction, smoothed (the follow camera sits behind it).
    if (this.points && step.lengthSq() > 1e-8) this.heading.lerp(step.normalize(), 0.15).normalize();
    this.position.set(mover[0], mover[1], mover[2]);
    this.va = pointOf(app.meta.emotion, agent.emotion);
    emotionColor(this.va.valence, this.va.arousal, this.color);
    this.points = frame.world.subarray(3 * P * b, 3 * P * (b + 1));
    if (this.sticks.object.visible) {
      this.sticks.pose(this.points);
      this.sticks.color(this.color);
    }
    if (this.mannequin?.object.visible) {
      this.mannequin.pose(frame.rotations.subarray(4 * J * b, 4 * J * (b + 1)), mover, this.points);
      this.mannequin.color(this.color);
    }
  }

  dispose() {
    world.remove(this.group);
    this.sticks.dispose();
    if (this.mannequin) this.mannequin.dispose();
  }
}

let listIds = "";

/** Bring the figures to the engine's latest frame. */
function showFrame(frame) {
  app.shownFrame = frame;
  const seen = new Set();
  frame.ids.forEach((id, b) => {
    const agent = app.engine.agent(id);
    if (!agent) return;
    seen.add(id);
    let v = app.views.get(id);
    if (!v) {
      v = new AgentView(id);
      app.views.set(id, v);
    }
    v.update(frame, b, agent);
  });
  for (const [id, v] of app.views) {
    if (!seen.has(id)) {
      v.dispose();
      app.views.delete(id);
      if (app.selected === id) select(null);
    }
  }
  const ids = [...app.views.keys()].join(",");
  if (ids !== listIds) {
    listIds = ids;
    renderAgentList();
  }
  const selected = app.views.get(app.selected);
  if (selected) disc.show(selected.va);
}

function renderAgentList() {
  const list = $("agent-list");
  list.replaceChildren();
  for (const id of app.views.keys()) {
    const li = document.createElement("li");
    const button = document.createElement("button");
    button.dataset.agent = String(id);
    button.classList.toggle("on", id === app.selected);
    const swatch = document.createElement("span");
    swatch.className = "swatch";
    button.append(swatch, `Agent ${id}`);
    button.addEventListener("click", () => select(id));
    li.append(button);
    list.append(li);
  }
  refreshSwatches();
}

function refreshSwatches() {
  for (const button of $("agent-list").querySelectorAll("button")) {
    const v = app.views.get(Number(button.dataset.agent));
    if (v) button.firstChild.style.background = `#${v.color.getHexString()}`;
  }
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
  for (const button of $("agent-list").querySelectorAll("button")) {
    button.classList.toggle("on", Number(button.dataset.agent) === app.selected);
  }
  view.setLine(view.selectedPathLine, agent ? agent.path.outline() : []);
}

$("remove-agent").addEventListener("click", () => {
  if (app.selected === null || !app.engine) return;
  app.engine.remove([app.selected]);
  select(null);
});

// --- mouse on the ground: place, pick, draw --------------------------------------------------

function nearestView(point) {
  let best = null;
  let bestDistance = PICK_RADIUS;
  for (const v of app.views.values()) {
    const d = Math.hypot(v.position.x - point.x, v.position.z - point.z);
    if (v.group.visible && d < bestDistance) {
      best = v;
      bestDistance = d;
    }
  }
  return best;
}

// An agent added with the mouse is selected once it shows.
let pendingSelect = null;

async function addAgent(path) {
  const engine = running();
  if (!engine) return;
  const emotion = emotionWeights(app.meta.emotion, { neutral: 1 });
  [pendingSelect] = await engine.add([{ path, emotion, phase: Math.random() * 2 * Math.PI }]);
}

function onClick(point) {
  const v = nearestView(point);
  if (v) select(v.id);
  else if (app.mouseMode === "place") addAgent(circlePath(round(point.x), round(point.z), PLACED_RADIUS));
  else select(null);
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

let press = null;

renderer.domElement.addEventListener("pointerdown", (event) => {
  if (event.button !== 0 || renderer.xr.isPresenting) return;
  const point = view.groundAt(event);
  press = { x: event.clientX, y: event.clientY, point, drawing: app.mouseMode === "draw" && point !== null };
  if (press.drawing) {
    renderer.domElement.setPointerCapture(event.pointerId);
    press.path = [[round(point.x), round(point.z)]];
    view.setLine(view.drawnLine, press.path);
  }
});

renderer.domElement.addEventListener("pointermove", (event) => {
  if (!press?.drawing) return;
  const point = view.groundAt(event);
  if (!point) return;
  const [lx, lz] = press.path[press.path.length - 1];
  if (Math.hypot(point.x - lx, point.z - lz) >= PATH_SPACING) {
    press.path.push([round(point.x), round(point.z)]);
    view.setLine(view.drawnLine, press.path);
  }
});

renderer.domElement.addEventListener("pointerup", (event) => {
  if (!press) return;
  const moved = Math.hypot(event.clientX - press.x, event.clientY - press.y);
  const { drawing, path, point } = press;
  press = null;
  if (drawing && path.length >= 2) {
    const end = view.groundAt(event);
    const [lx, lz] = path[path.length - 1];
    if (end && Math.hypot(end.x - lx, end.z - lz) > 1e-3) path.push([round(end.x), round(end.z)]);
    onPathDrawn(path);
  } else if (moved < CLICK_PIXELS && point) {
    if (drawing) view.setLine(view.drawnLine, app.drawnPath);
    onClick(point);
  }
});

// --- toggles -----------------------------------------------------------------------------------

/** Buttons of which one is on; `onChange(value)` when another is pressed. */
function toggleGroup(buttons, onChange) {
  let current = buttons[0][1];
  for (const [id, value] of buttons) {
    $(id).addEventListener("click", () => {
      if (value === current) return;
      current = value;
      for (const [other] of buttons) $(other).classList.toggle("on", other === id);
      onChange(value);
    });
  }
}

toggleGroup([["mode-place", "place"], ["mode-draw", "draw"]], (mode) => {
  app.mouseMode = mode;
  controls.enabled = mode === "place" && app.cameraMode === "fixed";
  $("mode-hint").textContent = mode === "draw"
    ? "Press, drag and release on the ground: the selected agent walks the path (no selection: a new agent)."
    : "Click the ground to place an agent; click an agent to select it.";
});

toggleGroup([["figure-mannequin", "mannequin"], ["figure-sticks", "sticks"]], (mode) => {
  app.figureMode = mode;
  for (const v of app.views.values()) v.showMode();
  if (app.shownFrame) showFrame(app.shownFrame);
});

const followLook = new THREE.Vector3();

toggleGroup([["camera-fixed", "fixed"], ["camera-follow", "follow"]], (mode) => {
  app.cameraMode = mode;
  if (mode === "fixed") {
    camera.position.copy(view.fixedView.position);
    controls.target.copy(view.fixedView.target);
    controls.update();
  } else {
    view.fixedView.position.copy(camera.position);
    view.fixedView.target.copy(controls.target);
    if (app.selected === null && app.views.size) select(app.views.keys().next().value);
    followLook.copy(controls.target);
  }
  controls.enabled = mode === "fixed" && app.mouseMode === "place";
});

function setRunning(on) {
  app.running = on;
  $("pause").textContent = on ? "Pause" : "Run";
  $("pause").classList.toggle("on", !on);
}
$("pause").addEventListener("click", () => setRunning(!app.running));
setRunning(app.running);

// --- the clock: fixed steps at the model's frame rate ----------------------------------------

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
      await engine.step();
      backlog -= h;
    }
  } catch (err) {
    fail(`the agents stopped: a step failed (${err.message})`);
    return;
  }
  setTimeout(tick, Math.max(1, (h - backlog) * 1000));
}

// --- render loop and stats ---------------------------------------------------------------------

const timer = new THREE.Timer();
let xr = null;
let rendered = 0;
let statsAt = performance.now();
let stepsAtStats = 0;

function updateCamera(dt) {
  const v = app.views.get(app.selected);
  if (app.cameraMode !== "follow" || !v || renderer.xr.isPresenting) return;
  const wanted = v.position.clone().addScaledVector(v.heading, -FOLLOW_BACK);
  wanted.y = FOLLOW_UP;
  const look = v.position.clone();
  look.y = 1.0;
  camera.position.lerp(world.localToWorld(wanted), 1 - Math.exp(-FOLLOW_RATE * dt));
  followLook.lerp(world.localToWorld(look), 1 - Math.exp(-LOOK_RATE * dt));
  camera.lookAt(followLook);
}

function render(time, xrFrame) {
  timer.update(time);
  // Capped so that a long pause (a hidden tab) does not jump the follow camera.
  const dt = Math.min(timer.getDelta(), 0.5);
  if (xrFrame && xr) xr.update(xrFrame);
  const frame = app.engine?.frame;
  if (frame && frame !== app.shownFrame) showFrame(frame);
  updateCamera(dt);
  if (pendingSelect !== null && app.views.get(pendingSelect)?.group.visible) {
    select(pendingSelect);
    pendingSelect = null;
  }
  const selected = app.views.get(app.selected);
  selectionRing.visible = Boolean(selected?.group.visible);
  if (selected) selectionRing.position.set(selected.position.x, 0.01, selected.position.z);
  renderer.render(view.scene, camera);
  rendered++;
  app.framesRendered++;
}

function everySecond() {
  const now = performance.now();
  const seconds = (now - statsAt) / 1000;
  const steps = app.engine?.frames ?? 0;
  app.renderFps = rendered / seconds;
  app.stepsPerSecond = (steps - stepsAtStats) / seconds;
  statsAt = now;
  rendered = 0;
  stepsAtStats = steps;
  $("stat-fps").textContent = app.renderFps.toFixed(0);
  $("stat-steps").textContent = app.engine ? app.stepsPerSecond.toFixed(0) : "-";
  const ms = app.engine?.medianMs();
  $("stat-step-ms").textContent = ms == null ? "-" : ms.toFixed(1);
  refreshSwatches();
}

// --- the hook for tests and the console ----------------------------------------------------------

installHook({ app, view, errors, lock, running, setRunning });

// --- start ---------------------------------------------------------------------------------------

async function loadMannequin(meta) {
  try {
    return (await new GLTFLoader().loadAsync(new URL(meta.mannequin, location.href).href)).scene;
  } catch (err) {
    toast(`mannequin unavailable, drawing stick figures: ${err.message}`);
    return null;
  }
}

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
  renderer.setAnimationLoop(render);
  setInterval(everySecond, 1000);
  xr = await setUpXR(renderer, view.scene, world, $("xr"), {
    onStart: (session) => {
      if (session.environmentBlendMode !== "opaque") {
        view.scene.background = null;
        view.floor.visible = false;
      }
    },
    onEnd: () => {
      view.scene.background = view.background;
      view.floor.visible = true;
    },
  });
  requireWasmSimd();
  const meta = await loadMetadata();
  app.meta = meta;
  sliders = new LabelSliders($("sliders"), meta.emotion.labels, onSliders);
  disc.setLabels(Object.fromEntries(Object.entries(meta.emotion.points)
    .filter(([label]) => MAIN_LABELS.includes(label))));
  const [{ ort, session }, template] = await Promise.all([loadRuntime(meta), loadMannequin(meta)]);
  Object.assign(app, { ort, session, template });
  if (!template) {
    app.figureMode = "sticks";
    $("figure-sticks").classList.add("on");
    $("figure-mannequin").classList.remove("on");
    $("figure-mannequin").disabled = true;
  }
  app.engine = new AgentEngine(ort, session, meta.step, lock);
  app.status = "running";
  app.ready = true;
  $("stat-status").textContent = `running: ${meta.emotion.labels.length} emotions, ${meta.step.fps} fps`;
  tick();
  if (params.get("demo") === "1") startDemo();
}

start().catch((err) => fail(err instanceof RuntimeError ? err.message
                                                        : `the page could not start: ${err.message}`));
