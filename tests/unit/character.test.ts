// The character in real WASM (Node): the runtime wrapper walks where it is asked to with its
// world pose as zero-copy views; the public Character speaks the caller's frame (one position
// space) and shares one database between characters; freeing releases WASM memory.
import fs from 'node:fs';
import path from 'node:path';
import * as THREE from 'three';
import { beforeAll, describe, expect, it } from 'vitest';
import { Character, CharacterRuntime, Crowd, Database, createDrive, createMoveInput, initWasmSync, liveObjects } from '../../web/src/index.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const DB = new Uint8Array(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.mmdb')));

let db: Database;
beforeAll(() => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
  db = Database.fromBytes(DB, 'locomotion.mmdb');
});

describe('CharacterRuntime (WASM in Node)', () => {
  it('walks forward, turns, and its world pose is a view of WASM memory', () => {
    const c = new CharacterRuntime(db);
    try {
      const input = createDrive();
      const start = Array.from(c.root);
      input.moveZ = 1;
      c.setDrive(input);
      for (let step = 0; step < 120; step++) c.update(1 / 60);
      expect(c.root[2] - start[2]).toBeGreaterThan(1.5);
      expect(Math.abs(c.root[0] - start[0])).toBeLessThan(0.5);
      // The world pose is a view, not a copy: the same memory sees the next update.
      const rotations = c.worldRotations;
      const before = rotations.slice();
      c.update(1 / 60);
      expect(c.worldRotations.byteOffset).toBe(rotations.byteOffset);
      expect(Array.from(c.worldRotations)).not.toEqual(Array.from(before));
      for (let k = 0; k < c.numJoints; k++) {
        const q = c.worldRotations.subarray(4 * k, 4 * k + 4);
        expect(Math.hypot(q[0], q[1], q[2], q[3])).toBeCloseTo(1, 4);
      }
      // Joint 0 is the root: the world pose starts at it; the hips stand ~1 m above it.
      expect(c.worldPositions[0]).toBeCloseTo(c.root[0], 5);
      const hips = db.roles.get('hips')!;
      expect(c.worldPositions[3 * hips + 1]).toBeGreaterThan(0.7);
      expect(c.searches).toBeGreaterThan(10);
      expect(c.transitions).toBeGreaterThan(0);
    } finally {
      c.free();
    }
    expect(() => c.update(1 / 60)).toThrow(/after free/);
  });

  it('takes settings as JSON and rejects typos', () => {
    const c = new CharacterRuntime(db, { beta_trajectory: 2.5 });
    try {
      c.setSettings({ clamp_distance: 0.3, search_method: 'simd' });
      const s = c.settings();
      expect(s['beta_trajectory']).toBe(2.5);
      expect(s['clamp_distance']).toBeCloseTo(0.3, 6);
      expect(s['search_method']).toBe('simd');
      expect(s['foot_lock']).toBe(true);
      expect(() => c.setSettings({ clamp_distnce: 0.3 })).toThrow(/clamp_distnce/);
      expect(() => new CharacterRuntime(db, { nope: 1 })).toThrow(/nope/);
    } finally {
      c.free();
    }
  });

  it('exposes the trajectory it asked for, the matched one and the simulated character', () => {
    const c = new CharacterRuntime(db);
    try {
      const input = createDrive();
      input.moveX = 1; // walk toward +X
      c.setDrive(input);
      for (let step = 0; step < 90; step++) c.update(1 / 60);
      const predicted = c.predictedPositions;
      expect(predicted.length).toBe(9);
      const sim = c.simulation;
      expect(predicted[0]).toBeGreaterThan(sim[0]);
      expect(predicted[6]).toBeGreaterThan(predicted[3]);
      expect(predicted[3]).toBeGreaterThan(predicted[0]);
      // The root stays within α (0.15 m) of the simulated character.
      expect(Math.hypot(c.root[0] - sim[0], c.root[2] - sim[2])).toBeLessThanOrEqual(0.15 + 1e-4);
      // The matched trajectory (the frame playing's features, in the world) also heads +X.
      const m = c.matchedTrajectory();
      expect(m.length).toBe(12);
      expect(m[8]).toBeGreaterThan(c.root[0] + 0.5);
      expect(c.searchCost).toBeGreaterThanOrEqual(0);
    } finally {
      c.free();
    }
  });

  it('follows a path square and rejects a bad path', () => {
    const c = new CharacterRuntime(db);
    try {
      // A 4 m square walked at 1.5 m/s, looping, starting where the character stands.
      c.setPath(new Float32Array([0, 0, 0, 4, -4, 4, -4, 0]), new Float32Array([1.5, 1.5, 1.5, 1.5]), true);
      let worst = 0;
      for (let step = 0; step < 600; step++) {
        c.update(1 / 60);
        const [x, , z] = c.root;
        const d = Math.min(Math.abs(x), Math.abs(x + 4), Math.abs(z), Math.abs(z - 4));
        const inside = x <= 0.2 && x >= -4.2 && z >= -0.2 && z <= 4.2;
        worst = Math.max(worst, inside ? d : Infinity);
      }
      expect(worst).toBeLessThanOrEqual(0.15 + 0.02);
      expect(() => c.setPath(new Float32Array([0, 0]), new Float32Array([]), false)).toThrow(/at least 2 points/);
      expect(() => c.setPath(new Float32Array([0, 0, 1]), new Float32Array([1]), false)).toThrow(/pairs/);
      c.setDrive(createDrive()); // move input again
      c.update(1 / 60);
    } finally {
      c.free();
    }
  });
});

describe('Character (the public API)', () => {
  it('shares one database; dispose frees the runtime and, with the last owner, the database', () => {
    const before = liveObjects();
    const shared = Database.fromBytes(DB, 'shared');
    const a = new Character(shared, null);
    const b = new Character(shared, null);
    shared.release(); // the characters hold it now
    expect(liveObjects().characters - before.characters).toBe(2);
    expect(liveObjects().databases - before.databases).toBe(1);
    a.dispose();
    expect(liveObjects().characters - before.characters).toBe(1);
    expect(shared.isFreed).toBe(false);
    b.dispose();
    b.dispose(); // twice is harmless
    expect(liveObjects().characters).toBe(before.characters);
    expect(liveObjects().databases).toBe(before.databases);
    expect(shared.isFreed).toBe(true);
  });

  it('restartRuntime keeps the debug views (a page’s choice of what to show, their compiled materials) and draws the new runtime', () => {
    const c = new Character(Database.fromBytes(DB, 'debug'), null, { debug: true });
    const views = c.debugViews!;
    views.matched.object.visible = false;
    c.setMove(0, 1);
    for (let i = 0; i < 60; i++) c.update(1 / 60);
    c.restartRuntime();
    expect(c.debugViews).toBe(views);
    expect(views.matched.object.visible).toBe(false);
    c.setMove(1, 0);
    for (let i = 0; i < 30; i++) c.update(1 / 60); // would throw on a freed runtime
    const s = c.runtime.simulation;
    expect([views.simulation.position.x, views.simulation.position.z]).toEqual([s[0], s[2]]);
    c.dispose();
  });

  it('walkTo reaches its target within α in the frame of object3d’s parent, however object3d is placed', () => {
    const c = new Character(db.retain(), null);
    try {
      // The character's floor frame: moved, turned and scaled in its parent (a scene).
      c.object3d.position.set(5, 0, -3);
      c.object3d.rotation.y = 1.1;
      c.object3d.scale.setScalar(1.3);
      c.teleport(4, -2, 0.5);
      const r0 = c.root;
      expect(r0.x).toBeCloseTo(4, 3);
      expect(r0.z).toBeCloseTo(-2, 3);
      expect(r0.yaw).toBeCloseTo(0.5, 3);
      c.walkTo(7, 1.5);
      expect(c.followingPath).toBe(true);
      for (let step = 0; step < 60 * 8; step++) c.update(1 / 60);
      const r = c.root;
      const alpha = (c.settings['clamp_distance'] as number) * c.metresPerDatabaseUnit;
      expect(Math.hypot(r.x - 7, r.z - 1.5)).toBeLessThan(alpha);
      // The skeleton is drawn where the root is reported: the hips' world position (scene
      // frame) sits over the root.
      c.object3d.updateMatrixWorld(true);
      const hips = c.jointPosition(db.roles.get('hips')!, new THREE.Vector3());
      expect(Math.hypot(hips.x - r.x, hips.z - r.z)).toBeLessThan(0.15);
      // A move input in the parent frame moves it that way in the parent frame.
      c.setMove(-1, 0);
      expect(c.followingPath).toBe(false);
      const x0 = c.root.x;
      for (let step = 0; step < 90; step++) c.update(1 / 60);
      expect(c.root.x - x0).toBeLessThan(-1.0);
    } finally {
      c.dispose();
    }
  });

  it('styles: neutral by default, another on request, unknown names refused with the list', () => {
    expect(db.styles).toEqual(expect.arrayContaining(['neutral', 'angry', 'akimbo']));
    const c = new Character(db, null);
    try {
      expect(c.style).toBe('neutral');
      // A calm first view: the character starts standing, in the neutral style.
      expect(c.tags).toEqual(expect.arrayContaining(['idle', 'style:neutral']));
      const styleShare = (style: string) => {
        let inStyle = 0;
        for (let step = 0; step < 600; step++) {
          c.update(1 / 60);
          if (c.tags.includes(`style:${style}`)) inStyle++;
        }
        return inStyle / 600;
      };
      expect(styleShare('neutral')).toBe(1);
      c.setStyle('angry');
      expect(c.style).toBe('angry');
      c.setMove(0, 1);
      expect(styleShare('angry')).toBeGreaterThan(0.8);
      expect(() => c.setStyle('grumpy')).toThrow(/unknown style "grumpy" .*neutral, angry, akimbo|unknown style "grumpy" .*akimbo/);
      expect(c.style).toBe('angry');
      c.setTagQuery({ exclude: ['run'] });
      expect(c.settings['exclude_tags']).toEqual(['run']);
      expect(() => c.setTagQuery({ require: ['walk', 'flying'] })).toThrow(/require: no tag "flying"/);
      expect(c.settings['require_tags']).toEqual([]);
    } finally {
      c.dispose();
    }
  });

  it('one dispose rule: after dispose() every method and property throws the same error', () => {
    const c = new Character(db.retain(), null);
    c.update(1 / 60);
    c.dispose();
    c.dispose(); // twice is harmless
    expect(c.isDisposed).toBe(true);
    const calls: [string, () => unknown][] = [
      ['update', () => c.update(1 / 60)],
      ['setMove', () => c.setMove(0, 1)],
      ['setInput', () => c.setInput(createMoveInput())],
      ['walkTo', () => c.walkTo(1, 1)],
      ['followPath', () => c.followPath([[0, 0], [1, 1]])],
      ['stop', () => c.stop()],
      ['teleport', () => c.teleport(0, 0)],
      ['setTracked', () => c.setTracked(0, 0, 0, 0, 0)],
      ['setHipsDrop', () => c.setHipsDrop(0.1)],
      ['setCrouch', () => c.setCrouch(0.1, 0)],
      ['setAlpha', () => c.setAlpha(0.2)],
      ['setAvatar', () => c.setAvatar(null)],
      ['setDatabase', () => c.setDatabase(db)],
      ['restartRuntime', () => c.restartRuntime()],
      ['toDatabase', () => c.toDatabase(0, 0)],
      ['fromDatabase', () => c.fromDatabase(0, 0, 0)],
      ['jointPosition', () => c.jointPosition(1)],
      ['root', () => c.root],
      ['frame', () => c.frame],
      ['clip', () => c.clip],
      ['tags', () => c.tags],
      ['contacts', () => c.contacts],
      ['settings', () => c.settings],
      ['set settings', () => (c.settings = {})],
      ['database', () => c.database],
      ['runtime', () => c.runtime],
      ['avatar', () => c.avatar],
      ['worldScale', () => c.worldScale],
      ['metresPerDatabaseUnit', () => c.metresPerDatabaseUnit],
      ['drive', () => c.drive],
      ['followingPath', () => c.followingPath],
      ['debug', () => c.debug],
      ['set debug', () => (c.debug = true)],
      ['debugViews', () => c.debugViews],
      ['showSkeleton', () => c.showSkeleton],
      ['set showSkeleton', () => (c.showSkeleton = true)],
    ];
    const wrong = calls.flatMap(([name, call]) => {
      try {
        call();
        return [`${name}: no error`];
      } catch (e) {
        return e instanceof Error && e.message === 'Character used after dispose()' ? [] : [`${name}: ${String(e)}`];
      }
    });
    expect(wrong).toEqual([]);
  });

  it('setAlpha and settings refuse NaN and infinities by name, changing nothing', () => {
    const c = new Character(db.retain(), null);
    try {
      c.setAlpha(0.3);
      for (const bad of [NaN, Infinity, -1, '0.2' as unknown as number]) {
        expect(() => c.setAlpha(bad)).toThrow(`setAlpha: α must be a number of metres ≥ 0, got ${String(bad)}`);
      }
      expect(c.drive.clampDistance).toBeCloseTo(0.3 / c.metresPerDatabaseUnit, 12);
      c.update(1 / 60);
      expect(c.settings['clamp_distance']).toBeCloseTo(0.3, 6);
      expect(() => (c.settings = { clamp_distance: NaN })).toThrow('settings: clamp_distance is NaN, expected a finite number');
      expect(() => (c.settings = { controller: { walk: { forward: Infinity } } })).toThrow('settings: controller.walk.forward is Infinity, expected a finite number');
      expect(c.settings['clamp_distance']).toBeCloseTo(0.3, 6);
    } finally {
      c.dispose();
    }
  });

  it('a crowd refuses a count that is not a whole number and an index it does not have', () => {
    for (const bad of [NaN, 1.5, 0, -3, Infinity]) {
      expect(() => new Crowd(db, bad)).toThrow(`crowd: the character count must be a whole number ≥ 1, got ${String(bad)}`);
    }
    const crowd = new Crowd(db, 4);
    try {
      for (const i of [4, -1, 1.5, NaN]) {
        expect(() => crowd.worldPositions(i)).toThrow(`crowd: no character ${String(i)} (the crowd has 4: 0 to 3)`);
        expect(() => crowd.setInput(i, createMoveInput())).toThrow(RangeError);
      }
      expect(crowd.worldPositions(3).length).toBe(db.numJoints * 3);
    } finally {
      crowd.free();
    }
  });

  it('a crowd is sized by cost: the issue’s 100,000 is refused with how many fit', () => {
    const most = Crowd.maxCharacters(db);
    // Every character searches all frames × dims at its first update: ~1 s of search at most.
    expect(most).toBe(Math.floor(2 ** 32 / (db.numFrames * db.numFeatures)));
    expect(() => new Crowd(db, 100_000)).toThrow(new RegExp(`^crowd: 100000 characters asked for; at most ${most} on this database`));
    const crowd = new Crowd(db, most);
    try {
      const t = performance.now();
      crowd.update(1 / 60);
      console.log(`the largest crowd on locomotion.mmdb (${most} characters): first update ${(performance.now() - t).toFixed(0)} ms in WASM`);
      expect(crowd.worldPositions(most - 1).every(Number.isFinite)).toBe(true);
    } finally {
      crowd.free();
    }
  });

  it('a crowd on the same database moves hundreds of characters in one call', () => {
    const crowd = new Crowd(db, 64);
    try {
      const input = createMoveInput();
      input.moveZ = 1;
      for (let i = 0; i < 64; i++) crowd.setInput(i, input);
      const z0 = crowd.worldPositions(63)[2];
      for (let step = 0; step < 60; step++) crowd.update(1 / 60);
      expect(crowd.worldPositions(63)[2] - z0).toBeGreaterThan(0.5);
    } finally {
      crowd.free();
    }
  });
});
