// The two ways an agent is drawn: a stick figure (lines between the frame's world positions)
// and the skinned mannequin of GET /api/mannequin.glb (bones posed from the frame's local
// rotations), both coloured by the agent's emotion.
//
// Legend: J joints, E end sites, P = J + E points.

import * as THREE from "three";
import * as SkeletonUtils from "three/addons/utils/SkeletonUtils.js";

// The figures' emotion colours (app.css, --figure-*): neutral at the centre of the
// valence-arousal circumplex, and one colour per quadrant at these angles (degrees): happy
// (+v, +a) yellow-orange, angry (-v, +a) red, sad (-v, -a) blue, calm (+v, -a) green.
const QUADRANTS = [[45, "happy"], [135, "angry"], [225, "sad"], [315, "calm"]];

// Share of its own colour the mannequin gives off (emissive, linear RGB). Lit by the view's
// lights alone, its upright sides render at about half their colour's luminance (most of a
// standing body faces sideways); with this they stay near their colour, and so near its
// contrast against the ground (app.css).
const MANNEQUIN_GLOW = 0.45;

let palette = null;
const around = new THREE.Color();

/**
 * The colour of the custom property `--name` of the page's style sheet (app.css).
 *
 * @throws {Error} when the page has no such property (app.css not loaded).
 */
export function paletteColor(name) {
  const value = getComputedStyle(document.documentElement).getPropertyValue(`--${name}`).trim();
  if (!value) {
    throw new Error(`the colour --${name} is not set: load app.css before the app's modules`);
  }
  return new THREE.Color(value);
}

/** The figures' colours from app.css, read once: {neutral, quadrants: [4 colours]}. */
function figurePalette() {
  palette ??= {
    neutral: paletteColor("figure-neutral"),
    quadrants: QUADRANTS.map(([, name]) => paletteColor(`figure-${name}`)),
  };
  return palette;
}

/**
 * The colour of an emotion on the valence-arousal circumplex: between two quadrants'
 * colours by the angle of (valence, arousal), then from neutral towards that by its distance
 * from the centre. Both blends are in linear RGB (three.js's working colour space), where
 * luminance is linear: no blend is darker than the darker of its colours, so each keeps the
 * contrast app.css gives its colours against the background.
 *
 * @param {number} valence -1..1
 * @param {number} arousal -1..1
 * @param {THREE.Color} target the colour to set (returned).
 */
export function emotionColor(valence, arousal, target = new THREE.Color()) {
  const { neutral, quadrants } = figurePalette();
  let angle = THREE.MathUtils.radToDeg(Math.atan2(arousal, valence)) - QUADRANTS[0][0];
  angle = ((angle % 360) + 360) % 360;
  const i = Math.min(Math.floor(angle / 90), 3);
  around.copy(quadrants[i]).lerp(quadrants[(i + 1) % 4], angle / 90 - i);
  return target.copy(neutral).lerp(around, Math.min(1, Math.hypot(valence, arousal)));
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
    for (const m of this.materials) {
      m.color.copy(c);
      m.emissive?.copy(c).multiplyScalar(MANNEQUIN_GLOW);
    }
  }

  dispose() {
    for (const m of this.materials) m.dispose();
  }
}
