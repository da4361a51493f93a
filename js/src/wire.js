// The wire format (docs/wire-format.md): arrays as {dtype, shape, data} blobs, rotations packed
// as f32, i16 or s48. Everything here is pure: typed arrays in, typed arrays out.

const TYPED = {
  '<f4': Float32Array, '<f8': Float64Array, '<i2': Int16Array, '<i4': Int32Array,
  '|i1': Int8Array, '|u1': Uint8Array,
};

// Blobs are little-endian; every platform that runs a browser or Node today is too. A
// big-endian one would read garbage silently, so refuse it loudly instead.
if (new Uint8Array(new Uint16Array([1]).buffer)[0] !== 1) {
  throw new Error('quadsynth-client needs a little-endian platform');
}

export class WireError extends Error {
  constructor(message, field = '') {
    super(field ? `${field}: ${message}` : message);
    this.name = 'WireError';
    this.field = field;
  }
}

/** A wire blob -> a typed array of its dtype (a copy when the bytes sit at an offset the typed
 * array cannot view: msgpack's bin payloads start anywhere in the message). */
export function unblob(blob, field = '') {
  const Typed = TYPED[blob.dtype];
  if (!Typed) throw new WireError(`dtype must be one of ${Object.keys(TYPED).join(', ')}, got ${blob.dtype}`, `${field}.dtype`);
  const count = blob.shape.reduce((a, b) => a * b, 1);
  const data = blob.data;
  if (data.byteLength !== count * Typed.BYTES_PER_ELEMENT) {
    throw new WireError(`${data.byteLength} bytes do not hold ${blob.dtype} of shape [${blob.shape}]`, `${field}.data`);
  }
  if (data.byteOffset % Typed.BYTES_PER_ELEMENT === 0) {
    return new Typed(data.buffer, data.byteOffset, count);
  }
  return new Typed(data.slice().buffer, 0, count); // slice() copies into a fresh, aligned buffer
}

/** A typed array -> a wire blob of the given shape. */
export function blob(array, shape) {
  const dtype = Object.keys(TYPED).find((k) => array instanceof TYPED[k]);
  if (!dtype) throw new WireError('expected a Float32Array, Float64Array, Int16Array, Int32Array, Int8Array or Uint8Array');
  const count = shape.reduce((a, b) => a * b, 1);
  if (array.length !== count) throw new WireError(`${array.length} items do not fill shape [${shape}]`);
  return { dtype, shape, data: new Uint8Array(array.buffer, array.byteOffset, array.byteLength) };
}

/** Worst decoding error of each encoding (degrees; mm at a point 3 cm from the joint), as
 * published by GET /v1/limits and checked by the service's tests. */
export const ENCODING_ERROR = { f32: [0, 0], i16: [0.0035, 0.0019], s48: [0.0075, 0.0040] };
/** delta's budget: every joint's world position within this (mm), by construction. */
export const DELTA_MAX_ERROR_MM = 0.1;

const SQRT_HALF = Math.SQRT1_2;
const S48_MAX = 32767;
const S48_STEP = SQRT_HALF / (S48_MAX / 2);

/** Packed rotations (a `rotations` map: {dtype, shape, data, encoding}) -> unit quaternions,
 * xyzw, Float32Array of (...shape without its last axis) x 4 (delta: of its `decoded_shape`).
 * A level of detail's map sends some `joints` and (in a chunk) some `characters`: given
 * `{ joints: J, characters: C }`, the rest are filled in with the identity rotation. */
export function decodeRotations(rotations, field = 'rotations', full = {}) {
  const packed = unblob(rotations, field);
  let q;
  switch (rotations.encoding) {
    case 'f32': q = packed; break;
    case 'i16': q = decodeI16(packed); break;
    case 's48': q = decodeS48(packed); break;
    case 'delta': {
      q = decodeDelta(packed, field).rotations;
      const want = (rotations.decoded_shape ?? []).reduce((a, b) => a * b, 1);
      if (!rotations.decoded_shape || want !== q.length) {
        throw new WireError(`decoded_shape ${JSON.stringify(rotations.decoded_shape)} does not hold the ${q.length / 4} rotations decoded`, `${field}.decoded_shape`);
      }
      break;
    }
    default: throw new WireError(`encoding must be f32, i16, s48 or delta, got ${rotations.encoding}`, `${field}.encoding`);
  }
  return expandDetail(q, rotations, full);
}

/** Rows (characters) and joints a level of detail left out, back as identity rotations. */
function expandDetail(q, rotations, { joints: J, characters: C }) {
  const joints = rotations.joints, rows = rotations.characters;
  if (joints && J !== undefined) {
    const Jsent = joints.length, m = Jsent ? q.length / (4 * Jsent) : 0;  // rows x frames sent
    const frames = Jsent ? m : (rotations.decoded_shape ?? rotations.shape).slice(0, -2).reduce((a, b) => a * b, 1);
    const out = identity(frames * J);
    for (let i = 0; i < m; i++) {
      for (let k = 0; k < Jsent; k++) out.set(q.subarray((i * Jsent + k) * 4, (i * Jsent + k + 1) * 4), (i * J + joints[k]) * 4);
    }
    q = out;
  }
  if (rows && C !== undefined) {
    const shape = rotations.decoded_shape ?? rotations.shape;  // (rows, frames, joints sent, .)
    const per = shape[1] * (J ?? shape[2]) * 4;
    const out = identity((C * per) / 4);
    rows.forEach((c, i) => out.set(q.subarray(i * per, (i + 1) * per), c * per));
    q = out;
  }
  return q;
}

function identity(n) {
  const out = new Float32Array(n * 4);
  for (let i = 3; i < out.length; i += 4) out[i] = 1;
  return out;
}

/** The delta encoding (docs/wire-format.md): blocks of time-axis residuals of quantized rotation
 * vectors, Rice coded. Every block one after another -> their rotations, xyzw, Float32Array of
 * blocks x frames x joints x 4 (blocks of equal frames and joints), and that count of each. */
export function decodeDelta(bytes, field = 'rotations') {
  const blocks = [];
  let at = 0, total = 0;
  while (at < bytes.length) {
    const block = decodeDeltaBlock(bytes.subarray(at), field);
    blocks.push(block);
    total += block.rotations.length;
    at += block.size;
  }
  const out = new Float32Array(total);
  let o = 0;
  for (const b of blocks) {
    if (b.frames !== blocks[0].frames || b.joints !== blocks[0].joints) throw new WireError('delta blocks of different frames or joints', field);
    out.set(b.rotations, o);
    o += b.rotations.length;
  }
  return { rotations: out, blocks: blocks.length, frames: blocks[0]?.frames ?? 0, joints: blocks[0]?.joints ?? 0 };
}

const ESCAPE = 24, NO_RESIDUALS = 31, HEADER = 14;

/** `width` (<= 32) bits at bit `pos` (bit i: bit i % 8 of byte i / 8), as a number. */
function bitsAt(bytes, pos, width) {
  let value = 0, got = 0;
  while (got < width) {
    const byte = bytes[(pos + got) >> 3] ?? 0, shift = (pos + got) & 7;
    const take = Math.min(8 - shift, width - got);
    value += ((byte >> shift) & ((1 << take) - 1)) * 2 ** got;
    got += take;
  }
  return value;
}

const unzigzag = (u) => (u % 2 === 0 ? u / 2 : -(u + 1) / 2);

function decodeDeltaBlock(bytes, field) {
  if (bytes.length < HEADER) throw new WireError(`a delta block needs at least ${HEADER} bytes, got ${bytes.length}`, field);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const version = view.getUint8(0), n = view.getUint16(2, true), J = view.getUint16(4, true);
  const size = view.getUint32(6, true), unary = view.getUint32(10, true);
  if (version !== 1) throw new WireError(`delta block version ${version}, this decoder reads 1`, field);
  if (!(HEADER + J <= unary && unary <= size && size <= bytes.length)) {
    throw new WireError(`a delta block of ${size} bytes (unary at ${unary}) does not fit the ${bytes.length} bytes given`, field);
  }
  const T = 3 * J;
  let pos = 8 * (HEADER + J);
  const ks = new Array(T), w0 = new Array(T), w1 = new Array(T);
  for (let i = 0; i < T; i++, pos += 15) {
    ks[i] = bitsAt(bytes, pos, 5); w0[i] = bitsAt(bytes, pos + 5, 5); w1[i] = bitsAt(bytes, pos + 10, 5);
  }
  const v = new Float64Array(T * n);  // track-major: v[i * n + t]
  const first = new Float64Array(T);  // each track's first change, v[1] - v[0]
  for (let i = 0; i < T; i++) {
    if (n) v[i * n] = unzigzag(bitsAt(bytes, pos, w0[i]));
    pos += w0[i];
    first[i] = unzigzag(bitsAt(bytes, pos, w1[i]));
    pos += w1[i];
  }
  let upos = 8 * unary;
  const end = 8 * size;
  for (let i = 0; i < T; i++) {
    const k = ks[i];
    let delta = first[i];
    if (n > 1) v[i * n + 1] = v[i * n] + delta;
    for (let t = 2; t < n; t++) {
      if (k !== NO_RESIDUALS) {  // none stored: every residual is zero
        let q = 0;
        while (!((bytes[upos >> 3] >> (upos & 7)) & 1)) {
          q++; upos++;
          if (upos >= end) throw new WireError('the delta block ends before its residuals', field);
        }
        upos++;
        let u;
        if (q >= ESCAPE) { u = bitsAt(bytes, pos, 32); pos += 32; } else { u = q * 2 ** k + bitsAt(bytes, pos, k); pos += k; }
        if (pos > 8 * unary) throw new WireError("the delta block's remainders run past their section", field);
        delta += unzigzag(u);  // r_t = v_t - 2 v_(t-1) + v_(t-2): the change grows by the residual
      }
      v[i * n + t] = v[i * n + t - 1] + delta;
    }
  }
  const out = new Float32Array(n * J * 4);
  for (let j = 0; j < J; j++) {
    const step = 2 ** (-bytes[HEADER + j] / 8);
    for (let t = 0; t < n; t++) {
      const x = v[(3 * j) * n + t] * step, y = v[(3 * j + 1) * n + t] * step, z = v[(3 * j + 2) * n + t] * step;
      const angle = Math.hypot(x, y, z);
      const s = angle > 1e-8 ? Math.sin(angle / 2) / angle : 0.5 - angle * angle / 48;
      const o = (t * J + j) * 4;
      out[o] = x * s; out[o + 1] = y * s; out[o + 2] = z * s; out[o + 3] = Math.cos(angle / 2);
    }
  }
  return { rotations: out, frames: n, joints: J, size };
}

/** glTF's normalized SHORT: max(v / 32767, -1), then normalized. */
export function decodeI16(packed) {
  const out = new Float32Array(packed.length);
  for (let i = 0; i < packed.length; i += 4) {
    const x = Math.max(packed[i] / S48_MAX, -1), y = Math.max(packed[i + 1] / S48_MAX, -1);
    const z = Math.max(packed[i + 2] / S48_MAX, -1), w = Math.max(packed[i + 3] / S48_MAX, -1);
    const n = Math.hypot(x, y, z, w) || 1;
    out[i] = x / n; out[i + 1] = y / n; out[i + 2] = z / n; out[i + 3] = w / n;
  }
  return out;
}

/** Smallest three in 48 bits: bits 0-1 the dropped component's index, then three 15-bit
 * values (bits 2-16, 17-31, 32-46) of the others in x, y, z, w order. */
export function decodeS48(bytes) {
  if (bytes.length % 6 !== 0) throw new WireError(`s48 needs 6 bytes per rotation, got ${bytes.length} bytes`);
  const n = bytes.length / 6;
  const out = new Float32Array(n * 4);
  const rest = [0, 0, 0];
  for (let r = 0; r < n; r++) {
    const b = r * 6;
    // Bits 0-31 as an unsigned 32-bit word, bits 32-47 as a 16-bit one (no 64-bit integers needed).
    const lo = (bytes[b] | (bytes[b + 1] << 8) | (bytes[b + 2] << 16) | (bytes[b + 3] << 24)) >>> 0;
    const hi = bytes[b + 4] | (bytes[b + 5] << 8);
    const dropped = lo & 3;
    rest[0] = ((lo >>> 2) & S48_MAX) * S48_STEP - SQRT_HALF;
    rest[1] = ((lo >>> 17) & S48_MAX) * S48_STEP - SQRT_HALF;
    rest[2] = (hi & S48_MAX) * S48_STEP - SQRT_HALF;
    const big = Math.sqrt(Math.max(1 - rest[0] * rest[0] - rest[1] * rest[1] - rest[2] * rest[2], 0));
    const o = r * 4;
    for (let k = 0, m = 0; k < 4; k++) out[o + k] = k === dropped ? big : rest[m++];
  }
  return out;
}

/** A contacts bit mask (1 LF, 2 RF, 4 LH, 8 RH) -> four booleans in foot order LF, RF, LH, RH. */
export function contactFeet(mask) {
  return [(mask & 1) !== 0, (mask & 2) !== 0, (mask & 4) !== 0, (mask & 8) !== 0];
}

export const FEET = ['LF', 'RF', 'LH', 'RH'];
export const GAITS = ['static', 'walk', 'trot', 'canter', 'gallop'];
