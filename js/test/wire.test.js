// Decoding without a service: the worked examples of docs/wire-format.md, unaligned blobs.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { decodeRotations, decodeS48, decodeI16, decodeDelta, unblob, blob, contactFeet, WireError } from '../src/index.js';

test('s48: the worked example (45 degrees about Y)', () => {
  const q = decodeS48(Uint8Array.from([0x03, 0x00, 0x45, 0xc5, 0x00, 0x40]));
  const want = [0.0000216, 0.3826834, 0.0000216, 0.9238795];
  want.forEach((v, k) => assert.ok(Math.abs(q[k] - v) < 2e-5, `component ${k}: ${q[k]} != ${v}`));
});

test('s48: each dropped index lands in its place, with its sign made positive', () => {
  // u = 16384 is c = 0.0000216 (the middle); dropped index 0 -> x rebuilt, the rest ~0.
  for (let k = 0; k < 4; k++) {
    const word = BigInt(k) | (16384n << 2n) | (16384n << 17n) | (16384n << 32n);
    const bytes = Uint8Array.from({ length: 6 }, (_, b) => Number((word >> BigInt(8 * b)) & 0xffn));
    const q = decodeS48(bytes);
    assert.ok(Math.abs(q[k] - 1) < 1e-6, `index ${k}: ${Array.from(q)}`);
  }
});

test('i16: the worked example, normalized', () => {
  const q = decodeI16(Int16Array.from([0, 12539, 0, 30273]));
  assert.ok(Math.abs(q[1] - 0.3826834) < 1e-4 && Math.abs(q[3] - 0.9238795) < 1e-4);
  assert.ok(Math.abs(Math.hypot(...q) - 1) < 1e-6);
});

test('a blob at an unaligned offset decodes (a zero-copy Float32Array would throw)', () => {
  const values = Float32Array.from([1.5, -2.25, 3.125]);
  const message = new Uint8Array(13);
  message.set(new Uint8Array(values.buffer), 1); // msgpack puts bin payloads at any offset
  const data = message.subarray(1);
  assert.throws(() => new Float32Array(data.buffer, data.byteOffset, 3), RangeError);
  assert.deepEqual(Array.from(unblob({ dtype: '<f4', shape: [3], data })), [1.5, -2.25, 3.125]);
  assert.deepEqual(Array.from(decodeRotations({ dtype: '<f4', shape: [3], data, encoding: 'f32' })), [1.5, -2.25, 3.125]);
});

test('blobs that do not add up are refused, naming the field', () => {
  assert.throws(() => unblob({ dtype: '<f4', shape: [2, 3], data: new Uint8Array(20) }, 'root'),
    (e) => e instanceof WireError && e.field === 'root.data');
  assert.throws(() => unblob({ dtype: '>f4', shape: [1], data: new Uint8Array(4) }, 'root'),
    (e) => e instanceof WireError && e.field === 'root.dtype');
  assert.throws(() => decodeRotations({ dtype: '|u1', shape: [6], data: new Uint8Array(6), encoding: 'x' }), WireError);
  const b = blob(Float32Array.from([1, 2, 3, 4, 5, 6]), [2, 3]);
  assert.equal(b.dtype, '<f4');
  assert.equal(b.data.byteLength, 24);
});

test('contacts bit mask in foot order LF, RF, LH, RH', () => {
  assert.deepEqual(contactFeet(0b1001), [true, false, false, true]);
});

test('delta: the worked example (one joint turning 0, 10, 20, 30 degrees about Y)', () => {
  const bytes = Uint8Array.from([0x01, 0x00, 0x04, 0x00, 0x01, 0x00, 0x17, 0x00, 0x00, 0x00, 0x16, 0x00, 0x00, 0x00,
    0x40, 0x1f, 0x00, 0x00, 0xce, 0x07, 0x40, 0x0b, 0x12]);
  const { rotations: q, blocks, frames, joints } = decodeDelta(bytes);
  assert.deepEqual([blocks, frames, joints], [1, 4, 1]);
  const step = 2 ** (-64 / 8); // the joint's step code 0x40: 1/256 rad
  [0, 10, 20, 30].forEach((deg, t) => {
    const angle = 2 * Math.atan2(q[t * 4 + 1], q[t * 4 + 3]);
    assert.ok(Math.abs(angle - (deg * Math.PI) / 180) <= (step * Math.sqrt(3)) / 2, `frame ${t}: ${angle}`);
    assert.ok(Math.abs(q[t * 4]) < 1e-7 && Math.abs(q[t * 4 + 2]) < 1e-7);
  });
  // The same bytes as a response's rotations map; a level of detail's joints filled in.
  const rot = { dtype: '|u1', shape: [23], data: bytes, encoding: 'delta', decoded_shape: [4, 1, 4], joints: [2] };
  const full = decodeRotations(rot, 'rotations', { joints: 3 });
  assert.equal(full.length, 4 * 3 * 4);
  assert.deepEqual(Array.from(full.subarray(0, 8)), [0, 0, 0, 1, 0, 0, 0, 1]); // joints 0 and 1: identity
  assert.equal(full[8 + 1], q[1]);
});

test('delta: a cut or altered block is refused, not misread', () => {
  const bytes = Uint8Array.from([0x01, 0x00, 0x04, 0x00, 0x01, 0x00, 0x17, 0x00, 0x00, 0x00, 0x16, 0x00, 0x00, 0x00,
    0x40, 0x1f, 0x00, 0x00, 0xce, 0x07, 0x40, 0x0b, 0x12]);
  assert.throws(() => decodeDelta(bytes.subarray(0, 20)), WireError);
  const other = bytes.slice();
  other[0] = 2;
  assert.throws(() => decodeDelta(other), /version 2/);
  assert.throws(() => decodeRotations({ dtype: '|u1', shape: [23], data: bytes, encoding: 'delta', decoded_shape: [5, 1, 4] }),
    (e) => e instanceof WireError && e.field === 'rotations.decoded_shape');
});
