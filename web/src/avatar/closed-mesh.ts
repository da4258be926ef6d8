/**
 * Double-sided materials on closed meshes draw front faces only. Exported avatars often mark every
 * material double-sided, and on a closed, consistently wound surface seen from outside a back face
 * is always behind a front one: it is rasterized and shaded, then hidden. Dropping it changes no
 * pixel and halves the fragment work — measured on the shipped avatar at 320×240 on SwiftShader:
 * 41 frames/s with its body double-sided, 60 (the display's rate) without; a phone or a headset
 * GPU is fill-rate bound the same way.
 *
 * Only where nothing can be seen through or past the surface: an opaque material (no blending,
 * no alpha test, no alpha map) whose every mesh is closed — after welding vertices at equal
 * positions (seams split them), each edge is shared by exactly two triangles running it in
 * opposite directions — and wound outward (positive signed volume, so its front faces are the
 * outside; the test runs in the core: `core/closed_mesh.ts`). Anything else (cards, hair, open
 * clothing, a flipped or broken mesh) stays as it was. Needs the core initialized.
 */
import * as THREE from 'three';
import { isClosedMesh } from '../core/closed_mesh.ts';

/** Sets `FrontSide` on the double-sided opaque materials whose meshes under `root` are all closed; returns how many. */
export function cullHiddenBackFaces(root: THREE.Object3D): number {
  const meshesOf = new Map<THREE.Material, THREE.Mesh[]>();
  const mixed = new Set<THREE.Material>();
  root.traverse((o) => {
    const mesh = o as THREE.Mesh;
    if (!mesh.isMesh) return;
    const materials = Array.isArray(mesh.material) ? mesh.material : [mesh.material];
    for (const m of materials) {
      // A material drawn on part of a mesh (groups) leaves the rest of its surface open.
      if (materials.length > 1) mixed.add(m);
      if (!meshesOf.has(m)) meshesOf.set(m, []);
      meshesOf.get(m)!.push(mesh);
    }
  });
  const closed = new Map<THREE.BufferGeometry, boolean>();
  let changed = 0;
  for (const [material, meshes] of meshesOf) {
    if (material.side !== THREE.DoubleSide || mixed.has(material)) continue;
    if (material.transparent || material.alphaTest > 0 || (material as THREE.MeshStandardMaterial).alphaMap) continue;
    const all = meshes.every((m) => {
      if (!closed.has(m.geometry)) closed.set(m.geometry, isClosedMesh(m.geometry));
      return closed.get(m.geometry);
    });
    if (!all) continue;
    material.side = THREE.FrontSide;
    material.needsUpdate = true;
    changed++;
  }
  return changed;
}
