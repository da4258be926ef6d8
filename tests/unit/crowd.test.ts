// The motion-matching character in real WASM (Node): it walks where it is asked to, its pose is
// a zero-copy view of WASM memory, settings round-trip as JSON, debug views are consistent.
import fs from 'node:fs';
import path from 'node:path';
import { beforeAll, describe, expect, it } from 'vitest';
import { RawCrowd } from '../../web/src/core/pkg/mmcore.js';
import { initWasmSync, wasmMemory } from '../../web/src/core/wasm.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const DB = new Uint8Array(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.mmdb')));

beforeAll(() => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
});

function root(crowd: RawCrowd, i: number): Float32Array {
  return new Float32Array(wasmMemory().buffer, crowd.pose_positions_ptr(i), 3);
}

describe('RawCrowd (WASM in Node)', () => {
  it('walks forward, turns and keeps its pose in WASM memory', () => {
    const crowd = new RawCrowd(DB, 1);
    try {
      const j = crowd.num_joints();
      const start = Array.from(root(crowd, 0));
      // 2 s of "forward" (+Z) at 60 Hz: about 1.75 m/s once up to speed.
      for (let step = 0; step < 120; step++) {
        crowd.set_input(0, 0, 1, 0, 1, false, false);
        crowd.update(1 / 60);
      }
      const moved = root(crowd, 0)[2] - start[2];
      expect(moved).toBeGreaterThan(1.5);
      expect(Math.abs(root(crowd, 0)[0] - start[0])).toBeLessThan(0.5);
      // The pose is a view, not a copy: the same pointer sees the next update.
      const rotations = new Float32Array(wasmMemory().buffer, crowd.pose_rotations_ptr(0), j * 4);
      const before = rotations.slice();
      crowd.update(1 / 60);
      const view = new Float32Array(wasmMemory().buffer, crowd.pose_rotations_ptr(0), j * 4);
      expect(view.byteOffset).toBe(rotations.byteOffset);
      expect(Array.from(view)).not.toEqual(Array.from(before));
      for (let k = 0; k < j; k++) {
        const n = Math.hypot(view[4 * k], view[4 * k + 1], view[4 * k + 2], view[4 * k + 3]);
        expect(n).toBeCloseTo(1, 4);
      }
      expect(crowd.searches(0)).toBeGreaterThan(10);
      expect(crowd.transitions(0)).toBeGreaterThan(0);
    } finally {
      crowd.free();
    }
  });

  it('takes settings as JSON and rejects typos', () => {
    const crowd = new RawCrowd(DB, 2);
    try {
      crowd.set_settings_json('{"beta_trajectory": 2.5, "clamp_distance": 0.3, "search_method": "simd"}');
      const s = JSON.parse(crowd.settings_json(1)) as Record<string, unknown>;
      expect(s['beta_trajectory']).toBe(2.5);
      expect(s['clamp_distance']).toBeCloseTo(0.3, 6);
      expect(s['search_method']).toBe('simd');
      expect(s['foot_lock']).toBe(true);
      expect(() => crowd.set_settings_json('{"clamp_distnce": 0.3}')).toThrow(/clamp_distnce/);
    } finally {
      crowd.free();
    }
  });

  it('exposes the trajectory it asked for and the simulated character', () => {
    const crowd = new RawCrowd(DB, 1);
    try {
      for (let step = 0; step < 90; step++) {
        crowd.set_input(0, 1, 0, 0, 1, false, false); // walk toward +X
        crowd.update(1 / 60);
      }
      const k = crowd.num_predictions();
      expect(k).toBe(3);
      const predicted = new Float32Array(wasmMemory().buffer, crowd.predicted_positions_ptr(0), k * 3);
      const sim = new Float32Array(wasmMemory().buffer, crowd.simulation_ptr(0), 7);
      // Ahead of the simulated character along +X, further for later points.
      expect(predicted[0]).toBeGreaterThan(sim[0]);
      expect(predicted[6]).toBeGreaterThan(predicted[3]);
      expect(predicted[3]).toBeGreaterThan(predicted[0]);
      // The root stays within α (0.15 m) of the simulated character.
      const r = root(crowd, 0);
      expect(Math.hypot(r[0] - sim[0], r[2] - sim[2])).toBeLessThanOrEqual(0.15 + 1e-4);
      const d = crowd.num_features();
      const query = new Float32Array(wasmMemory().buffer, crowd.query_ptr(0), d);
      expect(query.every(Number.isFinite)).toBe(true);
      expect(crowd.search_cost(0)).toBeGreaterThanOrEqual(0);
      const clips = (JSON.parse(crowd.inspect_json()) as { clips: unknown[] }).clips;
      expect(crowd.clip(0)).toBeLessThan(clips.length);
    } finally {
      crowd.free();
    }
  });

  it('follows a path square and rejects a bad path', () => {
    const crowd = new RawCrowd(DB, 1);
    try {
      // A 4 m square walked at 1.5 m/s, looping, starting where the character stands.
      const square = new Float32Array([0, 0, 0, 4, -4, 4, -4, 0]);
      crowd.set_path(0, square, new Float32Array([1.5, 1.5, 1.5, 1.5]), true);
      let worst = 0;
      for (let step = 0; step < 600; step++) {
        crowd.update(1 / 60);
        const [x, , z] = root(crowd, 0);
        // Distance to the square's outline.
        const d = Math.min(Math.abs(x), Math.abs(x + 4), Math.abs(z), Math.abs(z - 4));
        const inside = x <= 0.2 && x >= -4.2 && z >= -0.2 && z <= 4.2;
        worst = Math.max(worst, inside ? d : Infinity);
      }
      expect(worst).toBeLessThanOrEqual(0.15 + 0.02);
      expect(() => crowd.set_path(0, new Float32Array([0, 0]), new Float32Array([]), false)).toThrow(/at least 2 points/);
      expect(() => crowd.set_path(0, new Float32Array([0, 0, 1]), new Float32Array([1]), false)).toThrow(/pairs/);
      crowd.clear_path(0);
      crowd.update(1 / 60);
    } finally {
      crowd.free();
    }
  });
});

describe('Crowd (TS wrapper)', () => {
  it('drives characters from MoveInput and exposes their pose as views', async () => {
    const { Crowd } = await import('../../web/src/core/crowd.ts');
    const { createMoveInput } = await import('../../web/src/input/input.ts');
    const crowd = new Crowd(DB, 2);
    try {
      const input = createMoveInput();
      input.moveX = 1; // walk toward +X
      crowd.setInput(1, input);
      const x0 = crowd.positionsOf(1)[0];
      for (let step = 0; step < 120; step++) crowd.update(1 / 60);
      expect(crowd.positionsOf(1)[0] - x0).toBeGreaterThan(1.5);
      expect(crowd.rotationsOf(0).length).toBe(crowd.numJoints * 4);
      crowd.setSettings({ foot_lock: false });
      expect(crowd.settings(1)['foot_lock']).toBe(false);
      expect(() => crowd.setSettings({ nope: 1 })).toThrow(/nope/);
    } finally {
      crowd.free();
    }
    expect(() => crowd.update(1 / 60)).toThrow(/after free/);
  });
});
