import fs from 'node:fs';
import path from 'node:path';
import { Quaternion, Vector3 } from 'three';
import { beforeAll, describe, expect, it } from 'vitest';
import { Database } from '../../web/src/core/database.ts';
import { initWasmSync } from '../../web/src/core/wasm.ts';
import { skeletonFromGlb, parseGlbJson, type GlbSkeleton } from '../../web/src/avatar/glb-skeleton.ts';
import { findRoles, HUMANOID_ROLES, normalizeJointName, type HumanoidRole } from '../../web/src/avatar/joint-maps.ts';
import { forwardKinematics, Retargeter } from '../../web/src/avatar/retarget.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const GLB_PATH = path.join(ROOT, 'public/avatars/ubc_male.glb');
const DB_PATH = path.join(ROOT, 'public/databases/locomotion.mmdb');

/** The 22 core roles (hips, spine, chest, upperChest, neck, head, 4 per limb). */
const CORE_ROLES: readonly HumanoidRole[] = HUMANOID_ROLES;

interface SourceSkeleton {
  names: string[];
  parents: Int32Array;
  restWorldRotations: Float32Array;
  restWorldPositions: Float64Array;
}

let avatar: GlbSkeleton;
let source: SourceSkeleton;

beforeAll(() => {
  avatar = skeletonFromGlb(fs.readFileSync(GLB_PATH));
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
  const db = Database.fromBytes(fs.readFileSync(DB_PATH));
  try {
    const J = db.numJoints;
    // .mmdb rest pose (BVH rest): every rotation identity; offsets from frame 0 (constant for
    // every joint but the root).
    const rot = new Float32Array(J * 4);
    for (let j = 0; j < J; j++) rot[j * 4 + 3] = 1;
    const pos = new Float64Array(J * 3);
    forwardKinematics(db.jointParents, rot, db.localPositions.slice(0, J * 3), new Float64Array(J * 4), pos);
    source = { names: [...db.jointNames], parents: Int32Array.from(db.jointParents), restWorldRotations: rot, restWorldPositions: pos };
  } finally {
    db.free();
  }
});

function makeRetargeter(): Retargeter {
  return new Retargeter({
    sourceParents: source.parents,
    sourceRestWorldRotations: source.restWorldRotations,
    sourceRestWorldPositions: source.restWorldPositions,
    targetParents: avatar.parents,
    targetRestLocalRotations: avatar.restLocalRotations,
    targetRestLocalPositions: avatar.restLocalPositions,
    sourceRoles: findRoles(source.names),
    targetRoles: findRoles(avatar.names),
  });
}

function identityPose(J: number): Float32Array {
  const q = new Float32Array(J * 4);
  for (let j = 0; j < J; j++) q[j * 4 + 3] = 1;
  return q;
}

/** World rotations of the target from local ones (three.js, independent of retarget.ts). */
function targetWorld(local: Float32Array): Quaternion[] {
  const out: Quaternion[] = [];
  const done = new Array<boolean>(avatar.parents.length).fill(false);
  const visit = (j: number): Quaternion => {
    if (done[j]) return out[j];
    const l = new Quaternion().fromArray(local, j * 4);
    const p = avatar.parents[j];
    out[j] = p < 0 ? l : visit(p).clone().multiply(l);
    done[j] = true;
    return out[j];
  };
  for (let j = 0; j < avatar.parents.length; j++) visit(j);
  return out;
}

describe('glb-skeleton', () => {
  it('reads the GLB header and the 65-joint skin of ubc_male.glb', () => {
    const json = parseGlbJson(fs.readFileSync(GLB_PATH));
    expect(json.asset?.version).toBe('2.0');
    expect(avatar.names.length).toBe(65);
    expect(avatar.names).toContain('pelvis');
    expect(avatar.names).toContain('lowerarm_l');
    expect(avatar.parents.filter((p) => p < 0).length).toBe(1);
    expect(avatar.names[avatar.parents[avatar.names.indexOf('calf_l')]]).toBe('thigh_l');
  });

  it('rejects bytes that are not GLB 2', () => {
    expect(() => parseGlbJson(new Uint8Array(40))).toThrow(/magic/);
    const b = Buffer.from(fs.readFileSync(GLB_PATH).subarray(0, 64));
    b.writeUInt32LE(1, 4);
    expect(() => parseGlbJson(b)).toThrow(/version 1/);
  });
});

describe('findRoles', () => {
  it('normalizes names (case, separators, namespace)', () => {
    expect(normalizeJointName('mixamorig:LeftArm')).toBe('leftarm');
    expect(normalizeJointName('Armature|J_Bip_C_Hips')).toBe('jbipchips');
    expect(normalizeJointName('spine_01')).toBe('spine01');
  });

  it('finds every core role on the avatar (Unreal/Quaternius names)', () => {
    const roles = findRoles(avatar.names);
    for (const r of CORE_ROLES) expect(roles.has(r), r).toBe(true);
    const name = (r: HumanoidRole) => avatar.names[roles.get(r)!];
    expect(name('hips')).toBe('pelvis');
    expect(name('head')).toBe('Head');
    expect(name('leftLowerArm')).toBe('lowerarm_l');
    expect(name('rightToes')).toBe('ball_r');
    expect(name('upperChest')).toBe('spine_03');
  });

  it('finds every core role on the database skeleton (CMU ASF names)', () => {
    const roles = findRoles(source.names);
    for (const r of CORE_ROLES) expect(roles.has(r), r).toBe(true);
    const name = (r: HumanoidRole) => source.names[roles.get(r)!];
    expect(name('hips')).toBe('root');
    expect(name('leftLowerArm')).toBe('lradius');
    expect(name('leftHand')).toBe('lwrist');
    expect(name('rightUpperLeg')).toBe('rfemur');
    expect(roles.get('hips')).not.toBe(0); // not the VirtualRoot
  });

  it('maps Mixamo-style names', () => {
    const sides = ['Left', 'Right'];
    const names = ['Hips', 'Spine', 'Spine1', 'Spine2', 'Neck', 'Head', 'HeadTop_End'];
    for (const s of sides) names.push(...['Shoulder', 'Arm', 'ForeArm', 'Hand', 'HandIndex1', 'UpLeg', 'Leg', 'Foot', 'ToeBase'].map((n) => s + n));
    const prefixed = names.map((n) => `mixamorig:${n}`);
    const roles = findRoles(prefixed);
    for (const r of CORE_ROLES) expect(roles.has(r), r).toBe(true);
    expect(prefixed[roles.get('leftUpperArm')!]).toBe('mixamorig:LeftArm');
    expect(prefixed[roles.get('leftLowerLeg')!]).toBe('mixamorig:LeftLeg');
    expect(prefixed[roles.get('chest')!]).toBe('mixamorig:Spine1');
    expect(prefixed[roles.get('rightToes')!]).toBe('mixamorig:RightToeBase');
  });

  it('maps VRM-style names (humanoid bone names and VRoid J_Bip_*)', () => {
    const vrm = [...CORE_ROLES].reverse();
    const roles = findRoles(vrm);
    for (const r of CORE_ROLES) expect(vrm[roles.get(r)!]).toBe(r);
    const vroid = ['J_Bip_C_Hips', 'J_Bip_C_Spine', 'J_Bip_C_Chest', 'J_Bip_C_UpperChest', 'J_Bip_C_Neck', 'J_Bip_C_Head'];
    for (const s of ['L', 'R']) vroid.push(...['Shoulder', 'UpperArm', 'LowerArm', 'Hand', 'UpperLeg', 'LowerLeg', 'Foot', 'ToeBase'].map((n) => `J_Bip_${s}_${n}`));
    const r2 = findRoles(vroid.map((n) => `Root|${n}`));
    for (const r of CORE_ROLES) expect(r2.has(r), r).toBe(true);
    expect(vroid[r2.get('rightLowerArm')!]).toBe('J_Bip_R_LowerArm');
  });

  it('lets a manual override win, and rejects an override to a missing joint', () => {
    const roles = findRoles(source.names, { neck: 'upperneck', leftToes: '' });
    expect(source.names[roles.get('neck')!]).toBe('upperneck');
    expect(roles.has('leftToes')).toBe(false);
    const byNorm = findRoles(avatar.names, { head: 'NECK_01' });
    expect(avatar.names[byNorm.get('head')!]).toBe('neck_01');
    expect(byNorm.has('neck')).toBe(false); // neck_01 is taken by the override
    expect(() => findRoles(avatar.names, { head: 'nope' })).toThrow(/nope/);
  });
});

describe('Retargeter (T-pose method)', () => {
  it('source and avatar agree on left/right and facing in their rest poses', () => {
    const sr = findRoles(source.names);
    const sp = source.restWorldPositions;
    const tr = findRoles(avatar.names);
    const tp = new Float64Array(avatar.names.length * 3);
    forwardKinematics(avatar.parents, avatar.restLocalRotations, avatar.restLocalPositions, new Float64Array(avatar.names.length * 4), tp);
    const x = (p: Float64Array, i: number) => p[i * 3];
    const z = (p: Float64Array, i: number) => p[i * 3 + 2];
    // Left is +X (facing +Z, Y up) on both.
    expect(Math.sign(x(sp, sr.get('leftUpperLeg')!) - x(sp, sr.get('hips')!))).toBe(Math.sign(x(tp, tr.get('leftUpperLeg')!) - x(tp, tr.get('hips')!)));
    expect(Math.sign(x(sp, sr.get('leftHand')!) - x(sp, sr.get('hips')!))).toBe(Math.sign(x(tp, tr.get('leftHand')!) - x(tp, tr.get('hips')!)));
    // Toes in front of the ankle on both.
    expect(Math.sign(z(sp, sr.get('leftToes')!) - z(sp, sr.get('leftFoot')!))).toBe(Math.sign(z(tp, tr.get('leftToes')!) - z(tp, tr.get('leftFoot')!)));
  });

  it('gives the target rest pose for the source rest pose', () => {
    const rt = makeRetargeter();
    const T = avatar.names.length;
    const out = new Float32Array(T * 4);
    const hips = new Float32Array(3);
    const sh = findRoles(source.names).get('hips')!;
    rt.apply(identityPose(source.names.length), source.restWorldPositions.subarray(sh * 3, sh * 3 + 3), out, hips);
    for (let i = 0; i < T * 4; i++) expect(Math.abs(out[i] - avatar.restLocalRotations[i]), `${avatar.names[i >> 2]}[${i & 3}]`).toBeLessThan(1e-6);
  });

  it('bends the avatar elbow by the same 90° as the source elbow, nothing else', () => {
    const rt = makeRetargeter();
    const J = source.names.length;
    const T = avatar.names.length;
    const rest = new Float32Array(T * 4);
    const out = new Float32Array(T * 4);
    const hips = new Float32Array(3);
    rt.apply(identityPose(J), [0, 1, 0], rest, hips);

    // Source: lradius bent 90° about an arbitrary axis; its descendants follow (world = parent).
    const bend = new Quaternion().setFromAxisAngle(new Vector3(0.3, -0.5, 0.8).normalize(), Math.PI / 2);
    const pose = identityPose(J);
    const elbow = source.names.indexOf('lradius');
    for (let j = 0; j < J; j++) {
      let a = j;
      while (a >= 0 && a !== elbow) a = source.parents[a];
      if (a === elbow) bend.toArray(pose, j * 4);
    }
    rt.apply(pose, [0, 1, 0], out, hips);

    const restWorld = targetWorld(rest);
    const nowWorld = targetWorld(out);
    const lower = avatar.names.indexOf('lowerarm_l');
    expect(nowWorld[lower].angleTo(restWorld[lower])).toBeCloseTo(Math.PI / 2, 3);
    // The world delta is the source's bend itself (both skeletons share world axes).
    const delta = nowWorld[lower].clone().multiply(restWorld[lower].clone().invert());
    expect(Math.abs(delta.dot(bend))).toBeCloseTo(1, 5);
    // The hand and fingers turn with the forearm; every other joint keeps its world rotation.
    const moved = new Set(['lowerarm_l', 'hand_l']);
    for (let t = 0; t < T; t++) {
      let a = t;
      while (a >= 0 && avatar.names[a] !== 'hand_l') a = avatar.parents[a];
      if (a >= 0) moved.add(avatar.names[t]);
    }
    for (let t = 0; t < T; t++) {
      const n = avatar.names[t];
      // |dot| rather than angleTo: acos near 1 turns float32 rounding into ~1e-3 rad.
      if (!moved.has(n)) expect(Math.abs(nowWorld[t].dot(restWorld[t])), n).toBeGreaterThan(1 - 1e-6);
      else expect(nowWorld[t].angleTo(restWorld[t]), n).toBeCloseTo(Math.PI / 2, 3);
      // Only the forearm's local rotation changes.
      if (n !== 'lowerarm_l') {
        for (let c = 0; c < 4; c++) expect(Math.abs(out[t * 4 + c] - rest[t * 4 + c]), n).toBeLessThan(1e-6);
      }
    }
  });

  it('scales the hips translation by the ratio of hip heights', () => {
    const rt = makeRetargeter();
    // Avatar: 1.81 m tall, pelvis ≈ 0.95 m up; CMU subjects are of similar height.
    expect(rt.targetHipsHeight).toBeGreaterThan(0.85);
    expect(rt.targetHipsHeight).toBeLessThan(1.05);
    expect(rt.hipsScale).toBeGreaterThan(0.8);
    expect(rt.hipsScale).toBeLessThan(1.3);
    const out = new Float32Array(avatar.names.length * 4);
    const hips = new Float32Array(3);
    rt.apply(identityPose(source.names.length), [0.5, 0.9, -2], out, hips);
    // The hips' parent is `root` (rotated -90° about X, at the origin): back to world to compare.
    const root = avatar.parents[avatar.names.indexOf('pelvis')];
    const world = new Vector3(hips[0], hips[1], hips[2]).applyQuaternion(new Quaternion().fromArray(avatar.restLocalRotations, root * 4));
    expect(world.x).toBeCloseTo(0.5 * rt.hipsScale, 5);
    expect(world.y).toBeCloseTo(0.9 * rt.hipsScale, 5);
    expect(world.z).toBeCloseTo(-2 * rt.hipsScale, 5);
  });

  it('apply() runs 10,000 times on one set of buffers (no per-call allocation by design)', () => {
    const rt = makeRetargeter();
    const J = source.names.length;
    const pose = identityPose(J);
    const bend = new Quaternion().setFromAxisAngle(new Vector3(0, 0, 1), 0.7);
    bend.toArray(pose, source.names.indexOf('lfemur') * 4);
    const out = new Float32Array(avatar.names.length * 4);
    const first = new Float32Array(out.length);
    const hips = new Float32Array(3);
    const hipsPos = [0, 0.9, 0];
    rt.apply(pose, hipsPos, first, hips);
    for (let i = 0; i < 10_000; i++) rt.apply(pose, hipsPos, out, hips);
    expect(out).toEqual(first);
    expect(out.every(Number.isFinite)).toBe(true);
  });
});
