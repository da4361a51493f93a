// Pose assembly: a frame's local rotations -> every joint's world position, rotation and matrix.
//
// The convention (the same as synth_core.motion.skeleton.forward_kinematics, docs/play-the-stream.md):
//   joint 0 (the pelvis):  position = root (the stream's `root`, already in world metres)
//                          rotation = q[0]
//   joint j > 0, parent p: position = position[p] + rotate(rotation[p], offsets[j] * scale)
//                          rotation = rotation[p] * q[j]
// `scale` is the character's (the `start` message's / REST answer's `scale`); it multiplies the
// rest offsets, never the root. World matrices are T(position) R(rotation) S(scale), column-major
// (WebGL's and three.js' layout).

/** What a client needs of `GET /v1/libraries/{animal}`, as flat typed arrays. */
export class Skeleton {
  constructor(detail) {
    const { joint_names: names, parents, offsets } = detail;
    if (!Array.isArray(names) || parents.length !== names.length || offsets.length !== names.length) {
      throw new Error('a library detail needs joint_names, parents and offsets of one length');
    }
    this.animal = detail.animal;
    this.names = names;
    this.joints = names.length;
    this.parents = Int32Array.from(parents);
    this.offsets = Float32Array.from(offsets.flat());
    this.endSites = Uint8Array.from(detail.end_sites ?? names.map(() => false), Boolean);
    this.feet = detail.feet ?? {}; // {LF: jointName, ...}
    this.footJoints = ['LF', 'RF', 'LH', 'RH'].map((f) => names.indexOf(this.feet[f]));
    parents.forEach((p, j) => {
      if (j === 0 ? p !== -1 : !(p >= 0 && p < j)) throw new Error(`parents must be topological (parents[${j}] = ${p})`);
    });
  }
}

/** World positions (J x 3) and rotations (J x 4, xyzw) of one character at one frame.
 * `root` and `rotations` are typed arrays; `rootAt`/`rotAt` the index of this frame's first item. */
export function worldPose(skeleton, root, rootAt, rotations, rotAt, scale, positions, worldRotations) {
  const J = skeleton.joints, par = skeleton.parents, off = skeleton.offsets;
  const P = positions ?? new Float32Array(J * 3);
  const Q = worldRotations ?? new Float32Array(J * 4);
  P[0] = root[rootAt]; P[1] = root[rootAt + 1]; P[2] = root[rootAt + 2];
  Q[0] = rotations[rotAt]; Q[1] = rotations[rotAt + 1]; Q[2] = rotations[rotAt + 2]; Q[3] = rotations[rotAt + 3];
  for (let j = 1; j < J; j++) {
    const p4 = par[j] * 4, p3 = par[j] * 3, j4 = j * 4, j3 = j * 3, r = rotAt + j4;
    const qx = Q[p4], qy = Q[p4 + 1], qz = Q[p4 + 2], qw = Q[p4 + 3];
    // rotate(parent rotation, offset * scale): v + 2w (u x v) + 2 u x (u x v)
    const vx = off[j3] * scale, vy = off[j3 + 1] * scale, vz = off[j3 + 2] * scale;
    const tx = 2 * (qy * vz - qz * vy), ty = 2 * (qz * vx - qx * vz), tz = 2 * (qx * vy - qy * vx);
    P[j3] = P[p3] + vx + qw * tx + (qy * tz - qz * ty);
    P[j3 + 1] = P[p3 + 1] + vy + qw * ty + (qz * tx - qx * tz);
    P[j3 + 2] = P[p3 + 2] + vz + qw * tz + (qx * ty - qy * tx);
    // parent rotation * local rotation (Hamilton product, xyzw)
    const bx = rotations[r], by = rotations[r + 1], bz = rotations[r + 2], bw = rotations[r + 3];
    Q[j4] = qw * bx + qx * bw + qy * bz - qz * by;
    Q[j4 + 1] = qw * by - qx * bz + qy * bw + qz * bx;
    Q[j4 + 2] = qw * bz + qx * by - qy * bx + qz * bw;
    Q[j4 + 3] = qw * bw - qx * bx - qy * by - qz * bz;
  }
  return { positions: P, rotations: Q };
}

/** Column-major 4x4 T(p) R(q) S(s) into `out` at `at` (16 floats). */
export function composeMatrix(out, at, px, py, pz, x, y, z, w, s) {
  const x2 = x + x, y2 = y + y, z2 = z + z;
  const xx = x * x2, xy = x * y2, xz = x * z2, yy = y * y2, yz = y * z2, zz = z * z2;
  const wx = w * x2, wy = w * y2, wz = w * z2;
  out[at] = (1 - (yy + zz)) * s; out[at + 1] = (xy + wz) * s; out[at + 2] = (xz - wy) * s; out[at + 3] = 0;
  out[at + 4] = (xy - wz) * s; out[at + 5] = (1 - (xx + zz)) * s; out[at + 6] = (yz + wx) * s; out[at + 7] = 0;
  out[at + 8] = (xz + wy) * s; out[at + 9] = (yz - wx) * s; out[at + 10] = (1 - (xx + yy)) * s; out[at + 11] = 0;
  out[at + 12] = px; out[at + 13] = py; out[at + 14] = pz; out[at + 15] = 1;
}

/** Every joint's world matrix T(position) R(rotation) S(scale), J x 16 floats, column-major. */
export function worldMatrices(skeleton, root, rootAt, rotations, rotAt, scale, out, scratch) {
  const J = skeleton.joints;
  const { positions: P, rotations: Q } = worldPose(skeleton, root, rootAt, rotations, rotAt, scale,
    scratch?.positions, scratch?.rotations);
  const M = out ?? new Float32Array(J * 16);
  for (let j = 0; j < J; j++) {
    composeMatrix(M, j * 16, P[j * 3], P[j * 3 + 1], P[j * 3 + 2], Q[j * 4], Q[j * 4 + 1], Q[j * 4 + 2], Q[j * 4 + 3], scale);
  }
  return M;
}

/** World positions of the four feet (LF, RF, LH, RH) x 3 of a chunk's character `c` at frame `f`. */
export function feetAt(skeleton, chunk, c, f, scale) {
  const J = skeleton.joints, n = chunk.frames;
  const { positions } = worldPose(skeleton, chunk.root, (c * n + f) * 3, chunk.rotations, (c * n + f) * J * 4, scale);
  return skeleton.footJoints.map((j) => [positions[j * 3], positions[j * 3 + 1], positions[j * 3 + 2]]);
}
