// The questions of an item, as form controls that work by mouse, touch and keyboard:
//
//   likert  a row of radio buttons min..max, the two anchors at the ends; the keys 1-9 (and 0)
//           pick that value of the focused question, the arrow keys move
//   choice  one radio button an option, drawn as buttons; the keys 1-9 pick the n-th option
//   grid    the affect grid: size x size cells, unpleasant..pleasant across and low..high
//           arousal up; the arrow keys move a cursor, Enter or Space picks, a click picks;
//           the answer is {valence: column, arousal: row}, cells from 1 (left, bottom)
//
// Every widget is {id, element, value, focus()}; `value` is null until answered.

let counter = 0;

function el(tag, props = {}, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(props)) {
    if (key === "class") node.className = value;
    else if (key === "text") node.textContent = value;
    else if (key.startsWith("aria-") || key.startsWith("data-") || key === "role") {
      node.setAttribute(key, value);
    } else node[key] = value;
  }
  node.append(...children);
  return node;
}

function fieldset(q, kind) {
  const legend = el("legend", { text: q.prompt });
  // Focusable by script (a new item focuses its first question: the keys work at once, and
  // no answer looks picked), not by Tab.
  return el("fieldset", { class: `question ${kind}`, "data-question": q.id, tabIndex: -1 },
            legend);
}

/** Radio buttons in a fieldset: the shared part of likert and choice questions. */
function radios(q, kind, values, labels, texts, onChange) {
  const node = fieldset(q, kind);
  const name = `q${++counter}-${q.id}`;
  const row = el("div", { class: "options" });
  const widget = { id: q.id, element: node, value: null };
  const inputs = values.map((value, i) => {
    const input = el("input", { type: "radio", name, value: String(value),
                                "aria-label": labels[i] });
    input.addEventListener("change", () => {
      if (!input.checked) return;
      widget.value = value;
      onChange(q.id, value);
    });
    row.append(el("label", { class: "option", "data-value": String(value) }, input,
                  el("span", { text: texts[i], "aria-hidden": "true" })));
    return input;
  });
  node.append(row);
  node.addEventListener("keydown", (event) => {
    if (event.altKey || event.ctrlKey || event.metaKey || !/^[0-9]$/.test(event.key)) return;
    const i = kind === "likert" ? values.indexOf(Number(event.key)) : Number(event.key) - 1;
    if (i < 0 || i >= inputs.length) return;
    event.preventDefault();
    inputs[i].checked = true;
    inputs[i].focus();
    inputs[i].dispatchEvent(new Event("change", { bubbles: true }));
  });
  widget.focus = (options) => node.focus(options);
  return widget;
}

function likert(q, onChange) {
  const values = [];
  for (let v = q.min; v <= q.max; v++) values.push(v);
  const [low, high] = q.anchors.length === 2 ? q.anchors : ["", ""];
  const labels = values.map((v, i) => {
    if (i === 0 && low) return `${v}, ${low}`;
    if (i === values.length - 1 && high) return `${v}, ${high}`;
    return String(v);
  });
  const widget = radios(q, "likert", values, labels, values.map(String), onChange);
  if (low || high) {
    widget.element.append(el("div", { class: "anchors", "aria-hidden": "true" },
                              el("span", { text: low }), el("span", { text: high })));
  }
  const row = widget.element.querySelector(".options");
  row.style.setProperty("--points", values.length);
  // A long scale wraps rather than squeezing its buttons.
  row.classList.toggle("long", values.length > 11);
  return widget;
}

function choice(q, onChange) {
  const labels = q.options.map((o, i) => (i < 9 ? `${o} (key ${i + 1})` : o));
  return radios(q, "choice", q.options, labels, q.options, onChange);
}

function grid(q, onChange) {
  const node = fieldset(q, "grid");
  const n = q.size;
  const [unpleasant, pleasant, low, high] = q.anchors.length === 4 ? q.anchors
    : ["unpleasant", "pleasant", "low arousal", "high arousal"];
  const widget = { id: q.id, element: node, value: null };
  const cells = el("div", { class: "cells", role: "radiogroup",
                            "aria-label": `${q.prompt} Across: ${unpleasant} to ${pleasant}; `
                              + `up: ${low} to ${high}. Arrow keys move, Enter picks.` });
  cells.style.setProperty("--size", n);
  const centre = (n + 1) / 2;
  let cursor = { col: centre, row: centre };
  const byCell = new Map();
  // Rows from the top: arousal n first, 1 at the bottom.
  for (let row = n; row >= 1; row--) {
    for (let col = 1; col <= n; col++) {
      const cell = el("button", {
        type: "button", class: "cell", role: "radio", tabIndex: -1,
        "aria-checked": "false", "data-col": String(col), "data-row": String(row),
        "aria-label": `${unpleasant} to ${pleasant} ${col} of ${n}, `
          + `${low} to ${high} ${row} of ${n}`,
      });
      if (col === centre && row === centre) cell.classList.add("centre");
      cell.addEventListener("click", () => { move(col, row); pick(); });
      byCell.set(`${col},${row}`, cell);
      cells.append(cell);
    }
  }
  const at = (c) => byCell.get(`${c.col},${c.row}`);
  function move(col, row, focus = true) {
    at(cursor).tabIndex = -1;
    at(cursor).classList.remove("cursor");
    cursor = { col: Math.min(n, Math.max(1, col)), row: Math.min(n, Math.max(1, row)) };
    const cell = at(cursor);
    cell.tabIndex = 0;
    cell.classList.add("cursor");
    if (focus) cell.focus();
  }
  function pick() {
    for (const cell of byCell.values()) cell.setAttribute("aria-checked", "false");
    at(cursor).setAttribute("aria-checked", "true");
    widget.value = { valence: cursor.col, arousal: cursor.row };
    onChange(q.id, { ...widget.value });
  }
  move(centre, centre, false);
  cells.addEventListener("keydown", (event) => {
    const steps = { ArrowLeft: [-1, 0], ArrowRight: [1, 0], ArrowUp: [0, 1], ArrowDown: [0, -1],
                    Home: [-n, 0], End: [n, 0], PageUp: [0, n], PageDown: [0, -n] };
    if (steps[event.key]) {
      event.preventDefault();
      move(cursor.col + steps[event.key][0], cursor.row + steps[event.key][1]);
    } else if (event.key === "Enter" || event.key === " ") {
      event.preventDefault();
      pick();
    }
  });
  const board = el("div", { class: "affect" },
                   el("span", { class: "anchor high", text: high, "aria-hidden": "true" }),
                   el("span", { class: "anchor unpleasant", text: unpleasant,
                                "aria-hidden": "true" }),
                   cells,
                   el("span", { class: "anchor pleasant", text: pleasant, "aria-hidden": "true" }),
                   el("span", { class: "anchor low", text: low, "aria-hidden": "true" }));
  node.append(board);
  widget.focus = (options) => node.focus(options);
  return widget;
}

/**
 * The widget of one question.
 *
 * @param {{id: string, kind: string, prompt: string, min: number, max: number,
 *   anchors: string[], options: string[], size: number}} q a question of GET /api/study.
 * @param {(id: string, value: any) => void} onChange told each answer given.
 */
export function questionWidget(q, onChange) {
  if (q.kind === "likert") return likert(q, onChange);
  if (q.kind === "choice") return choice(q, onChange);
  if (q.kind === "grid") return grid(q, onChange);
  throw new Error(`unknown question kind ${q.kind}`);
}
