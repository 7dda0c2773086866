// The view's two cameras (scene-setup.js): "fixed", the orbit camera where the user left it,
// and "follow", behind and above the selected agent, eased towards it every frame.
//
// Units: metres in scene coordinates (Y up), seconds; rates in 1/s.

import * as THREE from "three";

// Follow camera: offset behind and above the agent (metres) and smoothing rates (1/s).
const FOLLOW_BACK = 4.5;
const FOLLOW_UP = 2.2;
const FOLLOW_RATE = 2.5;
const LOOK_RATE = 6;

export class FollowCamera {
  constructor(view) {
    this.view = view;
    this.mode = "fixed";
    this.look = new THREE.Vector3();
  }

  /** Switch to `mode`: back to the orbit camera's last place, or from it to following. */
  set(mode) {
    const { camera, controls, fixedView } = this.view;
    this.mode = mode;
    if (mode === "fixed") {
      camera.position.copy(fixedView.position);
      controls.target.copy(fixedView.target);
      controls.update();
    } else {
      fixedView.position.copy(camera.position);
      fixedView.target.copy(controls.target);
      this.look.copy(controls.target);
    }
  }

  /**
   * Ease the follow camera `dt` seconds towards `agent` ({position, heading}, scene
   * coordinates); nothing in fixed mode, without an agent or in an XR session.
   */
  update(agent, dt) {
    const { camera, renderer, world } = this.view;
    if (this.mode !== "follow" || !agent || renderer.xr.isPresenting) return;
    const wanted = agent.position.clone().addScaledVector(agent.heading, -FOLLOW_BACK);
    wanted.y = FOLLOW_UP;
    const look = agent.position.clone();
    look.y = 1.0;
    camera.position.lerp(world.localToWorld(wanted), 1 - Math.exp(-FOLLOW_RATE * dt));
    this.look.lerp(world.localToWorld(look), 1 - Math.exp(-LOOK_RATE * dt));
    camera.lookAt(this.look);
  }
}
