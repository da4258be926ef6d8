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
 * outside). Anything else (cards, hair, open clothing, a flipped or broken mesh) stays as it was.
 */
import * as THREE from 'three';

/** Whether `geometry` is a closed, consistently wound surface whose front faces point out. */
export function isClosedMesh(geometry: THREE.BufferGeometry): boolean {
  const position = geometry.getAttribute('position');
  if (!position || position.count < 4) return false;
  const index = geometry.getIndex();
  const count = index ? index.count : position.count;
  if (count < 12 || count % 3 !== 0) return false;
  const [welded, xyz] = weld(position);
  const corners = index ? index.array : null;
  // Edges in an open-addressed table, keyed by their two ends (low, high), with the directions
  // they were run in: a closed, consistently wound surface runs each edge once each way, so every
  // key ends with both directions and none is run twice the same way. Counting keys and keys
  // with both directions answers without a pass over the table. Fibonacci hashing (the product's
  // high bits): the low bits of a product of small ids cluster under linear probing (4× slower).
  const size = tableSize(count); // > the most keys there can be (one per corner): never full
  const mask = size - 1;
  const shift = 32 - Math.log2(size);
  const low = new Int32Array(size).fill(-1);
  const high = new Int32Array(size);
  const runs = new Uint8Array(size);
  let keys = 0;
  let paired = 0;
  let volume = 0;
  for (let t = 0; t < count; t += 3) {
    const i0 = corners ? corners[t] : t;
    const i1 = corners ? corners[t + 1] : t + 1;
    const i2 = corners ? corners[t + 2] : t + 2;
    const a = welded[i0];
    const b = welded[i1];
    const c = welded[i2];
    if (a === b || b === c || c === a) continue; // degenerate: no area, never seen
    for (let e = 0; e < 3; e++) {
      const p = e === 0 ? a : e === 1 ? b : c;
      const q = e === 0 ? b : e === 1 ? c : a;
      const lo = p < q ? p : q;
      const hi = p < q ? q : p;
      const run = p < q ? 1 : 2;
      let h = Math.imul(Math.imul(lo, 0x9e3779b1) ^ hi, 0x85ebca77) >>> shift;
      while (low[h] !== -1 && (low[h] !== lo || high[h] !== hi)) h = (h + 1) & mask;
      if (low[h] === -1) {
        low[h] = lo;
        high[h] = hi;
        runs[h] = run;
        keys++;
      } else if (runs[h] & run) return false; // the same edge run the same way twice
      else {
        runs[h] |= run;
        paired++;
      }
    }
    // 6 × the signed volume of the tetrahedron (origin, p0, p1, p2): p0 · (p1 × p2).
    const x1 = xyz[3 * i1];
    const y1 = xyz[3 * i1 + 1];
    const z1 = xyz[3 * i1 + 2];
    const x2 = xyz[3 * i2];
    const y2 = xyz[3 * i2 + 1];
    const z2 = xyz[3 * i2 + 2];
    volume += xyz[3 * i0] * (y1 * z2 - z1 * y2) + xyz[3 * i0 + 1] * (z1 * x2 - x1 * z2) + xyz[3 * i0 + 2] * (x1 * y2 - y1 * x2);
  }
  if (paired !== keys) return false; // an edge run one way only: a hole or a flipped triangle
  return volume > 0; // also false with no triangle at all
}

/** A power of two at least twice `n` (open addressing stays short). */
function tableSize(n: number): number {
  let size = 16;
  while (size < 2 * n) size *= 2;
  return size;
}

/**
 * An id per vertex, equal for vertices at the same position (a UV or normal seam splits one), and
 * the positions as floats.
 */
function weld(position: THREE.BufferAttribute | THREE.InterleavedBufferAttribute): [Int32Array, Float32Array] {
  const n = position.count;
  const xyz = new Float32Array(n * 3);
  // The stored numbers as they are: a normalized (quantized) attribute's integers differ from its
  // positions by a positive factor, which changes neither which are equal nor the volume's sign.
  // + 0 turns −0 into +0: equal positions, equal bits.
  const raw = (position as THREE.InterleavedBufferAttribute).isInterleavedBufferAttribute ? null : position.array;
  const stride = position.itemSize;
  for (let i = 0; i < n; i++) {
    xyz[3 * i] = (raw ? raw[i * stride] : position.getX(i)) + 0;
    xyz[3 * i + 1] = (raw ? raw[i * stride + 1] : position.getY(i)) + 0;
    xyz[3 * i + 2] = (raw ? raw[i * stride + 2] : position.getZ(i)) + 0;
  }
  const bits = new Int32Array(xyz.buffer);
  const mask = tableSize(n) - 1;
  const shift = 32 - Math.log2(mask + 1);
  const first = new Int32Array(mask + 1).fill(-1);
  const id = new Int32Array(n);
  let ids = 0;
  for (let i = 0; i < n; i++) {
    const x = bits[3 * i];
    const y = bits[3 * i + 1];
    const z = bits[3 * i + 2];
    let h = Math.imul(Math.imul(Math.imul(x, 0x9e3779b1) ^ y, 0x85ebca77) ^ z, 0xc2b2ae3d) >>> shift;
    for (; first[h] !== -1; h = (h + 1) & mask) {
      const j = first[h];
      if (bits[3 * j] === x && bits[3 * j + 1] === y && bits[3 * j + 2] === z) break;
    }
    if (first[h] === -1) {
      first[h] = i;
      id[i] = ids++;
    } else id[i] = id[first[h]];
  }
  return [id, xyz];
}

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
