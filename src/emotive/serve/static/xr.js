// WebXR: an AR button (hit-test: a reticle on the real floor, a tap puts the scene's origin
// there) and a VR button, or a message saying why they are missing.

import * as THREE from "three";
import { ARButton } from "three/addons/webxr/ARButton.js";
import { VRButton } from "three/addons/webxr/VRButton.js";

/**
 * Add the AR and VR buttons that this browser supports to `container`, and a message for
 * each session type it does not.
 *
 * @param {THREE.WebGLRenderer} renderer with `xr.enabled` set.
 * @param {THREE.Scene} scene
 * @param {THREE.Object3D} world the group holding the agents and the grid; AR placement moves it.
 * @param {HTMLElement} container
 * @param {{onStart: () => void, onEnd: () => void}} hooks called as a session starts and ends.
 * @returns {Promise<{update: (frame: XRFrame) => void}>} call `update` every XR frame.
 */
export async function setUpXR(renderer, scene, world, container, hooks) {
  const notes = [];
  const reticle = new THREE.Mesh(
    new THREE.RingGeometry(0.12, 0.16, 32).rotateX(-Math.PI / 2),
    new THREE.MeshBasicMaterial({ color: 0xffffff }),
  );
  reticle.matrixAutoUpdate = false;
  reticle.visible = false;
  scene.add(reticle);
  let hitSource = null;
  let hitRequested = false;

  if (!("xr" in navigator)) {
    notes.push("WebXR is not available in this browser: AR and VR need a WebXR browser "
               + "(for example Chrome on Android, Quest Browser) on https:// or localhost.");
  } else {
    const ar = await navigator.xr.isSessionSupported("immersive-ar").catch(() => false);
    const vr = await navigator.xr.isSessionSupported("immersive-vr").catch(() => false);
    if (ar) container.append(ARButton.createButton(renderer, { requiredFeatures: ["hit-test"] }));
    else notes.push("AR is not supported here (immersive-ar sessions are unavailable on this device).");
    if (vr) container.append(VRButton.createButton(renderer));
    else notes.push("VR is not supported here (immersive-vr sessions are unavailable on this device).");
  }
  const message = notes.join(" ");
  if (message) {
    const p = document.createElement("p");
    p.id = "xr-message";
    p.textContent = message;
    container.append(p);
  }

  const controller = renderer.xr.getController(0);
  controller.addEventListener("select", () => {
    if (!reticle.visible) return;
    reticle.matrix.decompose(world.position, new THREE.Quaternion(), new THREE.Vector3());
  });
  scene.add(controller);

  renderer.xr.addEventListener("sessionstart", () => {
    hitRequested = false;
    hooks.onStart(renderer.xr.getSession());
  });
  renderer.xr.addEventListener("sessionend", () => {
    hitSource = null;
    reticle.visible = false;
    world.position.set(0, 0, 0);
    hooks.onEnd();
  });

  function update(frame) {
    const session = renderer.xr.getSession();
    // Only AR sessions (which see the real world) asked for hit-test.
    if (!session || session.environmentBlendMode === "opaque") return;
    if (!hitRequested) {
      hitRequested = true;
      session.requestReferenceSpace("viewer")
        .then((space) => session.requestHitTestSource({ space }))
        .then((source) => { hitSource = source; });
    }
    if (!hitSource) return;
    const hits = frame.getHitTestResults(hitSource);
    const pose = hits.length ? hits[0].getPose(renderer.xr.getReferenceSpace()) : null;
    reticle.visible = pose !== null;
    if (pose) reticle.matrix.fromArray(pose.transform.matrix);
  }

  return { update };
}
