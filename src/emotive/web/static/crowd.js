// The crowd of `emotive export web --scene`: the scene's gait agents walking to their goals
// without walking through each other, each body with a navigation agent in recast-navigation's
// Detour crowd (vendored in vendor/recast-navigation, loaded only for a scene), as
// `emotive crowd` pairs each body with a JuPedSim agent (docs/crowd.md).
//
// scene.json (emotive.web.scene) carries the walkable area as triangles, the groups' spawn
// places, goals and emotions, and the emotion-to-navigation table. Recast builds a navigation
// mesh from the triangles, eroded by a body's half width; a Detour crowd walks one agent per
// body. One frame (`step`):
//
//  1. spawn the agents due (a group's count at the first frame, or its flow over time) on
//     free spawn places, each a gait agent in the engine and a Detour agent;
//  2. move each goal on (exits, waypoints within the arrival radius, wandering) and ask the
//     Detour agent for the destination when it changed;
//  3. set each Detour agent's parameters from its body's emotion now (crowd-math.js: the
//     table blended as emotive.crowd.emotion_table does, mapped onto Detour's parameters);
//  4. tie-back: put each Detour agent where its body stands, with its body's velocity, then
//     let Detour plan and move one frame (`crowd.update`): that is the short-horizon plan;
//  5. send each body along a straight path towards its plan (crowd-math.js bodyPathEnd:
//     `emotive crowd`'s rule), and step every body in one session.run;
//  6. record the bodies' hips and the plans, and let agents that reached their exit leave.
//
// Units: metres, seconds; Detour's world is the bodies' (x, y, z), Y up, the scene's (x, y) on
// the ground as (x, z).

import { Crowd, init } from "./vendor/recast-navigation/core/index.mjs";
import { generateSoloNavMesh } from "./vendor/recast-navigation/generators/index.mjs";
import { GroundPath } from "./paths.js";
import { RuntimeError } from "./runtime.js";
import {
  TriangleSampler, bodyPathEnd, detourParams, drawEmotion, insidePolygon, navigationParams,
  randomSource, sample,
} from "./crowd-math.js";

// The value of scene.json's `format`.
const FORMAT = "emotive-web-scene/1";
const FIX = "export the folder again with `emotive export web --scene SCENE.toml --out DIR`";
// Recast's voxels: cell size and height, metres. The mesh is eroded by the body clearance of
// the scene checks (scene.json's constants: a body's half width), the distance every spawn
// place keeps from walls.
const CELL = 0.05;
// Detour agents when a flow has no count (Detour's crowd is sized once).
const FLOW_CAPACITY = 512;
// Frames of records kept (the oldest are dropped beyond: ten minutes at 30 fps).
const KEEP_FRAMES = 18000;
// Length of a new agent's first path, towards the first corner of its route, metres.
const FIRST_PATH = 0.5;

/** scene.json beside the page, checked. */
export async function loadSceneDocument(name) {
  const url = new URL(`./${name}`, location.href);
  let response;
  try {
    response = await fetch(url);
  } catch (err) {
    throw new RuntimeError(`the scene ${name} could not be fetched (${err.message}); is the static server still running?`);
  }
  if (!response.ok) throw new RuntimeError(`the scene ${name} is missing: GET ${url} answered HTTP ${response.status}; ${FIX}`);
  let doc;
  try {
    doc = await response.json();
  } catch (err) {
    throw new RuntimeError(`${name} is not valid JSON (${err.message}); ${FIX}`);
  }
  if (doc?.format !== FORMAT) {
    throw new RuntimeError(`${name} is not a scene of an emotive web export (format ${JSON.stringify(doc?.format)}, expected "${FORMAT}"); ${FIX}`);
  }
  return doc;
}

/** The median of numbers (null for none). */
function median(values) {
  const v = [...values].sort((a, b) => a - b);
  return v.length ? v[Math.floor(v.length / 2)] : null;
}

export class CrowdRunner {
  /**
   * Build the navigation mesh and the Detour crowd of a scene (loads Recast's WebAssembly).
   *
   * @param {object} doc scene.json.
   * @param {object} meta agent.json.
   * @param {AgentEngine} engine the page's engine: the bodies.
   * @param {{avoidance?: boolean, seed?: number}} options avoidance false: the baseline, where
   *   navigation agents neither see nor push each other; seed: of every random draw.
   */
  static async create(doc, meta, engine, { avoidance = true, seed = 0 } = {}) {
    try {
      await init();
    } catch (err) {
      throw new RuntimeError(`recast-navigation's WebAssembly did not load (${err.message}); ${FIX}`);
    }
    return new CrowdRunner(doc, meta, engine, avoidance, seed);
  }

  constructor(doc, meta, engine, avoidance, seed) {
    this.doc = doc;
    this.meta = meta;
    this.engine = engine;
    this.avoidance = avoidance;
    this.seed = seed;
    this.rng = randomSource(seed);
    this.fps = engine.fps;
    const t0 = performance.now();
    const positions = doc.mesh.vertices.flatMap(([x, z]) => [x, 0, z]);
    const indices = doc.mesh.triangles.flat();
    const built = generateSoloNavMesh(positions, indices, {
      cs: CELL, ch: CELL, walkableRadius: Math.round(doc.constants.body_clearance / CELL),
      walkableHeight: Math.ceil(2 / CELL), walkableClimb: 4, maxEdgeLen: Math.round(12 / CELL),
    });
    if (!built.success) throw new RuntimeError(`Recast could not build a navigation mesh of the scene (${built.error}); ${FIX}`);
    this.navMesh = built.navMesh;
    this.navMeshMs = performance.now() - t0;
    const capacity = doc.groups.some((g) => g.flow > 0 && g.count === 0) ? FLOW_CAPACITY
      : doc.groups.reduce((n, g) => n + g.count, 0);
    const radii = Object.values(doc.navigation.table).map((row) => row[doc.navigation.columns.indexOf("radius")]);
    this.crowd = new Crowd(this.navMesh, { maxAgents: Math.max(capacity, 1), maxAgentRadius: Math.max(...radii) + 0.05 });
    this.capacity = Math.max(capacity, 1);
    // Each label's walking speed (agent.json's table: the gait's own pace per label).
    this.speeds = meta.emotion.labels.map((label) => meta.navigation.rows[label][0]);
    this.groups = doc.groups.map((g) => ({
      ...g, spawned: 0, due: 0,
      targets: g.goal.kind === "exit" ? new TriangleSampler(g.goal.targets) : null,
    }));
    this.roam = new TriangleSampler(doc.roam);
    this.spacing = doc.constants.spawn_spacing;
    this.arrival = doc.constants.arrival_radius;
    this.agents = [];
    this.frame = 0;
    this.records = [];
    this.updateMs = [];
    this.left = [];
    this.queue = Promise.resolve();
  }

  // ------------------------------------------------------------------------------- agents

  /** Where a body stands now: its spawn place during its start steps, else the engine's. */
  here(agent, index) {
    const b = index.get(agent.id);
    const body = this.engine.agents[b];
    if (b === undefined || body.warm > 0) return agent.spawn;
    const g = this.engine.ground;
    return [g[3 * b], g[3 * b + 1]];
  }

  /** A new destination by the agent's goal (exit: a point of the exit; wander: of the area). */
  destination(agent) {
    const group = this.groups[agent.group];
    if (group.goal.kind === "exit") return group.targets.sample(this.rng);
    if (group.goal.kind === "waypoints") return group.goal.points[agent.index];
    return this.roam.sample(this.rng);
  }

  /** The Detour agent heads for `dest` [x, z]. */
  head(agent, dest) {
    agent.dest = dest;
    agent.nav.requestMoveTarget({ x: dest[0], y: 0, z: dest[1] });
  }

  /** The first path of a body at `p` [x, z]: towards the first corner of its route. */
  firstPath(p, dest) {
    const route = this.crowd.navMeshQuery.computePath({ x: p[0], y: 0, z: p[1] }, { x: dest[0], y: 0, z: dest[1] });
    const corner = route.success && route.path.length > 1 ? [route.path[1].x, route.path[1].z] : dest;
    let dx = corner[0] - p[0];
    let dz = corner[1] - p[1];
    const norm = Math.hypot(dx, dz);
    [dx, dz] = norm > 1e-6 ? [dx / norm, dz / norm] : [1, 0];
    return new GroundPath([p, [p[0] + FIRST_PATH * dx, p[1] + FIRST_PATH * dz]], false, "spawn");
  }

  /** Spawn the agents due this frame on free places of their spawns (Crowd._spawn_due). */
  async spawnDue() {
    const index = new Map(this.engine.ids().map((id, b) => [id, b]));
    const taken = this.agents.map((a) => this.here(a, index));
    for (const [gi, g] of this.groups.entries()) {
      let want;
      if (g.flow === 0) {
        want = this.frame === 0 ? g.count : 0;
      } else {
        g.due += g.flow / this.fps;
        const left = g.count ? g.count - g.spawned : Infinity;
        want = Math.floor(Math.min(g.due, left));
      }
      want = Math.min(want, this.capacity - this.agents.length);
      if (want <= 0) continue;
      const free = g.sites.filter(([x, z]) => taken.every(([tx, tz]) => Math.hypot(x - tx, z - tz) >= this.spacing));
      const take = Math.min(want, free.length);
      if (take === 0) continue;
      const pick = sample(free.length, take, this.rng).map((k) => free[k]);
      const made = pick.map((p) => {
        const agent = {
          group: gi, spawn: p, index: 0, standing: false, done: false, reached: 0, lastEnd: null,
          emotion: drawEmotion(g.emotion, this.meta.emotion, this.rng),
          pace: g.pace[0] + this.rng() * (g.pace[1] - g.pace[0]), firstFrame: this.frame,
          lastFrame: this.frame, params: "",
        };
        agent.dest = this.destination(agent);
        return agent;
      });
      const ids = await this.engine.add(made.map((a) => ({
        path: this.firstPath(a.spawn, a.dest), emotion: a.emotion, pace: a.pace,
        phase: this.rng() * 2 * Math.PI,
      })));
      made.forEach((agent, k) => {
        agent.id = ids[k];
        // The body owns its emotion from now on (the page's controls may change it).
        agent.body = this.engine.agent(agent.id);
        agent.nav = this.crowd.addAgent({ x: agent.spawn[0], y: 0, z: agent.spawn[1] }, this.parameters(agent, true).detour);
        this.head(agent, agent.dest);
        this.agents.push(agent);
        taken.push(agent.spawn);
      });
      g.spawned += take;
      if (g.flow) g.due -= take;
    }
  }

  /** Navigation parameters from the body's emotion now; Detour's with `warm` (still). */
  parameters(agent, warm) {
    const params = navigationParams(this.doc.navigation, this.meta.emotion, this.speeds,
                                    agent.body?.emotion ?? agent.emotion, agent.pace);
    const detour = detourParams(params, this.doc.navigation, this.avoidance);
    if (warm) detour.maxSpeed = 0;
    return { params, detour };
  }

  /** Move goals on (GoalState.update), with the body at `here`; true when it left. */
  updateGoal(agent, here) {
    const group = this.groups[agent.group];
    if (group.goal.kind === "exit") {
      if (insidePolygon(here[0], here[1], group.goal.polygon)) {
        agent.reached = 1;
        agent.done = true;
      }
      return agent.done;
    }
    if (agent.standing || Math.hypot(agent.dest[0] - here[0], agent.dest[1] - here[1]) > this.arrival) return false;
    agent.reached++;
    if (group.goal.kind === "waypoints") {
      if (agent.index + 1 < group.goal.points.length) {
        agent.index++;
        this.head(agent, this.destination(agent));
      } else {
        agent.standing = true;
        agent.nav.resetMoveTarget();
      }
    } else {
      this.head(agent, this.destination(agent));
    }
    return false;
  }

  /** Whether an agent met its goal: left by its exit, stands at its last waypoint, or (a
   * wanderer) reached one point. */
  finished(agent) {
    return this.groups[agent.group].goal.kind === "wander" ? agent.reached > 0 : agent.done || agent.standing;
  }

  // ------------------------------------------------------------------------------- a frame

  /** One frame of the scene (see the top of this file); resolves with the engine's frame.
   * Frames run one after another, whoever asks (the clock, the test hook). */
  step() {
    const run = this.queue.then(() => this.stepOnce());
    this.queue = run.catch(() => {});
    return run;
  }

  async stepOnce() {
    const { engine, fps } = this;
    let index = new Map(engine.ids().map((id, b) => [id, b]));
    // A body removed with the page's controls takes its navigation agent along.
    for (const agent of this.agents.filter((a) => !index.has(a.id))) this.crowd.removeAgent(agent.nav);
    this.agents = this.agents.filter((a) => index.has(a.id));
    await this.spawnDue();
    index = new Map(engine.ids().map((id, b) => [id, b]));
    const heres = this.agents.map((a) => this.here(a, index));
    this.agents.forEach((agent, k) => {
      const b = index.get(agent.id);
      const warm = engine.agents[b].warm > 0;
      const here = heres[k];
      this.updateGoal(agent, here);
      const { params, detour } = this.parameters(agent, warm);
      agent.speed = params.desired_speed;
      const key = JSON.stringify(detour);
      if (key !== agent.params) {
        agent.nav.updateParameters(detour);
        agent.params = key;
      }
      // Tie-back: the navigation agent stands where its body stands. Its velocity stays
      // Detour's own, so that its plan asks for the speed it wants, not the body's.
      agent.nav.raw.set_npos(0, here[0]);
      agent.nav.raw.set_npos(2, here[1]);
    });
    const t0 = performance.now();
    this.crowd.update(1 / fps);
    this.updateMs.push(performance.now() - t0);
    if (this.updateMs.length > 600) this.updateMs.splice(0, this.updateMs.length - 600);
    const plans = this.agents.map((a) => {
      const p = a.nav.position();
      return [p.x, p.z];
    });
    for (const [k, agent] of this.agents.entries()) {
      const b = index.get(agent.id);
      if (engine.agents[b].warm > 0) continue;
      const end = bodyPathEnd(heres[k], engine.ground[3 * b + 2], plans[k], agent.speed, fps, agent.lastEnd);
      if (end === null) continue;
      agent.lastEnd = end;
      await engine.setPath(agent.id, new GroundPath([heres[k], end], false, "navigation"));
    }
    const frame = await engine.step();
    index = new Map(engine.ids().map((id, b) => [id, b]));
    const record = { frame: this.frame, ids: [], hips: [], nav: [], warm: [] };
    const gone = [];
    this.agents.forEach((agent, k) => {
      const b = index.get(agent.id);
      const hips = frame.root_position.subarray(3 * b, 3 * b + 3);
      record.ids.push(agent.id);
      record.hips.push(hips[0], hips[2]);
      record.nav.push(...plans[k]);
      record.warm.push(frame.walking[b] ? 0 : 1);
      agent.lastFrame = this.frame;
      if (frame.walking[b] && this.updateGoal(agent, [hips[0], hips[2]])) gone.push(agent);
    });
    this.records.push(record);
    if (this.records.length > KEEP_FRAMES) this.records.shift();
    if (gone.length) {
      await engine.remove(gone.map((a) => a.id));
      for (const agent of gone) {
        this.crowd.removeAgent(agent.nav);
        this.left.push(agent);
      }
      this.agents = this.agents.filter((a) => !a.done);
    }
    this.frame++;
    return frame;
  }

  // ------------------------------------------------------------------------------- reading

  /** Agents still to spawn (Infinity for a flow without a count). */
  spawnsLeft() {
    return this.groups.reduce((n, g) => n + (g.count ? g.count - g.spawned : (g.flow ? Infinity : 0)), 0);
  }

  /** Every agent spawned, and each met its goal (exits: left; wanderers walk on). */
  get done() {
    return this.frame > 0 && this.spawnsLeft() === 0 && this.agents.every((a) => this.finished(a));
  }

  /** What the test hook shows (hook.js, `crowd`). */
  summary() {
    const all = [...this.left, ...this.agents];
    return {
      frame: this.frame, done: this.done, avoidance: this.avoidance, seed: this.seed,
      agents: this.agents.length, spawned: all.length, left: this.left.length,
      reached: all.filter((a) => this.finished(a)).length, navMeshMs: this.navMeshMs,
      updateMs: median(this.updateMs), name: this.doc.name,
    };
  }

  /** Per agent: id, group, reached, left, first and last frame, pace, emotion, speed. */
  agentTable() {
    return [...this.left, ...this.agents].sort((a, b) => a.id - b.id).map((a) => ({
      id: a.id, group: this.groups[a.group].name, goal: this.groups[a.group].goal.kind,
      finished: this.finished(a), left: a.done, firstFrame: a.firstFrame, lastFrame: a.lastFrame,
      pace: a.pace, emotion: Array.from(a.body?.emotion ?? a.emotion), speed: a.speed ?? null,
    }));
  }

  /** The records of frames `from` on: {frame, ids, hips [x, z, ...], nav [x, z, ...], warm}. */
  framesSince(from) {
    const first = this.records.length ? this.records[0].frame : 0;
    return this.records.slice(Math.max(from - first, 0));
  }
}
