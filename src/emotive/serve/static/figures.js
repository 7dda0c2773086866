// The two ways an agent is drawn: a stick figure (lines between the frame's world positions)
// and the skinned mannequin of GET /api/mannequin.glb (bones posed from the frame's local
// rotations), both coloured by the agent's emotion.
//
// Legend: J joints, E end sites, P = J + E points.

import * as THREE from "three";
import * as SkeletonUtils from "three/addons/utils/SkeletonUtils.js";

// Emotion colour: the hue follows the angle of (valence, arousal) on the circumplex through
// these anchors (angle in degrees -> hue in degrees): happy (+v, +a) yellow-orange, angry
// (-v, +a) red, sad (-v, -a) blue, calm (+v, -a) green; between anchors the hue is linear in
// the angle. The saturation grows with the distance from the centre, so a neutral agent
// (0, 0) is grey.
const HUE_ANCHORS = [[45, 45], [135, 0], [225, -140], [315, -240], [405, -315]];

/**
 * The colour of an emotion on the valence-arousal circumplex.
 *
 * @param {number} valence -1..1
 * @param {number} arousal -1..1
 * @param {THREE.Color} target the colour to set (returned).
 */
export function emotionColor(valence, arousal, target = new THREE.Color()) {
  let angle = THREE.MathUtils.radToDeg(Math.atan2(arousal, valence));
  while (angle < 45) angle += 360;
  let hue = HUE_ANCHORS[0][1];
  for (let i = 1; i < HUE_ANCHORS.length; i++) {
    const [a0, h0] = HUE_ANCHORS[i - 1];
    const [a1, h1] = HUE_ANCHORS[i];
    if (angle <= a1) {
      hue = h0 + ((angle - a0) / (a1 - a0)) * (h1 - h0);
      break;
    }
  }
  const radius = Math.min(1, Math.hypot(valence, arousal));
  return target.setHSL((((hue % 360) + 360) % 360) / 360, 0.15 + 0.8 * radius, 0.55,
                       THREE.SRGBColorSpace);
}

/** Lines between each point and its parent, and a dot on every joint. */
export class StickFigure {
  /**
   * @param {{parents: number[], end_site_parents: number[], mover: number}} skeleton from
   *   /api/skeleton
   */
  constructor(skeleton) {
    const parents = [...skeleton.parents, ...skeleton.end_site_parents];
    // The joints above the mover place the figure in the world (a root on the ground under
    // the hips): no body part, so no line from them.
    const placement = new Set();
    for (let j = skeleton.parents[skeleton.mover]; j >= 0; j = skeleton.parents[j]) placement.add(j);
    this.pairs = [];
    parents.forEach((p, q) => { if (p >= 0 && !placement.has(p)) this.pairs.push(p, q); });
    this.numPoints = parents.length;
    const lines = new THREE.BufferGeometry();
    lines.setAttribute("position", new THREE.BufferAttribute(new Float32Array(this.pairs.length * 3), 3));
    const dots = new THREE.BufferGeometry();
    dots.setAttribute("position", new THREE.BufferAttribute(new Float32Array(this.numPoints * 3), 3));
    this.lineMaterial = new THREE.LineBasicMaterial();
    this.dotMaterial = new THREE.PointsMaterial({ size: 0.06 });
    this.lines = new THREE.LineSegments(lines, this.lineMaterial);
    this.dots = new THREE.Points(dots, this.dotMaterial);
    for (const o of [this.lines, this.dots]) o.frustumCulled = false;
    this.object = new THREE.Group();
    this.object.add(this.lines, this.dots);
  }

  /** @param {Float32Array} points (P, 3) world positions of joints then end sites. */
  pose(points) {
    const line = this.lines.geometry.attributes.position;
    this.pairs.forEach((q, i) => line.setXYZ(i, points[3 * q], points[3 * q + 1], points[3 * q + 2]));
    line.needsUpdate = true;
    const dot = this.dots.geometry.attributes.position;
    dot.array.set(points.subarray(0, 3 * this.numPoints));
    dot.needsUpdate = true;
  }

  color(c) {
    this.lineMaterial.color.copy(c);
    this.dotMaterial.color.copy(c);
  }

  dispose() {
    this.lines.geometry.dispose();
    this.dots.geometry.dispose();
    this.lineMaterial.dispose();
    this.dotMaterial.dispose();
  }
}

/** One clone of the skinned mannequin, its bones found by joint name. */
export class Mannequin {
  /**
   * @param {THREE.Object3D} template the loaded glTF scene.
   * @param {{joints: string[], parents: number[], mover: number}} skeleton from /api/skeleton
   */
  constructor(template, skeleton) {
    this.object = SkeletonUtils.clone(template);
    this.materials = [];
    const skinned = new Set();
    this.object.traverse((o) => {
      if (!o.isSkinnedMesh) return;
      o.frustumCulled = false;
      o.material = o.material.clone();
      this.materials.push(o.material);
      for (const bone of o.skeleton.bones) skinned.add(bone);
    });
    this.bones = skeleton.joints.map((name) => this.object.getObjectByName(
      THREE.PropertyBinding.sanitizeNodeName(name)) ?? null);
    // Joints found by name that are bones of the skin: what the debug hook reports.
    this.boundBones = this.bones.filter((b) => b !== null && skinned.has(b)).length;
    // The joints above the mover (a placement root), top first; then the mover itself.
    const chain = [];
    for (let j = skeleton.parents[skeleton.mover]; j >= 0; j = skeleton.parents[j]) chain.unshift(j);
    this.placed = chain.filter((j) => this.bones[j] !== null);
    this.mover = this.bones[skeleton.mover];
    this.world = new THREE.Vector3();
  }

  /** Put `bone` at `xyz` (coordinates of the group this figure is in) through its parent. */
  place(bone, xyz, offset = 0) {
    this.world.set(xyz[offset], xyz[offset + 1], xyz[offset + 2]);
    if (this.object.parent) this.object.parent.localToWorld(this.world);
    bone.parent.updateWorldMatrix(true, false);
    bone.position.copy(bone.parent.worldToLocal(this.world));
  }

  /**
   * @param {Float32Array} rotations (J, 4) local rotations, w, x, y, z.
   * @param {Float32Array} mover (3,) world position of the mover joint, in the coordinates of
   *   the group this figure is added to.
   * @param {Float32Array} points (P, 3) world positions of joints then end sites (same
   *   coordinates): they place the joints above the mover.
   */
  pose(rotations, mover, points) {
    this.bones.forEach((bone, j) => {
      if (bone !== null) {
        bone.quaternion.set(rotations[4 * j + 1], rotations[4 * j + 2], rotations[4 * j + 3],
                            rotations[4 * j]);
      }
    });
    // A translation is in the parent's frame: each world position goes through the inverse
    // of the parent chain (the bones above, posed first, and this clone's root), top down.
    for (const j of this.placed) this.place(this.bones[j], points, 3 * j);
    if (this.mover) this.place(this.mover, mover);
  }

  color(c) {
    for (const m of this.materials) m.color.copy(c);
  }

  dispose() {
    for (const m of this.materials) m.dispose();
  }
}
