// MoM Localizer browser client: one ES module, no build step, no dependencies.
//
//   import { MomlocClient } from "./momloc-client.js";
//   const client = new MomlocClient({ url: "ws://192.168.1.20:8765/v1/stream", token: "..." });
//   client.start();
//   function frame() {
//     for (const p of client.people().values()) moveMarker(p.id, p.x, p.y);  // metres, floor frame
//     requestAnimationFrame(frame);
//   }
//   requestAnimationFrame(frame);
//
// Three.js / A-Frame: the floor is x, y in metres; with y up put a person at (p.x, 0, p.y).
//
// Design:
// - Browsers cannot set headers on a WebSocket, so the token travels as `?token=` (the daemon
//   accepts both). Close code 4401 means the token is missing or wrong: the client stops
//   retrying (retrying cannot help) and sets `tokenRejected`; any other close reconnects with
//   exponential back-off (minBackoff doubling to maxBackoff, reset once a connection opens).
// - Interpolation: snapshots arrive 10-30 times a second, a display draws 60-120 frames. Each id
//   keeps its last few samples stamped with the capture time `t`; `people()` renders the room
//   `delay` seconds in the past, between the two samples around that moment, so markers glide
//   instead of jumping, and network jitter up to `delay` is hidden. Past the newest sample a
//   marker moves on with its velocity for at most `maxExtrapolate` seconds, then waits.
// - The daemon's clock (`t`) and the browser's need not agree: the offset between them is the
//   smallest (receive time - t) seen, i.e. the least-delayed snapshot, creeping up slowly so a
//   drifting clock or a lasting latency change is followed.
// - An id missing from a snapshot has left (the daemon's tracker already bridges occlusions): it
//   is dropped once the render time passes that snapshot.

const CLOSE_TOKEN_REJECTED = 4401;

export function defaultStreamUrl(location = globalThis.location) {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  return `${scheme}//${location.host}/v1/stream`;
}

export class MomlocClient extends EventTarget {
  /**
   * @param {object} [options]
   * @param {string} [options.url] stream URL; default: /v1/stream on the page's own host
   * @param {string} [options.token] API token, when the daemon has one
   * @param {number} [options.rate] ask the daemon for at most this many snapshots per second
   * @param {number} [options.delay=0.1] interpolation delay, seconds behind the newest snapshot
   * @param {number} [options.maxExtrapolate=0.25] seconds a marker may move on past its data
   * @param {number} [options.minBackoff=0.5] first reconnect delay, seconds
   * @param {number} [options.maxBackoff=10] longest reconnect delay, seconds
   * @param {typeof WebSocket} [options.WebSocket] WebSocket implementation (default: the browser's)
   */
  constructor(options = {}) {
    super();
    this.url = options.url ?? defaultStreamUrl();
    this.token = options.token ?? "";
    this.rate = options.rate ?? null;
    this.delay = options.delay ?? 0.1;
    this.maxExtrapolate = options.maxExtrapolate ?? 0.25;
    this.minBackoff = options.minBackoff ?? 0.5;
    this.maxBackoff = options.maxBackoff ?? 10;
    this.WebSocket = options.WebSocket ?? globalThis.WebSocket;
    this.connected = false;
    this.tokenRejected = false;
    this.attempts = 0;
    this.received = 0;
    this.lastSnapshot = null;
    this.lastError = null;
    this._tracks = new Map(); // id -> {samples: [{t, x, y, vx, vy, confidence, cameras}], goneAt}
    this._offset = null; // local seconds - daemon seconds
    this._socket = null;
    this._timer = null;
    this._backoff = this.minBackoff;
    this._running = false;
  }

  /** Connect (and keep reconnecting) until stop(). */
  start() {
    if (this._running) return;
    this._running = true;
    this.tokenRejected = false;
    this._connect();
  }

  stop() {
    this._running = false;
    clearTimeout(this._timer);
    this._timer = null;
    if (this._socket) this._socket.close(1000, "client stopped");
    this._socket = null;
    this.connected = false;
  }

  _streamUrl() {
    const url = new URL(this.url, globalThis.location?.href);
    if (this.token) url.searchParams.set("token", this.token);
    if (this.rate) url.searchParams.set("rate", String(this.rate));
    return url.toString();
  }

  _connect() {
    this.attempts += 1;
    let socket;
    try {
      socket = new this.WebSocket(this._streamUrl());
    } catch (error) {
      this.lastError = String(error);
      this._retry();
      return;
    }
    this._socket = socket;
    socket.onopen = () => {
      this.connected = true;
      this.lastError = null;
      this._backoff = this.minBackoff;
      this.dispatchEvent(new Event("open"));
    };
    socket.onmessage = (event) => {
      try {
        this.ingest(JSON.parse(event.data));
      } catch (error) {
        this.lastError = `bad message: ${error}`;
      }
    };
    socket.onclose = (event) => {
      if (this._socket !== socket) return; // an old socket closing after stop()/start()
      this._socket = null;
      this.connected = false;
      if (event.code === CLOSE_TOKEN_REJECTED) {
        this.tokenRejected = true;
        this.lastError = "the daemon rejected the token";
        this._running = false;
        this.dispatchEvent(new Event("tokenrejected"));
        return;
      }
      this.lastError = `closed (code ${event.code})`;
      this.dispatchEvent(new CustomEvent("close", { detail: { code: event.code } }));
      this._retry();
    };
  }

  _retry() {
    if (!this._running) return;
    const wait = this._backoff;
    this._backoff = Math.min(this._backoff * 2, this.maxBackoff);
    this._timer = setTimeout(() => {
      this._timer = null;
      if (this._running) this._connect();
    }, wait * 1000);
  }

  /**
   * Take one snapshot (schema v1); called for every message, public so tests and replays can
   * feed recorded snapshots. `receivedAt` is local seconds (default: now).
   */
  ingest(snapshot, receivedAt = performance.now() / 1000) {
    this.received += 1;
    this.lastSnapshot = snapshot;
    const t = snapshot.t;
    const offset = receivedAt - t;
    if (this._offset === null || offset < this._offset) this._offset = offset;
    else this._offset += (offset - this._offset) * 0.01;
    const present = new Set();
    for (const p of snapshot.people ?? []) {
      present.add(p.id);
      let track = this._tracks.get(p.id);
      if (!track) {
        track = { samples: [], goneAt: null };
        this._tracks.set(p.id, track);
      }
      const samples = track.samples;
      if (samples.length && t < samples[samples.length - 1].t) samples.length = 0; // clock jump
      samples.push({ t, x: p.x, y: p.y, vx: p.vx, vy: p.vy, confidence: p.confidence, cameras: p.cameras });
      if (samples.length > 8) samples.shift();
      track.goneAt = null;
    }
    for (const [id, track] of this._tracks) {
      if (!present.has(id) && track.goneAt === null) track.goneAt = t;
    }
    this.dispatchEvent(new CustomEvent("snapshot", { detail: snapshot }));
  }

  /** The daemon-clock time that people() renders at local time `now` (seconds). */
  renderTime(now = performance.now() / 1000) {
    return this._offset === null ? null : now - this._offset - this.delay;
  }

  /**
   * Interpolated people at local time `now` (seconds, default: now): a Map id ->
   * {id, x, y, vx, vy, confidence, cameras}. Call it once per animation frame.
   */
  people(now = performance.now() / 1000) {
    const out = new Map();
    const at = this.renderTime(now);
    if (at === null) return out;
    for (const [id, track] of this._tracks) {
      if (track.goneAt !== null && at >= track.goneAt) {
        this._tracks.delete(id);
        continue;
      }
      const s = track.samples;
      let a = s[0];
      let b = null;
      for (let i = 0; i < s.length; i++) {
        if (s[i].t <= at) a = s[i];
        else {
          b = s[i];
          break;
        }
      }
      let x, y;
      if (b && a !== b && at >= a.t) {
        const u = (at - a.t) / (b.t - a.t);
        x = a.x + (b.x - a.x) * u;
        y = a.y + (b.y - a.y) * u;
      } else if (!b) {
        const ahead = Math.min(Math.max(at - a.t, 0), this.maxExtrapolate);
        x = a.x + a.vx * ahead;
        y = a.y + a.vy * ahead;
      } else {
        x = a.x; // render time before the first sample: hold it
        y = a.y;
      }
      const last = s[s.length - 1];
      out.set(id, { id, x, y, vx: last.vx, vy: last.vy, confidence: last.confidence, cameras: last.cameras });
    }
    return out;
  }
}
