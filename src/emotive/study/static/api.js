// Calls to the study server (docs/study-protocol.md): JSON in and out, the one-line `error`
// of a refusal, and retries with backoff for what may succeed later.
//
// `request` retries a network failure, a 5xx and a 429 (waiting the server's Retry-After
// when it gives one) with exponential backoff, and hands any other reply back; an idempotent
// call (GET, a submission with its Idempotency-Key, completion) may use it, a join may not.

// First wait before a retry, and the longest one, milliseconds.
const FIRST_BACKOFF_MS = 500;
const MAX_BACKOFF_MS = 10000;

/** A refusal of the server: its HTTP status and its one-line reason. */
export class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
}

/** The reply's JSON body, or null when it has none (or not JSON). */
export async function bodyOf(response) {
  try {
    return await response.json();
  } catch {
    return null;
  }
}

/** The one-line reason of a refused reply. */
export async function reasonOf(response) {
  const body = await bodyOf(response);
  if (body && typeof body.error === "string") return body.error;
  return `the server answered HTTP ${response.status}`;
}

/** Whether a reply (or null: no reply) is worth sending again. */
export function retryable(response) {
  return response === null || response.status === 429 || response.status >= 500;
}

/** Milliseconds to wait before retry number `attempt` (0 first), honouring Retry-After. */
export function backoff(attempt, response = null) {
  const after = Number(response?.headers.get("Retry-After"));
  const base = Math.min(MAX_BACKOFF_MS, FIRST_BACKOFF_MS * 2 ** attempt);
  const wait = Number.isFinite(after) && after > 0 ? Math.max(base, after * 1000) : base;
  return Math.min(MAX_BACKOFF_MS * 3, wait * (0.8 + 0.4 * Math.random()));
}

const sleep = (ms) => new Promise((resolve) => { setTimeout(resolve, ms); });

/**
 * fetch(path, options) until a reply that is not worth retrying.
 *
 * @param {string} path a path on this origin.
 * @param {RequestInit} options as for fetch.
 * @param {{retry?: boolean, onRetry?: (attempt: number, why: string) => void}} how
 *   retry: false sends once; onRetry is told before each wait.
 * @returns {Promise<Response>} the last reply (which may be a refusal).
 * @throws {ApiError} status 0 when the network failed and retry is false.
 */
export async function request(path, options = {}, how = {}) {
  const retry = how.retry ?? true;
  for (let attempt = 0; ; attempt++) {
    let response = null;
    let why = "";
    try {
      response = await fetch(path, { cache: "no-store", ...options });
      why = `HTTP ${response.status}`;
    } catch (err) {
      why = `network error (${err.message})`;
    }
    if (!retry || !retryable(response)) {
      if (response === null) throw new ApiError(0, `the server cannot be reached: ${why}`);
      return response;
    }
    how.onRetry?.(attempt, why);
    await sleep(backoff(attempt, response));
  }
}

/**
 * The JSON of a successful call; a refusal throws ApiError with the server's reason.
 */
export async function call(path, options = {}, how = {}) {
  const response = await request(path, options, how);
  if (!response.ok) throw new ApiError(response.status, await reasonOf(response));
  return bodyOf(response);
}

/** Options of a JSON call: method, body and headers (a bearer token when given). */
export function jsonOptions(method, body = undefined, token = null, headers = {}) {
  const all = { Accept: "application/json", ...headers };
  if (body !== undefined) all["Content-Type"] = "application/json";
  if (token) all.Authorization = `Bearer ${token}`;
  return { method, headers: all, body: body === undefined ? undefined : JSON.stringify(body) };
}

/** A random key of 32 hex digits (works where crypto.randomUUID does not: plain http). */
export function randomKey() {
  const bytes = crypto.getRandomValues(new Uint8Array(16));
  return Array.from(bytes, (b) => b.toString(16).padStart(2, "0")).join("");
}
