// The browser app of `emotive serve`: the shared scene of walking agents on a ground grid,
// with tools to place agents, draw their paths and change their emotions live, stick or
// mannequin figures, fixed and follow cameras, recording, and WebXR AR/VR. A server started
// with --scene sends its geometry when the page joins: the area, obstacles and the groups'
// spawn and goal areas are drawn on the ground, and the path tools give way to dropping
// agents with a goal and drawing obstacles (scene-view.js, scene-tools.js).
//
// URL parameters: `?demo=1` fills an empty scene with four walking agents (not with a scene);
// `?token=T` is passed on to the websocket and every API call (servers started with --token).
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
//   mouseMode         "place" or "draw"; with a scene "place" (select), "agent" or "obstacle"
//   scene             the latest scene message of a server with --scene, or null
//   sceneDrawn()      what the view draws of it, read back from the lines on the ground:
//                     {version, area: [[x, z], ...], obstacles: [[[x, z], ...], ...],
//                     spawns: [...], goals: [...]} (goals: the exit areas)
//   draftObstacle     the corners of the obstacle being drawn, [[x, z], ...]
//   dropStart         where the agent being dropped stands, [x, z], or null
//   dropEmotion       the emotion a dropped agent gets (the emotion controls, no selection)
//   colors()          {background, ground, figures: {id: [...]}}: the colours drawn, "#rrggbb"
//                     (the scene's background, the ground's material, each agent's shown
//                     figure's materials)

import { Connection, socketUrl, throttled } from "./protocol.js";
import { Rig } from "./rig.js";
import { LabelSliders, MAIN_LABELS, ValenceArousalDisc, weightsText } from "./emotion-controls.js";
import { createView } from "./scene-setup.js";
import { SceneDrawing } from "./scene-view.js";
import { SceneTools } from "./scene-tools.js";
import { listenToGround, round } from "./ground-input.js";
import { AgentFigures, dropUnseen, figuresOf, loadMannequin } from "./agent-figures.js";
import { FollowCamera } from "./follow-camera.js";
import {
  AgentList, Rates, cameraButtons, collapsiblePanel, figureButtons, mouseModeButtons, sticksOnly,
  toaster,
} from "./panel.js";

const params = new URLSearchParams(location.search);
const token = params.get("token");
const demo = params.get("demo") === "1";

// Edits sent per second while a slider or the disc is dragged.
const EDITS_PER_SECOND = 20;
// Wait before opening a closed websocket again, milliseconds.
const RECONNECT_MS = 2000;
// Websocket close code of a missing or wrong token (docs/serve.md).
const UNAUTHORIZED_CLOSE = 4401;
// Radius of the circle a placed agent walks, metres.
const PLACED_RADIUS = 1.5;

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
const toast = toaster(errors);

// --- the 3-D view ---------------------------------------------------------------------

const view = createView($("view"));
const cameras = new FollowCamera(view);

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
  scene: null,
  dropEmotion: "neutral",
};

/** One agent of the scene: its figures, placement and emotion in the latest frame. */
class AgentView extends AgentFigures {
  constructor(id) {
    super(id, app.skeleton, app.template, view.world, app.figureMode);
    this.weights = {};
  }

  update(frame, b) {
    const { J, P, C } = frame;
    this.weights = {};
    app.skeleton.labels.slice(0, C).forEach((label, c) => { this.weights[label] = frame.weights[C * b + c]; });
    this.pose(frame.mover.subarray(3 * b, 3 * b + 3),
              { valence: frame.va[2 * b], arousal: frame.va[2 * b + 1] },
              frame.points.subarray(3 * P * b, 3 * P * (b + 1)),
              frame.rotations.subarray(4 * J * b, 4 * J * (b + 1)));
  }
}

// --- frames -----------------------------------------------------------------------------

const agentList = new AgentList((id) => select(id));

function onFrame(frame) {
  app.framesReceived++;
  app.lastFrame = frame;
  const seen = new Set();
  for (let b = 0; b < frame.B; b++) {
    const id = frame.ids[b];
    seen.add(id);
    figuresOf(app.agents, id, (i) => new AgentView(i)).update(frame, b);
  }
  dropUnseen(app.agents, seen, (id) => { if (app.selected === id) select(null); });
  agentList.update(app.agents, app.selected);
  const selected = app.agents.get(app.selected);
  if (selected) disc.show(selected.va);
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
  else if (app.mouseMode === "agent") app.dropEmotion = va;
});
let sliders = null;

function onSliders(weights) {
  const total = Object.values(weights).reduce((a, b) => a + b, 0);
  // All-zero weights name no emotion: wait for a non-zero one.
  if (total === 0) return;
  if (app.selected !== null) sendEdit({ id: app.selected, emotion: weightsText(weights) });
  else if (app.mouseMode === "agent") app.dropEmotion = weightsText(weights);
}

async function showSelectedPath() {
  const id = app.selected;
  if (id === null) {
    view.setLine(view.selectedPathLine, []);
    return;
  }
  const reply = await ask({ type: "state" });
  const agent = reply?.agents.find((a) => a.id === id);
  if (app.selected === id) view.setLine(view.selectedPathLine, agent?.path ?? []);
}

function select(id) {
  app.selected = id;
  const agent = id === null ? null : app.agents.get(id);
  $("selected-name").textContent = agent ? `Agent ${id}` : "none";
  $("remove-agent").disabled = !agent;
  // Without a selection, in the drop-agent mode, the controls choose the new agents' emotion.
  const dropping = !agent && app.mouseMode === "agent";
  disc.enabled = Boolean(agent) || dropping;
  disc.reset();
  if (agent) disc.show(agent.va);
  if (sliders) sliders.set(agent?.weights, Boolean(agent) || dropping);
  agentList.mark(id);
  showDownloads();
  showSelectedPath();
}

$("remove-agent").addEventListener("click", () => {
  if (app.selected === null) return;
  app.connection.send({ type: "remove_agent", id: app.selected });
  select(null);
});

// --- mouse on the ground: place, pick, draw ---------------------------------------------

// An agent just added is selected once its first frame arrives.
let pendingSelect = null;

async function addAgent(path) {
  const reply = await ask({ type: "add_agent", path });
  if (reply) pendingSelect = reply.id;
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

listenToGround(view, app, app.agents, {
  select,
  // With a scene, a click on the ground only drops the selection (agents navigate).
  place: (x, z) => (app.scene ? select(null)
    : addAgent({ shape: "circle", center: [x, z], radius: PLACED_RADIUS })),
  drawn: onPathDrawn,
});

// --- a scene: its geometry on the ground, the drop-agent and obstacle tools ---------------

const sceneDrawing = new SceneDrawing(view.world);
const sceneTools = new SceneTools(view, sceneDrawing, app, {
  request: ask,
  emotion: () => app.dropEmotion,
  modeChanged: (mode) => {
    if (mode === "agent") app.dropEmotion = "neutral";
    select(null);
  },
});

/**
 * Look at the whole area from above its near side (the fixed camera's place too), its middle
 * in the middle of the part of the page the panel leaves free.
 */
function frameScene() {
  const b = sceneDrawing.bounds();
  const cz = (b.minZ + b.maxZ) / 2;
  const d = Math.max(8, 1.25 * Math.max(b.maxX - b.minX, b.maxZ - b.minZ));
  const { camera } = view;
  // Metres across the view at the area's middle; the panel covers its left `covered` share.
  const across = 2 * Math.hypot(0.65 * d, d) * Math.tan((camera.fov * Math.PI) / 360) * camera.aspect;
  const covered = $("panel").getBoundingClientRect().right / window.innerWidth;
  const cx = (b.minX + b.maxX) / 2 - (covered / 2) * across;
  camera.position.set(cx, 0.65 * d, cz + d);
  view.controls.target.set(cx, 0, cz);
  view.controls.update();
  view.fixedView.position.copy(view.camera.position);
  view.fixedView.target.copy(view.controls.target);
}

/** A server message that answers no request: the scene's geometry (on joining, on changes). */
function onNotice(message) {
  if (message.type !== "scene") return;
  const first = app.scene === null;
  app.scene = message;
  sceneDrawing.show(message);
  if (first) {
    frameScene();
    sceneTools.enable();
  }
}

// --- toggles ----------------------------------------------------------------------------

// With a scene, collapsing or expanding the panel frames the area again beside it.
collapsiblePanel(() => { if (app.scene && app.cameraMode === "fixed") frameScene(); });
mouseModeButtons(app, view);
figureButtons(app, app.agents);
cameraButtons(app, cameras, app.agents, select);

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
  // A scene (its message comes before any reply) has agents of its own, and no paths.
  if (state.agents.length || app.scene) return;
  for (const agent of DEMO_AGENTS) await app.connection.request({ type: "add_agent", ...agent });
}

// --- render loop and stats --------------------------------------------------------------

const rates = new Rates();

/** Before each frame is drawn, `dt` seconds after the last. */
function beforeRender(dt) {
  cameras.update(app.agents.get(app.selected), dt);
  if (pendingSelect !== null && app.agents.has(pendingSelect)) {
    select(pendingSelect);
    pendingSelect = null;
  }
  view.ringAt(app.agents.get(app.selected)?.position);
  app.framesRendered++;
}

function everySecond() {
  const { rendered, received } = rates.sample({ rendered: app.framesRendered,
                                               received: app.framesReceived });
  app.renderFps = rendered;
  app.streamFps = received;
  $("stat-fps").textContent = app.renderFps.toFixed(0);
  $("stat-stream").textContent = app.streamFps.toFixed(0);
  const latency = app.connection?.latencyMs;
  $("stat-latency").textContent = latency == null ? "-" : latency.toFixed(1);
  agentList.refresh(app.agents);
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
  toScreen: (x, z) => view.toScreen(x, z),
  get errors() { return [...errors]; },
  get renderFps() { return app.renderFps; },
  get streamFps() { return app.streamFps; },
  get latencyMs() { return app.connection?.latencyMs ?? null; },
  get mouseMode() { return app.mouseMode; },
  get scene() { return app.scene && structuredClone(app.scene); },
  sceneDrawn: () => sceneDrawing.drawn(),
  get draftObstacle() { return sceneTools.corners.map((p) => [...p]); },
  get dropStart() { return sceneTools.start && [...sceneTools.start]; },
  get dropEmotion() { return structuredClone(app.dropEmotion); },
  colors: () => ({
    background: `#${view.scene.background.getHexString()}`,
    ground: `#${view.floor.children[0].material.color.getHexString()}`,
    figures: Object.fromEntries([...app.agents].map(([id, a]) => [id, a.materialColors()])),
  }),
});

// --- start --------------------------------------------------------------------------------

/**
 * Open the websocket; when it closes, open it again after RECONNECT_MS (the server may be
 * restarting), unless the server refused the token.
 */
function connect() {
  const status = (text) => { $("stat-connection").textContent = text; };
  app.connection = new Connection(socketUrl(token), {
    rig: app.rig,
    onFrame,
    onNotice,
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
  const [skeleton, template] = await Promise.all([
    getJSON("/api/skeleton"), loadMannequin(api("/api/mannequin.glb"), toast)]);
  app.skeleton = skeleton;
  app.rig = new Rig(skeleton);
  app.template = template;
  if (!template) sticksOnly(app);
  sliders = new LabelSliders($("sliders"), skeleton.labels, onSliders);
  disc.setLabels(Object.fromEntries(Object.entries(skeleton.points)
    .filter(([label]) => MAIN_LABELS.includes(label))));
  view.animate(beforeRender);
  setInterval(everySecond, 1000);
  await view.setUpXR($("xr"));
  await connect();
  if (demo) await startDemo();
  app.ready = true;
}

start().catch((err) => {
  $("stat-connection").textContent = `not started: ${err.message}`;
  toast(`the app could not start: ${err.message}`);
});
