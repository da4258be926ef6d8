import fs from 'node:fs';
import path from 'node:path';
import { beforeAll, expect, it } from 'vitest';
import { Database } from './database.ts';
import { forwardKinematics } from './forward-kinematics.ts';
import { initWasmSync } from './wasm.ts';

const ROOT = path.resolve(import.meta.dirname, '../../..');

beforeAll(() => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
});

it('matches the Rust forward kinematics on database frames', () => {
  const db = Database.fromBytes(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.mmdb')));
  try {
    const j = db.numJoints;
    const positions = new Float32Array(j * 3);
    const rotations = new Float32Array(j * 4);
    for (const frame of [0, 1234, db.numFrames - 1]) {
      const lp = db.localPositions.subarray(frame * j * 3, (frame + 1) * j * 3);
      const lr = db.localRotations.subarray(frame * j * 4, (frame + 1) * j * 4);
      forwardKinematics(db.jointParents, lp, lr, positions, rotations);
      const expected = db.worldPositions(frame);
      for (let i = 0; i < j * 3; i++) expect(Math.abs(positions[i] - expected[i])).toBeLessThan(1e-5);
    }
  } finally {
    db.free();
  }
});
