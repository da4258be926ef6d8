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
  const [values, stride] = storedPositions(position);
  return is_closed_mesh(values, stride, corners);
}

/**
 * The positions as stored, as floats, and the stride between vertices: an interleaved
 * attribute's buffer as it is (a quantized file pads its positions to four values), a quantized
 * attribute's integers as they are — they differ from its positions by a positive factor, which
 * changes neither which are equal nor the volume's sign. Copied by the typed arrays' own
 * conversion, not a loop of script.
 */
function storedPositions(position: THREE.BufferAttribute | THREE.InterleavedBufferAttribute): [Float32Array, number] {
  const interleaved = position as THREE.InterleavedBufferAttribute;
  const [array, stride, offset] = interleaved.isInterleavedBufferAttribute ? [interleaved.data.array, interleaved.data.stride, interleaved.offset] : [position.array, position.itemSize, 0];
  return [(array instanceof Float32Array ? array : Float32Array.from(array)).subarray(offset), stride];
}
