// The arithmetic of the browser runtime's crowd (crowd.js), pure functions that node tests:
// a seeded random source, uniform points in triangles, points in polygons, the emotion to
// navigation table of `emotive crowd` blended as emotive.crowd.emotion_table blends it, its
// mapping onto Detour crowd agent parameters, and the path that walks a body towards its
// navigation agent (emotive.crowd.crowd.Crowd._body_path, the same rule).
//
// Units: metres, seconds; the ground plane is (x, z) in the bodies' world, the scene's
// (x, y). Yaw 0 faces +Z. Legend: C emotion labels.

import { pointOf, weightsFromPoint } from "./emotion.js";

// The body follows its navigation agent as in `emotive crowd` (docs/crowd.md, "How
// navigation and the bodies are tied", step 5): a straight path towards the plan, turned from
// the body's heading by at most MAX_TURN a frame, as long as makes the gait's target speed
// the navigation agent's speed (the gait slows over its last STOP_DISTANCE metres); kept
// while a new one would turn less than KEEP_ANGLE and change length by less than KEEP_LEAD.
export const MIN_LEAD = 0.02;
export const MAX_TURN = (15 * Math.PI) / 180;
export const KEEP_ANGLE = (2 * Math.PI) / 180;
export const KEEP_LEAD = 0.05;
export const STOP_DISTANCE = 1.0;

// Detour's crowd agent from the table. Speed carries over; radius is the table's plus
// RADIUS_MARGIN, the body's tracking error (a gait body cannot be pushed sideways as Detour
// pushes its agents, so two hips come up to about 0.1 m closer than their navigation agents);
// the separation weight and the collision query range scale as docs/runtime.md maps them for
// Unreal's Detour crowd ("Crowds in an engine"): by yield_strength / neutral's and
// yield_range / neutral's, from a base of our choice. Detour's own sample (RecastDemo) uses a
// separation weight of 2 and a query range of 12 radii; in the tests' crossing that let the
// separation, which Detour adds in metres per second whatever the agent's speed, push the
// slow sad walkers about (43 of 50 reached their exit in 50 s with bodies that follow
// exactly), and a sad walker's 5 m range held more candidates than Detour's neighbour search
// takes (32), so it missed the nearest. Measured against the base below in docs/runtime.md
// ("Crowds in the page").
export const DETOUR = Object.freeze({
  separationWeight: 0.5, queryRadii: 6, optimizationRadii: 30, maxAcceleration: 8.0,
  height: 1.8, radiusMargin: 0.05,
});
// Detour's update flags: anticipate turns 1, obstacle avoidance 2, separation 4, visibility
// optimisation 8, topology optimisation 16.
export const FLAGS_AVOIDING = 1 | 2 | 4 | 8 | 16;
export const FLAGS_BLIND = 1 | 8 | 16;
// Query range of an agent that sees no other (the baseline without avoidance), metres.
const BLIND_RANGE = 1e-3;

/** Uniform numbers in [0, 1) from a 32-bit seed (mulberry32). */
export function randomSource(seed) {
  let s = seed >>> 0;
  return () => {
    s = (s + 0x6d2b79f5) >>> 0;
    let t = s;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

/** Index drawn from probabilities `p` (summing to 1). */
export function choice(p, rng) {
  const u = rng();
  let total = 0;
  for (let k = 0; k < p.length; k++) {
    total += p[k];
    if (u < total) return k;
  }
  return p.length - 1;
}

/** `take` distinct indices of `0..n-1`, drawn uniformly, in increasing order. */
export function sample(n, take, rng) {
  const order = Array.from({ length: n }, (_, i) => i);
  for (let i = 0; i < take; i++) {
    const j = i + Math.floor(rng() * (n - i));
    [order[i], order[j]] = [order[j], order[i]];
  }
  return order.slice(0, take).sort((a, b) => a - b);
}

/** Uniform points in triangles `[ax, ay, bx, by, cx, cy, ...]` (scene.json's targets). */
export class TriangleSampler {
  constructor(flat) {
    this.flat = flat;
    this.cumulative = [];
    let total = 0;
    for (let i = 0; i + 5 < flat.length; i += 6) {
      const [ax, ay, bx, by, cx, cy] = flat.slice(i, i + 6);
      total += Math.abs((bx - ax) * (cy - ay) - (by - ay) * (cx - ax)) / 2;
      this.cumulative.push(total);
    }
    this.total = total;
  }

  /** [x, y] uniform in the triangles. */
  sample(rng) {
    const u = rng() * this.total;
    let k = this.cumulative.findIndex((c) => u < c);
    if (k < 0) k = this.cumulative.length - 1;
    const [ax, ay, bx, by, cx, cy] = this.flat.slice(6 * k, 6 * k + 6);
    let r = rng();
    let s = rng();
    if (r + s > 1) [r, s] = [1 - r, 1 - s];
    return [ax + r * (bx - ax) + s * (cx - ax), ay + r * (by - ay) + s * (cy - ay)];
  }
}

/** Whether (x, y) lies inside the polygon `ring` [[x, y], ...] (even-odd rule). */
export function insidePolygon(x, y, ring) {
  let inside = false;
  for (let i = 0, j = ring.length - 1; i < ring.length; j = i++) {
    const [xi, yi] = ring[i];
    const [xj, yj] = ring[j];
    if ((yi > y) !== (yj > y) && x < ((xj - xi) * (y - yi)) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

/**
 * An agent's navigation parameters, as emotive.crowd.emotion_table.navigation_rows: the
 * emotion placed in the valence/arousal circumplex, blended over the table's four rows by the
 * project's kernel; the desired speed the emotion weights times each label's walking speed,
 * times the pace.
 *
 * @param {object} navigation scene.json's `navigation`: {columns, labels, table}.
 * @param {object} emotion agent.json's `emotion` (labels, points, point_labels, kernel_width).
 * @param {number[]} speeds (C,) each label's walking speed, m/s (agent.json's navigation rows).
 * @param {ArrayLike<number>} weights (C,) the agent's emotion.
 * @param {number} pace its factor on the emotion's speed.
 * @returns {{desired_speed: number, radius: number, time_gap: number,
 *   yield_strength: number, yield_range: number}}
 */
export function navigationParams(navigation, emotion, speeds, weights, pace = 1) {
  let total = 0;
  for (const w of weights) total += w;
  let speed = 0;
  weights.forEach((w, c) => { speed += (w / total) * speeds[c]; });
  const { valence, arousal } = pointOf(emotion, weights);
  const info = { ...emotion, labels: navigation.labels, point_labels: navigation.labels };
  const mix = weightsFromPoint(info, valence, arousal);
  const out = { desired_speed: speed * pace };
  navigation.columns.forEach((column, k) => {
    out[column] = navigation.labels.reduce((sum, label, r) => sum + mix[r] * navigation.table[label][k], 0);
  });
  return out;
}

/**
 * Detour crowd agent parameters of navigation parameters (see DETOUR).
 *
 * @param {object} params navigationParams' result.
 * @param {object} navigation scene.json's `navigation` (its neutral row scales the yielding).
 * @param {boolean} avoidance false: the agent neither avoids nor pushes others (the baseline).
 */
export function detourParams(params, navigation, avoidance = true) {
  const neutral = Object.fromEntries(navigation.columns.map((c, k) => [c, navigation.table.neutral[k]]));
  const r = params.radius;
  return {
    radius: r + DETOUR.radiusMargin,
    height: DETOUR.height,
    maxSpeed: params.desired_speed,
    maxAcceleration: DETOUR.maxAcceleration,
    separationWeight: DETOUR.separationWeight * (params.yield_strength / neutral.yield_strength),
    collisionQueryRange: avoidance ? DETOUR.queryRadii * r * (params.yield_range / neutral.yield_range)
                                   : BLIND_RANGE,
    pathOptimizationRange: DETOUR.optimizationRadii * r,
    updateFlags: avoidance ? FLAGS_AVOIDING : FLAGS_BLIND,
  };
}

/** Python's math.remainder(a, m): a - m * round(a / m). */
function remainder(a, m) {
  return a - m * Math.round(a / m);
}

/**
 * Where the body at `here` with heading `yaw` walks this frame towards its navigation agent's
 * `plan`: the end of a straight path from `here`, or null to keep its current path (whose end
 * is `last`, or null).
 *
 * @param {number[]} here [x, z] the body on the ground.
 * @param {number} yaw its heading, radians (0 faces +Z).
 * @param {number[]} plan [x, z] where its navigation agent went this frame.
 * @param {number} speed the navigation agent's desired speed, m/s.
 * @param {number} fps frames per second.
 * @param {number[]|null} last the end of the body's current path.
 * @returns {number[]|null} [x, z] the new path's end.
 */
export function bodyPathEnd(here, yaw, plan, speed, fps, last) {
  const sx = plan[0] - here[0];
  const sz = plan[1] - here[1];
  const gap = Math.hypot(sx, sz);
  const lead = Math.max(gap, STOP_DISTANCE * Math.min((gap * fps) / Math.max(speed, 1e-6), 1));
  let end;
  if (lead < MIN_LEAD) {
    end = [here[0] + 0.01 * Math.sin(yaw), here[1] + 0.01 * Math.cos(yaw)];
  } else {
    const turn = remainder(Math.atan2(sx, sz) - yaw, 2 * Math.PI);
    const heading = yaw + Math.max(-MAX_TURN, Math.min(MAX_TURN, turn));
    end = [here[0] + lead * Math.sin(heading), here[1] + lead * Math.cos(heading)];
  }
  if (last && lead >= MIN_LEAD) {
    const lx = last[0] - here[0];
    const lz = last[1] - here[1];
    const remaining = Math.hypot(lx, lz);
    const cos = (lx * (end[0] - here[0]) + lz * (end[1] - here[1])) / Math.max(remaining * lead, 1e-12);
    if (Math.abs(remaining - lead) < KEEP_LEAD && cos > Math.cos(KEEP_ANGLE)) return null;
  }
  return end;
}

/** An agent's emotion (C,) drawn from a group's resolved emotion (scene.json). */
export function drawEmotion(spec, emotion, rng) {
  if (spec.weights) return Float32Array.from(spec.weights);
  if (spec.choices) return Float32Array.from(spec.choices[choice(spec.p, rng)]);
  const [vlo, vhi] = spec.valence;
  const [alo, ahi] = spec.arousal;
  return weightsFromPoint(emotion, vlo + rng() * (vhi - vlo), alo + rng() * (ahi - alo));
}
