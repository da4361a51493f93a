// The ground (docs/terrain.md) from the JS client: `ground(...)` on REST, the WebSocket batch and
// a live session's opening and `ground` messages (LiveSession.setGround), against a real service
// (tests/test_js_client.py starts it and sets QUADSYNTH_URL).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { ServiceError, feetAt, ground } from '../src/index.js';
import { URL, characters, client, herd } from './helpers.js';

const skip = URL ? false : 'QUADSYNTH_URL not set (tests/test_js_client.py runs these against a real service)';
const C = 2, F = 360;
const points = herd(C, F); // y = 0: with a ground the points' y is not read
/** A level ground at `y` over the herd's paths (x and z within +-40 m). */
const level = (y) => ground([[y, y], [y, y]], { origin: [-40, -40], spacing: 80 });

test('ground(): rows or a typed array with its shape; bad ones refused naming the field', () => {
  const rows = ground([[0, 1, 2], [3, 4, 5]], { origin: [1, 2], spacing: 0.5 });
  assert.deepEqual(rows.heights.shape, [2, 3]);
  assert.equal(rows.heights.dtype, '<f4');
  assert.deepEqual(rows.origin, [1, 2]);
  assert.equal(rows.spacing, 0.5);
  const typed = ground(new Float64Array([0, 1, 2, 3]), { shape: [2, 2] });
  assert.equal(typed.heights.dtype, '<f8');
  const refused = (f, field) => assert.throws(f, (e) => e instanceof ServiceError && e.field === field);
  refused(() => ground([[0, 1], [2]]), 'ground.heights');
  refused(() => ground(new Float32Array(6), { shape: [2, 2] }), 'ground.heights.shape');
  refused(() => ground(new Float32Array(4)), 'ground.heights.shape');
  refused(() => ground([[0, 0], [0, 0]], { origin: [0] }), 'ground.origin');
});

test('REST and the WebSocket batch stand the herd on the ground sent, bit for bit alike', { skip }, async () => {
  const qs = client();
  const request = { animal: 'horse', fps: 60, seed: 3, encoding: 'f32', characters: characters(points, C) };
  const flat = await qs.synthesize(request);
  const raised = await qs.synthesize({ ...request, ground: level(0.5) });
  for (let c = 0; c < C; c++) {
    const a = flat.characters[c].root, b = raised.characters[c].root;
    const lifts = [];
    for (let f = 0; f < a.length / 3; f++) lifts.push(b[f * 3 + 1] - a[f * 3 + 1]);
    lifts.sort((p, q) => p - q);
    const median = lifts[lifts.length >> 1];
    assert.ok(Math.abs(median - 0.5) < 0.005, `character ${c}: the body ${median} m up on a ground 0.5 m up`);
  }
  let frames = 0;
  for await (const chunk of qs.stream({ ...request, ground: level(0.5) }, { chunkFrames: 50 })) {
    for (let c = 0; c < C; c++) {
      const n = chunk.frames;
      assert.deepEqual(chunk.root.subarray(c * n * 3, (c + 1) * n * 3),
        raised.characters[c].root.subarray(chunk.start * 3, (chunk.start + n) * 3));
    }
    frames += chunk.frames;
  }
  assert.equal(frames, raised.characters[0].frames);
  await assert.rejects(qs.synthesize({ ...request, ground: ground([[0, NaN], [0, 0]]) }),
    (e) => e instanceof ServiceError && e.status === 422 && e.field === 'ground.heights');
});

test('live: the session opens on its ground, and a new one sent mid-session is faded in', { skip }, async () => {
  const qs = client();
  const skeleton = await qs.skeleton('horse');
  const chunks = [];
  const session = await qs.live({ animal: 'horse', fps: 60, seed: 3, encoding: 'f32', ground: level(0.1),
    characters: [{ id: 'a' }, { id: 'b' }] }, { onChunk: (chunk) => { chunks.push(chunk); } });
  const scales = session.header.characters.map((ch) => ch.scale);
  const n = 30, L = 720, path = herd(C, L);
  for (let at = 0; at < L; at += n) {
    if (at === L / 2) {
      // Once frames have come on the first ground (they are rendered as the acks allow): 20 cm up.
      for (let waited = 0; chunks.reduce((k, ch) => k + ch.frames, 0) < 60; waited += 20) {
        assert.ok(waited < 30000, 'no frames within 30 s');
        await new Promise((resolve) => { setTimeout(resolve, 20); });
      }
      session.setGround(level(0.3));
    }
    const part = new Float32Array(C * n * 3);
    for (let c = 0; c < C; c++) part.set(path.subarray((c * L + at) * 3, (c * L + at + n) * 3), c * n * 3);
    session.push(part, n);
  }
  await session.finish();
  for (let c = 0; c < C; c++) {
    const ys = [];
    for (const chunk of chunks) {
      for (let f = 0; f < chunk.frames; f++) ys.push(Math.min(...feetAt(skeleton, chunk, c, f, scales[c]).map((p) => p[1])));
    }
    assert.ok(Math.abs(ys[30] - 0.1) < 0.01, `character ${c}: its lowest foot at ${ys[30]} m on a ground at 0.1 m`);
    // On the new ground by the end: over its last 30 frames (half a trot's stride: a trotting horse
    // has flights, no foot down in a frame), the lowest foot comes down to it and never under it.
    const end = ys.slice(-30);
    assert.ok(Math.abs(Math.min(...end) - 0.3) < 0.01 && Math.max(...end) < 0.45,
      `character ${c}: its lowest foot over the last 30 frames at ${Math.min(...end)}-${Math.max(...end)} m on a ground at 0.3 m`);
    let jump = 0;
    for (let f = 1; f < ys.length; f++) jump = Math.max(jump, Math.abs(ys[f] - ys[f - 1]));
    assert.ok(jump < 0.06, `character ${c}: its lowest foot moved ${jump} m up or down in one frame`);
  }
});
