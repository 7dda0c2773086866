// window.emotiveWeb: a read-only view of the browser runtime's state for tests and the
// console, and `test`, the functions through which a test feeds the page the inputs it feeds
// Python (agents on given polylines with given emotions and phases, N frames stepped now).
//
//   ready, status        true / "running" once the runtime is loaded; status "loading" or
//                        "error" before or instead
//   error, errors        the message that stopped the runtime (or null); every message shown
//   fps, labels          the model's frame rate and emotion labels
//   agents()             [{id, arc, walked, warm, closed, length, emotion, pace, phase}]
//   framesStepped        frames stepped (one session.run each)
//   world(id)            [[x, y, z], ...] the agent's joints then end sites in the latest
//                        frame (metres), or null while it takes its start steps
//   positions()          {id: [x, y, z]} world position of each shown agent's mover joint
//   stepMs, stepsPerSecond, renderFps, framesRendered   the numbers of the panel
//   selected, figureMode, cameraMode, drawnPath, running, toScreen(x, z), boundBones(id)
//   test.addAgents(specs)  agents on polylines, see addTestAgents; resolves with their ids
//   test.step(n)         step n frames now (the scene's crowd with its bodies, when there is
//                        one), whatever the clock does; resolves with framesStepped
//   crowd                with a scene (crowd.js), else null: summary() {frame, done,
//                        avoidance, seed, agents, spawned, left, reached, navMeshMs, updateMs,
//                        name}; agents() one row per agent that ever was (id, group, goal,
//                        finished, left, firstFrame, lastFrame, pace, emotion, speed);
//                        frames(from) the records of each frame from `from` on: {frame, ids,
//                        hips [x, z, ...] (each body's hips on the ground), nav [x, z, ...]
//                        (its navigation agent after Detour's update), warm [0/1, ...]}
//   test.pause(), test.resume(), test.removeAll(), test.setEmotion(id, emotion)
//   test.benchmark(batch, frames)  milliseconds of each session.run of `batch` agents (a
//                        separate engine on the same session, nothing drawn)

import { AgentEngine } from "./engine.js";
import { GroundPath, circlePath } from "./paths.js";
import { emotionWeights } from "./emotion.js";

/**
 * Install window.emotiveWeb.
 *
 * @param {object} deps the page's `app` state, its `view`, its `errors` list, the session's
 *   `lock`, `running()` (the engine or null after a toast), `setRunning(on)` and `advance()`
 *   (one frame of the page: the crowd's or the engine's).
 */
export function installHook({ app, view, errors, lock, running, setRunning, advance }) {
  /**
   * Add agents on polylines: `specs` [{points: [[x, z], ...], closed, emotion, phase, pace,
   * arc}], emotion (C,) weights, {label: weight} or a label; the points are the dense
   * polyline itself (GroundPath.from_polyline), not waypoints.
   */
  function addTestAgents(specs) {
    const engine = running();
    if (!engine) return Promise.reject(new Error(app.error ?? "the runtime is still loading"));
    return engine.add(specs.map((s) => ({
      path: new GroundPath(s.points, Boolean(s.closed), "test"),
      emotion: emotionWeights(app.meta.emotion, s.emotion ?? "neutral"),
      phase: s.phase ?? 0, pace: s.pace ?? 1, arc: s.arc ?? 0,
    })));
  }

  async function benchmark(batch, frames) {
    const engine = new AgentEngine(app.ort, app.session, app.meta.step, lock);
    const emotion = emotionWeights(app.meta.emotion, { neutral: 1 });
    await engine.add(Array.from({ length: batch }, (_, k) => ({
      path: circlePath(4 * Math.cos(k), 4 * Math.sin(k), 1 + (k % 7) * 0.25),
      emotion, phase: (k * 2.4) % (2 * Math.PI),
    })));
    for (let k = 0; k < engine.warmup + frames; k++) await engine.step();
    return engine.timings.slice(engine.warmup).map((t) => t.ms);
  }

  const test = Object.freeze({
    addAgents: addTestAgents,
    async step(n) {
      const engine = running();
      for (let k = 0; k < n && engine; k++) await advance();
      return engine?.frames ?? 0;
    },
    pause: () => setRunning(false),
    resume: () => setRunning(true),
    removeAll: () => app.engine?.remove(app.engine.ids()),
    setEmotion: (id, emotion) => app.engine?.setEmotion(id, emotionWeights(app.meta.emotion, emotion)),
    benchmark,
  });

  /** [frame, b] of a walking agent in the latest frame, or null. */
  function frameRow(id) {
    const frame = app.engine?.frame;
    const b = frame ? frame.ids.indexOf(id) : -1;
    return b >= 0 && frame.walking[b] === 1 ? [frame, b] : null;
  }

  window.emotiveWeb = Object.freeze({
    get ready() { return app.ready; },
    get status() { return app.status; },
    get error() { return app.error; },
    get errors() { return [...errors]; },
    get fps() { return app.meta?.step.fps ?? null; },
    get labels() { return app.meta ? [...app.meta.emotion.labels] : []; },
    agents: () => (app.engine?.agents ?? []).map((a) => ({
      id: a.id, arc: a.arc, walked: a.walked, warm: a.warm, closed: a.path.closed,
      length: a.path.length, emotion: [...a.emotion], pace: a.pace, phase: a.phase,
    })),
    get framesStepped() { return app.engine?.frames ?? 0; },
    world: (id) => {
      const row = frameRow(id);
      if (!row) return null;
      const [frame, b] = row;
      const P = app.engine.P;
      return Array.from({ length: P }, (_, p) => Array.from(
        frame.world.subarray(3 * (P * b + p), 3 * (P * b + p) + 3)));
    },
    positions: () => Object.fromEntries((app.engine?.ids() ?? []).flatMap((id) => {
      const row = frameRow(id);
      return row ? [[id, Array.from(row[0].root_position.subarray(3 * row[1], 3 * row[1] + 3))]] : [];
    })),
    get stepMs() { return app.engine?.medianMs() ?? null; },
    get stepsPerSecond() { return app.stepsPerSecond; },
    get renderFps() { return app.renderFps; },
    get framesRendered() { return app.framesRendered; },
    get selected() { return app.selected; },
    get figureMode() { return app.figureMode; },
    get cameraMode() { return app.cameraMode; },
    get drawnPath() { return app.drawnPath.map((p) => [...p]); },
    get running() { return app.running; },
    toScreen: (x, z) => view.toScreen(x, z),
    boundBones: (id) => app.views.get(id)?.mannequin?.boundBones ?? 0,
    get crowd() {
      const crowd = app.crowd;
      return crowd && Object.freeze({
        summary: () => crowd.summary(),
        agents: () => crowd.agentTable(),
        frames: (from = 0) => crowd.framesSince(from),
      });
    },
    test,
  });
}
