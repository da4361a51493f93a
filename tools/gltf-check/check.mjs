// Checks .glb files as engines read them; prints one JSON object per file (a JSON array).
//   node check.mjs FILE.glb [FILE.glb ...]
// validator: Khronos' glTF-Validator report counts and its messages (errors, warnings, infos).
// three: what three.js' GLTFLoader builds: skinned meshes with their bone names, animations, and
// how far the animation moves the bones (largest world displacement of a bone between the
// first frame and the middle of the clip, metres), and the skinned positions three.js computes
// for every SAMPLE-th vertex of the first two meshes at that middle time (world, metres), for a
// test to compare with its own skinning.
import { readFileSync } from "node:fs";
import validator from "gltf-validator";
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";

async function validate(bytes) {
  const report = await validator.validateBytes(new Uint8Array(bytes), { maxIssues: 100 });
  const issues = report.issues;
  return {
    errors: issues.numErrors, warnings: issues.numWarnings, infos: issues.numInfos,
    messages: issues.messages.map((m) => `${m.severity} ${m.code} ${m.pointer ?? ""}: ${m.message}`),
  };
}

function parse(bytes) {
  const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  return new Promise((resolve, reject) => new GLTFLoader().parse(buffer, "", resolve, reject));
}

function bonePositions(meshes) {
  return meshes.flatMap((m) => m.skeleton.bones.map((b) => b.getWorldPosition(new THREE.Vector3())));
}

async function three(bytes) {
  const gltf = await parse(bytes);
  gltf.scene.updateMatrixWorld(true);
  const meshes = [];
  gltf.scene.traverse((o) => { if (o.isSkinnedMesh) meshes.push(o); });
  const out = {
    skinnedMeshes: meshes.map((m) => ({
      name: m.name, bones: m.skeleton.bones.map((b) => b.name),
      vertices: m.geometry.attributes.position.count, triangles: m.geometry.index.count / 3,
      skinAttributes: Boolean(m.geometry.attributes.skinIndex && m.geometry.attributes.skinWeight),
      extras: m.userData ?? {},
    })),
    animations: gltf.animations.map((a) => ({ name: a.name, duration: a.duration, tracks: a.tracks.length })),
    moved: 0,
  };
  if (gltf.animations.length) {
    const mixer = new THREE.AnimationMixer(gltf.scene);
    mixer.clipAction(gltf.animations[0]).play();
    mixer.setTime(0);
    gltf.scene.updateMatrixWorld(true);
    const before = bonePositions(meshes);
    mixer.setTime(gltf.animations[0].duration / 2);
    gltf.scene.updateMatrixWorld(true);
    const after = bonePositions(meshes);
    out.moved = Math.max(0, ...before.map((p, i) => p.distanceTo(after[i])));
    out.time = gltf.animations[0].duration / 2;
  }
  out.sample = meshes.slice(0, 2).map((m) => { m.skeleton.update(); return skinnedSample(m); });
  out.sampleEvery = SAMPLE;
  return out;
}

const SAMPLE = 37;

function skinnedSample(mesh) {
  const out = [];
  const v = new THREE.Vector3();
  for (let i = 0; i < mesh.geometry.attributes.position.count; i += SAMPLE) {
    mesh.getVertexPosition(i, v);
    v.applyMatrix4(mesh.matrixWorld);
    out.push([v.x, v.y, v.z]);
  }
  return out;
}

const results = [];
for (const file of process.argv.slice(2)) {
  const bytes = readFileSync(file);
  results.push({ file, validator: await validate(bytes), three: await three(bytes) });
}
console.log(JSON.stringify(results));
