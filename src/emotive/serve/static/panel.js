// The side panel's parts that the served app and the browser runtime share: toasts, the
// toggle buttons (mouse mode, figures, camera), the list of agents with their emotion
// colours, and rates per second for the stats.
//
// Inputs are the page's elements by id (index.html); nothing here is in scene units.

const $ = (id) => document.getElementById(id);

/** A function that shows `text` as a toast for 5 s and appends it to `errors`. */
export function toaster(errors) {
  return (text) => {
    errors.push(text);
    const div = document.createElement("div");
    div.className = "toast";
    div.textContent = text;
    $("toasts").append(div);
    setTimeout(() => div.remove(), 5000);
  };
}

/** Buttons [[id, value], ...] of which one is on; `onChange(value)` when another is pressed. */
export function toggleGroup(buttons, onChange) {
  let current = buttons[0][1];
  for (const [id, value] of buttons) {
    $(id).addEventListener("click", () => {
      if (value === current) return;
      current = value;
      for (const [other] of buttons) $(other).classList.toggle("on", other === id);
      onChange(value);
    });
  }
}

/**
 * The Place / Draw buttons: set `app.mouseMode` and the hint; the orbit controls of `view`
 * (scene-setup.js) turn only in place mode with the fixed camera (`app.cameraMode`).
 */
export function mouseModeButtons(app, view) {
  toggleGroup([["mode-place", "place"], ["mode-draw", "draw"]], (mode) => {
    app.mouseMode = mode;
    view.controls.enabled = mode === "place" && app.cameraMode === "fixed";
    $("mode-hint").textContent = mode === "draw"
      ? "Press, drag and release on the ground: the selected agent walks the path (no selection: a new agent)."
      : "Click the ground to place an agent; click an agent to select it.";
  });
}

/**
 * The Mannequin / Sticks buttons: set `app.figureMode`, show that figure of each of `figures`
 * (a Map id -> agent-figures.js's AgentFigures), then `after()`.
 */
export function figureButtons(app, figures, after = () => {}) {
  toggleGroup([["figure-mannequin", "mannequin"], ["figure-sticks", "sticks"]], (mode) => {
    app.figureMode = mode;
    for (const figure of figures.values()) figure.showMode(mode);
    after();
  });
}

/**
 * The Fixed / Follow buttons: set `app.cameraMode` and switch `cameras` (follow-camera.js);
 * following with no agent selected first selects the first of `figures` (a Map) by
 * `select(id)`.
 */
export function cameraButtons(app, cameras, figures, select) {
  toggleGroup([["camera-fixed", "fixed"], ["camera-follow", "follow"]], (mode) => {
    app.cameraMode = mode;
    cameras.set(mode);
    if (mode === "follow" && app.selected === null && figures.size) select(figures.keys().next().value);
    cameras.view.controls.enabled = mode === "fixed" && app.mouseMode === "place";
  });
}

/** Stick figures only (no mannequin): set `app.figureMode` and turn the Mannequin button off. */
export function sticksOnly(app) {
  app.figureMode = "sticks";
  $("figure-sticks").classList.add("on");
  $("figure-mannequin").classList.remove("on");
  $("figure-mannequin").disabled = true;
}

/** The list of agents (#agent-list): a button each, with a swatch of its emotion colour. */
export class AgentList {
  /** @param {(id: number) => void} onSelect called with the id of a pressed button. */
  constructor(onSelect) {
    this.onSelect = onSelect;
    this.ids = "";
  }

  /** Show the agents of `figures` (a Map id -> {color}) when they changed; mark `selected`. */
  update(figures, selected) {
    const ids = [...figures.keys()].join(",");
    if (ids === this.ids) return;
    this.ids = ids;
    const list = $("agent-list");
    list.replaceChildren();
    for (const id of figures.keys()) {
      const li = document.createElement("li");
      const button = document.createElement("button");
      button.dataset.agent = String(id);
      button.classList.toggle("on", id === selected);
      const swatch = document.createElement("span");
      swatch.className = "swatch";
      button.append(swatch, `Agent ${id}`);
      button.addEventListener("click", () => this.onSelect(id));
      li.append(button);
      list.append(li);
    }
    this.refresh(figures);
  }

  /** Colour each swatch as its agent now. */
  refresh(figures) {
    for (const button of $("agent-list").querySelectorAll("button")) {
      const figure = figures.get(Number(button.dataset.agent));
      if (figure) button.firstChild.style.background = `#${figure.color.getHexString()}`;
    }
  }

  /** Mark the button of agent `selected` (null: none). */
  mark(selected) {
    for (const button of $("agent-list").querySelectorAll("button")) {
      button.classList.toggle("on", Number(button.dataset.agent) === selected);
    }
  }
}

/** Rates per second of counters, between two calls of `sample`. */
export class Rates {
  constructor() {
    this.at = performance.now();
    this.last = {};
  }

  /** `counts` {name: count now} -> {name: count per second since the last sample}. */
  sample(counts) {
    const now = performance.now();
    const seconds = (now - this.at) / 1000;
    const rates = {};
    for (const [name, count] of Object.entries(counts)) {
      rates[name] = (count - (this.last[name] ?? 0)) / seconds;
    }
    this.at = now;
    this.last = { ...counts };
    return rates;
  }
}
