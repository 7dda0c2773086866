// Parse a glTF file with three.js's GLTFLoader (no DOM needed for a file without textures),
// pose it at one time of its animation, and print what three.js built as JSON.
// Usage: node load_three.mjs FILE.glb|FILE.gltf TIME_SECONDS
import { readFileSync } from "node:fs";
import { AnimationMixer, Box3, Vector3 } from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";

// three.js reads a .gltf's data URI with fetch and reports progress with ProgressEvent,
// which browsers have and Node 20 does not.
globalThis.ProgressEvent ??= class ProgressEvent extends Event {
  constructor(type, init = {}) {
    super(type);
    Object.assign(this, init);
  }
};

const [path, time] = [process.argv[2], Number(process.argv[3])];
const bytes = readFileSync(path);
const data = path.toLowerCase().endsWith(".glb")
  ? bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength)
  : bytes.toString("utf8");
const gltf = await new Promise((resolve, reject) => new GLTFLoader().parse(data, "", resolve, reject));

const skinned = [];
gltf.scene.traverse((o) => { if (o.isSkinnedMesh) skinned.push(o); });
const clip = gltf.animations[0];
const mixer = new AnimationMixer(gltf.scene);
if (clip) mixer.clipAction(clip).play();
mixer.setTime(time);
gltf.scene.updateMatrixWorld(true);
const mesh = skinned[0];
const bones = mesh ? mesh.skeleton.bones : [];
const box = new Box3();
if (mesh) {
  mesh.skeleton.update();
  mesh.computeBoundingBox();  // with the bones' current pose (three >= r151)
  box.copy(mesh.boundingBox).applyMatrix4(mesh.matrixWorld);
}
console.log(JSON.stringify({
  skinned_meshes: skinned.length,
  vertices: mesh ? mesh.geometry.attributes.position.count : 0,
  bones: bones.map((b) => b.name),
  positions: bones.map((b) => b.getWorldPosition(new Vector3()).toArray()),
  clips: gltf.animations.length,
  duration: clip ? clip.duration : 0,
  tracks: clip ? clip.tracks.map((t) => t.name) : [],
  box_min: box.min.toArray(),
  box_max: box.max.toArray(),
}));
