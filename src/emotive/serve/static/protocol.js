// The websocket protocol of `emotive serve` (docs/serve.md): the binary frame decoder (both
// layouts: version 2, "EMF2", compact, which this app asks for; version 1, "EMF1", float32
// with world positions) and a connection that sends control messages, matches replies to
// requests by "ref", and measures the round-trip latency with ping/pong.
//
// Legend: B agents in a frame, J joints of the rig, P points per agent (joints then end
// sites), C emotion labels.

const MAGIC = "EMF1";
const MAGIC_V2 = "EMF2";
const HEADER_BYTES = 32;
// The frame layout this app asks for (?encoding= of the websocket).
export const ENCODING = 2;
// Version 2 stores each rotation's three smallest components in 15 bits: code 16383 + 16383
// sqrt(2) v for v in [-1/sqrt(2), 1/sqrt(2)].
const CODE_HALF = 16383;
const CODE_SCALE = Math.SQRT1_2 / CODE_HALF;
// Typed-array views read the platform's byte order; frames are little-endian.
const LITTLE_ENDIAN = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;

function floats(view, offset, count) {
  const out = new Float32Array(count);
  for (let i = 0; i < count; i++) out[i] = view.getFloat32(offset + 4 * i, true);
  return out;
}

const pad4 = (n) => n + ((4 - (n % 4)) % 4);

/**
 * Decode one binary frame of either layout (little-endian, every block 4-byte aligned).
 *
 * @param {ArrayBuffer} buffer the websocket message.
 * @param {import("./rig.js").Rig} [rig] the rig of /api/skeleton: version-2 frames carry no
 *   world positions, so `points` is computed from the rotations with it (null without).
 * @returns {{version: number, frame: number, time: number, B: number, J: number, P: number,
 *   C: number, ids: Int32Array, va: Float32Array, weights: Float32Array, mover: Float32Array,
 *   rotations: Float32Array, points: Float32Array|null}} flat arrays: `va` (B, 2), `weights`
 *   (B, C), `mover` (B, 3) metres, `rotations` (B, J, 4) quaternions w, x, y, z, `points`
 *   (B, P, 3) metres.
 * @throws {Error} when the magic or the length does not match the layout.
 */
export function decodeFrame(buffer, rig = null) {
  const view = new DataView(buffer);
  if (buffer.byteLength < HEADER_BYTES) throw new Error(`frame of ${buffer.byteLength} bytes`);
  const magic = String.fromCharCode(...new Uint8Array(buffer, 0, 4));
  if (magic === MAGIC_V2) return decodeCompact(buffer, view, rig);
  if (magic !== MAGIC) throw new Error(`frame magic ${JSON.stringify(magic)}, not ${MAGIC_V2} or ${MAGIC}`);
  const frame = view.getUint32(4, true);
  const time = view.getFloat64(8, true);
  const B = view.getUint32(16, true);
  const J = view.getUint32(20, true);
  const P = view.getUint32(24, true);
  const C = view.getUint32(28, true);
  const expected = HEADER_BYTES + 4 * B * (1 + 2 + C + 3 + 4 * J + 3 * P);
  if (buffer.byteLength !== expected) {
    throw new Error(`frame of ${buffer.byteLength} bytes, layout needs ${expected}`);
  }
  let offset = HEADER_BYTES;
  const ids = new Int32Array(B);
  for (let b = 0; b < B; b++) ids[b] = view.getInt32(offset + 4 * b, true);
  offset += 4 * B;
  const blocks = {};
  for (const [name, size] of [["va", 2], ["weights", C], ["mover", 3], ["rotations", 4 * J],
                              ["points", 3 * P]]) {
    blocks[name] = floats(view, offset, B * size);
    offset += 4 * B * size;
  }
  return { version: 1, frame, time, B, J, P, C, ids, ...blocks };
}

/** Version 2 (docs/serve.md): quantized rotations, emotions and valence/arousal. */
function decodeCompact(buffer, view, rig) {
  if (!LITTLE_ENDIAN) throw new Error("version-2 frames need a little-endian platform");
  const frame = view.getUint32(4, true);
  const time = view.getFloat64(8, true);
  const B = view.getUint32(16, true);
  const J = view.getUint32(20, true);
  const C = view.getUint32(24, true);
  const expected = HEADER_BYTES + 20 * B + pad4(6 * B * J) + pad4(B * C);
  if (buffer.byteLength !== expected) {
    throw new Error(`frame of ${buffer.byteLength} bytes, layout needs ${expected}`);
  }
  let offset = HEADER_BYTES;
  const ids = new Int32Array(buffer.slice(offset, offset + 4 * B));
  offset += 4 * B;
  const mover = new Float32Array(buffer.slice(offset, offset + 12 * B));
  offset += 12 * B;
  const codes = new Uint16Array(buffer, offset, 3 * B * J);
  offset += pad4(6 * B * J);
  const rotations = new Float32Array(4 * B * J);
  for (let k = 0; k < B * J; k++) {
    const a = codes[3 * k];
    const b = codes[3 * k + 1];
    const largest = ((a >> 15) << 1) | (b >> 15);
    const x = ((a & 0x7fff) - CODE_HALF) * CODE_SCALE;
    const y = ((b & 0x7fff) - CODE_HALF) * CODE_SCALE;
    const z = ((codes[3 * k + 2] & 0x7fff) - CODE_HALF) * CODE_SCALE;
    const implied = Math.sqrt(Math.max(0, 1 - x * x - y * y - z * z));
    // The three stored components fill the other slots, in w, x, y, z order.
    const q = 4 * k;
    rotations[q + largest] = implied;
    rotations[q + (largest === 0 ? 1 : 0)] = x;
    rotations[q + (largest <= 1 ? 2 : 1)] = y;
    rotations[q + (largest <= 2 ? 3 : 2)] = z;
  }
  const va = Float32Array.from(new Int16Array(buffer, offset, 2 * B), (v) => v / 32767);
  offset += 4 * B;
  const weights = Float32Array.from(new Uint8Array(buffer, offset, B * C), (v) => v / 255);
  const points = rig ? rig.poseAll(rotations, mover, B) : null;
  return { version: 2, frame, time, B, J, P: rig ? rig.P : 0, C, ids, va, weights, mover,
           rotations, points };
}

/** The websocket URL of the server this page came from, with the page's token and layout. */
export function socketUrl(token, encoding = ENCODING) {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  const query = new URLSearchParams({ encoding: String(encoding) });
  if (token) query.set("token", token);
  return `${scheme}//${location.host}/ws?${query}`;
}

/**
 * A websocket connection to the server.
 *
 * Callbacks: `onFrame(frame)` for each decoded frame, `onError(text)` for error replies and
 * undecodable frames, `onNotice(message)` for every other message that answers no request
 * (such as a scene's geometry), `onOpen()` once it is open, `onClose(code)` when it closes.
 * `rig` (a Rig of /api/skeleton) gives version-2 frames their world positions.
 */
export class Connection {
  constructor(url, { onFrame, onError, onOpen, onClose, onNotice = () => {}, rig = null }) {
    this.url = url;
    this.rig = rig;
    this.onFrame = onFrame;
    this.onNotice = onNotice;
    this.onError = onError;
    this.onOpen = onOpen;
    this.onClose = onClose;
    this.nextRef = 1;
    this.pending = new Map();
    this.latencyMs = null;
    this.socket = null;
  }

  /** Open the socket; resolves once it is open. */
  open() {
    return new Promise((resolve, reject) => {
      const socket = new WebSocket(this.url);
      socket.binaryType = "arraybuffer";
      socket.addEventListener("open", () => {
        this.onOpen();
        resolve();
      });
      socket.addEventListener("close", (event) => {
        for (const { fail } of this.pending.values()) fail(new Error("connection closed"));
        this.pending.clear();
        reject(new Error(`websocket closed with code ${event.code}`));
        this.onClose(event.code);
      });
      socket.addEventListener("message", (event) => this.receive(event.data));
      this.socket = socket;
    });
  }

  receive(data) {
    if (data instanceof ArrayBuffer) {
      let frame;
      try {
        frame = decodeFrame(data, this.rig);
      } catch (err) {
        this.onError(`bad frame: ${err.message}`);
        return;
      }
      this.onFrame(frame);
      return;
    }
    const msg = JSON.parse(data);
    if (msg.type === "pong") this.latencyMs = performance.now() - msg.t;
    const waiting = msg.ref !== undefined ? this.pending.get(msg.ref) : undefined;
    if (waiting) {
      this.pending.delete(msg.ref);
      if (msg.type === "error") waiting.fail(new Error(msg.message));
      else waiting.done(msg);
    }
    if (msg.type === "error") this.onError(msg.message);
    else if (!waiting && msg.type !== "pong") this.onNotice(msg);
  }

  get isOpen() {
    return this.socket !== null && this.socket.readyState === WebSocket.OPEN;
  }

  /** Send a control message without waiting for its reply. */
  send(message) {
    if (this.isOpen) this.socket.send(JSON.stringify(message));
  }

  /** Send a control message; resolves with its reply, rejects on an error reply. */
  request(message) {
    const ref = this.nextRef++;
    return new Promise((done, fail) => {
      if (!this.isOpen) {
        fail(new Error("not connected"));
        return;
      }
      this.pending.set(ref, { done, fail });
      this.socket.send(JSON.stringify({ ...message, ref }));
    });
  }

  ping() {
    this.send({ type: "ping", t: performance.now() });
  }
}

/**
 * A sender that sends at most `perSecond` messages a second and always sends the last value
 * (so the final position of a dragged slider arrives).
 */
export function throttled(send, perSecond) {
  const gap = 1000 / perSecond;
  let last = -Infinity;
  let timer = null;
  let latest = null;
  const flush = () => {
    timer = null;
    last = performance.now();
    send(latest);
  };
  return (value) => {
    latest = value;
    if (timer !== null) return;
    const wait = last + gap - performance.now();
    if (wait <= 0) flush();
    else timer = setTimeout(flush, wait);
  };
}
