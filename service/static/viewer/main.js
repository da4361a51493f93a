// The herd viewer: a herd simulated in the page, its points streamed live to /v1/stream, the
// poses that come back drawn with three.js. URL parameters: ?animal=horse&herd=200&auto=1, and
// terrain=hills: the herd walks on rolling hills (a height field sent as the session's `ground`).
import * as THREE from 'three';
import { OrbitControls, GLTFLoader } from 'three';
import { QuadSynthClient, GAITS, blob, worldPose } from 'quadsynth-client';
import { Player } from './player.js';
import { BoneHerd, SkinnedHerd, GAIT_COLOURS, restHeight } from './render.js';
import { hills, groundRequest, heightAt, terrainMesh } from './terrain.js';

const POINTS_FPS = 30;
const SKINNED_MAX = 64; // a skinned mesh is a draw call per animal: beyond this, instanced bones
const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
const client = new QuadSynthClient(location.origin);

// What the browser test reads (and a curious user in the console).
const stats = window.quadsynthViewer = {
  firstChunkMs: null, // ms since the page's navigation began (performance.now()'s origin)
  firstDrawMs: null, chunks: 0, frames: 0, animals: 0,
  renderFps: 0, frameMs: 0, frameMsP95: 0, latencyS: 0, aheadS: 0, stalls: 0, stalledS: 0,
  pointsSent: 0, reconnects: 0, drawn: 0, mode: '', errors: [], arrivals: [],
};

/** Software GL (no GPU: SwiftShader, llvmpipe) pays for every multisample and pixel with CPU the
 * stream needs too: no antialiasing and one pixel per CSS pixel there. */
function softwareGl() {
  const gl = document.createElement('canvas').getContext('webgl2');
  const info = gl?.getExtension('WEBGL_debug_renderer_info');
  const name = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : '';
  gl?.getExtension('WEBGL_lose_context')?.loseContext();
  return /swiftshader|llvmpipe|software/i.test(name);
}
const software = softwareGl();
const renderer = new THREE.WebGLRenderer({ canvas: $('view'), antialias: !software, preserveDrawingBuffer: true });
renderer.setPixelRatio(software ? 1 : Math.min(devicePixelRatio, 2));
const scene = new THREE.Scene();
scene.background = new THREE.Color('#cfd8dc');
scene.add(new THREE.HemisphereLight('#ffffff', '#6d6552', 2.2));
const sun = new THREE.DirectionalLight('#ffffff', 1.6);
sun.position.set(30, 60, 20);
scene.add(sun);
scene.fog = new THREE.Fog('#cfd8dc', 250, 900);
// The ground grid as a texture on the ground plane (5 m cells): lines drawn as triangles, with
// mipmaps, so it shows under software GL too (its GL lines did not) and does not shimmer afar.
function gridTexture(repeat = 4000 / 5) {
  const canvas = document.createElement('canvas');
  canvas.width = canvas.height = 256;
  const g = canvas.getContext('2d');
  g.fillStyle = '#b7c4a4';
  g.fillRect(0, 0, 256, 256);
  g.fillStyle = '#7d8d6b'; // lines 4 cm wide
  g.fillRect(0, 0, 256, 2);
  g.fillRect(0, 0, 2, 256);
  const texture = new THREE.CanvasTexture(canvas);
  texture.colorSpace = THREE.SRGBColorSpace;
  texture.wrapS = texture.wrapT = THREE.RepeatWrapping;
  texture.repeat.set(repeat, repeat);
  texture.anisotropy = 8;
  return texture;
}
const flatGround = new THREE.Mesh(new THREE.PlaneGeometry(4000, 4000).rotateX(-Math.PI / 2),
  new THREE.MeshLambertMaterial({ map: gridTexture() }));
scene.add(flatGround);
let ground = flatGround; // the terrain's mesh instead when there is one
const camera = new THREE.PerspectiveCamera(45, 1, 0.5, 3000);
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

let last = performance.now(), fpsCount = 0, fpsSince = last, shown = -1, dirty = true;
let run = null; // the herd being streamed: {worker, player, herd, ...}

/** The animal's skinned mesh, when the service has one: the library detail's `mesh_url` (null:
 * none); a service older than that field is asked at the route the mesh API defines. */
async function meshFor(skeleton) {
  const url = 'mesh_url' in skeleton.detail ? skeleton.detail.mesh_url
    : `/v1/libraries/${encodeURIComponent(skeleton.animal)}/mesh.glb`;
  if (!url) return null;
  const response = await fetch(url);
  if (response.status !== 200) return null; // no mesh on this service: instanced bones instead
  return new GLTFLoader().parseAsync(await response.arrayBuffer(), '');
}

async function start(animal, count) {
  stop();
  $('error').hidden = true;
  const [skeleton, limits] = await Promise.all([client.skeleton(animal), client.limits()]);
  const height = restHeight(skeleton);
  let herd = null;
  if (count <= SKINNED_MAX) {
    try {
      const gltf = await meshFor(skeleton);
      if (gltf) herd = new SkinnedHerd(scene, skeleton, count, gltf);
    } catch (error) {
      console.warn('the animal\'s mesh is not usable here; drawing instanced bones:', error);
    }
  }
  herd ??= new BoneHerd(scene, skeleton, count);
  stats.mode = herd instanceof SkinnedHerd ? 'skinned mesh' : 'instanced bones';
  // The herd's loop is centred on the origin (herd-sim.js): the hills cover it and the herd.
  const field = params.get('terrain') === 'hills'
    ? hills(Math.max(30, Math.ceil(Math.sqrt(count)) * 1.6 * height * 2) + Math.sqrt(count) * 1.6 * height + 20, height) : null;
  showTerrain(field);
  stats.animals = count;
  stats.openMs = performance.now();
  const worker = new Worker('/viewer/static/stream-worker.js', { type: 'module' });
  const me = { worker, herd, skeleton, height, field, player: null, scales: null, count, sent: 0, perPoint: 1 };
  run = me;
  worker.onmessage = (ev) => {
    if (run !== me) return;
    const m = ev.data;
    if (m.type === 'header') {
      stats.startMs = performance.now();
      me.player = new Player(m.header.fps);
      stats.streamFps = m.header.fps;
      me.scales = Float32Array.from(m.header.characters, (ch) => ch.scale);
      me.perPoint = m.perPoint;
      const size = Math.sqrt(count) * 1.6 * height;
      const [x, z] = m.centre;
      const y = field ? heightAt(field, x, z) : 0;
      controls.target.set(x, y + height * 0.5, z);
      camera.position.set(x + size + 6 * height, y + size * 0.7 + 3 * height, z - size - 6 * height);
      dirty = true;
    } else if (m.type === 'chunk') {
      if (stats.firstChunkMs === null) stats.firstChunkMs = performance.now();
      if (stats.arrivals.length < 12) stats.arrivals.push([Math.round(performance.now()), m.chunk.start, m.chunk.frames]);
      me.player.add(m.chunk);
      stats.chunks += 1;
      stats.frames = me.player.end;
    } else if (m.type === 'sent') {
      me.sent = m.sent;
      stats.pointsSent = m.sent;
    } else if (m.type === 'reconnect') {
      stats.reconnects += 1;
    } else if (m.type === 'error') {
      showError(m.message);
    }
  };
  worker.onerror = (ev) => showError(ev.message ?? 'the stream worker failed');
  worker.postMessage({ type: 'start', origin: location.origin, animal, count, gaits: skeleton.detail.gaits,
    spacing: 1.6 * height, pointsFps: POINTS_FPS, maxBodyBytes: limits.max_body_bytes,
    ground: field ? groundRequest(field, blob) : null });
}

/** Draw `field` (null: the flat grid) as the ground. */
function showTerrain(field) {
  if (ground !== flatGround) { scene.remove(ground); ground.geometry.dispose(); ground.material.map.dispose(); ground.material.dispose(); }
  ground = field ? terrainMesh(field, gridTexture(1)) : flatGround;
  if (field) scene.add(ground);
  flatGround.visible = !field;
  stats.terrain = field ? { nx: field.nx, nz: field.nz, spacing: field.spacing, vertices: ground.geometry.attributes.position.count,
    low: field.heights.reduce((a, b) => Math.min(a, b)), high: field.heights.reduce((a, b) => Math.max(a, b)) } : null;
  dirty = true;
}

function stop() {
  if (!run) return;
  shown = -1;
  run.worker.postMessage({ type: 'stop' });
  const { worker } = run;
  setTimeout(() => worker.terminate(), 1000); // after its cancel went out
  run.herd.dispose();
  run = null;
  Object.assign(stats, { firstChunkMs: null, firstDrawMs: null, chunks: 0, frames: 0, stalls: 0, stalledS: 0, drawn: 0 });
}

/** Follow the herd: move the camera with the animals' mean root, keeping the user's view (up and
 * down too over a terrain). */
function follow(frame, me, dt) {
  let x = 0, y = 0, z = 0;
  for (let c = 0; c < me.count; c++) {
    x += frame.root[frame.rootAt(c)]; y += frame.root[frame.rootAt(c) + 1]; z += frame.root[frame.rootAt(c) + 2];
  }
  x /= me.count; y /= me.count; z /= me.count;
  const k = 1 - Math.exp(-2 * dt); // the same catch-up per second at any draw rate
  const dx = (x - controls.target.x) * k, dz = (z - controls.target.z) * k;
  const dy = me.field ? (y - 0.5 * me.height - controls.target.y) * k : 0;
  controls.target.x += dx; controls.target.y += dy; controls.target.z += dz;
  camera.position.x += dx; camera.position.y += dy; camera.position.z += dz;
}

/** The frame shown, over the terrain (the browser test's "the herd walks on it" check): per animal,
 * its lowest foot's height over the ground under it, and the ground's height under its root. */
stats.terrainFeet = () => {
  const me = run, frame = me?.shown;
  if (!me?.field || !frame) return null;
  const lowest = [], under = [];
  for (let c = 0; c < me.count; c++) {
    const { positions: p } = worldPose(me.skeleton, frame.root, frame.rootAt(c), frame.rotations, frame.rotAt(c), me.scales[c]);
    lowest.push(Math.min(...me.skeleton.footJoints.map((j) => p[j * 3 + 1] - heightAt(me.field, p[j * 3], p[j * 3 + 2]))));
    under.push(heightAt(me.field, frame.root[frame.rootAt(c)], frame.root[frame.rootAt(c) + 2]));
  }
  return { frame: frame.frame, lowestFootOverGround: lowest, groundUnderRoot: under };
};

const frameTimes = [];

controls.addEventListener('change', () => { dirty = true; });
addEventListener('resize', () => { dirty = true; });
/** One display tick: advance the play-out clock; pose and draw only when the frame shown or the
 * view changed (poses come at 30 fps, displays tick at 60 or more: drawing the same pose twice
 * costs the GPU and, with software GL, the CPU the stream needs). */
function tick(now) {
  const dt = (now - last) / 1000; // a slow draw skips frames: playback keeps real time
  last = now;
  const me = run;
  if (me?.player) {
    const t0 = performance.now();
    const frame = me.player.advance(dt);
    if (frame && frame.frame !== shown) {
      shown = frame.frame;
      me.shown = frame;
      me.herd.update(frame, me.scales, $('gaitColour').checked);
      follow(frame, me, dt);
      stats.drawn += 1;
      dirty = true;
      frameTimes.push(performance.now() - t0);
      if (frameTimes.length > 120) frameTimes.shift();
    }
    stats.aheadS = me.player.ahead;
    stats.stalls = me.player.stalls;
    stats.stalledS = me.player.stalledSeconds;
    stats.latencyS = (me.sent - me.player.playhead / me.perPoint) / POINTS_FPS;
  }
  controls.update();
  if (dirty) {
    renderer.render(scene, camera);
    dirty = false;
    fpsCount += 1;
    if (me?.player?.started && stats.firstDrawMs === null) stats.firstDrawMs = performance.now();
  }
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
    `drawn          ${f(s.renderFps)} frames/s (poses at ${run?.player?.fps ?? '-'} fps)`,
    `pose + upload  ${f(s.frameMs)} ms/frame (p95 ${f(s.frameMsP95)})`,
    `latency        ${f(s.latencyS)} s sim -> screen`,
    `buffered       ${f(s.aheadS)} s ahead`,
    `stalls         ${s.stalls} (${f(s.stalledS)} s)`,
    `chunks         ${s.chunks}, frames ${s.frames}`,
    `first pose     ${s.firstDrawMs === null ? '-' : f(s.firstDrawMs, 0)} ms after load`,
  ].join('\n');
}

/** Pixels that differ between the scene drawn without the herd and with it (the browser test's
 * "animals are drawn" check: an empty scene is the ground and its grid only). */
stats.herdPixels = () => {
  const gl = renderer.getContext(), w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
  const read = () => { const px = new Uint8Array(w * h * 4); gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px); return px; };
  const meshes = scene.children.filter((o) => o !== ground && o !== flatGround && !o.isLight);
  meshes.forEach((o) => { o.visible = false; });
  renderer.render(scene, camera);
  const empty = read();
  meshes.forEach((o) => { o.visible = true; });
  renderer.render(scene, camera);
  const full = read();
  let differ = 0;
  for (let i = 0; i < full.length; i += 4) {
    if (Math.abs(full[i] - empty[i]) + Math.abs(full[i + 1] - empty[i + 1]) + Math.abs(full[i + 2] - empty[i + 2]) > 24) differ += 1;
  }
  return { differ, total: w * h };
};

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
  if (params.get('auto') === '0') return;
  await start($('animal').value, Number($('herd').value));
}

addEventListener('unhandledrejection', (ev) => showError(ev.reason));
main().catch(showError);
