// Pose assembly cost without a browser: world matrices of 1,000 animals of J joints per frame,
// as the viewer does them (worldPose, then composeMatrix per joint). Prints JSON: the median and
// best of 30 frames (after 10 to warm the JIT), milliseconds. Not a test.
//   node js/bench/pose.js [--animals 1000] [--joints 40]
import { parseArgs } from 'node:util';
import { Skeleton, worldMatrices } from '../src/index.js';

const { values } = parseArgs({ options: { animals: { type: 'string', default: '1000' }, joints: { type: 'string', default: '40' } } });
const C = Number(values.animals), J = Number(values.joints);
// A horse-like tree: a spine, four legs, a neck and a tail hanging off it.
const parents = [-1, ...Array.from({ length: J - 1 }, (_, j) => (j % 6 === 0 ? Math.max(0, j - 5) : j))];
const skeleton = new Skeleton({ joint_names: parents.map((_, j) => `j${j}`), parents,
  offsets: parents.map((_, j) => [0.01 * (j % 3), -0.2, 0.1]) });
const root = new Float32Array(C * 3).map((_, i) => i * 0.01);
const rotations = new Float32Array(C * J * 4);
for (let i = 0; i < C * J; i++) { const a = (i % 17) * 0.05; rotations[i * 4] = Math.sin(a); rotations[i * 4 + 3] = Math.cos(a); }
const out = new Float32Array(J * 16), scratch = { positions: new Float32Array(J * 3), rotations: new Float32Array(J * 4) };
const times = [];
for (let rep = 0; rep < 40; rep++) {
  const t0 = performance.now();
  for (let c = 0; c < C; c++) worldMatrices(skeleton, root, c * 3, rotations, c * J * 4, 1.05, out, scratch);
  if (rep >= 10) times.push(performance.now() - t0);
}
times.sort((a, b) => a - b);
console.log(JSON.stringify({ animals: C, joints: J, median_ms: +times[15].toFixed(2), best_ms: +times[0].toFixed(2) }));
