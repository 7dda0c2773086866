// Emotion weights of the browser runtime, as emotive.data.emotion computes them: a blend over
// the model's labels (non-negative, summing to 1), a valence/arousal point turned into a blend
// of the labels near it, and the point of a blend (for colours and the disc).
//
// `info` is the `emotion` entry of agent.json: {labels, points: {label: [v, a]},
// point_labels, kernel_width}.

/** Weights over `info.labels` from an array (C,) or an object {label: weight}, summing to 1. */
export function emotionWeights(info, value) {
  const labels = info.labels;
  const raw = new Array(labels.length).fill(0);
  if (typeof value === "string") value = { [value]: 1 };
  if (Array.isArray(value) || ArrayBuffer.isView(value)) {
    if (value.length !== labels.length) {
      throw new Error(`emotion weights must be ${labels.length} numbers (one per label), got ${value.length}`);
    }
    value.forEach((w, c) => { raw[c] = Number(w); });
  } else {
    for (const [label, w] of Object.entries(value ?? {})) {
      const c = labels.indexOf(label);
      if (c < 0) throw new Error(`emotion label ${JSON.stringify(label)} is unknown; use one of ${labels.join(", ")}`);
      raw[c] = Number(w);
    }
  }
  let total = 0;
  for (const w of raw) {
    if (!(Number.isFinite(w) && w >= 0)) throw new Error("emotion weights must be finite and non-negative");
    total += w;
  }
  if (!(total > 0)) throw new Error("emotion weights must not all be zero");
  // Divided in float64, then rounded to the graph's float32, as NumPy normalises.
  return Float32Array.from(raw, (w) => w / total);
}

/**
 * The blend of a valence/arousal point: weights exp(-|va - p_c|^2 / (2 width^2)) over the
 * point labels (happy, sad, angry, neutral; not the data set's styles), normalised.
 */
export function weightsFromPoint(info, valence, arousal) {
  const labels = info.labels;
  const over = info.point_labels ?? labels;
  const width = info.kernel_width;
  const logits = over.map((label) => {
    const [v, a] = info.points[label];
    return -((valence - v) ** 2 + (arousal - a) ** 2) / (2 * width * width);
  });
  const top = Math.max(...logits);
  const e = logits.map((x) => Math.exp(x - top));
  const total = e.reduce((a, b) => a + b, 0);
  const out = new Float32Array(labels.length);
  over.forEach((label, k) => { out[labels.indexOf(label)] = e[k] / total; });
  return out;
}

/** {valence, arousal} of weights (C,): the weighted mean of the labels' points. */
export function pointOf(info, weights) {
  let v = 0;
  let a = 0;
  let total = 0;
  info.labels.forEach((label, c) => {
    const [pv, pa] = info.points[label];
    v += weights[c] * pv;
    a += weights[c] * pa;
    total += weights[c];
  });
  return total > 0 ? { valence: v / total, arousal: a / total } : { valence: 0, arousal: 0 };
}

/** {label: weight} of the labels with weight, for display and the sliders. */
export function weightsObject(info, weights) {
  const out = {};
  info.labels.forEach((label, c) => { out[label] = weights[c]; });
  return out;
}
