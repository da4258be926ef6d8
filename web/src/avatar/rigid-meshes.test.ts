// Rigidly skinned meshes ride their bone: drawn where skinning drew them, in any pose; meshes
// with two influences, or on a bone nothing else poses, are left skinned.
import * as THREE from 'three';
import { describe, expect, it } from 'vitest';
import { attachRigidMeshes } from './rigid-meshes.ts';

/** Two bones (hips → head, 1 m up), a body skinned to both, and `extra` skinned by `weights`. */
function rig(weights: (v: number) => [number, number, number, number], indices: [number, number, number, number], shareBones = true) {
  const root = new THREE.Group();
  const hips = new THREE.Bone();
  const head = new THREE.Bone();
  head.position.set(0, 1, 0);
  hips.add(head);
  root.add(hips);
  root.position.set(0.3, 0, -0.2);
  root.updateMatrixWorld(true);
  const skinned = (w: (v: number) => [number, number, number, number], idx: [number, number, number, number], bones: THREE.Bone[]) => {
    const g = new THREE.BoxGeometry(0.2, 0.2, 0.2, 1, 1, 1).translate(-1.5, 1.1, 0.05); // values past ±1 too
    const n = g.getAttribute('position').count;
    g.setAttribute('skinIndex', new THREE.Uint16BufferAttribute(Array.from({ length: n }, () => idx).flat(), 4));
    g.setAttribute('skinWeight', new THREE.Float32BufferAttribute(Array.from({ length: n }, (_, v) => w(v)).flat(), 4));
    const m = new THREE.SkinnedMesh(g, new THREE.MeshBasicMaterial());
    m.position.set(0, 0, 0.01); // a mesh node transform of its own: part of the bind matrix
    root.add(m);
    m.updateMatrixWorld(true);
    m.bind(new THREE.Skeleton(bones));
    return m;
  };
  const body = skinned(() => [0.5, 0.5, 0, 0], [0, 1, 0, 0], [hips, head]);
  const extra = skinned(weights, indices, shareBones ? [hips, head] : [new THREE.Bone(), new THREE.Bone()]);
  return { root, hips, head, body, extra };
}

/** World positions of `mesh`'s vertices as drawn (skinned or not). */
function drawn(mesh: THREE.Mesh): number[] {
  mesh.updateMatrixWorld(true);
  const p = mesh.geometry.getAttribute('position');
  const out: number[] = [];
  const v = new THREE.Vector3();
  for (let i = 0; i < p.count; i++) {
    v.fromBufferAttribute(p, i);
    if ((mesh as THREE.SkinnedMesh).isSkinnedMesh) (mesh as THREE.SkinnedMesh).applyBoneTransform(i, v);
    out.push(...v.applyMatrix4(mesh.matrixWorld).toArray());
  }
  return out;
}

function pose(r: ReturnType<typeof rig>): void {
  r.hips.position.set(0.5, 0.1, 2);
  r.hips.quaternion.setFromEuler(new THREE.Euler(0.2, 1.1, -0.3));
  r.head.quaternion.setFromEuler(new THREE.Euler(-0.4, 0.7, 0.25));
  r.head.scale.setScalar(1.3);
  r.root.updateMatrixWorld(true);
  r.body.skeleton.update();
  r.extra.skeleton.update();
}

describe('attachRigidMeshes', () => {
  it('a mesh wholly on one bone becomes a plain mesh on it, drawn where skinning drew it', () => {
    const r = rig(() => [1, 0, 0, 0], [1, 0, 0, 0]);
    pose(r);
    const before = drawn(r.extra);
    expect(attachRigidMeshes(r.root)).toBe(1);
    const plain = r.head.children.find((c) => (c as THREE.Mesh).isMesh) as THREE.Mesh;
    expect(plain).toBeDefined();
    expect((plain as THREE.SkinnedMesh).isSkinnedMesh).toBeUndefined();
    expect(plain.geometry.getAttribute('skinIndex')).toBeUndefined();
    r.root.updateMatrixWorld(true);
    const after = drawn(plain);
    expect(after.length).toBe(before.length);
    for (let i = 0; i < after.length; i++) expect(after[i]).toBeCloseTo(before[i], 5);
    // In another pose too: the bone carries it.
    r.head.quaternion.setFromEuler(new THREE.Euler(1, -0.5, 0.1));
    r.root.updateMatrixWorld(true);
    r.body.skeleton.update();
    const skinnedAgain = rig(() => [1, 0, 0, 0], [1, 0, 0, 0]);
    pose(skinnedAgain);
    skinnedAgain.head.quaternion.copy(r.head.quaternion);
    skinnedAgain.root.updateMatrixWorld(true);
    skinnedAgain.extra.skeleton.update();
    const want = drawn(skinnedAgain.extra);
    const got = drawn(plain);
    for (let i = 0; i < got.length; i++) expect(got[i]).toBeCloseTo(want[i], 5);
    expect(r.body.parent).toBe(r.root); // the body stays skinned
  });

  it('moves the bounds with the geometry: they hold every baked vertex, so three.js need not measure them', () => {
    const r = rig(() => [1, 0, 0, 0], [1, 0, 0, 0]);
    r.extra.geometry.computeBoundingBox(); // as a glTF's accessors give them
    r.extra.geometry.computeBoundingSphere();
    attachRigidMeshes(r.root);
    const g = (r.head.children.find((c) => (c as THREE.Mesh).isMesh) as THREE.Mesh).geometry;
    const box = g.boundingBox;
    const sphere = g.boundingSphere;
    expect(box && sphere).toBeTruthy();
    const p = g.getAttribute('position');
    const v = new THREE.Vector3();
    for (let i = 0; i < p.count; i++) {
      v.fromBufferAttribute(p, i);
      expect(box!.distanceToPoint(v)).toBeLessThan(1e-6);
      expect(v.distanceTo(sphere!.center)).toBeLessThanOrEqual(sphere!.radius + 1e-6);
    }
    // Tight as the source's: the same radius (the bake is a rigid motion here).
    expect(sphere!.radius).toBeCloseTo(r.extra.geometry.boundingSphere!.radius, 6);
  });

  it('bakes normals too, a quantized attribute read through its normalization', () => {
    const r = rig(() => [1, 0, 0, 0], [1, 0, 0, 0]);
    // Normals stored as normalized bytes padded to four a vertex, as a quantized file does
    // (KHR_mesh_quantization): an interleaved attribute.
    const normal = r.extra.geometry.getAttribute('normal');
    const bytes = new Int8Array(normal.count * 3).map((_, i) => Math.round(normal.array[i] * 127));
    const padded = Int8Array.from({ length: normal.count * 4 }, (_, i) => (i % 4 === 3 ? 99 : bytes[(i >> 2) * 3 + (i % 4)]));
    r.extra.geometry.setAttribute('normal', new THREE.InterleavedBufferAttribute(new THREE.InterleavedBuffer(padded, 4), 3, 0, true));
    // A bind matrix that turns and stretches unevenly: normals need its inverse transpose.
    r.extra.bindMatrix.makeScale(1, 1.5, 0.8).multiply(new THREE.Matrix4().makeRotationY(0.7)).setPosition(0.1, 0, 0);
    r.extra.bindMatrixInverse.copy(r.extra.bindMatrix).invert();
    const bake = new THREE.Matrix4().multiplyMatrices(r.extra.skeleton.boneInverses[1], r.extra.bindMatrix);
    // three.js' own bake of the same values as floats (its bake of the bytes would round them).
    const floats = r.extra.geometry.clone();
    floats.setAttribute('normal', new THREE.BufferAttribute(Float32Array.from(bytes, (b) => Math.max(b / 127, -1)), 3));
    const want = floats.applyMatrix4(bake).getAttribute('normal');
    expect(attachRigidMeshes(r.root)).toBe(1);
    const plain = r.head.children.find((c) => (c as THREE.Mesh).isMesh) as THREE.Mesh;
    const got = plain.geometry.getAttribute('normal');
    expect(got.array).toBeInstanceOf(Float32Array);
    for (let i = 0; i < got.count; i++) for (let k = 0; k < 3; k++) expect(got.getComponent(i, k)).toBeCloseTo(want.getComponent(i, k), 5);
  });

  it('leaves a mesh with two influences, quantized weights below whole, or a bone nothing else poses', () => {
    expect(attachRigidMeshes(rig(() => [0.7, 0.3, 0, 0], [1, 0, 0, 0]).root)).toBe(0);
    expect(attachRigidMeshes(rig(() => [0.99, 0.01, 0, 0], [1, 0, 0, 0]).root)).toBe(0);
    expect(attachRigidMeshes(rig((v) => (v % 2 ? [0, 1, 0, 0] : [1, 0, 0, 0]), [1, 0, 0, 0]).root)).toBe(0);
    expect(attachRigidMeshes(rig(() => [1, 0, 0, 0], [1, 0, 0, 0], false).root)).toBe(0);
  });
});
