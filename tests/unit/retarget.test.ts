import fs from 'node:fs';
import path from 'node:path';
import { Quaternion, Vector3 } from 'three';
import { beforeAll, describe, expect, it } from 'vitest';
import { Database } from '../../web/src/core/database.ts';
import { initWasmSync } from '../../web/src/core/wasm.ts';
import { skeletonFromGlb, parseGlbJson, type GlbSkeleton } from '../../web/src/avatar/glb-skeleton.ts';
import { findRoles, HUMANOID_ROLES, normalizeJointName, type HumanoidRole } from '../../web/src/avatar/joint-maps.ts';
import { Grounding } from '../../web/src/avatar/grounding.ts';
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
/** Sampled database frames: world rotations, hips positions and contacts. */
let toeHeight: number;
let walk: { worldRotations: Float32Array[]; hips: Float64Array[]; contacts: [boolean, boolean][] };

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
    toeHeight = (db.inspect() as { toe_height_in_contact: number }).toe_height_in_contact;
    const hips = findRoles(source.names).get('hips')!;
    walk = { worldRotations: [], hips: [], contacts: [] };
    // Every 5th frame of the whole database (walks, runs, turns, stops; mirrored too).
    for (let f = 0; f < db.numFrames; f += 5) {
      const wr = new Float64Array(J * 4);
      const wp = new Float64Array(J * 3);
      forwardKinematics(db.jointParents, db.localRotations.subarray(f * J * 4, (f + 1) * J * 4), db.localPositions.subarray(f * J * 3, (f + 1) * J * 3), wr, wp);
      walk.worldRotations.push(Float32Array.from(wr));
      walk.hips.push(wp.slice(hips * 3, hips * 3 + 3));
      walk.contacts.push([db.contacts[f * 2] !== 0, db.contacts[f * 2 + 1] !== 0]);
    }
  } finally {
    db.free();
  }
});

function makeRetargeter(alignBones = true): Retargeter {
  return new Retargeter({
    alignBones,
    sourceToeHeight: alignBones ? toeHeight : undefined,
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

  it('gives the target rest pose for the source rest pose (plain T-pose method)', () => {
    const rt = makeRetargeter(false);
    const T = avatar.names.length;
    const out = new Float32Array(T * 4);
    const hips = new Float32Array(3);
    const sh = findRoles(source.names).get('hips')!;
    rt.apply(identityPose(source.names.length), source.restWorldPositions.subarray(sh * 3, sh * 3 + 3), out, hips);
    for (let i = 0; i < T * 4; i++) expect(Math.abs(out[i] - avatar.restLocalRotations[i]), `${avatar.names[i >> 2]}[${i & 3}]`).toBeLessThan(1e-6);
  });

  it('bends the avatar elbow by the same 90° as the source elbow, nothing else', () => {
    const rt = makeRetargeter(false);
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
    // Heights map about the floors (the planted toe heights): y_t = (y_s − floor_s)·s + floor_t.
    expect(world.y).toBeCloseTo((0.9 - rt.sourceFloor) * rt.hipsScale + rt.targetFloor, 5);
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

  /** Avatar world joint positions (T×3) for a source pose. */
  function avatarPose(rt: Retargeter, worldRotations: Float32Array, hips: ArrayLike<number>): Float64Array {
    const T = avatar.names.length;
    const local = new Float32Array(T * 4);
    const hipsLocal = new Float32Array(3);
    rt.apply(worldRotations, hips, local, hipsLocal);
    const positions = Float64Array.from(avatar.restLocalPositions);
    positions.set(hipsLocal, rt.targetHips * 3);
    const out = new Float64Array(T * 3);
    forwardKinematics(avatar.parents, local, positions, new Float64Array(T * 4), out);
    return out;
  }

  it('aligns limb bones: each avatar limb bone points along the source bone', () => {
    const rt = makeRetargeter(true);
    const sr = findRoles(source.names);
    const tr = findRoles(avatar.names);
    const f = 40;
    // A source bone now: its rest offset turned by its parent's world rotation.
    const local = (j: number) => new Vector3().fromArray(source.restWorldPositions, j * 3).sub(new Vector3().fromArray(source.restWorldPositions, source.parents[j] * 3));
    const tp = avatarPose(rt, walk.worldRotations[f], walk.hips[f]);
    for (const [a, b] of [['leftFoot', 'leftToes'], ['rightLowerLeg', 'rightFoot'], ['leftLowerArm', 'leftHand']] as [HumanoidRole, HumanoidRole][]) {
      const s = sr.get(b)!;
      const sDir = local(s).applyQuaternion(new Quaternion().fromArray(walk.worldRotations[f], source.parents[s] * 4)).normalize();
      const tDir = new Vector3().fromArray(tp, tr.get(b)! * 3).sub(new Vector3().fromArray(tp, tr.get(a)! * 3)).normalize();
      expect(tDir.angleTo(sDir), `${a}→${b}`).toBeLessThan(0.01);
    }
  });

  it('keeps the avatar toes on the floor while the source foot is in contact (within 3 cm)', () => {
    const T = avatar.names.length;
    const tr = findRoles(avatar.names);
    const rest = new Float64Array(T * 3);
    forwardKinematics(avatar.parents, avatar.restLocalRotations, avatar.restLocalPositions, new Float64Array(T * 4), rest);
    const toes = [tr.get('leftToes')!, tr.get('rightToes')!];
    const standing = (rest[toes[0] * 3 + 1] + rest[toes[1] * 3 + 1]) / 2;
    const report: string[] = [];
    const hips = new Float64Array(3);
    for (const mode of ['plain T-pose', 'aligned', 'aligned + grounding'] as const) {
      const rt = makeRetargeter(mode !== 'plain T-pose');
      const grounding = new Grounding(standing);
      const errors: number[] = [];
      for (let f = 0; f < walk.worldRotations.length; f++) {
        hips.set(walk.hips[f]);
        if (mode === 'aligned + grounding') hips[1] += grounding.offset / rt.hipsScale;
        const tp = avatarPose(rt, walk.worldRotations[f], hips);
        const [l, r] = [tp[toes[0] * 3 + 1], tp[toes[1] * 3 + 1]];
        const contacts = (walk.contacts[f][0] ? 1 : 0) | (walk.contacts[f][1] ? 2 : 0);
        // Skip the first second while the offset settles (frames are 5 database frames apart).
        if (f > 12) for (let side = 0; side < 2; side++) if (contacts & (1 << side)) errors.push((side ? r : l) - standing);
        grounding.update(l, r, contacts, 5 / 60);
      }
      const abs = errors.map(Math.abs).sort((a, b) => a - b);
      const signed = [...errors].sort((a, b) => a - b);
      const [median, p90] = [signed[signed.length >> 1], abs[Math.floor(abs.length * 0.9)]];
      report.push(`${mode}: avatar toe over its standing height in contact: median ${(median * 100).toFixed(1)} cm, |p90| ${(p90 * 100).toFixed(1)} cm (${errors.length} foot-frames)`);
      expect(errors.length).toBeGreaterThan(1000);
      if (mode === 'aligned + grounding') {
        expect(Math.abs(median)).toBeLessThan(0.01);
        expect(p90).toBeLessThan(0.03);
      }
    }
    console.log(report.join('\n'));
  });
});
