// The avatar on the runtime's retargeting, in real WASM (Node): the shipped avatar's bones take
// their roles by the runtime's conventions; walking, its toes stand on the floor while a foot
// is planted and its hips stay over the character's root (one position space).
import fs from 'node:fs';
import path from 'node:path';
import * as THREE from 'three';
import { beforeAll, describe, expect, it } from 'vitest';
import { Avatar, Character, Database, ROLE_NAMES, findRoles, initWasmSync, liveObjects } from '../../web/src/index.ts';
import { glbScene } from './glb-bones.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const GLB = new Uint8Array(fs.readFileSync(path.join(ROOT, 'public/avatars/ubc_male.glb')));
const DB = new Uint8Array(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.mmdb')));

let db: Database;
beforeAll(() => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
  db = Database.fromBytes(DB, 'locomotion.mmdb');
});

describe('roles (the runtime vocabulary on avatar bones)', () => {
  it('finds every role of the shipped avatar (Unreal/Quaternius names)', async () => {
    const avatar = await Avatar.load(glbScene(GLB), { name: 'ubc_male' });
    for (const r of ROLE_NAMES) expect(avatar.roles.has(r), r).toBe(true);
    const name = (r: (typeof ROLE_NAMES)[number]) => avatar.bones[avatar.roles.get(r)!].name;
    expect(name('hips')).toBe('pelvis');
    expect(name('head')).toBe('Head');
    expect(name('left_lower_arm')).toBe('lowerarm_l');
    expect(name('right_toe')).toBe('ball_r');
    expect(name('upper_chest')).toBe('spine_03');
    avatar.dispose();
  });

  it('finds the roles of an avatar whose bone names say nothing, from its rest pose (the same bones as by name)', async () => {
    const named = await Avatar.load(glbScene(GLB), { name: 'ubc_male' });
    const scene = glbScene(GLB);
    let k = 0;
    scene.traverse((o) => {
      if ((o as THREE.Bone).isBone) o.name = `Bone.${String(k++).padStart(3, '0')}`;
    });
    const anonymous = await Avatar.load(scene, { name: 'anonymous' });
    const core = ['hips', 'spine', 'head', 'left_upper_leg', 'left_lower_leg', 'left_foot', 'right_upper_leg', 'right_lower_leg', 'right_foot', 'left_upper_arm', 'left_lower_arm', 'left_hand', 'right_upper_arm', 'right_lower_arm', 'right_hand'] as const;
    const wrong = core.filter((r) => anonymous.roles.get(r) !== named.roles.get(r));
    expect(wrong, `roles found elsewhere: ${wrong.map((r) => `${r} → ${anonymous.roles.get(r)} (by name ${named.roles.get(r)})`).join(', ')}`).toEqual([]);
    named.dispose();
    anonymous.dispose();
  });

  it('maps Mixamo names and takes overrides; a bad override is an error naming it', () => {
    const names = ['Hips', 'Spine', 'Spine1', 'Spine2', 'Neck', 'Head'];
    const parents = [-1, 0, 1, 2, 3, 4];
    for (const s of ['Left', 'Right']) {
      const base = names.length;
      names.push(...['Shoulder', 'Arm', 'ForeArm', 'Hand'].map((n) => s + n), ...['UpLeg', 'Leg', 'Foot', 'ToeBase'].map((n) => s + n));
      parents.push(3, base, base + 1, base + 2, 0, base + 4, base + 5, base + 6);
    }
    const prefixed = names.map((n) => `mixamorig:${n}`);
    const roles = findRoles(prefixed, parents);
    for (const r of ROLE_NAMES) expect(roles.has(r), r).toBe(true);
    expect(prefixed[roles.get('left_upper_arm')!]).toBe('mixamorig:LeftArm');
    expect(prefixed[roles.get('chest')!]).toBe('mixamorig:Spine1');
    const o = findRoles(prefixed, parents, { head: 'mixamorig:Neck', left_toe: '' });
    expect(prefixed[o.get('head')!]).toBe('mixamorig:Neck');
    expect(o.has('left_toe')).toBe(false);
    expect(() => findRoles(prefixed, parents, { head: 'nope' })).toThrow(/nope/);
    expect(() => findRoles(prefixed, parents, { hed: 'Head' } as never)).toThrow(/unknown role 'hed'/);
  });

  it('rejects an object without skinned meshes, and one without hips', async () => {
    await expect(Avatar.load(new THREE.Group(), { name: 'empty' })).rejects.toThrow(/empty: no skinned mesh/);
    const g = new THREE.Group();
    const bone = new THREE.Bone();
    bone.name = 'tail';
    g.add(bone);
    const mesh = new THREE.SkinnedMesh(new THREE.BufferGeometry(), new THREE.MeshBasicMaterial());
    g.add(mesh);
    mesh.bind(new THREE.Skeleton([bone]));
    await expect(Avatar.load(g, { name: 'tail.glb' })).rejects.toThrow(/tail\.glb: no hips bone/);
  });
});

describe('Character with the shipped avatar', () => {
  it('walks with its toes on the floor in contact and its hips over the root; frees everything', async () => {
    const before = liveObjects();
    const avatar = await Avatar.load(glbScene(GLB), { name: 'ubc_male' });
    const character = new Character(db.retain(), avatar);
    const scene = new THREE.Scene();
    scene.add(character.object3d);
    expect(character.worldScale).toBeGreaterThan(0.85);
    expect(character.worldScale).toBeLessThan(1.1);
    const toeErrors: number[] = [];
    let worstHips = 0;
    const hips = avatar.bone('hips')!;
    const v = new THREE.Vector3();
    // 40 s: walk, turn, run, stop, strafe — the scripts the quality harness uses.
    for (let step = 0; step < 60 * 40; step++) {
      const t = step / 60;
      const phase = Math.floor(t / 5) % 4;
      const dir = [[0, 1], [0.7, 0.7], [-1, 0], [0, 0]][phase];
      character.setMove(dir[0], dir[1], { run: phase === 1 });
      character.update(1 / 60);
      if (t < 1) continue; // the grounding settles
      const c = character.contacts;
      for (let side = 0; side < 2; side++) if (c & (1 << side)) toeErrors.push(avatar.toeHeights[side] - avatar.standingToeHeight);
      const r = character.root;
      hips.getWorldPosition(v);
      worstHips = Math.max(worstHips, Math.hypot(v.x - r.x, v.z - r.z));
    }
    const abs = toeErrors.map(Math.abs).sort((a, b) => a - b);
    const signed = [...toeErrors].sort((a, b) => a - b);
    const [median, p90] = [signed[signed.length >> 1], abs[Math.floor(abs.length * 0.9)]];
    console.log(`avatar toe over its standing height in contact: median ${(median * 100).toFixed(2)} cm, |p90| ${(p90 * 100).toFixed(2)} cm over ${toeErrors.length} foot-frames; hips ↔ root worst ${(worstHips * 100).toFixed(1)} cm`);
    expect(toeErrors.length).toBeGreaterThan(1000);
    expect(Math.abs(median)).toBeLessThan(0.01);
    expect(p90).toBeLessThan(0.03);
    expect(worstHips).toBeLessThan(0.12);
    character.dispose();
    expect(liveObjects().characters).toBe(before.characters);
    expect(liveObjects().retargeters).toBe(before.retargeters);
  });
});

describe('Avatar.clone (a shared room shows others with the page own model)', () => {
  it('is at rest however the original is posed, finds the same roles, shares geometry and materials, and frees them with the last user', async () => {
    const avatar = await Avatar.load(glbScene(GLB), { name: 'ubc_male' });
    const character = new Character(db.retain(), avatar);
    for (let step = 0; step < 90; step++) (character.setMove(0.5, 1), character.update(1 / 60));
    const posed = avatar.bones.map((b) => b.quaternion.clone());
    const copy = avatar.clone();
    // The original keeps its pose; the copy has the rest pose of a fresh load.
    avatar.bones.forEach((b, i) => expect(b.quaternion.equals(posed[i])).toBe(true));
    const fresh = await Avatar.load(glbScene(GLB), { name: 'ubc_male' });
    // (Components, not angleTo: its acos near 1 turns float32 rounding into 5e-4 rad.)
    copy.bones.forEach((b, i) => b.quaternion.toArray().forEach((v, k) => expect(Math.abs(v - fresh.bones[i].quaternion.toArray()[k])).toBeLessThan(1e-6)));
    // The posed original differs from rest (the check above can fail).
    expect(avatar.bones.some((b, i) => b.quaternion.angleTo(fresh.bones[i].quaternion) > 0.05)).toBe(true);
    expect([...copy.roles]).toEqual([...avatar.roles]);
    expect(copy.standingToeHeight).toBeCloseTo(fresh.standingToeHeight, 6);
    const meshes = (a: Avatar) => {
      const out: THREE.SkinnedMesh[] = [];
      a.object.traverse((o) => (o as THREE.SkinnedMesh).isSkinnedMesh && out.push(o as THREE.SkinnedMesh));
      return out;
    };
    const [mine, theirs] = [meshes(avatar), meshes(copy)];
    expect(theirs.length).toBe(mine.length);
    theirs.forEach((m, i) => (expect(m.geometry).toBe(mine[i].geometry), expect(m.material).toBe(mine[i].material)));
    let disposed = 0;
    mine[0].geometry.addEventListener('dispose', () => disposed++);
    copy.dispose();
    copy.dispose(); // twice is once
    expect(disposed).toBe(0); // the original still draws them
    character.dispose(); // disposes the original avatar: the last user
    expect(disposed).toBe(1);
    fresh.dispose();
  });
});

describe('Avatar.coreSkinning (the crowd: bone and skin matrices from the core)', () => {
  it('gives the bones and skins the matrices three.js computes, walking, turning and running; off again, three.js poses', async () => {
    const model = await Avatar.load(glbScene(GLB), { name: 'ubc_male' });
    const core = model.clone();
    core.object.updateMatrixWorld(true);
    const restY = core.bones.map((b) => b.matrixWorld.elements[13]); // heights at rest
    const character = new Character(db, model);
    core.bind(db);
    core.coreSkinning = true;
    expect(core.coreSkinning).toBe(true);
    const skeletons = (a: Avatar) => {
      const out = new Set<THREE.Skeleton>();
      a.object.traverse((o) => (o as THREE.SkinnedMesh).isSkinnedMesh && out.add((o as THREE.SkinnedMesh).skeleton));
      return [...out];
    };
    let worst = 0;
    for (let step = 0; step < 240; step++) {
      const phase = Math.floor(step / 60);
      character.setMove(phase === 2 ? 1 : 0, phase === 2 ? 0 : 1, { run: phase === 1 });
      character.update(1 / 60); // poses `model` the three.js way (it is the character's)
      core.pose(character.runtime, 1 / 60);
      for (const [a, b] of skeletons(model).map((k, i) => [k, skeletons(core)[i]] as const)) {
        a.update();
        b.update();
        for (let k = 0; k < a.boneMatrices!.length; k++) worst = Math.max(worst, Math.abs(a.boneMatrices![k] - b.boneMatrices![k]));
      }
      model.bones.forEach((bone, i) => {
        const e = core.bones[i].matrixWorld.elements;
        bone.matrixWorld.elements.forEach((v, k) => (worst = Math.max(worst, Math.abs(v - e[k]))));
      });
      expect(core.toeHeights[0]).toBeCloseTo(model.toeHeights[0], 4);
    }
    console.log(`core skinning vs three.js over 240 frames: largest matrix element difference ${worst.toExponential(2)}`);
    expect(worst).toBeLessThan(1e-4);
    // A clone of it starts at rest like any clone, and it keeps the core's skinning.
    const copy = core.clone();
    expect(copy.coreSkinning).toBe(false);
    copy.object.updateMatrixWorld(true);
    copy.bones.forEach((b, i) => expect(b.matrixWorld.elements[13]).toBeCloseTo(restY[i], 4));
    expect(core.coreSkinning).toBe(true);
    copy.dispose();
    core.resetToRest(); // at rest too, still the core's
    core.bones.forEach((b, i) => expect(b.matrixWorld.elements[13]).toBeCloseTo(restY[i], 4));
    expect(core.coreSkinning).toBe(true);
    core.coreSkinning = false;
    expect([core.coreSkinning, core.bones.every((b) => b.matrixAutoUpdate && b.matrixWorldAutoUpdate)]).toEqual([false, true]);
    core.dispose();
    character.dispose();
  });
});
