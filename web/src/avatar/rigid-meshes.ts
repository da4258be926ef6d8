/**
 * Skinned meshes that follow one bone rigidly (eyes, eyebrows, teeth, hats, glasses: every vertex
 * weighted wholly to the same bone) become plain meshes carried by that bone. Why: three.js
 * updates and uploads one bone texture per skeleton per frame, whatever the mesh uses — the
 * shipped avatar's eyes and eyebrows each had a 65-bone skeleton of their own, three uploads a
 * frame per character where one does. As a child of the bone the mesh moves exactly as skinning
 * moved it: with the bind mode `attached`, a vertex v skinned to bone b alone is drawn at
 * `b.matrixWorld · boneInverse_b · bindMatrix · v`, so the geometry is baked once into the bone's
 * frame (v' = boneInverse_b · bindMatrix · v) and the bone's world matrix does the rest.
 */
import * as THREE from 'three';

/** Weights at least this close to 1 count as the whole vertex (quantized weights are not exact). */
const WHOLE = 0.999;

/** The one bone every vertex of `mesh` follows wholly, or −1. */
function rigidBone(mesh: THREE.SkinnedMesh): number {
  const index = mesh.geometry.getAttribute('skinIndex');
  const weight = mesh.geometry.getAttribute('skinWeight');
  if (!index || !weight || mesh.geometry.morphAttributes.position) return -1;
  let bone = -1;
  for (let i = 0; i < index.count; i++) {
    let whole = -1;
    for (let k = 0; k < weight.itemSize; k++) {
      const w = weight.getComponent(i, k);
      if (w >= WHOLE) whole = index.getComponent(i, k);
      else if (w > 1 - WHOLE) return -1; // a second influence: really skinned
    }
    if (whole < 0 || (bone >= 0 && whole !== bone)) return -1;
    bone = whole;
  }
  return bone;
}

/**
 * What a normalized attribute's stored integers are multiplied by (then clamped at −1): three.js'
 * `MathUtils.denormalize`, once per array instead of a call per value.
 */
function unit(array: ArrayLike<number>): number {
  if (array instanceof Int8Array) return 1 / 127;
  if (array instanceof Uint8Array) return 1 / 255;
  if (array instanceof Int16Array) return 1 / 32767;
  if (array instanceof Uint16Array) return 1 / 65535;
  return 1;
}

/**
 * `attribute` as floats (a quantized one read through its normalization), each item moved by
 * `m`: as a point, or as a direction (no translation, renormalized; a tangent's w kept). One
 * loop over the plain arrays: `BufferGeometry.applyMatrix4` made some ten calls a vertex, ~15 ms
 * for the shipped avatar's eyes and eyebrows while a page loads (its code not yet optimized).
 */
function baked(attribute: THREE.BufferAttribute | THREE.InterleavedBufferAttribute, m: THREE.Matrix4, point: boolean): THREE.BufferAttribute {
  const n = attribute.itemSize;
  const count = attribute.count;
  // An interleaved attribute (a quantized file pads positions and normals to four values) is read
  // from its buffer with the buffer's stride.
  const interleaved = attribute as THREE.InterleavedBufferAttribute;
  const [array, stride, offset] = interleaved.isInterleavedBufferAttribute ? [interleaved.data.array, interleaved.data.stride, interleaved.offset] : [attribute.array, n, 0];
  const values = array instanceof Float32Array ? array : Float32Array.from(array);
  const normalized = attribute.normalized;
  const s = normalized ? unit(array) : 1;
  const out = new Float32Array(count * n);
  for (let i = 0; i < count; i++) {
    for (let k = 0; k < n; k++) {
      const v = values[offset + i * stride + k];
      out[i * n + k] = normalized ? Math.max(v * s, -1) : v;
    }
  }
  const e = m.elements;
  const t = point ? 1 : 0;
  for (let i = 0; i < count * n; i += n) {
    const x = out[i];
    const y = out[i + 1];
    const z = out[i + 2];
    let a = e[0] * x + e[4] * y + e[8] * z + t * e[12];
    let b = e[1] * x + e[5] * y + e[9] * z + t * e[13];
    let c = e[2] * x + e[6] * y + e[10] * z + t * e[14];
    if (!point) {
      const l = Math.hypot(a, b, c) || 1;
      a /= l;
      b /= l;
      c /= l;
    }
    out[i] = a;
    out[i + 1] = b;
    out[i + 2] = c;
  }
  return new THREE.BufferAttribute(out, n);
}

/** `source` without its skin, its geometry baked by `bake` into the bone's frame. */
function bakedGeometry(source: THREE.BufferGeometry, bake: THREE.Matrix4): THREE.BufferGeometry {
  // Normals turn by the inverse transpose (a bind matrix may scale unevenly); tangents as edges.
  const normals = new THREE.Matrix4().setFromMatrix3(new THREE.Matrix3().getNormalMatrix(bake));
  const geometry = new THREE.BufferGeometry();
  geometry.name = source.name;
  if (source.index) geometry.setIndex(source.index.clone());
  for (const [name, a] of Object.entries(source.attributes)) {
    if (name === 'skinIndex' || name === 'skinWeight') continue;
    const point = name === 'position';
    const direction = name === 'normal' || name === 'tangent';
    geometry.setAttribute(name, point || direction ? baked(a, name === 'normal' ? normals : bake, point) : a.clone());
  }
  for (const g of source.groups) geometry.addGroup(g.start, g.count, g.materialIndex);
  geometry.setDrawRange(source.drawRange.start, source.drawRange.count);
  // Bounds moved with it (a glTF's come from its accessors' min/max; a transformed box and sphere
  // still hold every point): left unset, three.js measures every vertex in the first frame that
  // sorts the mesh, 4-10 ms for the shipped avatar's eyes and eyebrows while its code is cold.
  geometry.boundingBox = source.boundingBox?.clone().applyMatrix4(bake) ?? null;
  geometry.boundingSphere = source.boundingSphere?.clone().applyMatrix4(bake) ?? null;
  geometry.userData = source.userData;
  return geometry;
}

/**
 * Replaces every rigidly skinned mesh under `root` (bind mode `attached`, no morph targets, its
 * bone also in another skinned mesh's skeleton, so it is posed) by a plain mesh on its bone, with
 * the same material. Returns how many it replaced.
 */
export function attachRigidMeshes(root: THREE.Object3D): number {
  root.updateMatrixWorld(true);
  const skinned: THREE.SkinnedMesh[] = [];
  root.traverse((o) => (o as THREE.SkinnedMesh).isSkinnedMesh && skinned.push(o as THREE.SkinnedMesh));
  let replaced = 0;
  for (const mesh of skinned) {
    const b = mesh.bindMode === THREE.AttachedBindMode ? rigidBone(mesh) : -1;
    const bone = mesh.skeleton.bones[b];
    const posed = (m: THREE.SkinnedMesh) => m !== mesh && m.parent !== null && m.skeleton.bones.includes(bone);
    if (!bone || !skinned.some(posed)) continue;
    const bake = new THREE.Matrix4().multiplyMatrices(mesh.skeleton.boneInverses[b], mesh.bindMatrix);
    const geometry = bakedGeometry(mesh.geometry, bake);
    const plain = new THREE.Mesh(geometry, mesh.material);
    plain.name = mesh.name;
    plain.castShadow = mesh.castShadow;
    plain.receiveShadow = mesh.receiveShadow;
    plain.renderOrder = mesh.renderOrder;
    plain.visible = mesh.visible;
    plain.layers.mask = mesh.layers.mask;
    plain.userData = mesh.userData;
    mesh.parent!.remove(mesh);
    bone.add(plain);
    mesh.geometry.dispose();
    replaced++;
  }
  return replaced;
}
