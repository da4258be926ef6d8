// The one drive value in real WASM (Node): the TS mirror writes the runtime's own field order; a
// value the runtime cannot read is refused with the reason; one value moves a character from
// tracked to move input (the runtime leaves the tracked mode) and a Character's path ends with
// its runtime.
import fs from 'node:fs';
import path from 'node:path';
import { beforeAll, describe, expect, it } from 'vitest';
import { Character, CharacterRuntime, Database, initWasmSync } from '../index.ts';
import { DRIVE_FIELDS, createDrive } from './drive.ts';
import { RawCharacter } from './raw.ts';

const ROOT = path.resolve(import.meta.dirname, '../../..');

let db: Database;
beforeAll(() => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
  db = Database.fromBytes(new Uint8Array(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.mmdb'))), 'locomotion.mmdb');
});

describe('Drive', () => {
  it('mirrors the runtime field for field', () => {
    expect([...DRIVE_FIELDS]).toEqual(RawCharacter.drive_fields().split(','));
  });

  it('an unknown mode is refused by name and changes nothing', () => {
    const c = new CharacterRuntime(db);
    try {
      const before = Array.from(c.root);
      expect(() => c.setDrive({ ...createDrive(), mode: 'fly' as never })).toThrow('drive mode -1 (0 move, 1 path, 2 tracked)');
      c.update(1 / 60);
      expect(Math.hypot(c.root[0] - before[0], c.root[2] - before[2])).toBeLessThan(0.05);
    } finally {
      c.free();
    }
  });

  it('one value takes a character from a tracked user back to move input', () => {
    const c = new CharacterRuntime(db);
    try {
      const d = createDrive();
      Object.assign(d, { mode: 'tracked', headX: 0, headZ: 0, velocityX: 0, velocityZ: 0, yaw: 0 });
      for (let i = 0; i < 60; i++) (c.setDrive(d), c.update(1 / 60));
      const z0 = c.root[2];
      // The tracked head stays at the origin; move input now asks for a walk toward +Z.
      Object.assign(d, { mode: 'move', moveX: 0, moveZ: 1 });
      for (let i = 0; i < 120; i++) (c.setDrive(d), c.update(1 / 60));
      expect(c.root[2] - z0).toBeGreaterThan(1.5); // the per-field calls it replaced left it tracked: 0.02 m
      expect(c.faults().rejectedInputs).toBe(0);
    } finally {
      c.free();
    }
  });

  it('a path mode without a path is refused and counted; a new path object starts afresh', () => {
    const c = new CharacterRuntime(db);
    try {
      const d = createDrive();
      d.mode = 'path';
      c.setDrive(d);
      expect(c.faults().rejectedInputs).toBe(1);
      d.path = { points: Float32Array.of(0, 0, 0, 10), speeds: Float32Array.of(1.4), looped: false };
      for (let i = 0; i < 120; i++) (c.setDrive(d), c.update(1 / 60));
      expect(c.simulation[2]).toBeGreaterThan(2.5); // 2 s along it (not restarted every frame)
      d.path = { ...d.path };
      c.setDrive(d);
      c.update(1 / 60);
      expect(c.simulation[2]).toBeLessThan(0.1);
      expect(() => c.setDrive({ ...d, path: { points: Float32Array.of(0, 0), speeds: new Float32Array(), looped: false } })).toThrow(/at least 2 points/);
    } finally {
      c.free();
    }
  });

  it("a Character's path ends with its runtime (restart, another database): it stands, not following a path it lost", () => {
    const c = new Character(db.retain(), null);
    try {
      c.followPath([
        [0, 0],
        [0, 5],
      ]);
      c.update(1 / 60);
      c.restartRuntime();
      expect(c.followingPath).toBe(false);
      c.update(1 / 60);
      expect(c.runtime.faults().rejectedInputs).toBe(0);
      c.followPath([
        [0, 0],
        [0, 5],
      ]);
      c.setDatabase(db);
      expect(c.followingPath).toBe(false);
      c.update(1 / 60);
      expect(c.runtime.faults().rejectedInputs).toBe(0);
    } finally {
      c.dispose();
    }
  });
});
