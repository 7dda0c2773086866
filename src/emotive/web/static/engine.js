// The engine loop of docs/runtime.md ("What an engine does each frame", "Starting an agent")
// on onnxruntime-web: every agent of the scene in one session.run per frame.
//
// Per agent the engine keeps its path, its arc length along it, its emotion, pace and starting
// phase, how many start steps it has left, and its row of the batch: the GRU state
// (`recurrent`, L x H), the agent row (S) and the last `ground` (x, z, heading). Each frame it
// samples every path around its agent in the agent's frame, calls the graph once for the whole
// batch (new agents' start steps in the same call as the others' walking steps), feeds the
// state back and adds `advance` to each walking agent's arc length.
//
// Legend: B agents, L GRU layers, H GRU width, S agent row, C labels, K path samples,
// J joints, P = J + E points.

/** Runs jobs one after another (onnxruntime-web runs one call of a session at a time). */
export class Lock {
  constructor() {
    this.tail = Promise.resolve();
  }

  /** `job()`'s result, once every job queued before it has finished. */
  run(job) {
    const result = this.tail.then(job);
    this.tail = result.catch(() => {});
    return result;
  }
}

/** NumPy's `np.mod` for a positive divisor. */
function mod(a, m) {
  const r = a % m;
  return r < 0 ? r + m : r;
}

export class AgentEngine {
  /**
   * @param {object} ort the onnxruntime-web module (for its Tensor).
   * @param {object} session an InferenceSession of agent.onnx.
   * @param {object} step the `step` entry of agent.json (the graph's metadata).
   * @param {Lock} lock shared by every engine of `session`.
   */
  constructor(ort, session, step, lock = new Lock()) {
    this.ort = ort;
    this.session = session;
    this.lock = lock;
    this.fps = step.fps;
    this.warmup = step.warmup_steps;
    this.loopLeft = step.loop_left;
    const sampling = step.path_sampling;
    this.K = sampling.count;
    this.offsets = Float64Array.from({ length: this.K }, (_, k) => sampling.first + sampling.spacing * k);
    [this.L, , this.H] = step.inputs.recurrent;
    this.S = step.inputs.agent[1];
    this.C = step.inputs.emotion[1];
    this.J = step.outputs.rotations[1];
    this.P = step.outputs.world[1];
    this.agents = [];
    this.recurrent = new Float32Array(0);
    this.rows = new Float32Array(0);
    this.ground = new Float32Array(0);
    this.nextId = 0;
    // Frames stepped (one session.run each) and the outputs of the latest one.
    this.frames = 0;
    this.frame = null;
    // Milliseconds of the latest session.run calls, with their batch sizes.
    this.timings = [];
  }

  /** Ids of the agents, in batch order. */
  ids() {
    return this.agents.map((a) => a.id);
  }

  agent(id) {
    return this.agents.find((a) => a.id === id) ?? null;
  }

  /**
   * Add agents standing on their paths; each takes `warmup_steps` start steps (in the next
   * frames' calls) before its first walking frame.
   *
   * @param {{path: GroundPath, emotion: Float32Array, phase: number, pace?: number,
   *   arc?: number}[]} specs emotion: (C,) weights summing to 1; phase: radians.
   * @returns {Promise<number[]>} the new agents' ids.
   */
  add(specs) {
    return this.lock.run(() => {
      const n = specs.length;
      const B = this.agents.length;
      const { L, H, S } = this;
      const recurrent = new Float32Array(L * (B + n) * H);
      for (let l = 0; l < L; l++) {
        recurrent.set(this.recurrent.subarray(l * B * H, (l + 1) * B * H), l * (B + n) * H);
      }
      const rows = new Float32Array((B + n) * S);
      rows.set(this.rows);
      const ground = new Float32Array((B + n) * 3);
      ground.set(this.ground);
      [this.recurrent, this.rows, this.ground] = [recurrent, rows, ground];
      return specs.map((spec) => {
        const agent = {
          id: this.nextId++, path: spec.path, arc: spec.arc ?? 0, emotion: spec.emotion,
          pace: spec.pace ?? 1, phase: spec.phase, warm: this.warmup, walked: 0,
        };
        this.agents.push(agent);
        return agent.id;
      });
    });
  }

  /** Remove the agents with these ids (unknown ids are ignored). */
  remove(ids) {
    return this.lock.run(() => {
      const gone = new Set(ids);
      const keep = this.agents.map((a, b) => [a, b]).filter(([a]) => !gone.has(a.id));
      const { L, H, S } = this;
      const B = this.agents.length;
      const n = keep.length;
      const recurrent = new Float32Array(L * n * H);
      const rows = new Float32Array(n * S);
      const ground = new Float32Array(n * 3);
      keep.forEach(([, b], k) => {
        for (let l = 0; l < L; l++) {
          recurrent.set(this.recurrent.subarray((l * B + b) * H, (l * B + b + 1) * H), (l * n + k) * H);
        }
        rows.set(this.rows.subarray(b * S, (b + 1) * S), k * S);
        ground.set(this.ground.subarray(3 * b, 3 * b + 3), 3 * k);
      });
      this.agents = keep.map(([a]) => a);
      [this.recurrent, this.rows, this.ground] = [recurrent, rows, ground];
    });
  }

  /** A new emotion (C,) for an agent, from its next frame. */
  setEmotion(id, emotion) {
    const agent = this.agent(id);
    if (agent) agent.emotion = emotion;
  }

  /**
   * Send an agent along another path from the point of it nearest to where it stands; the
   * graph closes the gap as the agent walks.
   */
  setPath(id, path) {
    return this.lock.run(() => {
      const b = this.agents.findIndex((a) => a.id === id);
      if (b < 0) return;
      const agent = this.agents[b];
      agent.path = path;
      agent.arc = path.nearest(this.ground[3 * b], this.ground[3 * b + 1]);
    });
  }

  /** The inputs of one call for the agents in batch order. */
  feeds() {
    const { L, H, S, C, K } = this;
    const B = this.agents.length;
    const emotion = new Float32Array(B * C);
    const pace = new Float32Array(B);
    const path = new Float32Array(B * K * 2);
    const left = new Float32Array(B);
    const start = new Float32Array(B);
    const phase = new Float32Array(B);
    this.agents.forEach((a, b) => {
      emotion.set(a.emotion, b * C);
      pace[b] = a.pace;
      const g = this.ground;
      a.path.samples(a.arc, this.offsets, [g[3 * b], g[3 * b + 1], g[3 * b + 2]], path, b * K * 2);
      left[b] = a.path.closed ? this.loopLeft : a.path.length - a.arc;
      start[b] = a.warm > 0 ? 1 : 0;
      phase[b] = a.warm > 0 ? a.phase : 0;
    });
    const T = (data, dims) => new this.ort.Tensor("float32", data, dims);
    return {
      recurrent: T(this.recurrent, [L, B, H]), agent: T(this.rows, [B, S]),
      emotion: T(emotion, [B, C]), pace: T(pace, [B]), path: T(path, [B, K, 2]),
      path_left: T(left, [B]), start: T(start, [B]), phase: T(phase, [B]),
    };
  }

  /**
   * One frame of every agent: one session.run. Resolves with the frame's outputs
   * `{ids, walking, world, rotations, root_position, contacts, ground}` (null with no agent);
   * `walking[b]` is 0 for an agent still taking start steps (not to be shown yet).
   */
  step() {
    return this.lock.run(async () => {
      const B = this.agents.length;
      if (B === 0) return null;
      const feeds = this.feeds();
      const t0 = performance.now();
      const out = await this.session.run(feeds);
      this.timings.push({ batch: B, ms: performance.now() - t0 });
      if (this.timings.length > 600) this.timings.splice(0, this.timings.length - 600);
      this.recurrent = out.next_recurrent.data;
      this.rows = out.next_agent.data;
      this.ground = out.ground.data;
      const advance = out.advance.data;
      const walking = new Uint8Array(B);
      this.agents.forEach((a, b) => {
        if (a.warm > 0) {
          a.warm--;
          return;
        }
        a.arc += advance[b];
        if (a.path.closed) a.arc = mod(a.arc, a.path.length);
        a.walked++;
        walking[b] = 1;
      });
      this.frames++;
      this.frame = {
        ids: this.ids(), walking, world: out.world.data, rotations: out.rotations.data,
        root_position: out.root_position.data, contacts: out.contacts.data, ground: this.ground,
      };
      return this.frame;
    });
  }

  /** Median milliseconds of the latest session.run calls (null before any). */
  medianMs(count = 60) {
    const ms = this.timings.slice(-count).map((t) => t.ms).sort((a, b) => a - b);
    return ms.length ? ms[Math.floor(ms.length / 2)] : null;
  }
}
