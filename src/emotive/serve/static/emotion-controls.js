// The per-agent emotion editors: a valence-arousal disc (a point in the unit circle; valence
// right, arousal up) and one slider per emotion label.

import { emotionColor } from "./figures.js";

/** A 2-D disc on a canvas: press or drag to choose (valence, arousal). */
export class ValenceArousalDisc {
  /**
   * @param {HTMLCanvasElement} canvas
   * @param {(va: {valence: number, arousal: number}) => void} onInput called while dragging.
   */
  constructor(canvas, onInput) {
    this.canvas = canvas;
    this.onInput = onInput;
    this.labels = {};
    this.background = null;
    this.chosen = null;
    this.current = null;
    this.enabled = false;
    canvas.addEventListener("pointerdown", (e) => {
      if (!this.enabled) return;
      canvas.setPointerCapture(e.pointerId);
      this.pick(e);
    });
    canvas.addEventListener("pointermove", (e) => {
      if (this.enabled && canvas.hasPointerCapture(e.pointerId)) this.pick(e);
    });
    this.draw();
  }

  pick(event) {
    const rect = this.canvas.getBoundingClientRect();
    let v = (2 * (event.clientX - rect.left)) / rect.width - 1;
    let a = 1 - (2 * (event.clientY - rect.top)) / rect.height;
    const r = Math.hypot(v, a);
    if (r > 1) {
      v /= r;
      a /= r;
    }
    this.chosen = { valence: v, arousal: a };
    this.draw();
    this.onInput(this.chosen);
  }

  /** Mark labels at their circumplex points: `{label: [valence, arousal]}`. */
  setLabels(points) {
    this.labels = points;
    this.background = null;
    this.draw();
  }

  /** The agent's valence and arousal in the latest frame (drawn as a ring). */
  show(current) {
    const last = this.current;
    // Redraw only for a visible move of the ring.
    if (last && Math.hypot(current.valence - last.valence, current.arousal - last.arousal) < 0.01) return;
    this.current = current;
    this.draw();
  }

  reset() {
    this.chosen = null;
    this.current = null;
    this.draw();
  }

  /** The coloured disc and its label marks, drawn once (the markers move on top of it). */
  backdrop() {
    const { width: w, height: h } = this.canvas;
    const canvas = document.createElement("canvas");
    Object.assign(canvas, { width: w, height: h });
    const ctx = canvas.getContext("2d");
    const r = Math.min(w, h) / 2 - 2;
    const steps = 48;
    for (let i = 0; i < steps; i++) {
      const a0 = (i / steps) * 2 * Math.PI;
      const a1 = ((i + 1) / steps) * 2 * Math.PI;
      const mid = (a0 + a1) / 2;
      const gradient = ctx.createRadialGradient(w / 2, h / 2, 0, w / 2, h / 2, r);
      gradient.addColorStop(0, `#${emotionColor(0, 0).getHexString()}`);
      gradient.addColorStop(1, `#${emotionColor(Math.cos(mid), Math.sin(mid)).getHexString()}`);
      ctx.beginPath();
      ctx.moveTo(w / 2, h / 2);
      // Canvas angles turn clockwise (y down); arousal is up.
      ctx.arc(w / 2, h / 2, r, -a1 - 0.01, -a0);
      ctx.closePath();
      ctx.fillStyle = gradient;
      ctx.fill();
    }
    ctx.strokeStyle = "rgba(0,0,0,0.35)";
    ctx.beginPath();
    ctx.moveTo(w / 2 - r, h / 2);
    ctx.lineTo(w / 2 + r, h / 2);
    ctx.moveTo(w / 2, h / 2 - r);
    ctx.lineTo(w / 2, h / 2 + r);
    ctx.stroke();
    ctx.font = "10px system-ui, sans-serif";
    for (const [label, point] of Object.entries(this.labels)) {
      const [x, y] = this.at(point[0], point[1]);
      ctx.fillStyle = "rgba(255,255,255,0.9)";
      ctx.fillRect(x - 1.5, y - 1.5, 3, 3);
      // Keep the name inside the disc: towards the middle from points near the rim.
      ctx.textAlign = x > 0.7 * w ? "right" : x < 0.3 * w ? "left" : "center";
      ctx.fillText(label, x + (x > 0.7 * w ? -4 : x < 0.3 * w ? 4 : 0), y < 0.2 * h ? y + 12 : y - 4);
    }
    return canvas;
  }

  /** Canvas coordinates of (valence, arousal). */
  at(valence, arousal) {
    const { width: w, height: h } = this.canvas;
    const r = Math.min(w, h) / 2 - 2;
    return [w / 2 + valence * r, h / 2 - arousal * r];
  }

  draw() {
    this.background ??= this.backdrop();
    const ctx = this.canvas.getContext("2d");
    ctx.clearRect(0, 0, this.canvas.width, this.canvas.height);
    ctx.globalAlpha = this.enabled ? 1 : 0.35;
    ctx.drawImage(this.background, 0, 0);
    ctx.globalAlpha = 1;
    if (this.current) {
      const [x, y] = this.at(this.current.valence, this.current.arousal);
      ctx.strokeStyle = "#fff";
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.arc(x, y, 7, 0, 2 * Math.PI);
      ctx.stroke();
      ctx.lineWidth = 1;
    }
    if (this.chosen) {
      const [x, y] = this.at(this.chosen.valence, this.chosen.arousal);
      ctx.fillStyle = "#111";
      ctx.beginPath();
      ctx.arc(x, y, 4, 0, 2 * Math.PI);
      ctx.fill();
    }
  }
}

// Labels whose sliders are always shown; a model's other labels are folded under "more".
export const MAIN_LABELS = ["happy", "sad", "angry", "neutral"];

/** One range input (0..1) per emotion label; reports all weights on every input. */
export class LabelSliders {
  /**
   * @param {HTMLElement} container
   * @param {string[]} labels from /api/skeleton
   * @param {(weights: Object<string, number>) => void} onInput
   */
  constructor(container, labels, onInput) {
    this.inputs = new Map();
    container.replaceChildren();
    const more = document.createElement("details");
    const summary = document.createElement("summary");
    more.append(summary);
    for (const label of labels) {
      const row = document.createElement("label");
      row.className = "slider";
      const name = document.createElement("span");
      name.textContent = label;
      name.title = label;
      const input = document.createElement("input");
      Object.assign(input, { type: "range", min: "0", max: "1", step: "0.05", value: "0" });
      input.dataset.label = label;
      input.disabled = true;
      const value = document.createElement("output");
      value.textContent = "0.00";
      input.addEventListener("input", () => {
        value.textContent = Number(input.value).toFixed(2);
        onInput(this.weights());
      });
      row.append(name, input, value);
      (MAIN_LABELS.includes(label) ? container : more).append(row);
      this.inputs.set(label, { input, value });
    }
    const extra = labels.filter((label) => !MAIN_LABELS.includes(label)).length;
    if (extra) {
      summary.textContent = `${extra} more labels`;
      container.append(more);
    }
  }

  weights() {
    const out = {};
    for (const [label, { input }] of this.inputs) out[label] = Number(input.value);
    return out;
  }

  /** Show an agent's weights (on selection) and enable or disable the sliders. */
  set(weights, enabled) {
    for (const [label, { input, value }] of this.inputs) {
      input.value = String(weights?.[label] ?? 0);
      value.textContent = Number(input.value).toFixed(2);
      input.disabled = !enabled;
    }
  }
}

/** The weights as the protocol's emotion string, "happy=0.70,sad=0.00,...". */
export function weightsText(weights) {
  return Object.entries(weights).map(([k, v]) => `${k}=${v.toFixed(2)}`).join(",");
}
