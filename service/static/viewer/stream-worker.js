// The live stream, off the page's main thread: the herd simulation, its points out, the chunks
// in (msgpack and s48 decoding), acks. Drawing a big herd with software GL can hold the main
// thread for seconds; here the stream keeps its pace regardless, and the page takes the decoded
// frames when it can. (Imports by URL: import maps do not reach workers.)
import { encode, decode } from '/vendor/msgpack/msgpack.min.js';
import { QuadSynthClient } from '/viewer/client/client.js';
import { HerdSim } from '/viewer/static/herd-sim.js';

let run = null;

async function start({ origin, animal, count, gaits, spacing, pointsFps, maxBodyBytes, ground }) {
  const client = new QuadSynthClient(origin, { codec: { encode, decode } });
  const sim = new HerdSim(count, gaits, { fps: pointsFps, spacing, seed: 1 });
  const me = { sim, sent: 0 };
  run = me;
  const characters = Array.from({ length: count }, (_, c) => ({ id: `${animal}-${c}` }));
  // With a ground (the page's height field) the points' y is not read: the service stands the
  // herd on the terrain.
  const request = { animal, fps: pointsFps, seed: 1, encoding: 's48', characters, ...(ground ? { ground } : {}) };
  const session = await client.live(request, {
    onChunk: (chunk) => {
      if (run !== me) return;
      // Arrays of their own to hand over (moved, not copied): root, gait and contacts may be
      // views into the one message buffer.
      const own = (a) => (a.byteOffset === 0 && a.byteLength === a.buffer.byteLength ? a : a.slice());
      const out = { ...chunk, root: own(chunk.root), rotations: own(chunk.rotations), gait: own(chunk.gait), contacts: own(chunk.contacts) };
      postMessage({ type: 'chunk', chunk: out }, [out.root.buffer, out.rotations.buffer, out.gait.buffer, out.contacts.buffer]);
    },
    onReconnect: ({ code }) => postMessage({ type: 'reconnect', code }),
  });
  me.session = session;
  session.done.catch((error) => { if (run === me) postMessage({ type: 'error', message: String(error) }); });
  const perPoint = session.header.fps / pointsFps;
  // The first burst simulates ahead by the stream's latency (plus a second), so the first poses
  // come at once instead of after ~4 s of points; then points go out in real time.
  const lead = Math.ceil(session.header.latency_frames / perPoint) + pointsFps;
  const maxPoints = Math.max(1, Math.floor(maxBodyBytes / 2 / (count * 12))); // a message within the body limit
  const feed = (n) => {
    while (n > 0) {
      const k = Math.min(n, maxPoints);
      session.push(sim.step(k), k);
      me.sent += k; n -= k;
    }
    postMessage({ type: 'sent', sent: me.sent });
  };
  const began = performance.now();
  postMessage({ type: 'header', header: session.header, perPoint, lead, centre: centroid(sim) });
  feed(lead);
  me.timer = setInterval(() => {
    const due = lead + Math.floor(((performance.now() - began) / 1000) * pointsFps);
    if (run === me && due > me.sent) feed(due - me.sent);
  }, 100);
}

function centroid(sim) {
  let x = 0, z = 0;
  for (let c = 0; c < sim.C; c++) { x += sim.pos[c * 2]; z += sim.pos[c * 2 + 1]; }
  return [x / sim.C, z / sim.C];
}

function stop() {
  if (!run) return;
  clearInterval(run.timer);
  run.session?.close();
  run = null;
}

onmessage = (ev) => {
  const m = ev.data;
  if (m.type === 'start') {
    stop();
    start(m).catch((error) => postMessage({ type: 'error', message: String(error) }));
  } else if (m.type === 'stop') {
    stop();
  }
};
