// A REST answer cut short (a replica that died mid-answer) is asked for again, a bounded number
// of times, and counted: against a local server that cuts its first answers, no service needed.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import http from 'node:http';
import { encode } from '@msgpack/msgpack';
import { QuadSynthClient, ServiceError } from '../src/index.js';

const ANSWER = encode({ animal: 'horse', skeleton_id: 'horse-x', fps: 60, encoding: 's48', resample_rate: 1,
  characters: [], skipped: [], warnings: [] });

/** A server whose first `cut` answers send half their bytes and close; then the whole answer. */
async function cutting(cut) {
  let seen = 0;
  const server = http.createServer((req, res) => {
    req.resume();
    req.on('end', () => {
      seen++;
      res.writeHead(200, { 'content-type': 'application/vnd.msgpack', 'content-length': ANSWER.length });
      if (seen <= cut) {
        res.write(ANSWER.subarray(0, ANSWER.length >> 1));
        res.socket.destroy();
      } else res.end(ANSWER);
    });
  });
  await new Promise((resolve) => { server.listen(0, '127.0.0.1', resolve); });
  return { server, url: `http://127.0.0.1:${server.address().port}`, seen: () => seen };
}

const request = { animal: 'horse', characters: [{ id: 'a', points: new Float32Array(6) }] };

test('an answer cut short is asked for again and the retry counted', async () => {
  const s = await cutting(2);
  try {
    const qs = new QuadSynthClient(s.url, { retryDelayMs: 1 });
    const motion = await qs.synthesize(request);
    assert.equal(motion.animal, 'horse');
    assert.equal(qs.restRetriesMade, 2);
    assert.equal(s.seen(), 3);
  } finally { s.server.close(); }
});

test('the retries are bounded: past them the error reaches the caller', async () => {
  const s = await cutting(10);
  try {
    const qs = new QuadSynthClient(s.url, { retryDelayMs: 1, restRetries: 1 });
    await assert.rejects(qs.synthesize(request), (e) => !(e instanceof ServiceError));
    assert.equal(s.seen(), 2);
    assert.equal(qs.restRetriesMade, 1);
  } finally { s.server.close(); }
});
