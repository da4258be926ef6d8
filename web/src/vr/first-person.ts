/**
 * First person without losing the head (docs/vr.md, "The head in first person"): the headset's
 * own view must not show the inside of the avatar's head, but the mirror, the spectator view and
 * other people must. Scaling the head bone away hides it from every camera at once, so instead
 * (as three-vrm's `VRMFirstPerson` does) each skinned mesh that has head triangles gets a
 * headless copy — the same vertex buffers and skeleton, an index without the triangles skinned to
 * the head — and the two are put on layers: the headset's cameras see `FIRST_PERSON_LAYER`
 * (headless), every other camera `THIRD_PERSON_LAYER` (whole). Meshes without head triangles stay
 * on layer 0 (everyone sees them).
 *
 * Cameras: `FirstPerson.attach(scene)` makes every camera that renders the scene and is not the
 * headset's (three.js renders XR with an `ArrayCamera`; a mirror or a second renderer uses its
 * own camera) see the third-person layer. The headset's cameras copy the page camera's layers
 * when a frame starts, so `setHeadsetView(camera, on)` switches that camera when a session
 * starts and ends.
 */
import * as THREE from 'three';

/** Seen only from the headset (the headless copies). */
export const FIRST_PERSON_LAYER = 9;
/** Seen by every other camera (the whole meshes). */
export const THIRD_PERSON_LAYER = 10;

/** A vertex belongs to the head when at least this share of its skin weight is on head bones. */
const HEAD_WEIGHT = 0.3;

export class FirstPerson {
  /** The headless copies made (one per skinned mesh with head triangles). */
  readonly copies: THREE.SkinnedMesh[] = [];
  /** Triangles dropped from the copies (all meshes). */
  readonly hiddenTriangles: number = 0;

  /** Splits the skinned meshes under `object` whose triangles are skinned to `head` or below it. */
  constructor(object: THREE.Object3D, head: THREE.Object3D) {
    const headBones = new Set<THREE.Object3D>();
    head.traverse((o) => headBones.add(o));
    const meshes: THREE.SkinnedMesh[] = [];
    const rigid: THREE.Object3D[] = [];
    object.traverse((o) => {
      if ((o as THREE.SkinnedMesh).isSkinnedMesh) meshes.push(o as THREE.SkinnedMesh);
      else if ((o as THREE.Mesh).isMesh && headBones.has(o.parent as THREE.Object3D)) rigid.push(o); // hair or glasses on the head
    });
    let hidden = 0;
    for (const mesh of meshes) {
      const copy = headless(mesh, headBones);
      if (!copy) continue;
      hidden += copy.dropped;
      mesh.layers.set(THIRD_PERSON_LAYER);
      copy.mesh.layers.set(FIRST_PERSON_LAYER);
      mesh.parent?.add(copy.mesh);
      this.copies.push(copy.mesh);
    }
    for (const o of rigid) o.traverse((c) => c.layers.set(THIRD_PERSON_LAYER));
    this.hiddenTriangles = hidden;
  }

  /** Every camera rendering `scene` other than the headset's sees the third-person layer. */
  static attach(scene: THREE.Scene): void {
    const previous = scene.onBeforeRender;
    scene.onBeforeRender = function (...args) {
      const camera = args[2];
      if (!(camera as THREE.ArrayCamera).isArrayCamera) setHeadsetView(camera, false);
      previous.apply(this, args);
    };
  }

  /**
   * Removes the copies (the meshes keep their layers). Their geometries are not disposed: three.js
   * would free the vertex buffers they share with the whole meshes.
   */
  dispose(): void {
    for (const c of this.copies) c.removeFromParent();
    this.copies.length = 0;
  }
}

/** `camera` (and the headset's cameras, which copy it) shows the headless copies (`on`) or the whole meshes. */
export function setHeadsetView(camera: THREE.Camera, on: boolean): void {
  camera.layers.enable(on ? FIRST_PERSON_LAYER : THIRD_PERSON_LAYER);
  camera.layers.disable(on ? THIRD_PERSON_LAYER : FIRST_PERSON_LAYER);
}

/** A copy of `mesh` without the triangles that have a vertex skinned to `headBones`; null if it has none. */
function headless(mesh: THREE.SkinnedMesh, headBones: Set<THREE.Object3D>): { mesh: THREE.SkinnedMesh; dropped: number } | null {
  const g = mesh.geometry;
  const skinIndex = g.getAttribute('skinIndex');
  const skinWeight = g.getAttribute('skinWeight');
  if (!skinIndex || !skinWeight) return null;
  const bones = mesh.skeleton.bones;
  const isHead = new Uint8Array(skinIndex.count);
  let any = false;
  for (let v = 0; v < skinIndex.count; v++) {
    let w = 0;
    for (let k = 0; k < skinIndex.itemSize; k++) {
      const b = bones[skinIndex.getComponent(v, k)];
      if (b && headBones.has(b)) w += skinWeight.getComponent(v, k);
    }
    if (w >= HEAD_WEIGHT) isHead[v] = 1, any = true;
  }
  if (!any) return null;
  const index = g.getIndex();
  const count = index ? index.count : g.getAttribute('position').count;
  const kept: number[] = [];
  for (let t = 0; t + 2 < count; t += 3) {
    const a = index ? index.getX(t) : t, b = index ? index.getX(t + 1) : t + 1, c = index ? index.getX(t + 2) : t + 2;
    if (!isHead[a] && !isHead[b] && !isHead[c]) kept.push(a, b, c);
  }
  const copyGeometry = new THREE.BufferGeometry();
  for (const name of Object.keys(g.attributes)) copyGeometry.setAttribute(name, g.attributes[name]);
  copyGeometry.morphAttributes = g.morphAttributes;
  copyGeometry.morphTargetsRelative = g.morphTargetsRelative;
  copyGeometry.setIndex(skinIndex.count > 65535 ? new THREE.Uint32BufferAttribute(kept, 1) : new THREE.Uint16BufferAttribute(kept, 1));
  if (g.boundingSphere) copyGeometry.boundingSphere = g.boundingSphere.clone();
  if (g.boundingBox) copyGeometry.boundingBox = g.boundingBox.clone();
  const copy = new THREE.SkinnedMesh(copyGeometry, mesh.material);
  copy.name = `${mesh.name} (first person)`;
  copy.position.copy(mesh.position);
  copy.quaternion.copy(mesh.quaternion);
  copy.scale.copy(mesh.scale);
  copy.bindMode = mesh.bindMode;
  copy.bind(mesh.skeleton, mesh.bindMatrix);
  copy.frustumCulled = mesh.frustumCulled;
  copy.castShadow = mesh.castShadow;
  copy.receiveShadow = mesh.receiveShadow;
  if (mesh.morphTargetInfluences) copy.morphTargetInfluences = mesh.morphTargetInfluences; // one set of expressions drives both
  copy.morphTargetDictionary = mesh.morphTargetDictionary;
  return { mesh: copy, dropped: count / 3 - kept.length / 3 };
}
