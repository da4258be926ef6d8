import * as THREE from 'three';
import { describe, expect, it } from 'vitest';
import { FIRST_PERSON_LAYER, FirstPerson, THIRD_PERSON_LAYER, setHeadsetView } from './first-person.ts';

/** A body of two quads: one skinned to the spine, one to the head (and one vertex of it half to the neck). */
function avatar(indexed: boolean) {
  const spine = new THREE.Bone(), head = new THREE.Bone(), eye = new THREE.Bone();
  spine.add(head);
  head.add(eye);
  const positions = [0, 1, 0, 1, 1, 0, 1, 1.5, 0, 0, 1.5, 0, 0, 1.6, 0, 1, 1.6, 0, 1, 1.8, 0, 0, 1.8, 0];
  // Vertices 0-3 on the spine (bone 0), 4-7 on the head (bone 1) except 7 on the eye (bone 2), vertex 4 half neck.
  const skinIndex = [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0];
  const skinWeight = [1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0.5, 0.5, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0];
  const quads = [0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7];
  let g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute(positions, 3));
  g.setAttribute('skinIndex', new THREE.Uint16BufferAttribute(skinIndex, 4));
  g.setAttribute('skinWeight', new THREE.Float32BufferAttribute(skinWeight, 4));
  g.setIndex(quads);
  if (!indexed) g = g.toNonIndexed();
  const mesh = new THREE.SkinnedMesh(g, new THREE.MeshBasicMaterial());
  const root = new THREE.Group();
  root.add(spine, mesh);
  mesh.bind(new THREE.Skeleton([spine, head, eye]));
  return { root, mesh, head };
}

describe('FirstPerson', () => {
  for (const indexed of [true, false]) {
    it(`gives a mesh with head triangles a headless copy on the first-person layer (${indexed ? 'indexed' : 'non-indexed'})`, () => {
      const { root, mesh, head } = avatar(indexed);
      const fp = new FirstPerson(root, head);
      expect(fp.copies.length).toBe(1);
      expect(fp.hiddenTriangles).toBe(2);
      const copy = fp.copies[0];
      expect(copy.parent).toBe(root);
      expect(copy.skeleton).toBe(mesh.skeleton);
      expect(copy.geometry.getAttribute('position')).toBe(mesh.geometry.getAttribute('position')); // shared, not copied
      expect(copy.geometry.getIndex()!.count).toBe(6);
      expect(mesh.layers.mask).toBe(1 << THIRD_PERSON_LAYER);
      expect(copy.layers.mask).toBe(1 << FIRST_PERSON_LAYER);
      fp.dispose();
      expect(copy.parent).toBeNull();
    });
  }

  it('leaves a mesh without head triangles to every camera', () => {
    const { root, mesh } = avatar(true);
    const fp = new FirstPerson(root, new THREE.Bone());
    expect(fp.copies.length).toBe(0);
    expect(mesh.layers.mask).toBe(1);
  });

  it('shows the whole avatar to any camera but the headset, which sees the headless copy', () => {
    const { root, mesh, head } = avatar(true);
    const scene = new THREE.Scene();
    scene.add(root);
    const copy = new FirstPerson(root, head).copies[0];
    FirstPerson.attach(scene);
    const renderer = {} as THREE.WebGLRenderer;
    const mirrorCamera = new THREE.PerspectiveCamera();
    scene.onBeforeRender(renderer, scene, mirrorCamera, null as never, null as never, null as never);
    expect(mesh.layers.test(mirrorCamera.layers) && !copy.layers.test(mirrorCamera.layers)).toBe(true);
    expect(mirrorCamera.layers.isEnabled(0)).toBe(true);

    // The page camera while presenting: the headset's cameras copy its layers.
    const pageCamera = new THREE.PerspectiveCamera();
    setHeadsetView(pageCamera, true);
    const xrCamera = new THREE.ArrayCamera([]);
    xrCamera.layers.mask = pageCamera.layers.mask;
    scene.onBeforeRender(renderer, scene, xrCamera, null as never, null as never, null as never);
    expect(copy.layers.test(xrCamera.layers) && !mesh.layers.test(xrCamera.layers)).toBe(true);
    setHeadsetView(pageCamera, false);
    expect(mesh.layers.test(pageCamera.layers) && !copy.layers.test(pageCamera.layers)).toBe(true);
  });
});
