// Reads a skin's joint hierarchy and rest pose straight from GLB bytes: no three.js loader, no
// DOM, so it runs in Node (tests, tools) as well as in the page.

import { Matrix4, Quaternion, Vector3 } from 'three';

/** The parts of a glTF node this module reads. */
export interface GltfNode {
  name?: string;
  children?: number[];
  rotation?: [number, number, number, number];
  translation?: [number, number, number];
  scale?: [number, number, number];
  matrix?: number[];
}

/** The parts of the glTF JSON this module reads. */
export interface GltfJson {
  asset?: { version?: string };
  nodes?: GltfNode[];
  skins?: { joints: number[]; skeleton?: number; name?: string }[];
  [key: string]: unknown;
}

/** One skin's skeleton in its rest pose; arrays are indexed like `skins[i].joints`. */
export interface GlbSkeleton {
  names: string[];
  /** glTF node index of each joint. */
  nodeIndices: Int32Array;
  /** Parent joint index, -1 when the parent node is not a joint of this skin (or there is none). */
  parents: Int32Array;
  /** Rest local rotations (x, y, z, w), J×4 (identity when the node has none). */
  restLocalRotations: Float32Array;
  /** Rest local translations, J×3. */
  restLocalPositions: Float32Array;
}

const GLB_MAGIC = 0x46546c67; // 'glTF'
const CHUNK_JSON = 0x4e4f534a; // 'JSON'

/**
 * Parses the JSON chunk of a GLB file (binary glTF 2.0). Throws with a message on a bad header:
 * wrong magic, version other than 2, truncated file, first chunk not JSON.
 */
export function parseGlbJson(bytes: Uint8Array): GltfJson {
  if (bytes.byteLength < 20) throw new Error(`GLB: ${bytes.byteLength} bytes is too short for a header`);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (view.getUint32(0, true) !== GLB_MAGIC) throw new Error('GLB: bad magic (expected "glTF")');
  const version = view.getUint32(4, true);
  if (version !== 2) throw new Error(`GLB: version ${version}, expected 2`);
  const length = view.getUint32(8, true);
  if (length > bytes.byteLength) throw new Error(`GLB: header says ${length} bytes, file has ${bytes.byteLength}`);
  const chunkLength = view.getUint32(12, true);
  if (view.getUint32(16, true) !== CHUNK_JSON) throw new Error('GLB: chunk 0 is not JSON');
  if (20 + chunkLength > length) throw new Error(`GLB: JSON chunk (${chunkLength} bytes) runs past the end`);
  const text = new TextDecoder().decode(bytes.subarray(20, 20 + chunkLength));
  return JSON.parse(text) as GltfJson;
}

const _m4 = new Matrix4();
const _q = new Quaternion();
const _p = new Vector3();
const _s = new Vector3();

/** The joints of `skins[skinIndex]` with their parents and rest local transforms. */
export function skeletonFromGltf(gltf: GltfJson, skinIndex = 0): GlbSkeleton {
  const nodes = gltf.nodes ?? [];
  const skin = gltf.skins?.[skinIndex];
  if (!skin) throw new Error(`glTF: no skin ${skinIndex} (the file has ${gltf.skins?.length ?? 0})`);
  const J = skin.joints.length;
  const jointOfNode = new Map<number, number>();
  skin.joints.forEach((n, j) => jointOfNode.set(n, j));
  const parentNode = new Map<number, number>();
  nodes.forEach((n, i) => n.children?.forEach((c) => parentNode.set(c, i)));

  const out: GlbSkeleton = {
    names: [],
    nodeIndices: new Int32Array(J),
    parents: new Int32Array(J),
    restLocalRotations: new Float32Array(J * 4),
    restLocalPositions: new Float32Array(J * 3),
  };
  for (let j = 0; j < J; j++) {
    const ni = skin.joints[j];
    const node = nodes[ni];
    if (!node) throw new Error(`glTF: skin ${skinIndex} joint ${j} names node ${ni}, which does not exist`);
    out.names.push(node.name ?? `node${ni}`);
    out.nodeIndices[j] = ni;
    const pn = parentNode.get(ni);
    out.parents[j] = pn === undefined ? -1 : (jointOfNode.get(pn) ?? -1);
    if (node.matrix) {
      _m4.fromArray(node.matrix).decompose(_p, _q, _s);
      out.restLocalPositions.set([_p.x, _p.y, _p.z], j * 3);
      out.restLocalRotations.set([_q.x, _q.y, _q.z, _q.w], j * 4);
    } else {
      out.restLocalPositions.set(node.translation ?? [0, 0, 0], j * 3);
      out.restLocalRotations.set(node.rotation ?? [0, 0, 0, 1], j * 4);
    }
  }
  return out;
}

/** `skeletonFromGltf(parseGlbJson(bytes), skinIndex)`. */
export function skeletonFromGlb(bytes: Uint8Array, skinIndex = 0): GlbSkeleton {
  return skeletonFromGltf(parseGlbJson(bytes), skinIndex);
}
