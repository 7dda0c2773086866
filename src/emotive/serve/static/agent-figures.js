// The figures of one agent in a view: its stick figure and, when the mannequin loaded, its
// skinned mannequin (figures.js), one shown at a time, posed and coloured from a frame; and
// the loading of the mannequin.
//
// Units: metres in scene coordinates (Y up); rotations as quaternions [x, y, z, w].
// Legend: J joints, P points (joints, then end sites).

import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { Mannequin, StickFigure, emotionColor } from "./figures.js";

/**
 * The mannequin's scene at `url` (a glTF), or null after `toast(message)` saying that stick
 * figures are drawn instead.
 */
export async function loadMannequin(url, toast) {
  try {
    return (await new GLTFLoader().loadAsync(url)).scene;
  } catch (err) {
    toast(`mannequin unavailable, drawing stick figures: ${err.message}`);
    return null;
  }
}

/** One agent's figures, added to `world` (the view's group in scene coordinates). */
export class AgentFigures {
  /**
   * @param {number} id the agent's id.
   * @param skeleton the rig, as /api/skeleton gives it.
   * @param template the mannequin's scene (loadMannequin), or null: stick figures only.
   * @param {THREE.Object3D} world
   * @param {string} mode "mannequin" or "sticks" (showMode).
   */
  constructor(id, skeleton, template, world, mode) {
    this.id = id;
    this.world = world;
    this.group = new THREE.Group();
    this.sticks = new StickFigure(skeleton);
    this.mannequin = template ? new Mannequin(template, skeleton) : null;
    this.group.add(this.sticks.object);
    if (this.mannequin) this.group.add(this.mannequin.object);
    this.position = new THREE.Vector3();
    this.heading = new THREE.Vector3(0, 0, 1);
    this.color = new THREE.Color();
    this.va = { valence: 0, arousal: 0 };
    this.points = null;
    world.add(this.group);
    this.showMode(mode);
  }

  /** Show the mannequin ("mannequin", when there is one) or the stick figure ("sticks"). */
  showMode(mode) {
    const mannequin = mode === "mannequin" && this.mannequin !== null;
    this.sticks.object.visible = !mannequin;
    if (this.mannequin) this.mannequin.object.visible = mannequin;
  }

  /**
   * Pose the shown figure from one agent's row of a frame.
   *
   * @param {Float32Array} mover (3,) the mover joint's world position.
   * @param {{valence: number, arousal: number}} va the emotion, -1..1 each (the colour).
   * @param {Float32Array} points (P * 3,) world positions of the joints then the end sites.
   * @param {Float32Array} rotations (J * 4,) the joints' local rotations.
   */
  pose(mover, va, points, rotations) {
    const step = new THREE.Vector3(mover[0] - this.position.x, 0, mover[2] - this.position.z);
    // Heading from the walking direction, smoothed (the follow camera sits behind it).
    if (this.points && step.lengthSq() > 1e-8) this.heading.lerp(step.normalize(), 0.15).normalize();
    this.position.set(mover[0], mover[1], mover[2]);
    this.va = va;
    emotionColor(va.valence, va.arousal, this.color);
    this.points = points;
    if (this.sticks.object.visible) {
      this.sticks.pose(points);
      this.sticks.color(this.color);
    }
    if (this.mannequin?.object.visible) {
      this.mannequin.pose(rotations, mover, points);
      this.mannequin.color(this.color);
    }
  }

  /** The colours of the shown figure's materials, "#rrggbb" (sRGB). */
  materialColors() {
    const materials = this.mannequin?.object.visible ? this.mannequin.materials
      : [this.sticks.lineMaterial, this.sticks.dotMaterial];
    return materials.map((m) => `#${m.color.getHexString()}`);
  }

  /**
   * Largest distance (metres) between a bone of the posed mannequin and the same joint's
   * world position in the latest frame: zero when the skin follows the stream exactly; null
   * without a mannequin or a frame.
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
      worst = Math.max(worst, here.distanceTo(this.world.localToWorld(there)));
    });
    return worst;
  }

  dispose() {
    this.world.remove(this.group);
    this.sticks.dispose();
    if (this.mannequin) this.mannequin.dispose();
  }
}

/** The figures of agent `id` in `figures` (a Map), made by `make(id)` and added when missing. */
export function figuresOf(figures, id, make) {
  let figure = figures.get(id);
  if (!figure) {
    figure = make(id);
    figures.set(id, figure);
  }
  return figure;
}

/**
 * Keep the figures of the agents in `seen` (a Set of ids) in `figures` (a Map id -> figures):
 * dispose and drop the others, calling `onGone(id)` for each.
 */
export function dropUnseen(figures, seen, onGone) {
  for (const [id, figure] of figures) {
    if (!seen.has(id)) {
      figure.dispose();
      figures.delete(id);
      onGone(id);
    }
  }
}
