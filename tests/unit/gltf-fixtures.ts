// Motion in the web's formats for the tests, made here from a ../shared BVH take: three.js's
// BVHLoader reads it, @gltf-transform writes it out as
// - a GLB with animation clips, shaped like a DCC export: an "Armature" node (turned, scaled
//   0.01: the bones in centimetres), every bone with its own rest rotation (so the bones' axes
//   are not the BVH's), several clips;
// - a VRM Animation (.vrma): the VRMC_vrm_animation extension's humanoid map naming the bones,
//   whose names say nothing ("Bone0", "Bone1"…), hips translation and bone rotations animated.
// Both describe exactly the BVH's world motion, so a database built from them must match the
// BVH's. Also the broken variants the importer must name.
import fs from 'node:fs';
import { Document, NodeIO, type Node as GltfNode } from '@gltf-transform/core';
import * as THREE from 'three';
import { BVHLoader } from 'three/addons/loaders/BVHLoader.js';

/** The CMU ASF skeleton's joints → VRM humanoid bones. */
export const CMU_VRM_BONES: Record<string, string> = {
  root: 'hips', lfemur: 'leftUpperLeg', ltibia: 'leftLowerLeg', lfoot: 'leftFoot', ltoes: 'leftToes',
  rfemur: 'rightUpperLeg', rtibia: 'rightLowerLeg', rfoot: 'rightFoot', rtoes: 'rightToes',
  lowerback: 'spine', upperback: 'chest', thorax: 'upperChest', lowerneck: 'neck', head: 'head',
  lclavicle: 'leftShoulder', lhumerus: 'leftUpperArm', lradius: 'leftLowerArm', lwrist: 'leftHand',
  rclavicle: 'rightShoulder', rhumerus: 'rightUpperArm', rradius: 'rightLowerArm', rwrist: 'rightHand',
};

interface Take {
  bones: THREE.Bone[];
  /** Per bone (by index): key times, positions (xyz per key, offset included), quaternions (xyzw). */
  times: Float32Array<ArrayBufferLike>;
  positions: Map<string, Float32Array<ArrayBufferLike>>;
  rotations: Map<string, Float32Array<ArrayBufferLike>>;
}

export function readBvh(file: string): Take {
  const { skeleton, clip } = new BVHLoader().parse(fs.readFileSync(file, 'utf8'));
  const bones = skeleton.bones.filter((b) => b.name !== 'ENDSITE');
  const positions = new Map<string, Float32Array<ArrayBufferLike>>();
  const rotations = new Map<string, Float32Array<ArrayBufferLike>>();
  let times: Float32Array<ArrayBufferLike> = new Float32Array();
  for (const track of clip.tracks) {
    const [name, property] = track.name.split('.');
    times = track.times;
    (property === 'position' ? positions : rotations).set(name, track.values);
  }
  return { bones, times, positions, rotations };
}

/** A fixed, arbitrary rotation per bone: its glTF axes differ from the BVH's by it. */
function axes(i: number): THREE.Quaternion {
  return new THREE.Quaternion().setFromEuler(new THREE.Euler(0.3 * ((i % 5) - 2), 0.7 * ((i % 3) - 1), 0.45 * ((i % 4) - 1.5)));
}

export interface GlbOptions {
  /** Clips: [name, first key, end key) ranges of the take. */
  clips: [string, number, number][];
  /** The Armature parent (turned −90° about X over a Z-up skeleton, scale 0.01) and per-bone axes. */
  dcc?: boolean;
  /** VRM Animation: bones named Bone<i>, the humanoid map in VRMC_vrm_animation. */
  vrma?: boolean;
  interpolation?: 'LINEAR' | 'STEP' | 'CUBICSPLINE';
}

/**
 * The BVH take as glTF. With `dcc`, every bone j gets axes A_j (local q' = A_p⁻¹·q·A_j,
 * t' = A_p⁻¹·t) and the skeleton is expressed Z-up in centimetres under an Armature node that
 * turns and scales it back: the world motion is the BVH's.
 */
export async function bvhToGltf(take: Take, options: GlbOptions): Promise<Uint8Array> {
  const doc = new Document();
  const buffer = doc.createBuffer();
  const index = new Map(take.bones.map((b, i) => [b, i]));
  // The Armature turns Z-up (what the bones are written in) to Y-up and centimetres to metres.
  const turn = new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(1, 0, 0), -Math.PI / 2);
  const unit = options.dcc ? 100 : 1;
  const A = take.bones.map((_, i) => (options.dcc ? axes(i) : new THREE.Quaternion()));
  // The root's parent frame: the Armature's inverse (Z-up, cm) for a DCC export.
  const parentAxes = (b: THREE.Bone) => (b.parent instanceof THREE.Bone && index.has(b.parent) ? A[index.get(b.parent)!] : options.dcc ? turn : new THREE.Quaternion());
  const local = (b: THREE.Bone, t: THREE.Vector3, q: THREE.Quaternion) => {
    const p = parentAxes(b).clone().invert();
    return { t: t.clone().applyQuaternion(p).multiplyScalar(unit), q: p.multiply(q).multiply(A[index.get(b)!]).normalize() };
  };
  const nodes = new Map<THREE.Bone, GltfNode>();
  for (const [i, b] of take.bones.entries()) {
    const rest = local(b, b.position, new THREE.Quaternion());
    const node = doc.createNode(options.vrma ? `Bone${i}` : b.name).setTranslation(rest.t.toArray() as [number, number, number]).setRotation(rest.q.toArray() as [number, number, number, number]);
    nodes.set(b, node);
    if (b.parent instanceof THREE.Bone && nodes.has(b.parent)) nodes.get(b.parent)!.addChild(node);
  }
  const root = nodes.get(take.bones[0])!;
  const scene = doc.createScene('scene');
  if (options.dcc) {
    const armature = doc.createNode('Armature').setRotation(turn.toArray() as [number, number, number, number]).setScale([1 / unit, 1 / unit, 1 / unit]);
    armature.addChild(root);
    scene.addChild(armature);
  } else scene.addChild(root);

  const interpolation = options.interpolation ?? 'LINEAR';
  for (const [name, from, to] of options.clips) {
    const anim = doc.createAnimation(name);
    const times = take.times.slice(from, to).map((t) => t - take.times[from]);
    const input = doc.createAccessor().setType('SCALAR').setArray(new Float32Array(times)).setBuffer(buffer);
    const add = (node: GltfNode, path: 'translation' | 'rotation', values: number[], width: number) => {
      let array = values;
      if (interpolation === 'CUBICSPLINE') {
        // Zero tangents: in-tangent, value, out-tangent per key.
        array = [];
        for (let k = 0; k < values.length / width; k++) array.push(...new Array(width).fill(0), ...values.slice(k * width, (k + 1) * width), ...new Array(width).fill(0));
      }
      const output = doc.createAccessor().setType(width === 4 ? 'VEC4' : 'VEC3').setArray(new Float32Array(array)).setBuffer(buffer);
      const sampler = doc.createAnimationSampler().setInput(input).setOutput(output).setInterpolation(interpolation);
      anim.addSampler(sampler).addChannel(doc.createAnimationChannel().setTargetNode(node).setTargetPath(path).setSampler(sampler));
    };
    for (const b of take.bones) {
      const node = nodes.get(b)!;
      const rot = take.rotations.get(b.name)!;
      const pos = take.positions.get(b.name)!;
      const isRoot = b === take.bones[0];
      const t: number[] = [];
      const q: number[] = [];
      for (let k = from; k < to; k++) {
        const l = local(b, new THREE.Vector3().fromArray(pos, 3 * k), new THREE.Quaternion().fromArray(rot, 4 * k));
        t.push(...l.t.toArray());
        q.push(...l.q.toArray());
      }
      if (isRoot) add(node, 'translation', t, 3);
      add(node, 'rotation', q, 4);
    }
  }
  let glb: Uint8Array = await new NodeIO().writeBinary(doc);
  if (options.vrma) {
    const humanBones: Record<string, { node: number }> = {};
    const order = doc.getRoot().listNodes();
    for (const b of take.bones) {
      const bone = CMU_VRM_BONES[b.name];
      if (bone) humanBones[bone] = { node: order.indexOf(nodes.get(b)!) };
    }
    glb = editGlbJson(glb, (json) => {
      json.extensionsUsed = [...((json.extensionsUsed as string[]) ?? []), 'VRMC_vrm_animation'];
      json.extensions = { ...((json.extensions as object) ?? {}), VRMC_vrm_animation: { specVersion: '1.0', humanoid: { humanBones } } };
    });
  }
  return glb;
}

/** A GLB with its JSON chunk edited (the binary chunk kept as it is). */
export function editGlbJson(glb: Uint8Array, edit: (json: Record<string, unknown>) => void): Uint8Array {
  const view = new DataView(glb.buffer, glb.byteOffset, glb.byteLength);
  const jsonLength = view.getUint32(12, true);
  const json = JSON.parse(new TextDecoder().decode(glb.subarray(20, 20 + jsonLength))) as Record<string, unknown>;
  edit(json);
  let text = new TextEncoder().encode(JSON.stringify(json));
  const padded = new Uint8Array(Math.ceil(text.length / 4) * 4).fill(0x20);
  padded.set(text);
  text = padded;
  const rest = glb.subarray(20 + jsonLength);
  const out = new Uint8Array(20 + text.length + rest.length);
  const o = new DataView(out.buffer);
  out.set(glb.subarray(0, 12));
  o.setUint32(8, out.length, true);
  o.setUint32(12, text.length, true);
  o.setUint32(16, 0x4e4f534a, true);
  out.set(text, 20);
  out.set(rest, 20 + text.length);
  return out;
}
