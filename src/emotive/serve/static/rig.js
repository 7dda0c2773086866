// World positions of an agent's joints from its local rotations and the rig of
// GET /api/skeleton (docs/serve.md): version-2 frames carry the rotations and the mover's
// world position only. The same computation as emotive/serve/rig.py: the joints above the
// mover (a placement root) hang from the origin by their offsets, the mover sits at its
// world position, every other joint hangs from its parent by its offset turned by the
// parent's global rotation, and end sites likewise.
//
// Legend: J joints, E end sites, P = J + E points; quaternions w, x, y, z.

export class Rig {
  /**
   * @param {{parents: number[], offsets: number[][], mover: number,
   *   end_site_parents: number[], end_site_offsets?: number[][]}} skeleton from /api/skeleton
   */
  constructor(skeleton) {
    this.parents = Int32Array.from(skeleton.parents);
    this.J = this.parents.length;
    this.endParents = Int32Array.from(skeleton.end_site_parents ?? []);
    this.E = this.endParents.length;
    this.P = this.J + this.E;
    this.mover = skeleton.mover;
    this.offsets = Float64Array.from(skeleton.offsets.flat());
    const ends = skeleton.end_site_offsets ?? this.endParents.map(() => [0, 0, 0]);
    this.endOffsets = Float64Array.from(ends.flat());
    this.global = new Float64Array(4 * this.J);
    this.v = new Float64Array(3);
  }

  // this.v = global rotation of joint g (index into this.global) applied to (x, y, z).
  rotate(g, x, y, z) {
    const G = this.global;
    const w = G[4 * g];
    const qx = G[4 * g + 1];
    const qy = G[4 * g + 2];
    const qz = G[4 * g + 3];
    // v + 2 w (u x v) + 2 u x (u x v), u = (qx, qy, qz)
    const cx = qy * z - qz * y;
    const cy = qz * x - qx * z;
    const cz = qx * y - qy * x;
    this.v[0] = x + 2 * (w * cx + qy * cz - qz * cy);
    this.v[1] = y + 2 * (w * cy + qz * cx - qx * cz);
    this.v[2] = z + 2 * (w * cz + qx * cy - qy * cx);
  }

  /**
   * World positions of one agent's joints then end sites.
   *
   * @param {Float32Array} rotations local rotations, (J, 4) from `rOffset`.
   * @param {number} rOffset
   * @param {Float32Array} mover the mover's world position, (3,) from `mOffset`.
   * @param {number} mOffset
   * @param {Float32Array} out (P, 3) written from `oOffset`, metres.
   * @param {number} oOffset
   */
  pose(rotations, rOffset, mover, mOffset, out, oOffset) {
    const G = this.global;
    for (let j = 0; j < this.J; j++) {
      const p = this.parents[j];
      const r = rOffset + 4 * j;
      const ox = this.offsets[3 * j];
      const oy = this.offsets[3 * j + 1];
      const oz = this.offsets[3 * j + 2];
      const o = oOffset + 3 * j;
      if (p < 0) {
        for (let k = 0; k < 4; k++) G[4 * j + k] = rotations[r + k];
        out[o] = ox;
        out[o + 1] = oy;
        out[o + 2] = oz;
      } else {
        const aw = G[4 * p];
        const ax = G[4 * p + 1];
        const ay = G[4 * p + 2];
        const az = G[4 * p + 3];
        const bw = rotations[r];
        const bx = rotations[r + 1];
        const by = rotations[r + 2];
        const bz = rotations[r + 3];
        G[4 * j] = aw * bw - ax * bx - ay * by - az * bz;
        G[4 * j + 1] = aw * bx + ax * bw + ay * bz - az * by;
        G[4 * j + 2] = aw * by - ax * bz + ay * bw + az * bx;
        G[4 * j + 3] = aw * bz + ax * by - ay * bx + az * bw;
        this.rotate(p, ox, oy, oz);
        const q = oOffset + 3 * p;
        out[o] = out[q] + this.v[0];
        out[o + 1] = out[q + 1] + this.v[1];
        out[o + 2] = out[q + 2] + this.v[2];
      }
      if (j === this.mover) {
        out[o] = mover[mOffset];
        out[o + 1] = mover[mOffset + 1];
        out[o + 2] = mover[mOffset + 2];
      }
    }
    for (let e = 0; e < this.E; e++) {
      const p = this.endParents[e];
      this.rotate(p, this.endOffsets[3 * e], this.endOffsets[3 * e + 1], this.endOffsets[3 * e + 2]);
      const o = oOffset + 3 * (this.J + e);
      const q = oOffset + 3 * p;
      out[o] = out[q] + this.v[0];
      out[o + 1] = out[q + 1] + this.v[1];
      out[o + 2] = out[q + 2] + this.v[2];
    }
  }

  /**
   * World positions of every agent of a frame.
   *
   * @param {Float32Array} rotations (B, J, 4)
   * @param {Float32Array} mover (B, 3)
   * @param {number} B agents
   * @returns {Float32Array} (B, P, 3) metres
   */
  poseAll(rotations, mover, B) {
    const out = new Float32Array(B * this.P * 3);
    for (let b = 0; b < B; b++) this.pose(rotations, 4 * this.J * b, mover, 3 * b, out, 3 * this.P * b);
    return out;
  }
}
