// Ground that is not flat in the viewer (`?terrain=hills`): a height field made in the page, sent
// as the live session's `ground` (docs/terrain.md), drawn as a mesh, and looked up under the feet
// for the browser test. Layout as on the wire: heights[i * nx + j] is the ground's y at
// x = origin[0] + j * spacing, z = origin[1] + i * spacing; bilinear between, clamped outside.
import * as THREE from 'three';

const MAX_SIDE = 256; // 256 x 256 float32 heights: 256 KB in the live session's opening message

/** Rolling hills under the herd's loop: `extent` metres each side of the origin, crest to trough
 * about 1.2 standing heights, slopes up to ~25% (waves of 30 standing heights). */
export function hills(extent, height) {
  const spacing = Math.max(0.5, (2 * extent) / (MAX_SIDE - 1));
  const n = Math.min(MAX_SIDE, Math.ceil((2 * extent) / spacing) + 1);
  const heights = new Float32Array(n * n);
  const a = 0.6 * height, k = (2 * Math.PI) / (30 * height);
  for (let i = 0; i < n; i++) {
    const z = -extent + i * spacing;
    for (let j = 0; j < n; j++) {
      const x = -extent + j * spacing;
      heights[i * n + j] = a * Math.sin(k * x) * Math.cos(0.8 * k * z) + 0.35 * a * Math.sin(1.7 * k * (x - 0.6 * z));
    }
  }
  return { heights, nx: n, nz: n, origin: [-extent, -extent], spacing };
}

/** The field as the request's `ground` (`blob` from the JS client). */
export function groundRequest(field, blob) {
  return { heights: blob(field.heights, [field.nz, field.nx]), origin: field.origin, spacing: field.spacing };
}

/** The ground's y at (x, z): bilinear, clamped to the grid (as the service reads it). */
export function heightAt(field, x, z) {
  const { heights, nx, nz, origin, spacing } = field;
  const u = Math.min(Math.max((x - origin[0]) / spacing, 0), nx - 1);
  const v = Math.min(Math.max((z - origin[1]) / spacing, 0), nz - 1);
  const j = Math.min(Math.floor(u), nx - 2), i = Math.min(Math.floor(v), nz - 2);
  const fu = u - j, fv = v - i, at = (ii, jj) => heights[ii * nx + jj];
  return (at(i, j) * (1 - fu) + at(i, j + 1) * fu) * (1 - fv) + (at(i + 1, j) * (1 - fu) + at(i + 1, j + 1) * fu) * fv;
}

/** The field as a lit mesh, `texture` repeated every `cell` metres (the flat ground's grid). */
export function terrainMesh(field, texture, cell = 5) {
  const { heights, nx, nz, origin, spacing } = field;
  const position = new Float32Array(nx * nz * 3), uv = new Float32Array(nx * nz * 2), colour = new Float32Array(nx * nz * 3);
  // Troughs darker than crests: soft light alone hardly shows gentle hills.
  const low = heights.reduce((a, b) => Math.min(a, b)), span = Math.max(heights.reduce((a, b) => Math.max(a, b)) - low, 1e-6);
  for (let i = 0; i < nz; i++) {
    for (let j = 0; j < nx; j++) {
      const v = i * nx + j, x = origin[0] + j * spacing, z = origin[1] + i * spacing;
      position[v * 3] = x; position[v * 3 + 1] = heights[v]; position[v * 3 + 2] = z;
      uv[v * 2] = x / cell; uv[v * 2 + 1] = z / cell;
      colour.fill(0.6 + 0.4 * ((heights[v] - low) / span), v * 3, v * 3 + 3);
    }
  }
  const index = new Uint32Array((nx - 1) * (nz - 1) * 6);
  let o = 0;
  for (let i = 0; i < nz - 1; i++) {
    for (let j = 0; j < nx - 1; j++) {
      const a = i * nx + j, b = a + 1, c = a + nx, d = c + 1;
      index.set([a, c, b, b, c, d], o); // counter-clockwise seen from above (+y)
      o += 6;
    }
  }
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(position, 3));
  geometry.setAttribute('uv', new THREE.BufferAttribute(uv, 2));
  geometry.setAttribute('color', new THREE.BufferAttribute(colour, 3));
  geometry.setIndex(new THREE.BufferAttribute(index, 1));
  geometry.computeVertexNormals();
  return new THREE.Mesh(geometry, new THREE.MeshLambertMaterial({ map: texture, vertexColors: true }));
}
