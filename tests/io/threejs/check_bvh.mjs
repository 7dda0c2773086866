// Parse a BVH file with three.js's BVHLoader and print what it found as JSON.
// Usage: node check_bvh.mjs FILE.bvh
import { readFileSync } from "node:fs";
import { BVHLoader } from "three/examples/jsm/loaders/BVHLoader.js";

const text = readFileSync(process.argv[2], "utf8");
const result = new BVHLoader().parse(text);
const bones = result.skeleton.bones;
const track = result.clip.tracks[0];
console.log(JSON.stringify({
  bones: bones.map((b) => b.name),
  parents: bones.map((b) => (b.parent && b.parent.isBone ? b.parent.name : null)),
  frames: track ? track.times.length : 0,
  duration: result.clip.duration,
}));
