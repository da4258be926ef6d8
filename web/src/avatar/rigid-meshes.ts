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

/** A float copy of `attribute` (a quantized one is read through its normalization). */
function floatCopy(attribute: THREE.BufferAttribute | THREE.InterleavedBufferAttribute): THREE.BufferAttribute {
  const n = attribute.itemSize;
  const out = new Float32Array(attribute.count * n);
  for (let i = 0; i < attribute.count; i++) for (let k = 0; k < n; k++) out[i * n + k] = attribute.getComponent(i, k);
  return new THREE.BufferAttribute(out, n);
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
    const geometry = mesh.geometry.clone();
    for (const name of ['position', 'normal', 'tangent']) {
      const a = geometry.getAttribute(name);
      if (a) geometry.setAttribute(name, floatCopy(a));
    }
    geometry.deleteAttribute('skinIndex');
    geometry.deleteAttribute('skinWeight');
    geometry.applyMatrix4(bake);
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
