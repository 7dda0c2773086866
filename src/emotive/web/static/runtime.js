// Loading the agents' runtime: the feature test for WebAssembly SIMD, agent.json (the graph's
// metadata, the rig and the emotion points), onnxruntime-web (vendored beside this file) and
// the session of agent.onnx. Every failure is a RuntimeError whose message says what is
// missing and how to fix it; the page shows it and stays usable.

// The smallest module using a SIMD instruction (i8x16.popcnt of a v128.const), as the
// `wasm-feature-detect` package probes it: WebAssembly.validate says whether SIMD is there.
const SIMD_PROBE = new Uint8Array([
  0, 97, 115, 109, 1, 0, 0, 0, 1, 5, 1, 96, 0, 1, 123, 3, 2, 1, 0, 10, 10, 1, 8, 0, 65, 0, 253,
  15, 253, 98, 11,
]);
// The value of agent.json's `format`.
const FORMAT = "emotive-web/1";
// The vendored runtime, relative to this file.
const ORT_FOLDER = "./vendor/onnxruntime-web/";
const ORT_MODULE = `${ORT_FOLDER}ort.wasm.bundle.min.mjs`;
const ORT_WASM = `${ORT_FOLDER}ort-wasm-simd-threaded.wasm`;
const FIX = "export the folder again with `emotive export web --out DIR`";

/** A problem that stops the agents, with the message to show. */
export class RuntimeError extends Error {}

/** Whether this browser runs WebAssembly with SIMD (onnxruntime-web's CPU build needs it). */
export function hasWasmSimd() {
  try {
    return typeof WebAssembly === "object" && WebAssembly.validate(SIMD_PROBE);
  } catch {
    return false;
  }
}

/** Throw the message for a browser without WebAssembly SIMD. */
export function requireWasmSimd() {
  if (!hasWasmSimd()) {
    throw new RuntimeError("This browser cannot run the agents: it has no WebAssembly SIMD, "
                           + "which onnxruntime-web needs. Open the page in a current Chrome, "
                           + "Edge or Firefox, or Safari 16.4 or later.");
  }
}

async function fetchOk(url, what) {
  let response;
  try {
    response = await fetch(url);
  } catch (err) {
    throw new RuntimeError(`${what} could not be fetched from ${url} (${err.message}); is the `
                           + "static server still running?");
  }
  if (!response.ok) {
    throw new RuntimeError(`${what} is missing: GET ${url} answered HTTP ${response.status}; ${FIX}`);
  }
  return response;
}

/** agent.json beside the page, checked. */
export async function loadMetadata() {
  const url = new URL("./agent.json", location.href);
  const response = await fetchOk(url, "the agents' metadata agent.json");
  let meta;
  try {
    meta = await response.json();
  } catch (err) {
    throw new RuntimeError(`agent.json is not valid JSON (${err.message}); ${FIX}`);
  }
  if (meta?.format !== FORMAT || !meta.step || !meta.skeleton || !meta.emotion) {
    throw new RuntimeError(`agent.json is not the metadata of an emotive web export (format `
                           + `${JSON.stringify(meta?.format)}, expected "${FORMAT}"); ${FIX}`);
  }
  return meta;
}

/**
 * onnxruntime-web and a session of the graph named in `meta` (one thread: no
 * SharedArrayBuffer, so any static server works).
 *
 * @returns {Promise<{ort: object, session: object}>}
 */
export async function loadRuntime(meta) {
  requireWasmSimd();
  const graphUrl = new URL(meta.graph, location.href);
  // Fetched first, so that a missing graph is named before 15 MB of runtime load.
  const bytes = new Uint8Array(await (await fetchOk(graphUrl, `the agents' graph ${meta.graph}`)).arrayBuffer());
  let ort;
  try {
    ort = await import(ORT_MODULE);
  } catch (err) {
    throw new RuntimeError(`onnxruntime-web (${ORT_MODULE}) did not load (${err.message}); ${FIX}`);
  }
  ort.env.wasm.numThreads = 1;
  ort.env.wasm.proxy = false;
  // The binary beside the bundle, named explicitly; the bundle's own Emscripten glue is used
  // (a prefix here would make it fetch a separate glue module that is not vendored).
  ort.env.wasm.wasmPaths = { wasm: new URL(ORT_WASM, import.meta.url).href };
  let session;
  try {
    session = await ort.InferenceSession.create(bytes, { executionProviders: ["wasm"],
                                                         graphOptimizationLevel: "all" });
  } catch (err) {
    throw new RuntimeError(`onnxruntime-web cannot run ${meta.graph} (${err.message}); ${FIX}`);
  }
  const want = Object.keys(meta.step.inputs).join(",");
  if (session.inputNames.join(",") !== want) {
    throw new RuntimeError(`${meta.graph} has inputs ${session.inputNames.join(", ")}, not the `
                           + `agent step's ${want.replaceAll(",", ", ")}; ${FIX}`);
  }
  return { ort, session };
}
