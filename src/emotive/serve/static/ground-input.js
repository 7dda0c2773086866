// The mouse on the ground plane (y = 0) of a view (scene-setup.js): a click picks the agent
// near it, or places one there; a press, drag and release draws a path, shown as it grows.
//
// Units: metres on the ground, rounded to the millimetre; pixels on the page.

// A click within this distance (metres, on the ground) of an agent selects it.
const PICK_RADIUS = 0.8;
// Drawn paths keep a point every this many metres.
const PATH_SPACING = 0.2;
// A press that moves less than this (pixels) is a click.
const CLICK_PIXELS = 5;

/** `v` metres rounded to the millimetre. */
export const round = (v) => Math.round(v * 1000) / 1000;

/** The visible figure among `figures` ({position, group}) nearest `point`, within PICK_RADIUS. */
function nearest(figures, point) {
  let best = null;
  let bestDistance = PICK_RADIUS;
  for (const figure of figures) {
    const d = Math.hypot(figure.position.x - point.x, figure.position.z - point.z);
    if (figure.group.visible && d < bestDistance) {
      best = figure;
      bestDistance = d;
    }
  }
  return best;
}

/**
 * Listen to the mouse on `view`'s canvas (not while an XR session shows).
 *
 * @param view the view of scene-setup.js.
 * @param app the page's state: `mouseMode` ("place" or "draw") and `drawnPath` (the last path
 *   drawn, shown again after a click in draw mode).
 * @param {Map} figures the agents' figures by id ({id, position, group}).
 * @param {object} on `select(id)` (null: none); `place(x, z)`: a click on the ground away
 *   from the agents in place mode; `drawn(points)`: a path drawn, [[x, z], ...] every
 *   PATH_SPACING metres and at the release.
 */
export function listenToGround(view, app, figures, on) {
  const canvas = view.renderer.domElement;
  let press = null;

  function onClick(point) {
    const figure = nearest(figures.values(), point);
    if (figure) on.select(figure.id);
    else if (app.mouseMode === "place") on.place(round(point.x), round(point.z));
    else on.select(null);
  }

  canvas.addEventListener("pointerdown", (event) => {
    if (event.button !== 0 || view.renderer.xr.isPresenting) return;
    const point = view.groundAt(event);
    press = { x: event.clientX, y: event.clientY, point, drawing: app.mouseMode === "draw" && point !== null };
    if (press.drawing) {
      canvas.setPointerCapture(event.pointerId);
      press.path = [[round(point.x), round(point.z)]];
      view.setLine(view.drawnLine, press.path);
    }
  });

  canvas.addEventListener("pointermove", (event) => {
    if (!press?.drawing) return;
    const point = view.groundAt(event);
    if (!point) return;
    const [lx, lz] = press.path[press.path.length - 1];
    if (Math.hypot(point.x - lx, point.z - lz) >= PATH_SPACING) {
      press.path.push([round(point.x), round(point.z)]);
      view.setLine(view.drawnLine, press.path);
    }
  });

  canvas.addEventListener("pointerup", (event) => {
    if (!press) return;
    const moved = Math.hypot(event.clientX - press.x, event.clientY - press.y);
    const { drawing, path, point } = press;
    press = null;
    if (drawing && path.length >= 2) {
      const end = view.groundAt(event);
      const [lx, lz] = path[path.length - 1];
      if (end && Math.hypot(end.x - lx, end.z - lz) > 1e-3) path.push([round(end.x), round(end.z)]);
      on.drawn(path);
    } else if (moved < CLICK_PIXELS && point) {
      if (drawing) view.setLine(view.drawnLine, app.drawnPath);
      onClick(point);
    }
  });
}
