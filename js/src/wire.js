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

const SQRT_HALF = Math.SQRT1_2;
const S48_MAX = 32767;
const S48_STEP = SQRT_HALF / (S48_MAX / 2);

/** Packed rotations (a `rotations` map: {dtype, shape, data, encoding}) -> unit quaternions,
 * xyzw, Float32Array of (...shape without its last axis) x 4. */
export function decodeRotations(rotations, field = 'rotations') {
  const packed = unblob(rotations, field);
  switch (rotations.encoding) {
    case 'f32': return packed;
    case 'i16': return decodeI16(packed);
    case 's48': return decodeS48(packed);
    default: throw new WireError(`encoding must be f32, i16 or s48, got ${rotations.encoding}`, `${field}.encoding`);
  }
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
