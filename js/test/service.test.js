// Against a real `quadsynth serve` (tests/test_js_client.py starts it and sets QUADSYNTH_URL):
// REST and WebSocket, every encoding, pose assembly, live mode.
import { test } from 'node:test';
import { readFileSync } from 'node:fs';
import assert from 'node:assert/strict';
import { ENCODING_ERROR, ServiceError, feetAt, worldPose } from '../src/index.js';
import { URL, angleDeg, characters, client, herd } from './helpers.js';

const skip = URL ? false : 'QUADSYNTH_URL not set (tests/test_js_client.py runs these against a real service)';
const C = 3, F = 360;
const points = herd(C, F);
const request = (encoding) => ({ animal: 'horse', fps: 60, seed: 7, encoding, characters: characters(points, C) });

/** A REST character as a one-character "chunk" (the layout pose assembly reads). */
const asChunk = (ch) => ({ frames: ch.frames, root: ch.root, rotations: ch.rotations });

test('s48 and i16 decode within their documented error of REST f32 (REST and WebSocket)', { skip }, async (t) => {
  const qs = client();
  const exact = await qs.synthesize(request('f32'));
  for (const encoding of ['s48', 'i16']) {
    const rest = await qs.synthesize(request(encoding));
    let worst = 0;
    rest.characters.forEach((ch, c) => {
      const ref = exact.characters[c].rotations;
      assert.equal(ch.rotations.length, ref.length);
      for (let i = 0; i < ref.length; i += 4) worst = Math.max(worst, angleDeg(ref, i, ch.rotations, i));
    });
    assert.ok(worst <= ENCODING_ERROR[encoding][0], `${encoding} REST: ${worst} deg > ${ENCODING_ERROR[encoding][0]}`);
    t.diagnostic(`${encoding}: worst ${worst.toFixed(5)} deg from f32 (REST), documented ${ENCODING_ERROR[encoding][0]}`);
    assert.ok(worst > 0, `${encoding} is lossy: an error of exactly 0 means f32 came back`);
    let streamed = 0, frames = 0;
    for await (const chunk of qs.stream(request(encoding), { chunkFrames: 50 })) {
      const J = chunk.joints;
      for (let c = 0; c < C; c++) {
        const ref = exact.characters[c].rotations;
        for (let f = 0; f < chunk.frames; f++) {
          for (let j = 0; j < J; j++) {
            const i = ((c * chunk.frames + f) * J + j) * 4, k = ((chunk.start + f) * J + j) * 4;
            streamed = Math.max(streamed, angleDeg(ref, k, chunk.rotations, i));
          }
        }
      }
      frames += chunk.frames;
    }
    assert.equal(frames, exact.characters[0].frames);
    assert.ok(streamed <= ENCODING_ERROR[encoding][0], `${encoding} stream: ${streamed} deg`);
  }
});

test('the batch stream is REST bit for bit: chunk numbering, frames, root, gait, contacts', { skip }, async () => {
  const qs = client();
  const rest = await qs.synthesize(request('f32'));
  let starts = [], header;
  for await (const chunk of qs.stream(request('f32'), { chunkFrames: 64, onStart: (m) => { header = m; } })) {
    starts.push([chunk.index, chunk.start]);
    for (let c = 0; c < C; c++) {
      const ch = rest.characters[c], n = chunk.frames, J = chunk.joints;
      assert.deepEqual(chunk.root.subarray(c * n * 3, (c + 1) * n * 3), ch.root.subarray(chunk.start * 3, (chunk.start + n) * 3));
      assert.deepEqual(chunk.rotations.subarray(c * n * J * 4, (c + 1) * n * J * 4),
        ch.rotations.subarray(chunk.start * J * 4, (chunk.start + n) * J * 4));
      assert.deepEqual(chunk.gait.subarray(c * n, (c + 1) * n), ch.gait.subarray(chunk.start, chunk.start + n));
      assert.deepEqual(chunk.contacts.subarray(c * n, (c + 1) * n), ch.contacts.subarray(chunk.start, chunk.start + n));
    }
  }
  assert.equal(header.frames, rest.characters[0].frames);
  assert.deepEqual(starts, Array.from({ length: header.chunks }, (_, i) => [i, i * 64]));
});

test('pose assembly puts planted hooves on the ground (y ~ 0); without the scale they float', { skip }, async (t) => {
  const qs = client();
  const skeleton = await qs.skeleton('horse');
  const motion = await qs.synthesize({ ...request('s48'), scale_min: 0.8, scale_max: 1.2 });
  const planted = [], unscaled = [];
  for (const ch of motion.characters) {
    assert.ok(Math.abs(ch.scale - 1) > 0.01, `scale ${ch.scale}: the test needs scaled characters`);
    for (let f = 0; f < ch.frames; f++) {
      const feet = feetAt(skeleton, asChunk(ch), 0, f, ch.scale);
      const flat = feetAt(skeleton, asChunk(ch), 0, f, 1);
      for (let k = 0; k < 4; k++) {
        if (ch.contacts[f] & (1 << k)) { planted.push(Math.abs(feet[k][1])); unscaled.push(Math.abs(flat[k][1])); }
      }
    }
  }
  planted.sort((a, b) => a - b); unscaled.sort((a, b) => a - b);
  const p95 = (xs) => xs[Math.floor(0.95 * (xs.length - 1))];
  t.diagnostic(`planted hooves |y|: p95 ${(p95(planted) * 1000).toFixed(2)} mm, max ${(planted[planted.length - 1] * 1000).toFixed(2)} mm over ${planted.length} foot-frames; offsets unscaled: p95 ${(p95(unscaled) * 1000).toFixed(1)} mm`);
  assert.ok(planted.length > 500, `${planted.length} planted foot-frames`);
  assert.ok(p95(planted) < 0.002, `planted hooves 95th percentile ${p95(planted) * 1000} mm off the ground`);
  assert.ok(p95(unscaled) > 0.02, `offsets not scaled: hooves only ${p95(unscaled) * 1000} mm off (the check would not notice)`);
});

test('world pose: bone lengths are the rest offsets times the scale', { skip }, async () => {
  const qs = client();
  const skeleton = await qs.skeleton('dog');
  const motion = await qs.synthesize({ ...request('i16'), animal: 'dog' });
  const ch = motion.characters[1];
  const J = skeleton.joints;
  const { positions: P } = worldPose(skeleton, ch.root, 100 * 3, ch.rotations, 100 * J * 4, ch.scale);
  assert.deepEqual(Array.from(P.subarray(0, 3)), Array.from(ch.root.subarray(300, 303)), 'joint 0 is the root');
  for (let j = 1; j < J; j++) {
    const p = skeleton.parents[j];
    const bone = Math.hypot(P[j * 3] - P[p * 3], P[j * 3 + 1] - P[p * 3 + 1], P[j * 3 + 2] - P[p * 3 + 2]);
    const rest = Math.hypot(...skeleton.offsets.subarray(j * 3, j * 3 + 3)) * ch.scale;
    assert.ok(Math.abs(bone - rest) < 1e-5, `${skeleton.names[j]}: ${bone} != ${rest}`);
  }
});

test('live: points in, contiguous frames out, an end after finish', { skip }, async () => {
  const qs = client();
  const n = 40, fps = 30, live = herd(2, 600, fps);
  const got = [];
  const session = await qs.live({ animal: 'dog', fps, seed: 1, characters: [{ id: 'a' }, { id: 'b' }] },
    { onChunk: (chunk) => { got.push([chunk.start, chunk.frames, chunk.characters]); } });
  assert.equal(session.header.mode, 'live');
  for (let at = 0; at < 600; at += n) {
    const part = new Float32Array(2 * n * 3);
    for (let c = 0; c < 2; c++) part.set(live.subarray((c * 600 + at) * 3, (c * 600 + at + n) * 3), c * n * 3);
    session.push(part, n);
  }
  await session.finish();
  assert.ok(got.length > 2, `${got.length} chunks`);
  let next = 0;
  for (const [start, frames, characters] of got) {
    assert.equal(start, next, 'frames follow each other, none twice');
    assert.equal(characters, 2);
    next = start + frames;
  }
  assert.ok(next >= 590, `${next} frames for 600 points at the library's multiple of 30 fps`);
});

test('live: a low-latency session reads the velocity sent with each point; a bad one is named', { skip }, async () => {
  const qs = client();
  const n = 30, fps = 30, T = 300, live = herd(2, T, fps);
  const open = async () => {
    const got = [];
    const session = await qs.live({ animal: 'dog', fps, seed: 1, mode: 'low_latency', characters: [{ id: 'a' }, { id: 'b' }] },
      { onChunk: (chunk) => { got.push(chunk.frames); } });
    return { session, got };
  };
  const step = (velocity) => {
    const { session, got } = velocity.session;
    for (let at = 0; at < T; at += n) {
      const part = new Float32Array(2 * n * 3), v = new Float32Array(2 * n * 2);
      for (let c = 0; c < 2; c++) {
        part.set(live.subarray((c * T + at) * 3, (c * T + at + n) * 3), c * n * 3);
        for (let i = 0; i < n; i++) { // the points' own velocity: the simulator's
          const j = Math.min(at + i + 1, T - 1), k = j - 1, o = (c * T) * 3;
          v[(c * n + i) * 2] = (live[o + j * 3] - live[o + k * 3]) * fps * velocity.scale;
          v[(c * n + i) * 2 + 1] = (live[o + j * 3 + 2] - live[o + k * 3 + 2]) * fps;
        }
      }
      session.push(part, n, v);
    }
    return got;
  };
  const good = await open();
  const got = step({ session: good, scale: 1 });
  await good.session.finish();
  assert.ok(got.reduce((a, b) => a + b, 0) >= T - 2, `${got} frames for ${T} points`);
  const bad = await open(); // a velocity of 100,000 m/s: over the limit (5 m a point)
  step({ session: bad, scale: 1e5 });
  await assert.rejects(bad.session.finish(),
    (e) => e instanceof ServiceError && e.code === 1007 && /^velocity\[[01]\]$/.test(e.field) && /limit/.test(e.message));
});

test('bad input is an error naming the field, not a hang', { skip }, async () => {
  const qs = client();
  await assert.rejects(qs.synthesize({ animal: 'unicorn', characters: characters(points, C) }),
    (e) => e instanceof ServiceError && e.status === 404 && e.field === 'animal');
  const bad = points.slice(0, F * 3);
  bad[30] = NaN;
  const stream = qs.stream({ animal: 'horse', characters: [{ id: 'x', points: bad }] });
  await assert.rejects(stream.next(), (e) => e instanceof ServiceError && e.code === 1007 && e.field.startsWith('characters[0].points'));
});

const FIXTURE = process.env.QUADSYNTH_POSE_FIXTURE;
test('pose assembly equals synth_core FK: f32 within 0.01 mm, s48 within the encoding\'s error carried down the limb', {
  skip: skip || (FIXTURE ? false : 'QUADSYNTH_POSE_FIXTURE not set (tests/test_js_client.py writes it)'),
}, async (t) => {
  const { request, characters: ref } = JSON.parse(readFileSync(FIXTURE, 'utf8'));
  const qs = client();
  const skeleton = await qs.skeleton(request.animal);
  const J = skeleton.joints;
  for (const encoding of ['f32', 's48']) {
    // Each joint's rotation may be off by the encoding's worst angle, which moves the foot by at
    // most that angle times the joint's distance to it: the bound is that sum up the chain.
    const angle = (ENCODING_ERROR[encoding][0] * Math.PI) / 180;
    const motion = await qs.synthesize({ ...request, encoding });
    let worst = 0, hoof = 0, refHoof = 0, over = 0;
    motion.characters.forEach((ch, c) => {
      assert.equal(ch.scale, ref[c].scale);
      for (let f = 0; f < ch.frames; f++) {
        const { positions: P } = worldPose(skeleton, ch.root, f * 3, ch.rotations, f * J * 4, ch.scale);
        skeleton.footJoints.forEach((foot, k) => {
          const want = ref[c].feet[f][k];
          const err = Math.hypot(P[foot * 3] - want[0], P[foot * 3 + 1] - want[1], P[foot * 3 + 2] - want[2]);
          let lever = 0;
          for (let a = skeleton.parents[foot]; a >= 0; a = skeleton.parents[a]) {
            lever += Math.hypot(P[foot * 3] - P[a * 3], P[foot * 3 + 1] - P[a * 3 + 1], P[foot * 3 + 2] - P[a * 3 + 2]);
          }
          if (err > angle * lever + 1e-5) over += 1; // 1e-5 m: float32 arithmetic (FK runs in float32)
          worst = Math.max(worst, err);
          if (ref[c].planted[f][k]) { hoof = Math.max(hoof, Math.abs(P[foot * 3 + 1])); refHoof = Math.max(refHoof, Math.abs(want[1])); }
        });
      }
    });
    t.diagnostic(`${encoding}: feet within ${(worst * 1000).toFixed(4)} mm of synth_core FK; highest planted hoof ${(hoof * 1000).toFixed(2)} mm (FK ${(refHoof * 1000).toFixed(2)} mm)`);
    assert.equal(over, 0, `${encoding}: ${over} foot-frames further from synth_core's FK than the encoding allows`);
  }
});

test('a herd spread over requests in flight is the motion one request gives', { skip }, async () => {
  const qs = client();
  const n = 7, pts = herd(n, 240);
  const whole = { animal: 'horse', fps: 60, seed: 11, encoding: 'f32', characters: characters(pts, n) };
  const one = await qs.synthesize(whole);
  const spread = await qs.synthesizeSpread(whole, { concurrency: 3 });
  assert.equal(spread.characters.length, n);
  spread.characters.forEach((ch, c) => {
    assert.equal(ch.id, one.characters[c].id);
    assert.equal(ch.scale, one.characters[c].scale);
    assert.deepEqual(ch.rotations, one.characters[c].rotations);
    assert.deepEqual(ch.root, one.characters[c].root);
  });
  assert.deepEqual(spread.warnings, one.warnings);
});

test('delta: every joint within 0.1 mm of f32 after FK (REST; WebSocket batch with levels of detail)', { skip }, async (t) => {
  const qs = client();
  const skeleton = await qs.skeleton('horse');
  const J = skeleton.joints;
  const exact = await qs.synthesize(request('f32'));
  /** Largest distance (m) between the joints of `rot` and of f32's character c, frame f. */
  const worstAt = (c, f, rot, at, fRef) => {
    const ch = exact.characters[c];
    const a = worldPose(skeleton, ch.root, fRef * 3, ch.rotations, fRef * J * 4, ch.scale).positions.slice();
    const b = worldPose(skeleton, ch.root, fRef * 3, rot, at, ch.scale).positions;
    let worst = 0;
    for (let j = 0; j < J; j++) worst = Math.max(worst, Math.hypot(a[j * 3] - b[j * 3], a[j * 3 + 1] - b[j * 3 + 1], a[j * 3 + 2] - b[j * 3 + 2]));
    return worst;
  };
  const rest = await qs.synthesize(request('delta'));
  let worst = 0;
  rest.characters.forEach((ch, c) => {
    assert.equal(ch.rotations.length, exact.characters[c].rotations.length);
    for (let f = 0; f < ch.frames; f++) worst = Math.max(worst, worstAt(c, f, ch.rotations, f * J * 4, f));
  });
  t.diagnostic(`delta REST: every joint within ${(worst * 1000).toFixed(4)} mm of f32`);
  assert.ok(worst <= 1e-4 + 1e-5, `delta REST: ${worst * 1000} mm`); // 1e-5 m: FK in float32
  // The stream: character 0 at full detail, 1 and 2 far (root and gait only), every 2nd frame.
  const lod = { ...request('delta'), lod: { detail: 'root_gait', frame_step: 2 } };
  lod.characters = lod.characters.map((ch, c) => (c === 0 ? { ...ch, detail: 'full' } : ch));
  let streamed = 0, frames = 0, header;
  for await (const chunk of qs.stream(lod, { chunkFrames: 40, onStart: (m) => { header = m; } })) {
    assert.equal(chunk.joints, J);
    for (let f = 0; f < chunk.frames; f++) {
      const fRef = (chunk.start + f) * 2;
      streamed = Math.max(streamed, worstAt(0, f, chunk.rotations, f * J * 4, fRef));
      for (let c = 1; c < C; c++) {
        const at = ((c * chunk.frames + f) * J) * 4;
        for (let j = 0; j < J; j++) assert.equal(chunk.rotations[at + j * 4 + 3], 1); // identity: not sent
        assert.equal(chunk.root[(c * chunk.frames + f) * 3], exact.characters[c].root[fRef * 3]);
      }
    }
    frames += chunk.frames;
  }
  assert.equal(header.frame_step, 2);
  assert.equal(frames, Math.ceil(exact.characters[0].frames / 2));
  assert.ok(streamed <= 1e-4 + 1e-5, `delta stream: ${streamed * 1000} mm`);
});
