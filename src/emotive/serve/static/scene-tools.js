// The mouse tools of a server with a scene (docs/serve.md#crowds), beside the selection:
//   "agent"     Drop agent: click where it stands, then click its goal; it is added with the
//               emotion of the emotion controls (add_agent with "at" and "goal").
//   "obstacle"  Draw obstacle: click its corners; a double-click, a click on the first
//               corner or Enter closes it (add_obstacle), Backspace takes the last corner
//               back, Esc cancels. A click on the last corner adds none (a double-click's
//               second click).
// In those modes the tools take the clicks on the view before anything else (agents are not
// picked, the orbit camera does not turn); "place" is the selection of ground-input.js.
//
// Units: metres on the ground ([x, z], rounded to the millimetre), pixels on the page.

import { round } from "./ground-input.js";

// A press that moves less than this (pixels) is a click.
const CLICK_PIXELS = 5;
// A click this near (pixels) the last corner adds none (the second click of a double-click);
// this near the first, it closes the obstacle.
const CLOSE_PIXELS = 8;

const $ = (id) => document.getElementById(id);

const HINTS = {
  place: "Click an agent to select it; the scene's agents navigate to their goals.",
  agent: "Click where the new agent stands, then click its goal. Its emotion: the controls below.",
  obstacle: "Click the obstacle's corners; double-click, click the first corner or press Enter to close it, Esc to cancel.",
};

/**
 * The scene tools on `view` (scene-setup.js), drafts drawn by `drawing` (scene-view.js).
 *
 * @param {object} app the page's state: `mouseMode` is set here.
 * @param {object} on `request(message)`: send a control message, resolving with its reply or
 *   null after an error (shown already); `emotion()`: the emotion for a new agent;
 *   `modeChanged(mode)`: after the mode changed.
 */
export class SceneTools {
  constructor(view, drawing, app, on) {
    this.view = view;
    this.drawing = drawing;
    this.app = app;
    this.on = on;
    this.corners = [];
    this.start = null;
    this.enabled = false;
    this.press = null;
    const container = view.renderer.domElement.parentElement;
    // Capture on the canvas's parent: before the canvas's own listeners (picking, orbiting).
    container.addEventListener("pointerdown", (e) => this.pointerDown(e), { capture: true });
    container.addEventListener("pointerup", (e) => this.pointerUp(e), { capture: true });
    container.addEventListener("dblclick", (e) => {
      if (!this.active || e.target !== view.renderer.domElement) return;
      e.stopPropagation();
      if (this.app.mouseMode === "obstacle") this.close();
    }, { capture: true });
    window.addEventListener("keydown", (e) => this.key(e));
    this.buttons = [["mode-place", "place"], ["mode-agent", "agent"], ["mode-obstacle", "obstacle"]];
    for (const [id, mode] of this.buttons) $(id).addEventListener("click", () => this.setMode(mode));
  }

  /** Show the scene tools instead of path drawing (once the server says it has a scene). */
  enable() {
    if (this.enabled) return;
    this.enabled = true;
    $("mode-draw").hidden = true;
    $("mode-agent").hidden = false;
    $("mode-obstacle").hidden = false;
    $("mode-place").textContent = "Select";
    this.setMode("place");
  }

  get active() {
    return this.enabled && (this.app.mouseMode === "agent" || this.app.mouseMode === "obstacle");
  }

  setMode(mode) {
    if (!this.enabled) return;
    this.cancel();
    this.app.mouseMode = mode;
    for (const [id, value] of this.buttons) $(id).classList.toggle("on", value === mode);
    this.view.controls.enabled = mode === "place" && this.app.cameraMode === "fixed";
    $("mode-hint").textContent = HINTS[mode];
    this.on.modeChanged(mode);
  }

  /** Drop the drafts: the obstacle's corners so far, the new agent's start. */
  cancel() {
    this.corners = [];
    this.start = null;
    this.drawing.draft([]);
    this.drawing.mark(null);
  }

  pointerDown(event) {
    if (!this.active || event.button !== 0 || event.target !== this.view.renderer.domElement
        || this.view.renderer.xr.isPresenting) return;
    event.stopPropagation();
    this.press = { x: event.clientX, y: event.clientY };
  }

  pointerUp(event) {
    if (!this.active || !this.press) return;
    event.stopPropagation();
    const moved = Math.hypot(event.clientX - this.press.x, event.clientY - this.press.y);
    this.press = null;
    const hit = this.view.groundAt(event);
    if (moved >= CLICK_PIXELS || !hit) return;
    const point = [round(hit.x), round(hit.z)];
    if (this.app.mouseMode === "obstacle") this.corner(point, event);
    else this.drop(point);
  }

  /** A click in obstacle mode: a corner, nothing (on the last), or the close (on the first). */
  corner(point, event) {
    const near = (p) => {
      const [px, py] = this.view.toScreen(p[0], p[1]);
      return Math.hypot(px - event.clientX, py - event.clientY) < CLOSE_PIXELS;
    };
    const n = this.corners.length;
    if (n && near(this.corners[n - 1])) return;
    if (n >= 3 && near(this.corners[0])) {
      this.close();
      return;
    }
    this.corners.push(point);
    this.drawing.draft(this.corners);
  }

  /** Send the obstacle drawn so far (at least three corners). */
  async close() {
    const polygon = this.corners;
    this.cancel();
    if (polygon.length < 3) return;
    await this.on.request({ type: "add_obstacle", polygon });
  }

  /** A click in agent mode: where the agent stands, then its goal. */
  async drop(point) {
    if (!this.start) {
      this.start = point;
      this.drawing.mark(point);
      return;
    }
    const at = this.start;
    this.cancel();
    await this.on.request({ type: "add_agent", at, goal: point, emotion: this.on.emotion() });
  }

  key(event) {
    if (!this.active || event.target.closest?.("input, textarea")) return;
    if (event.key === "Escape") this.cancel();
    else if (event.key === "Enter" && this.app.mouseMode === "obstacle") this.close();
    else if (event.key === "Backspace" && this.app.mouseMode === "obstacle") {
      this.corners.pop();
      this.drawing.draft(this.corners);
    }
  }
}
