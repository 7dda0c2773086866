// The stimulus view of the participant page: one stimulus GLB looping at a fixed camera that
// frames its whole walk, drawn in a neutral grey (an emotion colour would bias the raters) on
// a ground grid, in one of three renders:
//
//   mannequin  the GLB's skinned mesh, played by an AnimationMixer (LoopRepeat)
//   sticks     the mesh hidden; a stick between each bone's world position and its parent's,
//              and a dot on every joint
//   effectors  only dots at the item's effector bones (head, hands, feet, hips) with a fading
//              trace of the last TRACE_SECONDS of each (the end-effector trajectories of
//              Carreno-Medrano et al. 2018, section 7.1.1)
//
// Every stimulus loops over the study's `seconds`. The walk is sampled once, at SAMPLE_HZ,
// when it loads: the box around every joint over the loop places the camera and the grid, and
// the samples draw the effector traces (the same at any frame rate).

import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";

// Colours: the figure's neutral grey, the page behind, the ground grid.
const FIGURE = 0x7b8088;
const BACKGROUND = 0xf2f3f5;
const GROUND = 0xe8eaed;
const GRID_MAJOR = 0xaeb3b9;
const GRID_MINOR = 0xcdd1d6;
// Samples a second of the walk taken when a stimulus loads.
const SAMPLE_HZ = 30;
// Seconds of each effector's trace.
const TRACE_SECONDS = 1.0;
// Metres around the joints that the body's volume takes (a head above its joint...): the
// grid's box grows by BODY_PAD, and every framed joint by BODY_OFFSETS.
const BODY_PAD = 0.25;
const BODY_OFFSETS = [[0, 0, 0], [0, 0.2, 0], [0.12, 0, 0], [-0.12, 0, 0], [0, 0, 0.12],
                      [0, 0, -0.12]];
// Moments of the loop whose poses the camera frames, at most (a long loop is strided).
const MAX_FRAMED_TIMES = 120;
// The camera looks down at this angle (degrees), from the side of the walk.
const ELEVATION_DEG = 40;
// Vertical field of view (degrees).
const FOV_DEG = 35;
// The framed box fills at most this fraction of the view's half-width and half-height.
const FILL = 0.9;
// Radii (metres): sticks, joint dots, effector dots, trace dots.
const STICK_RADIUS = 0.022;
const JOINT_RADIUS = 0.035;
const EFFECTOR_RADIUS = 0.05;
const TRACE_RADIUS = 0.035;

const UP = new THREE.Vector3(0, 1, 0);

/** The bone a `.position` track moves the most: the mover (hips), or null. */
function moverOf(clip, root) {
  let best = null;
  let range = -1;
  for (const track of clip.tracks) {
    const parsed = THREE.PropertyBinding.parseTrackName(track.name);
    if (parsed.propertyName !== "position") continue;
    const v = track.values;
    let r = 0;
    for (let k = 0; k < 3; k++) {
      let lo = Infinity;
      let hi = -Infinity;
      for (let i = k; i < v.length; i += 3) { lo = Math.min(lo, v[i]); hi = Math.max(hi, v[i]); }
      r = Math.max(r, hi - lo);
    }
    const node = THREE.PropertyBinding.findNode(root, parsed.nodeName);
    if (node && r > range) { best = node; range = r; }
  }
  return best;
}

/** A stimulus loaded and ready to play in one render. */
class Stimulus {
  constructor(gltf, render, seconds, effectorNames) {
    this.render = render;
    this.seconds = seconds;
    this.root = gltf.scene;
    this.meshes = [];
    this.material = new THREE.MeshStandardMaterial({ color: FIGURE, roughness: 0.85,
                                                    metalness: 0 });
    let bones = [];
    this.root.traverse((o) => {
      if (!o.isMesh) return;
      o.material = this.material;
      o.frustumCulled = false;
      o.visible = render === "mannequin";
      this.meshes.push(o);
      if (o.isSkinnedMesh && bones.length === 0) bones = o.skeleton.bones;
    });
    if (bones.length === 0) this.root.traverse((o) => { if (o.isBone) bones.push(o); });
    if (bones.length === 0) throw new Error("the stimulus has no skeleton");
    this.bones = bones;
    const clip = gltf.animations[0];
    if (!clip) throw new Error("the stimulus has no animation");
    // The loop is `seconds` long whatever the clip's last key time is.
    clip.duration = seconds;
    this.mixer = new THREE.AnimationMixer(this.root);
    this.action = this.mixer.clipAction(clip);
    this.action.setLoop(THREE.LoopRepeat, Infinity);
    this.action.play();

    const index = new Map(bones.map((b, j) => [b, j]));
    const mover = moverOf(clip, this.root) ?? bones[0];
    // The bones above the mover place the figure in the world (a root on the ground under the
    // hips): no body part, so no stick from them.
    const placement = new Set();
    for (let b = mover.parent; b; b = b.parent) placement.add(b);
    this.pairs = [];
    bones.forEach((b, j) => {
      if (index.has(b.parent) && !placement.has(b.parent)) this.pairs.push([index.get(b.parent), j]);
    });
    this.joints = bones.map((_, j) => j).filter((j) => !placement.has(bones[j]));
    this.mover = index.get(mover) ?? 0;
    const byName = (name) => {
      const node = this.root.getObjectByName(THREE.PropertyBinding.sanitizeNodeName(name));
      return index.has(node) ? index.get(node) : -1;
    };
    let effectors = effectorNames.map(byName).filter((j) => j >= 0);
    if (effectors.length === 0) {
      // Names not found: the leaves of the skeleton and the mover.
      effectors = this.joints.filter((j) => !bones.some((b) => b.parent === bones[j]));
      effectors.push(this.mover);
    }
    this.effectors = [...new Set(effectors)];
    this.sample();
    this.build();
  }

  /**
   * Sample every joint's world position over the loop: the traces, the box of the whole walk
   * (which places the grid) and the points the camera frames (every body joint at up to
   * MAX_FRAMED_TIMES moments, widened by the body's volume).
   */
  sample() {
    const n = Math.max(2, Math.round(this.seconds * SAMPLE_HZ));
    const J = this.bones.length;
    this.samples = new Float32Array(n * J * 3);
    this.box = new THREE.Box3();
    const p = new THREE.Vector3();
    const path = [];
    const body = new Set(this.joints);
    const stride = Math.max(1, Math.ceil(n / MAX_FRAMED_TIMES));
    const framed = [];
    for (let i = 0; i < n; i++) {
      this.mixer.setTime(i / SAMPLE_HZ);
      this.root.updateMatrixWorld(true);
      this.bones.forEach((bone, j) => {
        bone.getWorldPosition(p);
        p.toArray(this.samples, 3 * (i * J + j));
        if (!body.has(j)) return;
        this.box.expandByPoint(p);
        if (i % stride !== 0 && i !== n - 1) return;
        for (const [dx, dy, dz] of BODY_OFFSETS) framed.push(p.x + dx, p.y + dy, p.z + dz);
      });
      const m = 3 * (i * J + this.mover);
      path.push([this.samples[m], this.samples[m + 2]]);
    }
    this.numSamples = n;
    this.framed = new Float32Array(framed);
    this.box.expandByScalar(BODY_PAD);
    this.box.min.y = Math.min(this.box.min.y, 0);
    // The main direction of the mover's path on the ground (the camera looks across it).
    let mx = 0;
    let mz = 0;
    for (const [x, z] of path) { mx += x / n; mz += z / n; }
    let cxx = 0;
    let czz = 0;
    let cxz = 0;
    for (const [x, z] of path) {
      cxx += (x - mx) ** 2; czz += (z - mz) ** 2; cxz += (x - mx) * (z - mz);
    }
    this.heading = 0.5 * Math.atan2(2 * cxz, cxx - czz);
    this.mixer.setTime(0);
  }

  /** The objects of the render: sticks and dots, or effector dots and traces. */
  build() {
    this.group = new THREE.Group();
    this.group.add(this.root);
    this.dummy = new THREE.Object3D();
    if (this.render === "sticks") {
      const stick = new THREE.CylinderGeometry(STICK_RADIUS, STICK_RADIUS, 1, 10);
      this.sticks = new THREE.InstancedMesh(stick, this.material, this.pairs.length);
      const dot = new THREE.SphereGeometry(JOINT_RADIUS, 14, 10);
      this.dots = new THREE.InstancedMesh(dot, this.material, this.joints.length);
      for (const o of [this.sticks, this.dots]) { o.frustumCulled = false; this.group.add(o); }
    } else if (this.render === "effectors") {
      const dot = new THREE.SphereGeometry(EFFECTOR_RADIUS, 16, 12);
      this.dots = new THREE.InstancedMesh(dot, this.material, this.effectors.length);
      this.traceLength = Math.max(2, Math.round(TRACE_SECONDS * SAMPLE_HZ));
      const traceDot = new THREE.SphereGeometry(TRACE_RADIUS, 8, 6);
      this.traceMaterial = new THREE.MeshBasicMaterial({ color: 0xffffff });
      this.trace = new THREE.InstancedMesh(traceDot, this.traceMaterial,
                                           this.traceLength * this.effectors.length);
      // Older trace points fade into the background.
      const c = new THREE.Color();
      const figure = new THREE.Color(FIGURE);
      const back = new THREE.Color(BACKGROUND);
      for (let e = 0; e < this.effectors.length; e++) {
        for (let k = 0; k < this.traceLength; k++) {
          const age = k / this.traceLength;
          this.trace.setColorAt(e * this.traceLength + k, c.copy(figure).lerp(back, 0.15 + 0.8 * age));
        }
      }
      for (const o of [this.dots, this.trace]) { o.frustumCulled = false; this.group.add(o); }
    }
  }

  /** Advance the loop by `dt` seconds and pose the render's objects. */
  update(dt) {
    this.mixer.update(dt);
    this.root.updateMatrixWorld(true);
    if (this.render === "mannequin") return;
    const a = new THREE.Vector3();
    const b = new THREE.Vector3();
    const d = this.dummy;
    if (this.render === "sticks") {
      this.pairs.forEach(([p, q], i) => {
        this.bones[p].getWorldPosition(a);
        this.bones[q].getWorldPosition(b);
        const length = a.distanceTo(b);
        d.position.copy(a).add(b).multiplyScalar(0.5);
        d.quaternion.setFromUnitVectors(UP, b.sub(a).normalize());
        d.scale.set(1, Math.max(length, 1e-4), 1);
        d.updateMatrix();
        this.sticks.setMatrixAt(i, d.matrix);
      });
      this.sticks.instanceMatrix.needsUpdate = true;
      this.joints.forEach((j, i) => {
        this.bones[j].getWorldPosition(d.position);
        d.quaternion.identity();
        d.scale.setScalar(1);
        d.updateMatrix();
        this.dots.setMatrixAt(i, d.matrix);
      });
      this.dots.instanceMatrix.needsUpdate = true;
      return;
    }
    // Effectors: dots now, and the samples of the last TRACE_SECONDS of this pass of the loop
    // (a trace does not jump back across the loop's seam).
    const now = this.action.time;
    const J = this.bones.length;
    const newest = Math.min(this.numSamples - 1, Math.floor(now * SAMPLE_HZ));
    d.quaternion.identity();
    this.effectors.forEach((j, e) => {
      this.bones[j].getWorldPosition(d.position);
      d.scale.setScalar(1);
      d.updateMatrix();
      this.dots.setMatrixAt(e, d.matrix);
      for (let k = 0; k < this.traceLength; k++) {
        const i = newest - k;
        const shown = i >= 0;
        const s = 3 * (Math.max(i, 0) * J + j);
        d.position.set(this.samples[s], this.samples[s + 1], this.samples[s + 2]);
        d.scale.setScalar(shown ? 1 - 0.6 * (k / this.traceLength) : 0);
        d.updateMatrix();
        this.trace.setMatrixAt(e * this.traceLength + k, d.matrix);
      }
    });
    this.dots.instanceMatrix.needsUpdate = true;
    this.trace.instanceMatrix.needsUpdate = true;
  }

  dispose() {
    this.mixer.stopAllAction();
    this.group.traverse((o) => {
      if (o.geometry) o.geometry.dispose();
      if (o.isInstancedMesh) o.dispose();
      if (o.isSkinnedMesh) o.skeleton.dispose();
    });
    this.material.dispose();
    this.traceMaterial?.dispose();
  }
}

/** The view: renderer, fixed camera, ground; shows one stimulus at a time. */
export class Stage {
  /**
   * @param {HTMLElement} container the element the canvas fills. Set `onFirstFrame` to be
   *   told when a stimulus is first drawn.
   */
  constructor(container) {
    this.container = container;
    this.renderer = new THREE.WebGLRenderer({ antialias: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
    this.renderer.setClearColor(BACKGROUND);
    const canvas = this.renderer.domElement;
    canvas.setAttribute("role", "img");
    canvas.setAttribute("aria-label", "animation of a figure, looping");
    container.appendChild(canvas);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(BACKGROUND);
    this.camera = new THREE.PerspectiveCamera(FOV_DEG, 1, 0.05, 500);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x9a9a9a, 2.2));
    const sun = new THREE.DirectionalLight(0xffffff, 1.6);
    sun.position.set(3, 8, 5);
    this.scene.add(sun);
    this.ground = new THREE.Group();
    this.scene.add(this.ground);
    this.stimulus = null;
    this.framesRendered = 0;
    this.stimulusFrames = 0;
    this.onFirstFrame = null;
    this.last = performance.now();
    this.loader = new GLTFLoader();
    this.width = 0;
    this.height = 0;
    new ResizeObserver(() => this.resize()).observe(container);
    this.renderer.setAnimationLoop(() => this.frame());
  }

  /**
   * Show a stimulus from its GLB bytes in `render`, looping over `seconds`.
   *
   * @param {ArrayBuffer} bytes the GLB.
   * @param {string} render mannequin | sticks | effectors
   * @param {number} seconds the loop's length.
   * @param {string[]} effectors bone names of the effectors render.
   */
  async show(bytes, render, seconds, effectors) {
    const gltf = await this.loader.parseAsync(bytes, "");
    const stimulus = new Stimulus(gltf, render, seconds, effectors);
    this.clear();
    this.stimulus = stimulus;
    this.scene.add(stimulus.group);
    this.makeGround(stimulus.box);
    this.fit();
    this.stimulusFrames = 0;
    this.last = performance.now();
    stimulus.update(0);
  }

  /** Take the stimulus away (the view shows the empty ground until the next one). */
  clear() {
    if (!this.stimulus) return;
    this.scene.remove(this.stimulus.group);
    this.stimulus.dispose();
    this.stimulus = null;
    if (this.width > 0 && this.height > 0) this.renderer.render(this.scene, this.camera);
  }

  /** A grid of half-metre cells around the walk's box. */
  makeGround(box) {
    for (const o of [...this.ground.children]) {
      this.ground.remove(o);
      o.geometry.dispose();
      o.material.dispose();
    }
    const centre = box.getCenter(new THREE.Vector3());
    const extent = Math.max(box.max.x - box.min.x, box.max.z - box.min.z);
    const size = 2 * Math.ceil((extent + 3) / 2);
    const plane = new THREE.Mesh(new THREE.PlaneGeometry(size, size),
                                 new THREE.MeshBasicMaterial({ color: GROUND }));
    plane.rotation.x = -Math.PI / 2;
    plane.position.set(Math.round(centre.x), -0.002, Math.round(centre.z));
    const grid = new THREE.GridHelper(size, size * 2, GRID_MAJOR, GRID_MINOR);
    grid.position.set(Math.round(centre.x), 0, Math.round(centre.z));
    this.ground.add(plane, grid);
  }

  /**
   * The view's box around the framed points, [minX, minY, maxX, maxY] (-1..1 is the view), or
   * null when nothing is shown; Infinity when a point is behind the camera.
   */
  framing() {
    if (!this.stimulus) return null;
    const cam = this.camera;
    cam.updateMatrixWorld(true);
    const m = cam.matrixWorldInverse.elements;
    const f = 1 / Math.tan(THREE.MathUtils.degToRad(cam.fov / 2));
    const pts = this.stimulus.framed;
    const r = [Infinity, Infinity, -Infinity, -Infinity];
    for (let i = 0; i < pts.length; i += 3) {
      const x = pts[i];
      const y = pts[i + 1];
      const z = pts[i + 2];
      const cx = m[0] * x + m[4] * y + m[8] * z + m[12];
      const cy = m[1] * x + m[5] * y + m[9] * z + m[13];
      const cz = m[2] * x + m[6] * y + m[10] * z + m[14];
      if (-cz < cam.near) return [-Infinity, -Infinity, Infinity, Infinity];
      const px = (f / cam.aspect) * cx / -cz;
      const py = f * cy / -cz;
      if (px < r[0]) r[0] = px;
      if (py < r[1]) r[1] = py;
      if (px > r[2]) r[2] = px;
      if (py > r[3]) r[3] = py;
    }
    return r;
  }

  /**
   * Place the camera: from the side of the walk's main direction, ELEVATION_DEG above, as
   * close as lets every framed point fill at most FILL of the view; then centred on them.
   */
  fit() {
    if (!this.stimulus || this.width === 0) return;
    const s = this.stimulus;
    const e = THREE.MathUtils.degToRad(ELEVATION_DEG);
    // Across the walk's main direction (heading is the angle of that direction in x, z).
    const across = new THREE.Vector3(-Math.sin(s.heading), 0, Math.cos(s.heading));
    if (across.z < 0) across.negate();
    const dir = across.multiplyScalar(Math.cos(e)).setY(Math.sin(e)).normalize();
    const target = s.box.getCenter(new THREE.Vector3());
    const cam = this.camera;
    const fits = (distance) => {
      cam.position.copy(target).addScaledVector(dir, distance);
      cam.lookAt(target);
      const [x0, y0, x1, y1] = this.framing();
      return Math.max(-x0, -y0, x1, y1) <= FILL;
    };
    const place = () => {
      let lo = 0.1;
      let hi = 1;
      while (!fits(hi) && hi < 1e4) hi *= 2;
      for (let k = 0; k < 30; k++) {
        const mid = 0.5 * (lo + hi);
        if (fits(mid)) hi = mid; else lo = mid;
      }
      fits(hi);
      return hi;
    };
    for (let round = 0; round < 3; round++) {
      const distance = place();
      // Move the aim so that the framed points' picture is centred on the view.
      const [x0, y0, x1, y1] = this.framing();
      const halfH = distance / (1 / Math.tan(THREE.MathUtils.degToRad(cam.fov / 2)));
      const right = new THREE.Vector3().setFromMatrixColumn(cam.matrixWorld, 0);
      const up = new THREE.Vector3().setFromMatrixColumn(cam.matrixWorld, 1);
      target.addScaledVector(right, 0.5 * (x0 + x1) * halfH * cam.aspect)
        .addScaledVector(up, 0.5 * (y0 + y1) * halfH);
    }
    place();
  }

  resize() {
    const w = this.container.clientWidth;
    const h = this.container.clientHeight;
    if (w === this.width && h === this.height) return;
    this.width = w;
    this.height = h;
    if (w === 0 || h === 0) return;
    this.renderer.setSize(w, h, false);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.fit();
  }

  frame() {
    const now = performance.now();
    const dt = Math.min((now - this.last) / 1000, 0.25);
    this.last = now;
    this.resize();
    if (!this.stimulus || this.width === 0 || this.height === 0) return;
    this.stimulus.update(dt);
    this.renderer.render(this.scene, this.camera);
    this.framesRendered++;
    this.stimulusFrames++;
    if (this.stimulusFrames === 1 && this.onFirstFrame) this.onFirstFrame();
  }

  /** The loop's time of the stimulus shown (seconds), or null. */
  get time() {
    return this.stimulus ? this.stimulus.action.time : null;
  }
}
