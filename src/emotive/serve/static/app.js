// The browser app of `emotive serve`: the shared scene of walking agents on a ground grid,
// with tools to place agents, draw their paths and change their emotions live, stick or
// mannequin figures, fixed and follow cameras, recording, and WebXR AR/VR.
//
// URL parameters: `?demo=1` fills an empty scene with four walking agents; `?token=T` is passed
// on to the websocket and every API call (servers started with --token).
//
// window.emotive is a read-only view of the app's state, for tests and the console:
//   ready             true once the rig, the figures and the socket are set up
//   agents()          ids of the agents in the latest frame
//   positions()       {id: [x, y, z]} world position of each agent's mover joint, latest frame
//   framesReceived    binary frames decoded so far
//   framesRendered    frames the render loop has drawn so far
//   lastFrame         {frame, time, ids} of the latest frame, or null
//   selected          the selected agent's id, or null
//   figureMode        "mannequin" or "sticks"
//   cameraMode        "fixed" or "follow"
//   joints            number of joints of the rig (/api/skeleton)
//   boundBones(id)    how many joints of agent `id` were found by name among the bones of its
//                     mannequin's skin (== joints when the mannequin is fully bound)
//   mannequinOffset(id)  largest distance (metres) from a bone of agent `id`'s mannequin to
//                     the same joint's world position in the latest frame, or null
//   drawnPath         the last path drawn with the mouse, [[x, z], ...] (metres)
//   toScreen(x, z)    page coordinates [px, py] of the ground point (x, z)
//   errors            the messages shown as error toasts so far
//   renderFps, streamFps, latencyMs   the numbers shown in the panel

import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { Connection, socketUrl, throttled } from "./protocol.js";
import { Rig } from "./rig.js";
import { Mannequin, StickFigure, emotionColor } from "./figures.js";
import { LabelSliders, MAIN_LABELS, ValenceArousalDisc, weightsText } from "./emotion-controls.js";
import { setUpXR } from "./xr.js";

const params = new URLSearchParams(location.search);
const token = params.get("token");
const demo = params.get("demo") === "1";

// Edits sent per second while a slider or the disc is dragged.
const EDITS_PER_SECOND = 20;
// A click within this distance (metres, on the ground) of an agent selects it.
const PICK_RADIUS = 0.8;
// Drawn paths keep a point every this many metres.
const PATH_SPACING = 0.2;
// A press that moves less than this (pixels) is a click.
const CLICK_PIXELS = 5;
// Wait before opening a closed websocket again, milliseconds.
const RECONNECT_MS = 2000;
// Websocket close code of a missing or wrong token (docs/serve.md).
const UNAUTHORIZED_CLOSE = 4401;
// Side of the ground grid, metres.
const GRID_SIZE = 40;
// Radius of the circle a placed agent walks, metres.
const PLACED_RADIUS = 1.5;
// Follow camera: offset behind and above the agent (metres) and smoothing rates (1/s).
const FOLLOW_BACK = 4.5;
const FOLLOW_UP = 2.2;
const FOLLOW_RATE = 2.5;
const LOOK_RATE = 6;

/** An API path with the page's token. */
function api(path) {
  const url = new URL(path, location.origin);
  if (token) url.searchParams.set("token", token);
  return url.pathname + url.search;
}

async function getJSON(path) {
  const response = await fetch(api(path));
  if (response.status === 401) {
    throw new Error(`GET ${path}: HTTP 401, this server needs its token: open the page as `
                    + "/?token=TOKEN (the --token given to emotive serve)");
  }
  if (!response.ok) throw new Error(`GET ${path}: HTTP ${response.status}`);
  return response.json();
}

const $ = (id) => document.getElementById(id);
const errors = [];

function toast(text) {
  errors.push(text);
  const div = document.createElement("div");
  div.className = "toast";
  div.textContent = text;
  $("toasts").append(div);
  setTimeout(() => div.remove(), 5000);
}

// --- the 3-D view ---------------------------------------------------------------------

const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
renderer.setSize(window.innerWidth, window.innerHeight);
renderer.xr.enabled = true;
$("view").append(renderer.domElement);

const scene = new THREE.Scene();
const background = new THREE.Color(0x1d2126);
scene.background = background;
scene.add(new THREE.HemisphereLight(0xffffff, 0x445566, 2.0));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
sun.position.set(5, 10, 7);
scene.add(sun);

/**
 * Lines every metre over a `size` x `size` square, the axes in `axisColor`. Each line is cut
 * into 1 m segments: some WebGL implementations (SwiftShader) drop a whole line that
 * crosses the camera's near plane instead of clipping it.
 */
function groundGrid(size, axisColor, lineColor) {
  const half = size / 2;
  const positions = [];
  const colors = [];
  const axis = new THREE.Color(axisColor);
  const line = new THREE.Color(lineColor);
  for (let i = -half; i <= half; i++) {
    const c = i === 0 ? axis : line;
    for (let j = -half; j < half; j++) {
      positions.push(i, 0, j, i, 0, j + 1, j, 0, i, j + 1, 0, i);
      for (let k = 0; k < 4; k++) colors.push(c.r, c.g, c.b);
    }
  }
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.Float32BufferAttribute(positions, 3));
  geometry.setAttribute("color", new THREE.Float32BufferAttribute(colors, 3));
  return new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ vertexColors: true }));
}

// Everything placed in scene coordinates (metres, Y up); AR moves it onto the real floor.
const world = new THREE.Group();
scene.add(world);
const floor = new THREE.Group();
const grid = groundGrid(GRID_SIZE, 0x8a96a3, 0x48515b);
const ground = new THREE.Mesh(new THREE.PlaneGeometry(GRID_SIZE, GRID_SIZE).rotateX(-Math.PI / 2),
                              new THREE.MeshStandardMaterial({
                                // Pushed back in depth so the grid lines on it always show.
                                color: 0x272c32, roughness: 1, polygonOffset: true,
                                polygonOffsetFactor: 1, polygonOffsetUnits: 4,
                              }));
floor.add(ground, grid);
world.add(floor);

const camera = new THREE.PerspectiveCamera(50, window.innerWidth / window.innerHeight, 0.05, 200);
camera.position.set(0, 7, 10.5);
const controls = new OrbitControls(camera, renderer.domElement);
controls.target.set(0, 0.5, 0);
controls.update();
const fixedView = { position: camera.position.clone(), target: controls.target.clone() };

function lineAt(color) {
  const line = new THREE.Line(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color }));
  line.frustumCulled = false;
  world.add(line);
  return line;
}
const drawnLine = lineAt(0x4fd1ff);
const selectedPathLine = lineAt(0xffd54f);

function setLine(line, points) {
  // A new geometry each time: the number of points changes.
  line.geometry.dispose();
  line.geometry = new THREE.BufferGeometry().setFromPoints(
    points.map(([x, z]) => new THREE.Vector3(x, 0.02, z)));
}

const selectionRing = new THREE.Mesh(new THREE.RingGeometry(0.35, 0.42, 40).rotateX(-Math.PI / 2),
                                     new THREE.MeshBasicMaterial({ color: 0xffffff }));
selectionRing.position.y = 0.01;
selectionRing.visible = false;
world.add(selectionRing);

window.addEventListener("resize", () => {
  camera.aspect = window.innerWidth / window.innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(window.innerWidth, window.innerHeight);
});

// --- app state --------------------------------------------------------------------------

const app = {
  skeleton: null,
  rig: null,
  template: null,
  figureMode: "mannequin",
  cameraMode: "fixed",
  mouseMode: "place",
  agents: new Map(),
  selected: null,
  lastFrame: null,
  framesReceived: 0,
  framesRendered: 0,
  drawnPath: [],
  recording: null,
  connection: null,
  ready: false,
  renderFps: 0,
  streamFps: 0,
};

/** One agent of the scene: its figures, placement and emotion in the latest frame. */
class AgentView {
  constructor(id) {
    this.id = id;
    this.group = new THREE.Group();
    this.sticks = new StickFigure(app.skeleton);
    this.mannequin = app.template ? new Mannequin(app.template, app.skeleton) : null;
    this.group.add(this.sticks.object);
    if (this.mannequin) this.group.add(this.mannequin.object);
    this.position = new THREE.Vector3();
    this.heading = new THREE.Vector3(0, 0, 1);
    this.color = new THREE.Color();
    this.va = { valence: 0, arousal: 0 };
    this.weights = {};
    this.points = null;
    this.posed = false;
    world.add(this.group);
    this.showMode();
  }

  showMode() {
    const mannequin = app.figureMode === "mannequin" && this.mannequin !== null;
    this.sticks.object.visible = !mannequin;
    if (this.mannequin) this.mannequin.object.visible = mannequin;
  }

  update(frame, b) {
    const { J, P, C } = frame;
    const mover = frame.mover.subarray(3 * b, 3 * b + 3);
    const next = new THREE.Vector3(mover[0], mover[1], mover[2]);
    const step = new THREE.Vector3(next.x - this.position.x, 0, next.z - this.position.z);
    // Heading from the walking direction, smoothed (the follow camera sits behind it).
    if (this.posed && step.lengthSq() > 1e-8) this.heading.lerp(step.normalize(), 0.15).normalize();
    this.position.copy(next);
    this.posed = true;
    this.va = { valence: frame.va[2 * b], arousal: frame.va[2 * b + 1] };
    this.weights = {};
    app.skeleton.labels.slice(0, C).forEach((label, c) => { this.weights[label] = frame.weights[C * b + c]; });
    emotionColor(this.va.valence, this.va.arousal, this.color);
    this.points = frame.points.subarray(3 * P * b, 3 * P * (b + 1));
    if (this.sticks.object.visible) {
      this.sticks.pose(this.points);
      this.sticks.color(this.color);
    }
    if (this.mannequin && this.mannequin.object.visible) {
      this.mannequin.pose(frame.rotations.subarray(4 * J * b, 4 * J * (b + 1)), mover, this.points);
      this.mannequin.color(this.color);
    }
  }

  /**
   * Largest distance (metres) between a bone of the posed mannequin and the same joint's
   * world position in the latest frame: zero when the skin follows the stream exactly.
   */
  mannequinOffset() {
    if (!this.mannequin || !this.points) return null;
    this.group.updateMatrixWorld(true);
    const here = new THREE.Vector3();
    const there = new THREE.Vector3();
    let worst = 0;
    this.mannequin.bones.forEach((bone, j) => {
      if (bone === null) return;
      bone.getWorldPosition(here);
      there.fromArray(this.points, 3 * j);
      worst = Math.max(worst, here.distanceTo(world.localToWorld(there)));
    });
    return worst;
  }

  dispose() {
    world.remove(this.group);
    this.sticks.dispose();
    if (this.mannequin) this.mannequin.dispose();
  }
}

// --- frames -----------------------------------------------------------------------------

let listIds = "";

function onFrame(frame) {
  app.framesReceived++;
  app.lastFrame = frame;
  const seen = new Set();
  for (let b = 0; b < frame.B; b++) {
    const id = frame.ids[b];
    seen.add(id);
    let agent = app.agents.get(id);
    if (!agent) {
      agent = new AgentView(id);
      app.agents.set(id, agent);
    }
    agent.update(frame, b);
  }
  for (const [id, agent] of app.agents) {
    if (!seen.has(id)) {
      agent.dispose();
      app.agents.delete(id);
      if (app.selected === id) select(null);
    }
  }
  const ids = [...app.agents.keys()].join(",");
  if (ids !== listIds) {
    listIds = ids;
    renderAgentList();
  }
  const selected = app.agents.get(app.selected);
  if (selected) disc.show(selected.va);
}

function renderAgentList() {
  const list = $("agent-list");
  list.replaceChildren();
  for (const id of app.agents.keys()) {
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
    const agent = app.agents.get(Number(button.dataset.agent));
    if (agent) button.firstChild.style.background = `#${agent.color.getHexString()}`;
  }
}

// --- selection and emotion editing ----------------------------------------------------

/**
 * Send a control message; resolves with its reply, or null when it failed (the error reply
 * is already on screen as a toast, through the connection's onError).
 */
function ask(message) {
  return app.connection.request(message).catch(() => null);
}

const sendEdit = throttled(({ id, emotion }) => {
  app.connection.send({ type: "set_emotion", id, emotion });
}, EDITS_PER_SECOND);

const disc = new ValenceArousalDisc($("va-disc"), (va) => {
  if (app.selected !== null) sendEdit({ id: app.selected, emotion: va });
});
let sliders = null;

function onSliders(weights) {
  const total = Object.values(weights).reduce((a, b) => a + b, 0);
  // All-zero weights name no emotion: wait for a non-zero one.
  if (app.selected !== null && total > 0) sendEdit({ id: app.selected, emotion: weightsText(weights) });
}

async function showSelectedPath() {
  const id = app.selected;
  if (id === null) {
    setLine(selectedPathLine, []);
    return;
  }
  const reply = await ask({ type: "state" });
  const agent = reply?.agents.find((a) => a.id === id);
  if (app.selected === id) setLine(selectedPathLine, agent?.path ?? []);
}

function select(id) {
  app.selected = id;
  const agent = id === null ? null : app.agents.get(id);
  $("selected-name").textContent = agent ? `Agent ${id}` : "none";
  $("remove-agent").disabled = !agent;
  disc.enabled = Boolean(agent);
  disc.reset();
  if (agent) disc.show(agent.va);
  if (sliders) sliders.set(agent?.weights, Boolean(agent));
  for (const button of $("agent-list").querySelectorAll("button")) {
    button.classList.toggle("on", Number(button.dataset.agent) === id);
  }
  showDownloads();
  showSelectedPath();
}

$("remove-agent").addEventListener("click", () => {
  if (app.selected === null) return;
  app.connection.send({ type: "remove_agent", id: app.selected });
  select(null);
});

// --- mouse on the ground: place, pick, draw ---------------------------------------------

const raycaster = new THREE.Raycaster();
const groundPlane = new THREE.Plane(new THREE.Vector3(0, 1, 0), 0);

/** The ground point (scene coordinates) under a pointer event, or null. */
function groundAt(event) {
  const rect = renderer.domElement.getBoundingClientRect();
  const ndc = new THREE.Vector2(((event.clientX - rect.left) / rect.width) * 2 - 1,
                                -((event.clientY - rect.top) / rect.height) * 2 + 1);
  raycaster.setFromCamera(ndc, camera);
  const hit = raycaster.ray.intersectPlane(groundPlane, new THREE.Vector3());
  return hit ? world.worldToLocal(hit) : null;
}

function nearestAgent(point) {
  let best = null;
  let bestDistance = PICK_RADIUS;
  for (const agent of app.agents.values()) {
    const d = Math.hypot(agent.position.x - point.x, agent.position.z - point.z);
    if (d < bestDistance) {
      best = agent;
      bestDistance = d;
    }
  }
  return best;
}

const round = (v) => Math.round(v * 1000) / 1000;

// An agent just added is selected once its first frame arrives.
let pendingSelect = null;

async function addAgent(path) {
  const reply = await ask({ type: "add_agent", path });
  if (reply) pendingSelect = reply.id;
}

function onClick(point) {
  const agent = nearestAgent(point);
  if (agent) select(agent.id);
  else if (app.mouseMode === "place") {
    addAgent({ shape: "circle", center: [round(point.x), round(point.z)], radius: PLACED_RADIUS });
  } else select(null);
}

async function onPathDrawn(points) {
  app.drawnPath = points;
  if (app.selected !== null) {
    const id = app.selected;
    const ok = await ask({ type: "set_path", id, path: points });
    if (ok && app.selected === id) showSelectedPath();
  } else {
    await addAgent(points);
  }
}

let press = null;

renderer.domElement.addEventListener("pointerdown", (event) => {
  if (event.button !== 0 || renderer.xr.isPresenting) return;
  const point = groundAt(event);
  press = { x: event.clientX, y: event.clientY, point, drawing: app.mouseMode === "draw" && point !== null };
  if (press.drawing) {
    renderer.domElement.setPointerCapture(event.pointerId);
    press.path = [[round(point.x), round(point.z)]];
    setLine(drawnLine, press.path);
  }
});

renderer.domElement.addEventListener("pointermove", (event) => {
  if (!press?.drawing) return;
  const point = groundAt(event);
  if (!point) return;
  const [lx, lz] = press.path[press.path.length - 1];
  if (Math.hypot(point.x - lx, point.z - lz) >= PATH_SPACING) {
    press.path.push([round(point.x), round(point.z)]);
    setLine(drawnLine, press.path);
  }
});

renderer.domElement.addEventListener("pointerup", (event) => {
  if (!press) return;
  const moved = Math.hypot(event.clientX - press.x, event.clientY - press.y);
  const { drawing, path, point } = press;
  press = null;
  if (drawing && path.length >= 2) {
    const end = groundAt(event);
    const [lx, lz] = path[path.length - 1];
    if (end && Math.hypot(end.x - lx, end.z - lz) > 1e-3) path.push([round(end.x), round(end.z)]);
    onPathDrawn(path);
  } else if (moved < CLICK_PIXELS && point) {
    if (drawing) setLine(drawnLine, app.drawnPath);
    onClick(point);
  }
});

// --- toggles ----------------------------------------------------------------------------

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
  for (const agent of app.agents.values()) agent.showMode();
});

toggleGroup([["camera-fixed", "fixed"], ["camera-follow", "follow"]], (mode) => {
  app.cameraMode = mode;
  if (mode === "fixed") {
    camera.position.copy(fixedView.position);
    controls.target.copy(fixedView.target);
    controls.update();
  } else {
    fixedView.position.copy(camera.position);
    fixedView.target.copy(controls.target);
    if (app.selected === null && app.agents.size) select(app.agents.keys().next().value);
    followLook.copy(controls.target);
  }
  controls.enabled = mode === "fixed" && app.mouseMode === "place";
});

// --- recording --------------------------------------------------------------------------

$("record-start").addEventListener("click", async () => {
  const reply = await ask({ type: "start_recording" });
  if (!reply) return;
  app.recording = { id: reply.id, state: "started", agents: [] };
  $("record-start").disabled = true;
  $("record-stop").disabled = false;
  $("record-state").textContent = `recording ${reply.id}...`;
  showDownloads();
});

$("record-stop").addEventListener("click", async () => {
  const reply = await ask({ type: "stop_recording" });
  $("record-start").disabled = false;
  $("record-stop").disabled = true;
  if (!reply) return;
  app.recording = { id: reply.id, state: "stopped", agents: reply.agents };
  $("record-state").textContent = `recording ${reply.id}: ${reply.frames} frames, ${app.recording.agents.length} agents`;
  showDownloads();
});

function showDownloads() {
  const box = $("downloads");
  box.replaceChildren();
  const rec = app.recording;
  if (!rec || rec.state !== "stopped" || rec.agents.length === 0) return;
  const agent = rec.agents.includes(app.selected) ? app.selected : rec.agents[0];
  for (const format of ["bvh", "glb"]) {
    const a = document.createElement("a");
    a.className = "download";
    a.href = api(`/api/recordings/${encodeURIComponent(rec.id)}?agent=${agent}&format=${format}`);
    a.download = `emotive-${rec.id}-agent${agent}.${format}`;
    a.textContent = `Agent ${agent} as ${format.toUpperCase()}`;
    box.append(a);
  }
}

// --- demo scene ---------------------------------------------------------------------------

function loop(cx, cz, rx, rz, n = 12) {
  const points = [];
  for (let i = 0; i < n; i++) {
    const a = (i / n) * 2 * Math.PI;
    points.push([round(cx + rx * Math.cos(a)), round(cz + rz * Math.sin(a))]);
  }
  return { points, closed: true };
}

const DEMO_AGENTS = [
  { path: { shape: "circle", center: [-3, -1], radius: 1.8 }, emotion: "happy" },
  { path: loop(3, -1.5, 2.2, 1.4), emotion: "sad" },
  { path: { shape: "circle", center: [2.5, 3], radius: 1.5 }, emotion: "angry" },
  { path: loop(-2.5, 3, 1.6, 1.2), emotion: { valence: 0.5, arousal: -0.6 } },
];

async function startDemo() {
  const state = await app.connection.request({ type: "state" });
  if (state.agents.length) return;
  for (const agent of DEMO_AGENTS) await app.connection.request({ type: "add_agent", ...agent });
}

// --- render loop and stats --------------------------------------------------------------

const timer = new THREE.Timer();
const followLook = new THREE.Vector3();
let xr = null;
let rendered = 0;
let statsAt = performance.now();
let framesAtStats = 0;

function updateCamera(dt) {
  const agent = app.agents.get(app.selected);
  if (app.cameraMode !== "follow" || !agent || renderer.xr.isPresenting) return;
  const wanted = agent.position.clone().addScaledVector(agent.heading, -FOLLOW_BACK);
  wanted.y = FOLLOW_UP;
  const look = agent.position.clone();
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
  updateCamera(dt);
  if (pendingSelect !== null && app.agents.has(pendingSelect)) {
    select(pendingSelect);
    pendingSelect = null;
  }
  const selected = app.agents.get(app.selected);
  selectionRing.visible = Boolean(selected);
  if (selected) selectionRing.position.set(selected.position.x, 0.01, selected.position.z);
  renderer.render(scene, camera);
  rendered++;
  app.framesRendered++;
}

function everySecond() {
  const now = performance.now();
  const seconds = (now - statsAt) / 1000;
  const frames = app.framesReceived;
  app.renderFps = rendered / seconds;
  app.streamFps = (frames - framesAtStats) / seconds;
  statsAt = now;
  rendered = 0;
  framesAtStats = frames;
  $("stat-fps").textContent = app.renderFps.toFixed(0);
  $("stat-stream").textContent = app.streamFps.toFixed(0);
  const latency = app.connection?.latencyMs;
  $("stat-latency").textContent = latency == null ? "-" : latency.toFixed(1);
  refreshSwatches();
  if (app.connection?.isOpen) app.connection.ping();
}

// --- the debug hook -----------------------------------------------------------------------

window.emotive = Object.freeze({
  get ready() { return app.ready; },
  agents: () => [...app.agents.keys()],
  positions: () => Object.fromEntries([...app.agents].map(([id, a]) => [id, a.position.toArray()])),
  get framesReceived() { return app.framesReceived; },
  get framesRendered() { return app.framesRendered; },
  get lastFrame() {
    const f = app.lastFrame;
    return f && { frame: f.frame, time: f.time, ids: [...f.ids] };
  },
  get selected() { return app.selected; },
  get figureMode() { return app.figureMode; },
  get cameraMode() { return app.cameraMode; },
  get joints() { return app.skeleton ? app.skeleton.joints.length : 0; },
  boundBones: (id) => app.agents.get(id)?.mannequin?.boundBones ?? 0,
  mannequinOffset: (id) => app.agents.get(id)?.mannequinOffset() ?? null,
  get drawnPath() { return app.drawnPath.map((p) => [...p]); },
  toScreen: (x, z) => {
    const p = world.localToWorld(new THREE.Vector3(x, 0, z)).project(camera);
    const rect = renderer.domElement.getBoundingClientRect();
    return [rect.left + ((p.x + 1) / 2) * rect.width, rect.top + ((1 - p.y) / 2) * rect.height];
  },
  get errors() { return [...errors]; },
  get renderFps() { return app.renderFps; },
  get streamFps() { return app.streamFps; },
  get latencyMs() { return app.connection?.latencyMs ?? null; },
});

// --- start --------------------------------------------------------------------------------

async function loadMannequin() {
  try {
    const gltf = await new GLTFLoader().loadAsync(api("/api/mannequin.glb"));
    return gltf.scene;
  } catch (err) {
    toast(`mannequin unavailable, drawing stick figures: ${err.message}`);
    return null;
  }
}

/**
 * Open the websocket; when it closes, open it again after RECONNECT_MS (the server may be
 * restarting), unless the server refused the token.
 */
function connect() {
  const status = (text) => { $("stat-connection").textContent = text; };
  app.connection = new Connection(socketUrl(token), {
    rig: app.rig,
    onFrame,
    onError: toast,
    onOpen: () => status("connected"),
    onClose: (code) => {
      if (code === UNAUTHORIZED_CLOSE) {
        status("the server refused the token: open the page as /?token=TOKEN");
        return;
      }
      status(`disconnected (code ${code}), reconnecting...`);
      // A failed attempt closes too, which schedules the next one.
      setTimeout(() => connect().catch(() => {}), RECONNECT_MS);
    },
  });
  return app.connection.open();
}

async function start() {
  const [skeleton, template] = await Promise.all([getJSON("/api/skeleton"), loadMannequin()]);
  app.skeleton = skeleton;
  app.rig = new Rig(skeleton);
  app.template = template;
  if (!template) {
    app.figureMode = "sticks";
    $("figure-sticks").classList.add("on");
    $("figure-mannequin").classList.remove("on");
    $("figure-mannequin").disabled = true;
  }
  sliders = new LabelSliders($("sliders"), skeleton.labels, onSliders);
  disc.setLabels(Object.fromEntries(Object.entries(skeleton.points)
    .filter(([label]) => MAIN_LABELS.includes(label))));
  renderer.setAnimationLoop(render);
  setInterval(everySecond, 1000);
  xr = await setUpXR(renderer, scene, world, $("xr"), {
    onStart: (session) => {
      if (session.environmentBlendMode !== "opaque") {
        scene.background = null;
        floor.visible = false;
      }
    },
    onEnd: () => {
      scene.background = background;
      floor.visible = true;
    },
  });
  await connect();
  if (demo) await startDemo();
  app.ready = true;
}

start().catch((err) => {
  $("stat-connection").textContent = `not started: ${err.message}`;
  toast(`the app could not start: ${err.message}`);
});
