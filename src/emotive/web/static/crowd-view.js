// The scene of `emotive export web --scene` in the 3-D view: the walkable area's outline, the
// obstacles as grey blocks, the spawns (blue) and exits (green) on the ground, and a camera
// that frames the area. Scene (x, y) is the world (x, z), metres.

import * as THREE from "three";

// Height of an obstacle block, metres.
const OBSTACLE_HEIGHT = 1.0;

/** A THREE.Shape of a ring [[x, y], ...] in the scene's plane. */
function shapeOf(ring) {
  return new THREE.Shape(ring.map(([x, y]) => new THREE.Vector2(x, y)));
}

/** A flat, translucent patch of `ring` just above the ground. */
function patch(ring, color, lift) {
  // rotateX(+90 degrees) takes the shape's (x, y, 0) to the world's (x, 0, y).
  const geometry = new THREE.ShapeGeometry(shapeOf(ring)).rotateX(Math.PI / 2);
  const mesh = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({
    color, transparent: true, opacity: 0.28, side: THREE.DoubleSide, depthWrite: false,
  }));
  mesh.position.y = lift;
  return mesh;
}

/** A closed line around `ring`. */
function outline(ring, color) {
  const points = [...ring, ring[0]].map(([x, y]) => new THREE.Vector3(x, 0.03, y));
  const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints(points),
                              new THREE.LineBasicMaterial({ color }));
  line.frustumCulled = false;
  return line;
}

/**
 * Draw scene.json's scene into `view.world` and point the fixed camera at it.
 *
 * @param {object} view the page's view (scene-setup.js).
 * @param {object} doc scene.json.
 * @returns {THREE.Group} what was drawn.
 */
export function drawScene(view, doc) {
  const group = new THREE.Group();
  const { area, groups } = doc.scene;
  group.add(outline(area.polygon, 0xe8edf2));
  for (const { polygon } of area.obstacles) {
    const block = new THREE.Mesh(
      new THREE.ExtrudeGeometry(shapeOf(polygon), { depth: OBSTACLE_HEIGHT, bevelEnabled: false })
        .rotateX(Math.PI / 2).translate(0, OBSTACLE_HEIGHT, 0),
      new THREE.MeshStandardMaterial({ color: 0x7d8690, roughness: 0.9 }));
    group.add(block, outline(polygon, 0xc9d1da));
  }
  for (const g of groups) {
    group.add(patch(g.spawn, 0x4f8fd6, 0.012));
    if (Array.isArray(g.goal)) group.add(patch(g.goal, 0x58c470, 0.014));
  }
  view.world.add(group);

  const xs = area.polygon.map((p) => p[0]);
  const ys = area.polygon.map((p) => p[1]);
  const cx = (Math.min(...xs) + Math.max(...xs)) / 2;
  const cz = (Math.min(...ys) + Math.max(...ys)) / 2;
  const size = Math.max(Math.max(...xs) - Math.min(...xs), Math.max(...ys) - Math.min(...ys));
  view.controls.target.set(cx, 0, cz);
  view.camera.position.set(cx, 0.95 * size + 2, cz + 0.85 * size + 2);
  view.controls.update();
  view.fixedView.position.copy(view.camera.position);
  view.fixedView.target.copy(view.controls.target);
  return group;
}
