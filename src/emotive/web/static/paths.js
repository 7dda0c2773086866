// Ground paths of the browser runtime: the arithmetic of emotive.paths.GroundPath (a dense
// polyline parameterised by arc length) and of PathBank.ahead (the samples around an agent that
// the agent step reads), in float64, so that an agent here is fed the numbers Python feeds it.
//
// Units and conventions as everywhere in emotive: metres on the ground plane (x, z), yaw 0
// faces +Z, positive curvature turns left. Legend: N polyline points, K path samples.

// Spacing of GroundPath's dense polylines and the step of its tangents (metres).
export const SAMPLE_SPACING = 0.01;
// Spacing of the uniform arc grid the samples are interpolated on (PathBank.GRID_SPACING).
export const GRID_SPACING = 0.01;
// Points closer than this are merged (metres).
const MIN_GAP = 1e-6;
// Coordinates beyond this many metres are refused (a likely unit mistake).
const MAX_COORDINATE = 1e5;

/** A path that cannot be built (too few points, non-finite or huge coordinates). */
export class PathError extends Error {}

/** NumPy's `np.mod` for a positive divisor: the result lies in [0, m). */
function mod(a, m) {
  const r = a % m;
  return r < 0 ? r + m : r;
}

/** A polyline `[[x, z], ...]` checked, consecutive duplicates dropped (`_check_points`). */
function checkedPoints(points, name) {
  if (!Array.isArray(points)) throw new PathError(`path ${name}: points must be [[x, z], ...]`);
  const out = [];
  let prev = null;
  for (const p of points) {
    if (!Array.isArray(p) || p.length !== 2) throw new PathError(`path ${name}: points must be pairs [x, z]`);
    const [x, z] = p.map(Number);
    if (!Number.isFinite(x) || !Number.isFinite(z)) throw new PathError(`path ${name}: points must be finite numbers`);
    if (Math.abs(x) > MAX_COORDINATE || Math.abs(z) > MAX_COORDINATE) {
      throw new PathError(`path ${name}: a coordinate exceeds ${MAX_COORDINATE} m; paths are in metres`);
    }
    // As NumPy's diff: each point against the previous given point, kept or not.
    if (prev === null || Math.sqrt((x - prev[0]) ** 2 + (z - prev[1]) ** 2) > MIN_GAP) out.push([x, z]);
    prev = [x, z];
  }
  if (out.length < 2) throw new PathError(`path ${name} needs at least two distinct points, got ${out.length}`);
  return out;
}

/** A smooth ground curve through a dense polyline, as `GroundPath.from_polyline`. */
export class GroundPath {
  /**
   * @param {number[][]} points (N, 2) [x, z] metres, dense (straight pieces between them).
   * @param {boolean} closed join the last point back to the first (a loop).
   * @param {string} name for messages.
   */
  constructor(points, closed = false, name = "path") {
    const pts = checkedPoints(points, name);
    const [x0, z0] = pts[0];
    const [xn, zn] = pts[pts.length - 1];
    if (closed && Math.sqrt((xn - x0) ** 2 + (zn - z0) ** 2) > MIN_GAP) pts.push([x0, z0]);
    const n = pts.length;
    this.xs = Float64Array.from(pts, (p) => p[0]);
    this.zs = Float64Array.from(pts, (p) => p[1]);
    this.arc = new Float64Array(n);
    for (let i = 1; i < n; i++) {
      const dx = this.xs[i] - this.xs[i - 1];
      const dz = this.zs[i] - this.zs[i - 1];
      this.arc[i] = this.arc[i - 1] + Math.sqrt(dx * dx + dz * dz);
    }
    this.length = this.arc[n - 1];
    if (!(this.length > MIN_GAP)) throw new PathError(`path ${name} has zero length: give points that are apart`);
    this.closed = Boolean(closed);
    this.name = name;
    this.makeGrid();
  }

  /** Arc length `s` wrapped on a loop, clamped to [0, length] on an open path. */
  wrap(s) {
    return this.closed ? mod(s, this.length) : Math.min(Math.max(s, 0), this.length);
  }

  /** [x, z] at arc length `s` (linear between points, as `np.interp`). */
  position(s) {
    const t = this.wrap(s);
    const { arc, xs, zs } = this;
    const n = arc.length;
    if (t <= arc[0]) return [xs[0], zs[0]];
    if (t >= arc[n - 1]) return [xs[n - 1], zs[n - 1]];
    let lo = 0;
    let hi = n - 1;
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (arc[mid] <= t) lo = mid;
      else hi = mid;
    }
    const u = (t - arc[lo]) / (arc[hi] - arc[lo]);
    return [xs[lo] + u * (xs[hi] - xs[lo]), zs[lo] + u * (zs[hi] - zs[lo])];
  }

  /** Yaw of the tangent at `s` (0 faces +Z), from a chord of about one sample either side. */
  heading(s) {
    const h = Math.min(SAMPLE_SPACING, 0.25 * this.length);
    const t = this.wrap(s);
    const lo = this.closed ? t - h : Math.max(t - h, 0);
    const hi = this.closed ? t + h : Math.min(t + h, this.length);
    const [ax, az] = this.position(lo);
    const [bx, bz] = this.position(hi);
    let dx = bx - ax;
    let dz = bz - az;
    const norm = Math.max(Math.sqrt(dx * dx + dz * dz), 1e-12);
    dx /= norm;
    dz /= norm;
    return Math.atan2(dx, dz);
  }

  /** The uniform arc grid of PathBank (about GRID_SPACING) and the end tangents. */
  makeGrid() {
    const steps = Math.max(Math.round(this.length / GRID_SPACING), 1);
    this.gridSteps = steps;
    this.gridSpacing = this.length / steps;
    this.grid = new Float64Array(2 * (steps + 1));
    for (let k = 0; k <= steps; k++) {
      const [x, z] = this.position(k * this.gridSpacing);
      this.grid[2 * k] = x;
      this.grid[2 * k + 1] = z;
    }
    const a = this.heading(0);
    const b = this.heading(this.length);
    this.startDir = [Math.sin(a), Math.cos(a)];
    this.endDir = [Math.sin(b), Math.cos(b)];
  }

  /**
   * The path at arc lengths `arc + offsets[k]` in an agent's frame, as PathBank.ahead and
   * to_agent_frame: an open path continues straight along its end tangents, a loop wraps.
   *
   * @param {number} arc the agent's arc length, metres.
   * @param {Float64Array} offsets (K,) arc offsets, metres.
   * @param {number[]} ground [x, z, heading] of the agent (its last `ground` output).
   * @param {Float32Array} out written at `at`: K pairs (x, z) in the agent's frame.
   * @param {number} at offset into `out`.
   */
  samples(arc, offsets, ground, out, at) {
    const [gx, gz, psi] = ground;
    const c = Math.cos(psi);
    const s = Math.sin(psi);
    const { grid, gridSteps, gridSpacing, closed, length } = this;
    for (let k = 0; k < offsets.length; k++) {
      const q = arc + offsets[k];
      const inside = closed ? mod(q, length) : Math.min(Math.max(q, 0), length);
      const u = inside / gridSpacing;
      const i = Math.min(Math.floor(u), gridSteps - 1);
      const t = u - i;
      let x = grid[2 * i] * (1 - t) + grid[2 * i + 2] * t;
      let z = grid[2 * i + 1] * (1 - t) + grid[2 * i + 3] * t;
      const past = closed ? 0 : q - inside;
      const dir = past > 0 ? this.endDir : this.startDir;
      // The operations in NumPy's order: continue past an end, then move to the agent.
      x = x + past * dir[0];
      z = z + past * dir[1];
      x -= gx;
      z -= gz;
      out[at + 2 * k] = c * x - s * z;
      out[at + 2 * k + 1] = s * x + c * z;
    }
  }

  /** Arc length of the path's point nearest to (x, z) (the earlier segment on a tie). */
  nearest(x, z) {
    const { xs, zs, arc } = this;
    let best = Infinity;
    let bestArc = 0;
    for (let i = 0; i + 1 < xs.length; i++) {
      const ax = xs[i];
      const az = zs[i];
      const bx = xs[i + 1] - ax;
      const bz = zs[i + 1] - az;
      const t = Math.min(Math.max(((x - ax) * bx + (z - az) * bz) / Math.max(bx * bx + bz * bz, 1e-12), 0), 1);
      const d = (ax + t * bx - x) ** 2 + (az + t * bz - z) ** 2;
      if (d < best) {
        best = d;
        bestArc = arc[i] + t * (arc[i + 1] - arc[i]);
      }
    }
    return bestArc;
  }

  /** About `count` points of the path for drawing, [[x, z], ...]. */
  outline(count = 200) {
    const step = Math.max(1, Math.floor(this.xs.length / count));
    const out = [];
    for (let i = 0; i < this.xs.length; i += step) out.push([this.xs[i], this.zs[i]]);
    out.push([this.xs[this.xs.length - 1], this.zs[this.zs.length - 1]]);
    return out;
  }
}

/** `_sample_count`: dense points for a curve of about `length` metres. */
function sampleCount(length) {
  return Math.max(Math.ceil(length / SAMPLE_SPACING) + 1, 16);
}

/** `n` values from `a` to `b`, as `np.linspace`. */
function linspace(a, b, n) {
  const step = (b - a) / (n - 1);
  return Array.from({ length: n }, (_, i) => (i === n - 1 ? b : a + i * step));
}

/**
 * A loop of `radius` metres whose bounding box is centred on (cx, cz), starting on its left
 * and heading +Z, turning left: the served app's placed agent, `{"shape": "circle",
 * "center": [cx, cz], "radius": r}`.
 */
export function circlePath(cx, cz, radius) {
  const t = linspace(0, 2 * Math.PI, sampleCount(2 * Math.PI * radius));
  const pts = t.map((a) => [radius * (1 - Math.cos(a)), radius * Math.sin(a)]);
  const xs = pts.map((p) => p[0]);
  const zs = pts.map((p) => p[1]);
  const mx = 0.5 * (Math.min(...xs) + Math.max(...xs));
  const mz = 0.5 * (Math.min(...zs) + Math.max(...zs));
  return new GroundPath(pts.map(([x, z]) => [x + cx - mx, z + cz - mz]), true, "circle");
}

/** Second derivatives of a natural cubic spline through (u, y). */
function naturalSecondDerivatives(u, y) {
  const n = u.length;
  const m = new Float64Array(n);
  if (n < 3) return m;
  const c = new Float64Array(n);
  const d = new Float64Array(n);
  // Thomas algorithm on the tridiagonal system of the interior points.
  for (let i = 1; i < n - 1; i++) {
    const h0 = u[i] - u[i - 1];
    const h1 = u[i + 1] - u[i];
    const rhs = 6 * ((y[i + 1] - y[i]) / h1 - (y[i] - y[i - 1]) / h0);
    const diag = 2 * (h0 + h1) - h0 * c[i - 1];
    c[i] = h1 / diag;
    d[i] = (rhs - h0 * d[i - 1]) / diag;
  }
  for (let i = n - 2; i >= 1; i--) m[i] = d[i] - c[i] * m[i + 1];
  return m;
}

/**
 * An open path smoothly through waypoints, as `emotive.paths.waypoints` (a natural cubic
 * spline over chord length, sampled densely): the served app's drawn path.
 */
export function waypointPath(points, name = "drawn") {
  const pts = checkedPoints(points, name);
  const chord = [0];
  for (let i = 1; i < pts.length; i++) {
    chord.push(chord[i - 1] + Math.hypot(pts[i][0] - pts[i - 1][0], pts[i][1] - pts[i - 1][1]));
  }
  const total = chord[chord.length - 1];
  if (pts.length === 2) {
    const u = linspace(0, total, sampleCount(total));
    return new GroundPath(u.map((v) => [pts[0][0] + (v / total) * (pts[1][0] - pts[0][0]),
                                        pts[0][1] + (v / total) * (pts[1][1] - pts[0][1])]), false, name);
  }
  const columns = [0, 1].map((k) => pts.map((p) => p[k]));
  const second = columns.map((y) => naturalSecondDerivatives(chord, y));
  const dense = [];
  let i = 0;
  for (const v of linspace(0, total, sampleCount(1.5 * total))) {
    while (i < chord.length - 2 && v > chord[i + 1]) i++;
    const h = chord[i + 1] - chord[i];
    const a = (chord[i + 1] - v) / h;
    const b = (v - chord[i]) / h;
    dense.push(columns.map((y, k) => a * y[i] + b * y[i + 1]
      + ((a ** 3 - a) * second[k][i] + (b ** 3 - b) * second[k][i + 1]) * (h * h) / 6));
  }
  return new GroundPath(dense, false, name);
}
