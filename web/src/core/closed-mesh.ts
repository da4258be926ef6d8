/**
 * Whether a three.js geometry is a closed surface wound outward, decided by the core
 * (`wasm-core/src/runtime/closed_mesh.rs`: why there, and what closed means). Needs the core
 * initialized (`initWasm`).
 */
import type * as THREE from 'three';
import { is_closed_mesh } from './raw.ts';

const NO_INDEX = new Uint32Array(0);

/** Whether `geometry`'s triangles are a closed, consistently wound surface whose front faces point out. */
export function isClosedMesh(geometry: THREE.BufferGeometry): boolean {
  const position = geometry.getAttribute('position');
  if (!position || position.count < 4) return false;
  const index = geometry.getIndex();
  const corners = index ? (index.array instanceof Uint32Array ? index.array : Uint32Array.from(index.array)) : NO_INDEX;
  return is_closed_mesh(floatPositions(position), corners);
}

/**
 * The positions as stored, as floats: a quantized attribute's integers differ from its positions
 * by a positive factor, which changes neither which are equal nor the volume's sign (copied by
 * the typed array's own conversion, not a loop of script).
 */
function floatPositions(position: THREE.BufferAttribute | THREE.InterleavedBufferAttribute): Float32Array {
  const raw = (position as THREE.InterleavedBufferAttribute).isInterleavedBufferAttribute ? null : position.array;
  if (raw && position.itemSize === 3) return raw instanceof Float32Array ? raw : Float32Array.from(raw);
  const out = new Float32Array(position.count * 3);
  for (let i = 0; i < position.count; i++) out.set([position.getX(i), position.getY(i), position.getZ(i)], 3 * i);
  return out;
}
