// QuadSynth client: REST (POST /v1/synthesize) and WebSocket /v1/stream, batch and live
// (docs/streaming.md). Runs in browsers and in Node >= 20 (pass a WebSocket factory there, e.g.
// from the `ws` package: Node 20 has fetch but no WebSocket).
import { blob, decodeRotations, unblob } from './wire.js';
import { Skeleton } from './pose.js';

const MSGPACK = 'application/vnd.msgpack';
/** Close codes after which the same request may succeed on a new connection: the server is
 * shutting down (1001: another replica takes it) or full / the client was too slow (1013). */
export const RETRY_CODES = new Set([1001, 1013]);

export class ServiceError extends Error {
  constructor(status, field, message, code = undefined) {
    super(field ? `${status} ${field}: ${message}` : `${status} ${message}`);
    this.name = 'ServiceError';
    this.status = status; this.field = field; this.detail = message;
    this.code = code; // the WebSocket close code, for stream errors
  }
}

/** msgpack: @msgpack/msgpack, loaded when first needed unless a codec ({encode, decode}) was given
 * (a Web Worker, which has no import map to resolve the package name, passes one). */
let defaultCodec = null;
async function loadCodec() {
  defaultCodec ??= await import('@msgpack/msgpack');
  return defaultCodec;
}

const sleep = (ms) => new Promise((resolve) => { setTimeout(resolve, ms); });

function toPoints(points, field) {
  if (points instanceof Float32Array || points instanceof Float64Array) {
    if (points.length % 3 !== 0 || points.length < 6) throw new ServiceError(422, field, 'need (F >= 2) x 3 numbers');
    return blob(points, [points.length / 3, 3]);
  }
  if (Array.isArray(points)) return toPoints(Float32Array.from(points.flat()), field);
  if (points && points.dtype) return points; // already a blob
  throw new ServiceError(422, field, 'expected a Float32Array (F x 3) or an array of [x, y, z]');
}

/**
 * A height field for a request's or a live session's `ground` (docs/terrain.md): the ground's y
 * at x = origin[0] + j * spacing, z = origin[1] + i * spacing for heights[i][j] (metres, Y up).
 * `heights`: rows (z) of heights (x), or a Float32Array / Float64Array of nz x nx with
 * `shape` [nz, nx]. The service checks the rest (finite, at least 2 x 2, the size limit).
 */
export function ground(heights, { origin = [0, 0], spacing = 1, shape } = {}) {
  let data = heights, dims = shape;
  if (Array.isArray(heights)) {
    const nx = Array.isArray(heights[0]) ? heights[0].length : -1;
    if (!heights.every((row) => Array.isArray(row) && row.length === nx)) {
      throw new ServiceError(422, 'ground.heights', 'expected rows (z) of heights (x), every row as long');
    }
    data = Float32Array.from(heights.flat()); dims = [heights.length, nx];
  }
  if (!(data instanceof Float32Array || data instanceof Float64Array)) {
    throw new ServiceError(422, 'ground.heights', 'expected a Float32Array or Float64Array (with its shape) or rows of numbers');
  }
  if (!Array.isArray(dims) || dims.length !== 2 || dims[0] * dims[1] !== data.length) {
    throw new ServiceError(422, 'ground.heights.shape', `expected [nz, nx] holding the ${data.length} heights, got ${JSON.stringify(dims)}`);
  }
  if (!Array.isArray(origin) || origin.length !== 2) {
    throw new ServiceError(422, 'ground.origin', `expected [x, z], got ${JSON.stringify(origin)}`);
  }
  return { heights: blob(data, dims), origin: [Number(origin[0]), Number(origin[1])], spacing: Number(spacing) };
}

/** A request's characters with their points as blobs (the body REST and `synthesize` share). */
function requestBody(request) {
  const characters = request.characters.map((ch, c) => ({
    ...ch, id: String(ch.id ?? c), points: toPoints(ch.points, `characters[${c}].points`),
  }));
  return { ...request, characters };
}

/** A `chunk` message decoded: typed arrays for all characters at once. `header`: the batch's
 * or session's `start` (its joint count fills in what a level of detail left out). */
export function decodeChunk(message, header = {}) {
  const root = unblob(message.root, 'root');
  const [C, n] = message.root.shape;
  const rotations = decodeRotations(message.rotations, 'rotations', { joints: header.joints, characters: C });
  return {
    batch: message.batch, index: message.chunk, start: message.start, frames: n, characters: C,
    joints: header.joints ?? rotations.length / Math.max(C * n * 4, 1), encoding: message.rotations.encoding,
    root, rotations, gait: unblob(message.gait, 'gait'), contacts: unblob(message.contacts, 'contacts'),
  };
}

/** Frames [from, n) of a chunk (characters kept): what is left of it after a reconnection. */
export function sliceChunk(chunk, from) {
  const { characters: C, frames: n, joints: J } = chunk;
  const m = n - from;
  const take = (src, per) => {
    const out = new src.constructor(C * m * per);
    for (let c = 0; c < C; c++) out.set(src.subarray((c * n + from) * per, (c + 1) * n * per), c * m * per);
    return out;
  };
  return { ...chunk, start: chunk.start + from, frames: m, root: take(chunk.root, 3),
    rotations: take(chunk.rotations, J * 4), gait: take(chunk.gait, 1), contacts: take(chunk.contacts, 1) };
}

/** One WebSocket with its binary msgpack messages queued for `next()`. */
class Socket {
  static open(url, connect, codec) {
    return new Promise((resolve, reject) => {
      const ws = connect(url);
      ws.binaryType = 'arraybuffer';
      const sock = new Socket(ws, codec);
      ws.addEventListener('open', () => resolve(sock), { once: true });
      ws.addEventListener('close', (ev) => reject(new ServiceError(503, '', `could not connect (${ev.code})`, ev.code)), { once: true });
    });
  }

  constructor(ws, codec) {
    this.ws = ws; this.codec = codec; this.queue = []; this.waiters = []; this.closed = null; this.error = null;
    ws.addEventListener('message', (ev) => {
      const message = codec.decode(new Uint8Array(ev.data));
      if (message.type === 'error') this.error = message.error; // the close follows
      else this.deliver(message);
    });
    ws.addEventListener('close', (ev) => {
      const e = this.error ?? { status: ev.code === 1000 ? 200 : 503, field: '', message: `the stream closed (${ev.code})` };
      this.closed = new ServiceError(e.status, e.field, e.message, ev.code);
      for (const w of this.waiters.splice(0)) w.reject(this.closed);
    });
  }

  deliver(message) {
    const waiter = this.waiters.shift();
    if (waiter) waiter.resolve(message); else this.queue.push(message);
  }

  next() {
    if (this.queue.length) return Promise.resolve(this.queue.shift());
    if (this.closed) return Promise.reject(this.closed);
    return new Promise((resolve, reject) => { this.waiters.push({ resolve, reject }); });
  }

  send(message) { if (!this.closed) this.ws.send(this.codec.encode(message)); }

  close() { if (!this.closed) this.ws.close(1000); }
}

export class QuadSynthClient {
  /**
   * @param url  the service, e.g. "http://127.0.0.1:8000"
   * @param options.webSocket  (url) => WebSocket; default the global WebSocket
   * @param options.codec  {encode, decode} of msgpack; default @msgpack/msgpack
   * @param options.retries  reconnections after a 1001/1013 close (default 5), backoff from
   *                         options.retryDelayMs (default 250) doubling each time
   * @param options.restRetries  a REST request sent again when it got no answer or its answer
   *                         was cut short (a replica died mid-answer; the request is idempotent:
   *                         same seed, same motion), at most this many times (default 2);
   *                         the retries made are counted in `.restRetriesMade`
   */
  constructor(url, options = {}) {
    this.url = url.replace(/\/+$/, '');
    this.connect = options.webSocket ?? ((u) => new globalThis.WebSocket(u));
    this.retries = options.retries ?? 5;
    this.retryDelayMs = options.retryDelayMs ?? 250;
    this.restRetries = options.restRetries ?? 2;
    this.restRetriesMade = 0;
    this.fetch = options.fetch ?? globalThis.fetch.bind(globalThis);
    this.givenCodec = options.codec ?? null;
  }

  async codec() { return this.givenCodec ?? loadCodec(); }

  async openSocket() { return Socket.open(this.streamUrl, this.connect, await this.codec()); }

  get streamUrl() { return `${this.url.replace(/^http/, 'ws')}/v1/stream`; }

  async getJson(path) {
    const response = await this.fetch(`${this.url}${path}`);
    const body = await response.json();
    if (!response.ok) throw new ServiceError(response.status, body.error?.field ?? '', body.error?.message ?? '');
    return body;
  }

  libraries() { return this.getJson('/v1/libraries'); }
  limits() { return this.getJson('/v1/limits'); }
  /** GET /v1/libraries/{animal} as a Skeleton (the raw answer in `.detail`). */
  async skeleton(animal) {
    const detail = await this.getJson(`/v1/libraries/${encodeURIComponent(animal)}`);
    return Object.assign(new Skeleton(detail), { detail });
  }

  /** POST /v1/synthesize (msgpack both ways). `request`: the body's fields, characters' `points`
   * as Float32Array (F x 3) or [[x, y, z], ...]. Rotations come back decoded, whatever the encoding. */
  async synthesize(request) {
    const { encode, decode } = await this.codec();
    const sent = encode(requestBody(request));
    let response, bytes;
    for (let attempt = 0; ; attempt++) {
      try {
        response = await this.fetch(`${this.url}/v1/synthesize`, {
          method: 'POST', body: sent, headers: { 'content-type': MSGPACK, accept: MSGPACK },
        });
        bytes = new Uint8Array(await response.arrayBuffer());  // rejects on a body cut short
        break;
      } catch (error) {
        if (attempt >= this.restRetries || error instanceof ServiceError) throw error;
        this.restRetriesMade++;
        await sleep(this.retryDelayMs * 2 ** attempt);
      }
    }
    if (!response.ok) {
      let error = { field: '', message: new TextDecoder().decode(bytes.subarray(0, 200)) };
      try { error = JSON.parse(new TextDecoder().decode(bytes)).error; } catch { /* not JSON */ }
      throw new ServiceError(response.status, error.field, error.message);
    }
    const body = decode(bytes);
    body.characters = body.characters.map((ch, c) => ({
      id: ch.id, scale: ch.scale, frames: ch.frames,
      root: unblob(ch.root, `characters[${c}].root`),
      rotations: decodeRotations(ch.rotations, `characters[${c}].rotations`, { joints: body.joints }),
      gait: unblob(ch.gait), contacts: unblob(ch.contacts),
    }));
    return body;
  }

  /**
   * A big herd spread over several requests in flight at once (`concurrency`, default 2), so
   * the replicas behind a load balancer share it; the answer is the one `synthesize` gives for
   * the whole herd: each piece says where it starts in the herd (`first_index`), so every
   * character draws its gait, scale and tempo as in one request, and pieces asked to resample
   * (`resample`) that came back at a lower rate than the fastest are asked again at that rate
   * (`min_resample_rate`), so all keep the same frames. `skipped` and `warnings` index the herd.
   */
  async synthesizeSpread(request, { concurrency = 2 } = {}) {
    const C = request.characters.length;
    const n = Math.max(1, Math.min(concurrency, C));
    const cuts = Array.from({ length: n + 1 }, (_, k) => Math.round((k * C) / n));
    const pieces = cuts.slice(0, -1).map((a, k) => [a, cuts[k + 1]]);
    const base = request.first_index ?? 0;
    const send = (a, b, rate) => this.synthesize({
      ...request, characters: request.characters.slice(a, b), first_index: base + a,
      ...(rate > (request.min_resample_rate ?? 1) ? { min_resample_rate: rate } : {}),
    });
    let answers = await Promise.all(pieces.map(([a, b]) => send(a, b, 1)));
    const rate = Math.max(...answers.map((m) => m.resample_rate));
    answers = await Promise.all(answers.map((m, k) => (m.resample_rate < rate && m.characters.length
      ? send(pieces[k][0], pieces[k][1], rate) : m)));
    const shift = (list, k) => (list ?? []).map((e) => ({ ...e, index: e.index + pieces[k][0] }));
    return {
      ...answers[0], resample_rate: rate,
      characters: answers.flatMap((m) => m.characters),
      skipped: answers.flatMap((m, k) => shift(m.skipped, k)),
      warnings: answers.flatMap((m, k) => shift(m.warnings, k)),
    };
  }

  async reconnecting(attempt, error) {
    if (!RETRY_CODES.has(error.code) || attempt >= this.retries) throw error;
    await sleep(this.retryDelayMs * 2 ** attempt);
  }

  /**
   * The batch over WebSocket, chunk by chunk as it is made (an async iterator). A chunk is acked
   * when the loop asks for the next one, so a slow consumer slows the server (flow control).
   * Closed with 1001/1013, it reconnects and asks again: the batch is deterministic, so the
   * chunks already given are skipped and the rest continue. `onStart(start)` sees each `start`.
   */
  async *stream(request, { chunkFrames = 30, onStart, onReconnect } = {}) {
    const message = { type: 'synthesize', chunk_frames: chunkFrames, ...requestBody(request) };
    let given = 0;
    for (let attempt = 0; ; attempt++) {
      let sock, header = {};
      try {
        sock = await this.openSocket();
        sock.send(message);
        for (;;) {
          const m = await sock.next();
          if (m.type === 'start') { header = m; onStart?.(m); }
          else if (m.type === 'chunk') {
            if (m.chunk >= given) {
              yield decodeChunk(m, header);
              given = m.chunk + 1;
              attempt = 0;
            }
            sock.send({ type: 'ack', chunk: m.chunk });
          } else if (m.type === 'end') {
            sock.close();
            return;
          }
        }
      } catch (error) {
        if (!(error instanceof ServiceError)) throw error;
        await this.reconnecting(attempt, error);
        onReconnect?.({ code: error.code, error });
      } finally {
        sock?.close();
      }
    }
  }

  /**
   * Open a live session (docs/streaming.md, live mode). `options`: characters [{id, scale?,
   * seed?}], fps of the points, animal, seed, encoding, foot_lock, heading, ... `onChunk(chunk)`
   * gets each chunk (its `start` numbered from the session's first frame, across reconnections);
   * it may return a promise: the chunk is acked once it settles.
   */
  async live(options, { onChunk, onReconnect } = {}) {
    const session = new LiveSession(this, options, onChunk ?? (() => {}), onReconnect ?? (() => {}));
    await session.open(false);
    return session;
  }
}

const WARM_UP_POINTS = 60;

export class LiveSession {
  constructor(client, options, onChunk, onReconnect) {
    this.client = client; this.options = options; this.onChunk = onChunk; this.onReconnect = onReconnect;
    this.C = options.characters.length;
    this.history = []; // points messages [{data, n}] from historyStart on: what settles the frames not yet given
    this.historyStart = 0; // the first kept point's index (points per character, since the session began)
    this.historyPoints = 0;
    this.pointsSent = 0;
    this.offset = 0; // this connection's frame 0, in the session's output frames
    this.delivered = 0; // output frames given to onChunk
    this.finishing = false;
    this.attempts = 0;
    this.done = new Promise((resolve, reject) => { this.resolveDone = resolve; this.rejectDone = reject; });
    this.done.catch(() => {}); // observed through finish()
  }

  async open(again) {
    const characters = this.options.characters.map((ch, c) => ({
      ...ch, scale: this.header ? this.header.characters[c].scale : ch.scale,
    })).map((ch) => Object.fromEntries(Object.entries(ch).filter(([, v]) => v !== undefined)));
    // Until the new connection has its history, points pushed meanwhile only join the history
    // (the old socket is closed: its send does nothing), so they go out after it, in order.
    const sock = await this.client.openSocket();
    sock.send({ ...this.options, type: 'live', characters });
    const start = await sock.next();
    this.header = start;
    this.ratio = start.fps / this.options.fps; // output frames per point
    if (again) {
      this.offset = Math.round(this.historyStart * this.ratio);
      // Message by message as they first went: each was within the service's body limit.
      for (const entry of this.history) sock.send(this.pointsMessage(entry));
      if (this.finishing) sock.send({ type: 'finish' });
    }
    this.sock = sock;
    this.pump(sock);
  }

  get latencyFrames() { return this.header.latency_frames; }

  /** Every character's next `n` points: a Float32Array (C x n x 3), metres, in `characters` order;
   * `velocity` (optional): each point's ground velocity, C x n x 2 (x, z), m/s -- the low-latency
   * mode's speeds and headings read it instead of a fit of the points. */
  push(points, n = points.length / (3 * this.C), velocity = undefined) {
    if (!Number.isInteger(n) || n < 1 || points.length !== this.C * n * 3) {
      throw new ServiceError(422, 'points', `expected ${this.C} characters x n x 3 numbers, got ${points.length}`);
    }
    if (velocity != null && velocity.length !== this.C * n * 2) {
      throw new ServiceError(422, 'velocity', `expected ${this.C} characters x ${n} x 2 numbers, got ${velocity.length}`);
    }
    const entry = { data: Float32Array.from(points), n, velocity: velocity == null ? null : Float32Array.from(velocity) };
    this.history.push(entry);
    this.historyPoints += n;
    this.pointsSent += n;
    this.sock.send(this.pointsMessage(entry));
  }

  pointsMessage({ data, n, velocity }) {
    const message = { type: 'points', points: blob(data, [this.C, n, 3]) };
    if (velocity) message.velocity = blob(velocity, [this.C, n, 2]);
    return message;
  }

  /** Forget the points a reconnection would not need: those more than WARM_UP_POINTS before the
   * first frame not yet given (a new session starts fresh at its first point, so it gets a
   * couple of seconds of run-up before the frames that count). */
  trim() {
    const keepFrom = Math.floor(this.delivered / this.ratio) - WARM_UP_POINTS;
    while (this.history.length && this.historyStart + this.history[0].n <= keepFrom) {
      const { n } = this.history.shift();
      this.historyStart += n;
      this.historyPoints -= n;
    }
  }

  /** The ground of the frames rendered from now on (a `ground` message: `ground(...)`, or null:
   * the points' y), faded in by the service over 0.4 s. A reconnection opens the new session on
   * the latest ground (the points given again stand on it too). */
  setGround(heightField) {
    this.options = { ...this.options, ground: heightField };
    this.sock.send({ type: 'ground', ground: heightField });
  }

  /** No more points: resolves once every remaining chunk was handled and the session ended. */
  finish() {
    this.finishing = true;
    this.sock.send({ type: 'finish' });
    return this.done;
  }

  close() { this.sock.send({ type: 'cancel' }); this.sock.close(); this.resolveDone(); }

  async pump(sock) {
    try {
      for (;;) {
        const m = await sock.next();
        if (m.type === 'chunk') {
          const chunk = decodeChunk(m, this.header);
          chunk.start += this.offset;
          const skip = this.delivered - chunk.start;
          if (skip < chunk.frames) {
            const fresh = skip > 0 ? sliceChunk(chunk, skip) : chunk;
            await this.onChunk(fresh);
            this.delivered = fresh.start + fresh.frames;
            this.attempts = 0;
            this.trim();
          }
          sock.send({ type: 'ack', chunk: m.chunk });
        } else if (m.type === 'end') {
          sock.close();
          this.resolveDone();
          return;
        }
      }
    } catch (error) {
      if (!(error instanceof ServiceError) || sock !== this.sock) { this.rejectDone(error); return; }
      try {
        await this.reopen(error); // the new connection has a pump of its own
      } catch (fatal) {
        this.rejectDone(fatal);
      }
    }
  }

  /** After a 1001/1013 close: a new live session given the kept points again, so the frames
   * not yet played are settled again (numbered on from where they were; motion continues from
   * the same positions, its gait phase may jump). */
  async reopen(error) {
    for (;;) {
      await this.client.reconnecting(this.attempts++, error); // throws past the retries or for another code
      this.onReconnect({ code: error.code, error });
      try {
        await this.open(true);
        return;
      } catch (again) {
        if (!(again instanceof ServiceError)) throw again;
        error = again;
      }
    }
  }
}
