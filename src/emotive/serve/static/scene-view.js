// The scene of a server started with --scene (docs/serve.md#crowds), drawn on the ground of a
// view (scene-setup.js): the area's outline, the obstacles (outlined and shaded), and each
// group's spawn and goal areas, faintly; plus the drafts of the scene tools (scene-tools.js):
// an obstacle being drawn and the start of an agent being dropped.
//
// Units: metres; a scene message's points are [x, z] on the ground (the scene file's [x, y]).

import * as THREE from "three";

// Heights (metres) of the drawings above the ground, so that they are not hidden in it.
const LINE_Y = 0.03;
const FILL_Y = 0.015;
const COLORS = { area: 0xe8eef2, obstacle: 0xff8a65, spawn: 0x81c784, goal: 0x64b5f6, draft: 0xfff176 };
// Opacity of the spawn and goal outlines, and of the obstacles' and goal areas' shading.
const FAINT = 0.45;
const SHADE = 0.35;

/** A closed outline of `points` [[x, z], ...] on the ground. */
function outline(points, color, opacity = 1) {
  const geometry = new THREE.BufferGeometry().setFromPoints(
    points.map(([x, z]) => new THREE.Vector3(x, LINE_Y, z)));
  const material = new THREE.LineBasicMaterial({ color, transparent: opacity < 1, opacity });
  const line = new THREE.LineLoop(geometry, material);
  line.frustumCulled = false;
  return line;
}

/** The polygon `points` [[x, z], ...] as a flat shaded area on the ground. */
function shade(points, color, opacity) {
  // A shape in the (x, -z) plane, turned onto the ground (x, z) by a -90 degree turn about x.
  const shape = new THREE.Shape(points.map(([x, z]) => new THREE.Vector2(x, -z)));
  const geometry = new THREE.ShapeGeometry(shape).rotateX(-Math.PI / 2);
  const mesh = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({
    color, transparent: true, opacity, side: THREE.DoubleSide, depthWrite: false,
  }));
  mesh.position.y = FILL_Y;
  return mesh;
}

/** The [x, z] points of a line drawn on the ground (read back from its geometry). */
function pointsOf(line) {
  const p = line.geometry.getAttribute("position");
  const out = [];
  for (let i = 0; i < p.count; i++) out.push([p.getX(i), p.getZ(i)]);
  return out;
}

/** The scene's geometry on the ground of `view.world`, replaced whole by each message. */
export class SceneDrawing {
  constructor(world) {
    this.group = new THREE.Group();
    world.add(this.group);
    this.message = null;
    this.lines = { area: null, obstacles: [], spawns: [], goals: [] };
    this.draftLine = new THREE.Line(new THREE.BufferGeometry(),
                                    new THREE.LineBasicMaterial({ color: COLORS.draft }));
    this.draftLine.frustumCulled = false;
    this.marker = new THREE.Mesh(new THREE.RingGeometry(0.2, 0.3, 32).rotateX(-Math.PI / 2),
                                 new THREE.MeshBasicMaterial({ color: COLORS.draft }));
    this.marker.position.y = LINE_Y;
    this.marker.visible = false;
    world.add(this.draftLine, this.marker);
  }

  /** Draw the scene of a `{"type": "scene", ...}` message (docs/serve.md#crowds). */
  show(message) {
    for (const child of [...this.group.children]) {
      this.group.remove(child);
      child.geometry.dispose();
      child.material.dispose();
    }
    const add = (object) => { this.group.add(object); return object; };
    this.message = message;
    this.lines = {
      area: add(outline(message.area, COLORS.area)),
      obstacles: message.obstacles.map((o) => {
        add(shade(o, COLORS.obstacle, SHADE));
        return add(outline(o, COLORS.obstacle));
      }),
      spawns: message.groups.map((g) => add(outline(g.spawn, COLORS.spawn, FAINT))),
      goals: message.groups.filter((g) => g.goal.kind === "exit").map((g) => {
        add(shade(g.goal.polygon, COLORS.goal, SHADE * FAINT));
        return add(outline(g.goal.polygon, COLORS.goal, FAINT));
      }),
    };
  }

  /** What is drawn, read back from the lines: {version, area, obstacles, spawns, goals}. */
  drawn() {
    const l = this.lines;
    return {
      version: this.message ? this.message.version : null,
      area: l.area ? pointsOf(l.area) : [],
      obstacles: l.obstacles.map(pointsOf),
      spawns: l.spawns.map(pointsOf),
      goals: l.goals.map(pointsOf),
    };
  }

  /** The area's bounds {minX, maxX, minZ, maxZ}, or null without a scene. */
  bounds() {
    if (!this.message) return null;
    const xs = this.message.area.map((p) => p[0]);
    const zs = this.message.area.map((p) => p[1]);
    return { minX: Math.min(...xs), maxX: Math.max(...xs), minZ: Math.min(...zs), maxZ: Math.max(...zs) };
  }

  /** Show the open polyline `points` [[x, z], ...] of a draft (none: hide it). */
  draft(points) {
    this.draftLine.geometry.dispose();
    this.draftLine.geometry = new THREE.BufferGeometry().setFromPoints(
      points.map(([x, z]) => new THREE.Vector3(x, LINE_Y, z)));
  }

  /** Mark the ground point [x, z] (null: no mark). */
  mark(point) {
    this.marker.visible = Boolean(point);
    if (point) this.marker.position.set(point[0], LINE_Y, point[1]);
  }
}
