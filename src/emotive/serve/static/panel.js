// The side panel's parts that the served app and the browser runtime share: collapsing the
// panel, toasts, the toggle buttons (mouse mode, figures, camera), the list of agents with
// their emotion colours, and rates per second for the stats.
//
// Inputs are the page's elements by id (index.html); nothing here is in scene units.

const $ = (id) => document.getElementById(id);

// A window where the expanded panel takes more than this share of the width is narrow: the
// panel starts collapsed there, unless the page kept another state.
const NARROW_SHARE = 1 / 3;
// Where the panel's state is kept between visits (localStorage): "expanded" or "collapsed".
const PANEL_STATE_KEY = "emotive.panel";
// The key that collapses and expands the panel (with no modifier, outside text fields).
const PANEL_KEY = "p";

/** The kept state of the panel, or null (none kept, or no storage: a private window). */
function keptPanelState() {
  try {
    return localStorage.getItem(PANEL_STATE_KEY);
  } catch {
    return null;
  }
}

function keepPanelState(state) {
  try {
    localStorage.setItem(PANEL_STATE_KEY, state);
  } catch {
    // No storage (a private window, a sandbox): the state lasts until the page reloads.
  }
}

/**
 * Make #panel collapsible: a "Panel" button first in it (aria-expanded says its state) and
 * the P key hide all of it but the button (app.css, `#panel.collapsed`). The state is kept
 * in localStorage; with none kept, narrow windows (NARROW_SHARE) start collapsed.
 *
 * @param {(expanded: boolean) => void} onChange called after the user collapsed or expanded
 *   it (the panel's new size is laid out by then).
 * @returns {HTMLButtonElement} the button (#panel-toggle).
 */
export function collapsiblePanel(onChange = () => {}) {
  const panel = $("panel");
  const button = document.createElement("button");
  button.id = "panel-toggle";
  button.type = "button";
  button.title = `Hide or show the panel (${PANEL_KEY.toUpperCase()})`;
  button.setAttribute("aria-controls", "panel");
  button.setAttribute("aria-keyshortcuts", PANEL_KEY.toUpperCase());
  const arrow = document.createElement("span");
  arrow.setAttribute("aria-hidden", "true");
  button.append(arrow, "Panel");
  panel.prepend(button);

  const show = (expanded) => {
    panel.classList.toggle("collapsed", !expanded);
    button.setAttribute("aria-expanded", String(expanded));
    arrow.textContent = expanded ? "\u25C2 " : "\u25B8 ";
  };
  const toggle = () => {
    const expanded = panel.classList.contains("collapsed");
    // Focus on a control about to be hidden would be lost: it goes to the button.
    if (!expanded && panel.contains(document.activeElement)) button.focus();
    show(expanded);
    keepPanelState(expanded ? "expanded" : "collapsed");
    onChange(expanded);
  };

  const wide = panel.getBoundingClientRect().width <= NARROW_SHARE * window.innerWidth;
  const kept = keptPanelState();
  show(kept === "expanded" || (kept !== "collapsed" && wide));
  button.addEventListener("click", toggle);
  window.addEventListener("keydown", (event) => {
    const typing = event.target.closest?.("input, textarea, select, [contenteditable]");
    if (event.key.toLowerCase() !== PANEL_KEY || event.repeat || event.ctrlKey || event.metaKey
        || event.altKey || typing) return;
    toggle();
  });
  return button;
}

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
