// The herd viewer: a herd simulated in the page, its points streamed live to /v1/stream, the
// poses that come back drawn with three.js. URL parameters: ?animal=horse&herd=200&auto=1.
import * as THREE from 'three';
import { OrbitControls, GLTFLoader } from 'three';
import { QuadSynthClient, GAITS } from 'quadsynth-client';
import { HerdSim } from './herd-sim.js';
import { Player } from './player.js';
import { BoneHerd, SkinnedHerd, GAIT_COLOURS, restHeight } from './render.js';

const POINTS_FPS = 30;
const SKINNED_MAX = 64; // a skinned mesh is a draw call per animal: beyond this, instanced bones
const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
const client = new QuadSynthClient(location.origin);

// What the browser test reads (and a curious user in the console).
const stats = window.quadsynthViewer = {
  loadMs: performance.now(), firstChunkMs: null, firstDrawMs: null, chunks: 0, frames: 0, animals: 0,
  renderFps: 0, frameMs: 0, frameMsP95: 0, latencyS: 0, aheadS: 0, stalls: 0, stalledS: 0,
  pointsSent: 0, reconnects: 0, drawn: 0, mode: '', errors: [],
};

const renderer = new THREE.WebGLRenderer({ canvas: $('view'), antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(Math.min(devicePixelRatio, 2));
const scene = new THREE.Scene();
scene.background = new THREE.Color('#cfd8dc');
scene.add(new THREE.HemisphereLight('#ffffff', '#6d6552', 2.2));
const sun = new THREE.DirectionalLight('#ffffff', 1.6);
sun.position.set(30, 60, 20);
scene.add(sun);
const ground = new THREE.Mesh(new THREE.PlaneGeometry(4000, 4000).rotateX(-Math.PI / 2),
  new THREE.MeshLambertMaterial({ color: '#b7c4a4' }));
ground.position.y = -0.002;
scene.add(ground);
const grid = new THREE.GridHelper(2000, 1000, '#7a8a6a', '#9aaa8a');
scene.add(grid);
const camera = new THREE.PerspectiveCamera(45, 1, 0.1, 5000);
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = true;

function resize() {
  const w = innerWidth, h = innerHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
addEventListener('resize', resize);
resize();

function showError(error) {
  stats.errors.push(String(error));
  $('error').hidden = false;
  $('error').textContent = String(error);
}

let run = null; // the herd being streamed: {session, sim, player, herd, ...}

async function meshFor(animal) {
  const response = await fetch(`/v1/libraries/${encodeURIComponent(animal)}/mesh.glb`);
  if (response.status !== 200) return null; // no mesh on this service: instanced bones instead
  return new GLTFLoader().parseAsync(await response.arrayBuffer(), '');
}

async function start(animal, count) {
  stop();
  $('error').hidden = true;
  const [skeleton, limits] = await Promise.all([client.skeleton(animal), client.limits()]);
  const height = restHeight(skeleton);
  const sim = new HerdSim(count, skeleton.detail.gaits, { fps: POINTS_FPS, spacing: 1.6 * height, seed: 1 });
  const gltf = count <= SKINNED_MAX ? await meshFor(animal).catch(() => null) : null;
  const herd = gltf ? new SkinnedHerd(scene, skeleton, count, gltf) : new BoneHerd(scene, skeleton, count);
  stats.mode = gltf ? 'skinned mesh' : 'instanced bones';
  const ids = Array.from({ length: count }, (_, c) => ({ id: `${animal}-${c}` }));
  const me = { sim, herd, player: null, scales: new Float32Array(count).fill(1), skeleton, sent: 0, began: performance.now() };
  run = me;
  const session = await client.live({ animal, fps: POINTS_FPS, seed: 1, encoding: 's48', characters: ids }, {
    onChunk: (chunk) => {
      if (run !== me) return;
      if (stats.firstChunkMs === null) stats.firstChunkMs = performance.now();
      me.player.add(chunk);
      stats.chunks += 1;
      stats.frames = me.player.end;
    },
    onReconnect: () => { stats.reconnects += 1; },
  });
  me.session = session;
  me.player = new Player(session.header.fps);
  me.scales = Float32Array.from(session.header.characters, (ch) => ch.scale);
  me.perPoint = session.header.fps / POINTS_FPS; // output frames per point
  // Points per message within the body limit; the first burst simulates ahead by the stream's
  // latency (plus a second), so the first poses come at once instead of after ~4 s of points.
  me.maxPoints = Math.max(1, Math.floor(limits.max_body_bytes / 2 / (count * 12)));
  me.lead = Math.ceil(session.header.latency_frames / me.perPoint) + POINTS_FPS;
  feed(me, me.lead);
  me.timer = setInterval(() => {
    const due = me.lead + Math.floor(((performance.now() - me.began) / 1000) * POINTS_FPS);
    if (run === me && due > me.sent) feed(me, due - me.sent);
  }, 100);
  stats.animals = count;
  const size = Math.sqrt(count) * 1.6 * height;
  const centre = centroid(me.sim);
  controls.target.set(centre[0], height * 0.5, centre[1]);
  camera.position.set(centre[0] + size + 6 * height, size * 0.7 + 3 * height, centre[1] - size - 6 * height);
}

function feed(me, n) {
  while (n > 0) {
    const k = Math.min(n, me.maxPoints);
    me.session.push(me.sim.step(k), k);
    me.sent += k; n -= k;
  }
  stats.pointsSent = me.sent;
}

function stop() {
  if (!run) return;
  clearInterval(run.timer);
  run.session?.close();
  run.herd.dispose();
  run = null;
  Object.assign(stats, { firstChunkMs: null, firstDrawMs: null, chunks: 0, frames: 0, stalls: 0, stalledS: 0, drawn: 0 });
}

function centroid(sim) {
  let x = 0, z = 0;
  for (let c = 0; c < sim.C; c++) { x += sim.pos[c * 2]; z += sim.pos[c * 2 + 1]; }
  return [x / sim.C, z / sim.C];
}

/** Follow the herd: move the camera with the animals' mean root, keeping the user's view. */
function follow(frame, count) {
  let x = 0, z = 0;
  for (let c = 0; c < count; c++) { x += frame.root[frame.rootAt(c)]; z += frame.root[frame.rootAt(c) + 2]; }
  x /= count; z /= count;
  const dx = (x - controls.target.x) * 0.05, dz = (z - controls.target.z) * 0.05;
  controls.target.x += dx; controls.target.z += dz;
  camera.position.x += dx; camera.position.z += dz;
}

const frameTimes = [];
let last = performance.now(), fpsCount = 0, fpsSince = last;
function tick(now) {
  const dt = Math.min((now - last) / 1000, 0.25);
  last = now;
  const me = run;
  if (me?.player) {
    const t0 = performance.now();
    const frame = me.player.advance(dt);
    if (frame) {
      me.herd.update(frame, me.scales, $('gaitColour').checked);
      follow(frame, me.sim.C);
      stats.drawn += 1;
      frameTimes.push(performance.now() - t0);
      if (frameTimes.length > 120) frameTimes.shift();
    }
    stats.aheadS = me.player.ahead;
    stats.stalls = me.player.stalls;
    stats.stalledS = me.player.stalledSeconds;
    stats.latencyS = (me.sent - me.player.playhead / me.perPoint) / POINTS_FPS;
  }
  controls.update();
  renderer.render(scene, camera);
  if (me?.player?.started && stats.firstDrawMs === null) stats.firstDrawMs = performance.now();
  fpsCount += 1;
  if (now - fpsSince >= 1000) {
    stats.renderFps = (fpsCount * 1000) / (now - fpsSince);
    fpsCount = 0; fpsSince = now;
    const sorted = [...frameTimes].sort((a, b) => a - b);
    stats.frameMs = sorted.length ? sorted.reduce((a, b) => a + b, 0) / sorted.length : 0;
    stats.frameMsP95 = sorted.length ? sorted[Math.floor(0.95 * (sorted.length - 1))] : 0;
    showStats();
  }
  requestAnimationFrame(tick);
}

function showStats() {
  const s = stats, f = (x, d = 1) => (x === null ? '-' : x.toFixed(d));
  $('stats').textContent = [
    `animals        ${s.animals} (${s.mode})`,
    `render         ${f(s.renderFps)} frames/s`,
    `pose + upload  ${f(s.frameMs)} ms/frame (p95 ${f(s.frameMsP95)})`,
    `latency        ${f(s.latencyS)} s sim -> screen`,
    `buffered       ${f(s.aheadS)} s ahead`,
    `stalls         ${s.stalls} (${f(s.stalledS)} s)`,
    `chunks         ${s.chunks}, frames ${s.frames}`,
    `first chunk    ${s.firstChunkMs === null ? '-' : f(s.firstChunkMs - s.loadMs, 0)} ms`,
  ].join('\n');
}

async function main() {
  const { libraries } = await client.libraries();
  for (const lib of libraries) $('animal').add(new Option(`${lib.animal} (${lib.joints} joints)`, lib.animal));
  $('animal').value = params.get('animal') ?? (libraries.some((l) => l.animal === 'horse') ? 'horse' : libraries[0].animal);
  $('herd').value = params.get('herd') ?? $('herd').value;
  $('legend').innerHTML = GAITS.map((g, i) => `<span style="background:${GAIT_COLOURS[i]}">${g}</span>`).join('');
  $('controls').addEventListener('submit', (ev) => {
    ev.preventDefault();
    start($('animal').value, Math.max(1, Math.min(10000, Number($('herd').value) || 1))).catch(showError);
  });
  requestAnimationFrame(tick);
  await start($('animal').value, Number($('herd').value));
}

addEventListener('unhandledrejection', (ev) => showError(ev.reason));
main().catch(showError);
