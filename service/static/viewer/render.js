// Drawing a herd with three.js, two ways:
//  - BoneHerd: one InstancedMesh per bone (a tapered 5-sided prism from a joint's parent to it),
//    instance c = animal c, so a herd of any size is ~J draw calls; matrices from pose assembly.
//  - SkinnedHerd: the library's skinned mesh (GET /v1/libraries/{animal}/mesh.glb) cloned per
//    animal, its bones' world matrices set from pose assembly; one draw call per animal, so for
//    small herds only (main.js picks).
import * as THREE from 'three';
import { SkeletonUtils } from 'three';
import { worldPose, composeMatrix } from 'quadsynth-client';

export const GAIT_COLOURS = ['#8d8d8d', '#3f7fd9', '#2f9e58', '#e08a1e', '#d0342c'];
const PLAIN = new THREE.Color('#8a5a3b');

/** Bone radius as a share of the animal's standing height, from the joint's name (the built-in
 * rigs' names; other rigs get the limb default). */
function radiusShare(name) {
  if (/spine|chest|torso|back/i.test(name)) return 0.19;
  if (/neck/i.test(name)) return 0.09;
  if (/head/i.test(name)) return 0.07;
  if (/scapula|femur|shoulder|upleg|thigh/i.test(name)) return 0.09;
  if (/humerus|tibia|arm|leg/i.test(name)) return 0.06;
  if (/tail/i.test(name)) return 0.025;
  return 0.035;
}

/** Standing height: how far below the root the lowest joint is in the rest pose. */
export function restHeight(skeleton) {
  const J = skeleton.joints, root = new Float32Array(3), q = new Float32Array(J * 4);
  for (let j = 0; j < J; j++) q[j * 4 + 3] = 1;
  const { positions } = worldPose(skeleton, root, 0, q, 0, 1);
  let low = 0;
  for (let j = 0; j < J; j++) low = Math.min(low, positions[j * 3 + 1]);
  return -low || 1;
}

export class BoneHerd {
  constructor(scene, skeleton, count) {
    this.skeleton = skeleton; this.count = count; this.scene = scene;
    const J = skeleton.joints, h = restHeight(skeleton);
    // Open four-sided prisms, 8 triangles a bone: a thousand horses are 312k triangles, which
    // software GL (headless Chromium, SwiftShader) can still draw.
    const geometry = new THREE.CylinderGeometry(0.8, 1, 1, 4, 1, true).rotateY(Math.PI / 4).translate(0, 0.5, 0);
    this.material = new THREE.MeshLambertMaterial({ color: '#ffffff', side: THREE.DoubleSide });
    this.bones = []; // {joint, parent, local (16), mesh}
    const up = new THREE.Vector3(0, 1, 0), m = new THREE.Matrix4(), q = new THREE.Quaternion();
    for (let j = 1; j < J; j++) {
      const o = new THREE.Vector3().fromArray(skeleton.offsets, j * 3), length = o.length();
      if (length < 1e-4) continue;
      const r = radiusShare(skeleton.names[j]) * h;
      q.setFromUnitVectors(up, o.clone().normalize());
      m.compose(new THREE.Vector3(), q, new THREE.Vector3(r, length, r)); // the bone in its parent's frame
      const mesh = new THREE.InstancedMesh(geometry, this.material, count);
      mesh.instanceMatrix.setUsage(THREE.DynamicDrawUsage);
      mesh.frustumCulled = false; // the herd moves; bounds would need recomputing every frame
      mesh.setColorAt(0, PLAIN);
      mesh.count = 0; // nothing drawn before the first pose (a thousand bones at the origin cost)
      scene.add(mesh);
      this.bones.push({ parent: skeleton.parents[j], local: Float32Array.from(m.elements), mesh });
    }
    this.P = new Float32Array(J * 3); this.Q = new Float32Array(J * 4); this.W = new Float32Array(J * 16);
    this.lastGait = new Int8Array(count).fill(-2);
  }

  /** Pose every animal: `frame` = {root, rootAt(c), rotations, rotAt(c), gait, gaitAt(c)}, scales per animal. */
  update(frame, scales, gaitColour) {
    const { skeleton, P, Q, W } = this, J = skeleton.joints;
    for (let c = 0; c < this.count; c++) {
      const s = scales[c];
      worldPose(skeleton, frame.root, frame.rootAt(c), frame.rotations, frame.rotAt(c), s, P, Q);
      for (let j = 0; j < J; j++) {
        composeMatrix(W, j * 16, P[j * 3], P[j * 3 + 1], P[j * 3 + 2], Q[j * 4], Q[j * 4 + 1], Q[j * 4 + 2], Q[j * 4 + 3], s);
      }
      for (const bone of this.bones) multiplyAffine(bone.mesh.instanceMatrix.array, c * 16, W, bone.parent * 16, bone.local);
      const gait = gaitColour ? frame.gait[frame.gaitAt(c)] : -1;
      if (gait !== this.lastGait[c]) {
        this.lastGait[c] = gait;
        const colour = gait < 0 ? PLAIN : new THREE.Color(GAIT_COLOURS[gait] ?? '#ffffff');
        for (const bone of this.bones) bone.mesh.setColorAt(c, colour);
        this.coloursChanged = true;
      }
    }
    for (const bone of this.bones) {
      bone.mesh.count = this.count;
      bone.mesh.instanceMatrix.needsUpdate = true;
      if (this.coloursChanged) bone.mesh.instanceColor.needsUpdate = true;
    }
    this.coloursChanged = false;
  }

  dispose() {
    for (const bone of this.bones) { this.scene.remove(bone.mesh); bone.mesh.dispose(); }
    this.bones[0]?.mesh.geometry.dispose();
    this.material.dispose();
  }
}

/** out[o..o+16) = A[a..a+16) * B, column-major 4x4, A and B affine (last row 0 0 0 1). */
function multiplyAffine(out, o, A, a, B) {
  for (let col = 0; col < 4; col++) {
    const b0 = B[col * 4], b1 = B[col * 4 + 1], b2 = B[col * 4 + 2], b3 = B[col * 4 + 3];
    out[o + col * 4] = A[a] * b0 + A[a + 4] * b1 + A[a + 8] * b2 + A[a + 12] * b3;
    out[o + col * 4 + 1] = A[a + 1] * b0 + A[a + 5] * b1 + A[a + 9] * b2 + A[a + 13] * b3;
    out[o + col * 4 + 2] = A[a + 2] * b0 + A[a + 6] * b1 + A[a + 10] * b2 + A[a + 14] * b3;
    out[o + col * 4 + 3] = b3;
  }
}

export class SkinnedHerd {
  /** `gltf`: the loaded mesh.glb (one skinned mesh, a node per joint named as the library's). */
  constructor(scene, skeleton, count, gltf) {
    this.skeleton = skeleton; this.count = count; this.scene = scene;
    this.animals = [];
    for (let c = 0; c < count; c++) {
      const root = SkeletonUtils.clone(gltf.scene);
      const bones = skeleton.names.map((name) => root.getObjectByName(name) ?? null);
      const missing = skeleton.names.filter((_, j) => !bones[j]);
      if (missing.length) throw new Error(`mesh.glb has no nodes for joints ${missing.slice(0, 5).join(', ')}`);
      for (const bone of bones) { bone.matrixAutoUpdate = false; bone.matrixWorldAutoUpdate = false; }
      const materials = [];
      root.traverse((o) => {
        if (o.isMesh) { o.frustumCulled = false; o.material = o.material.clone(); materials.push(o.material); }
      });
      scene.add(root);
      this.animals.push({ root, bones, materials, gait: -2 });
    }
    this.P = new Float32Array(skeleton.joints * 3); this.Q = new Float32Array(skeleton.joints * 4);
  }

  update(frame, scales, gaitColour) {
    const { skeleton, P, Q } = this, J = skeleton.joints;
    this.animals.forEach((animal, c) => {
      const s = scales[c];
      worldPose(skeleton, frame.root, frame.rootAt(c), frame.rotations, frame.rotAt(c), s, P, Q);
      for (let j = 0; j < J; j++) {
        // Bones' world matrices straight from pose assembly (scale included): the skinning
        // multiplies them by the inverse bind matrices, whatever the node hierarchy above.
        composeMatrix(animal.bones[j].matrixWorld.elements, 0, P[j * 3], P[j * 3 + 1], P[j * 3 + 2],
          Q[j * 4], Q[j * 4 + 1], Q[j * 4 + 2], Q[j * 4 + 3], s);
      }
      const gait = gaitColour ? frame.gait[frame.gaitAt(c)] : -1;
      if (gait !== animal.gait) {
        animal.gait = gait;
        for (const m of animal.materials) if (m.color) m.color.set(gait < 0 ? '#ffffff' : GAIT_COLOURS[gait] ?? '#ffffff');
      }
    });
  }

  dispose() {
    for (const a of this.animals) this.scene.remove(a.root);
  }
}
