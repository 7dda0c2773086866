// The 3-D view of the served app and of the browser runtime (emotive export web): renderer,
// lights, a ground grid in metres (Y up), an orbit camera, the drawn and selected paths, the
// selection ring, the WebXR buttons, and the conversions between the ground and the page.
//
// Units: metres in scene coordinates (the ground is y = 0), pixels on the page.

import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { setUpXR } from "./xr.js";
import { paletteColor } from "./figures.js";

// Side of the ground grid, metres.
const GRID_SIZE = 40;

/**
 * Lines every metre over a `size` x `size` square, the axes in `axisColor`. Each line is cut
 * into 1 m segments: some WebGL implementations (SwiftShader) drop a whole line that crosses
 * the camera's near plane instead of clipping it.
 */
function groundGrid(size, axisColor, lineColor) {
  const half = size / 2;
  const positions = [];
  const colors = [];
  const axis = new THREE.Color(axisColor);
  const line = new THREE.Color(lineColor);
  for (let i = -half; i <= half; i++) {
    const c = i === 0 ? axis : line;
    for (let j = -half; j < half; j++) {
      positions.push(i, 0, j, i, 0, j + 1, j, 0, i, j + 1, 0, i);
      for (let k = 0; k < 4; k++) colors.push(c.r, c.g, c.b);
    }
  }
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute("position", new THREE.Float32BufferAttribute(positions, 3));
  geometry.setAttribute("color", new THREE.Float32BufferAttribute(colors, 3));
  return new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ vertexColors: true }));
}

/**
 * The view in `container` (an element the canvas fills, at the window's size).
 *
 * @returns the renderer, the scene and its `background`, the `world` group (everything in
 *   scene coordinates; AR moves it onto the real floor), the `floor` (ground and grid), the
 *   camera and its orbit `controls`, `fixedView` (the orbit camera's position and target),
 *   the `drawnLine` and `selectedPathLine`, and the functions below.
 */
export function createView(container) {
  const renderer = new THREE.WebGLRenderer({ antialias: true });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
  renderer.setSize(window.innerWidth, window.innerHeight);
  renderer.xr.enabled = true;
  container.append(renderer.domElement);

  const scene = new THREE.Scene();
  // The background, ground and grid colours are app.css's (--scene-*), with the figures'.
  const background = paletteColor("scene-background");
  scene.background = background;
  scene.add(new THREE.HemisphereLight(0xffffff, 0x445566, 2.0));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(5, 10, 7);
  scene.add(sun);

  const world = new THREE.Group();
  scene.add(world);
  const floor = new THREE.Group();
  const ground = new THREE.Mesh(new THREE.PlaneGeometry(GRID_SIZE, GRID_SIZE).rotateX(-Math.PI / 2),
                                new THREE.MeshStandardMaterial({
                                  // Pushed back in depth so the grid lines on it always show.
                                  color: paletteColor("scene-ground"), roughness: 1,
                                  polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 4,
                                }));
  floor.add(ground,
            groundGrid(GRID_SIZE, paletteColor("scene-grid-axis"), paletteColor("scene-grid")));
  world.add(floor);

  const camera = new THREE.PerspectiveCamera(50, window.innerWidth / window.innerHeight, 0.05, 200);
  camera.position.set(0, 7, 10.5);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.set(0, 0.5, 0);
  controls.update();

  const lineAt = (color) => {
    const line = new THREE.Line(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color }));
    line.frustumCulled = false;
    world.add(line);
    return line;
  };
  const drawnLine = lineAt(0x4fd1ff);
  const selectedPathLine = lineAt(0xffd54f);

  const selectionRing = new THREE.Mesh(new THREE.RingGeometry(0.35, 0.42, 40).rotateX(-Math.PI / 2),
                                       new THREE.MeshBasicMaterial({ color: 0xffffff }));
  selectionRing.position.y = 0.01;
  selectionRing.visible = false;
  world.add(selectionRing);

  window.addEventListener("resize", () => {
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(window.innerWidth, window.innerHeight);
  });

  const raycaster = new THREE.Raycaster();
  const groundPlane = new THREE.Plane(new THREE.Vector3(0, 1, 0), 0);
  let xr = null;

  return {
    renderer, scene, background, world, floor, camera, controls, drawnLine, selectedPathLine,
    fixedView: { position: camera.position.clone(), target: controls.target.clone() },

    /** Show `points` [[x, z], ...] (metres) as `line`, just above the ground. */
    setLine(line, points) {
      // A new geometry each time: the number of points changes.
      line.geometry.dispose();
      line.geometry = new THREE.BufferGeometry().setFromPoints(
        points.map(([x, z]) => new THREE.Vector3(x, 0.02, z)));
    },

    /** The selection ring around the ground point under `position` (metres), or none (null). */
    ringAt(position) {
      selectionRing.visible = Boolean(position);
      if (position) selectionRing.position.set(position.x, 0.01, position.z);
    },

    /** The ground point (scene coordinates, metres) under a pointer event, or null. */
    groundAt(event) {
      const rect = renderer.domElement.getBoundingClientRect();
      const ndc = new THREE.Vector2(((event.clientX - rect.left) / rect.width) * 2 - 1,
                                    -((event.clientY - rect.top) / rect.height) * 2 + 1);
      raycaster.setFromCamera(ndc, camera);
      const hit = raycaster.ray.intersectPlane(groundPlane, new THREE.Vector3());
      return hit ? world.worldToLocal(hit) : null;
    },

    /** Page coordinates [px, py] of the ground point (x, z) (metres). */
    toScreen(x, z) {
      const p = world.localToWorld(new THREE.Vector3(x, 0, z)).project(camera);
      const rect = renderer.domElement.getBoundingClientRect();
      return [rect.left + ((p.x + 1) / 2) * rect.width, rect.top + ((1 - p.y) / 2) * rect.height];
    },

    /**
     * Render every display or XR frame, calling `beforeRender(dt)` first: dt the seconds
     * since the last frame, capped at 0.5 s so that a long pause (a hidden tab) does not
     * jump the follow camera.
     */
    animate(beforeRender) {
      const timer = new THREE.Timer();
      renderer.setAnimationLoop((time, xrFrame) => {
        timer.update(time);
        const dt = Math.min(timer.getDelta(), 0.5);
        if (xrFrame && xr) xr.update(xrFrame);
        beforeRender(dt);
        renderer.render(scene, camera);
      });
    },

    /**
     * The AR and VR buttons in `container` (xr.js), updated by `animate`'s loop; in a
     * see-through AR session the background and the floor are hidden.
     */
    async setUpXR(container) {
      xr = await setUpXR(renderer, scene, world, container, {
        onStart: (session) => {
          if (session.environmentBlendMode !== "opaque") {
            scene.background = null;
            floor.visible = false;
          }
        },
        onEnd: () => {
          scene.background = background;
          floor.visible = true;
        },
      });
    },
  };
}
