// Test helper: the node hierarchy of a GLB as three.js objects with one SkinnedMesh over its
// first skin — what GLTFLoader would give, without images (Node has no DOM to decode them).
import * as THREE from 'three';

interface GltfNode {
  name?: string;
  children?: number[];
  rotation?: number[];
  translation?: number[];
  scale?: number[];
  matrix?: number[];
}

export function glbScene(bytes: Uint8Array): THREE.Group {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (view.getUint32(0, true) !== 0x46546c67) throw new Error('not a GLB');
  const length = view.getUint32(12, true);
  const gltf = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + length))) as {
    nodes: GltfNode[];
    skins: { joints: number[] }[];
    scenes: { nodes: number[] }[];
    scene?: number;
  };
  const skin = new Set(gltf.skins[0].joints);
  const objects = gltf.nodes.map((n, i) => {
    const o = skin.has(i) ? new THREE.Bone() : new THREE.Object3D();
    o.name = n.name ?? `node${i}`;
    if (n.matrix) new THREE.Matrix4().fromArray(n.matrix).decompose(o.position, o.quaternion, o.scale);
    else {
      if (n.translation) o.position.fromArray(n.translation);
      if (n.rotation) o.quaternion.fromArray(n.rotation);
      if (n.scale) o.scale.fromArray(n.scale);
    }
    return o;
  });
  gltf.nodes.forEach((n, i) => n.children?.forEach((c) => objects[i].add(objects[c])));
  const root = new THREE.Group();
  for (const i of gltf.scenes[gltf.scene ?? 0].nodes) root.add(objects[i]);
  root.updateMatrixWorld(true);
  const bones = gltf.skins[0].joints.map((j) => objects[j] as THREE.Bone);
  const mesh = new THREE.SkinnedMesh(new THREE.BufferGeometry(), new THREE.MeshBasicMaterial());
  root.add(mesh);
  mesh.bind(new THREE.Skeleton(bones));
  return root;
}
