// Decoding without a service: the worked examples of docs/wire-format.md, unaligned blobs.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { decodeRotations, decodeS48, decodeI16, unblob, blob, contactFeet, WireError } from '../src/index.js';

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
