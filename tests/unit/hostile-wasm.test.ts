/**
 * The hostile-input corpus through the WASM build (docs/robustness.md): every malformed BVH and
 * every `.mmdb` mutation the native tests check (written by the `mmdb-cases` binary, with the
 * native verdict and message) gets the same verdict and message here, with no trap; databases
 * that load play a character. Then garbage runtime inputs through the library's raw layer, and
 * at the end the same module still animates a character on the shipped database — one trap
 * anywhere would have broken every later call.
 */
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { beforeAll, describe, expect, it } from 'vitest';
import { bvh_info } from '../../web/src/core/raw.ts';
import { CharacterRuntime, Crowd, Database, createDrive, initWasmSync, liveObjects } from '../../web/src/index.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const CORE = path.join(ROOT, 'wasm-core');
const CASES_BIN = path.join(CORE, 'target/opt/mmdb-cases'); // built by `npm test`'s cargo suite

interface Case {
  kind: 'bvh' | 'mmdb';
  file: string;
  native: 'ok' | 'error';
  message: string | null;
}

let dir = '';
let cases: Case[] = [];
const traps: string[] = [];

/** Runs `f`; a WebAssembly.RuntimeError (a trap) is recorded, never swallowed silently. */
function outcome(label: string, f: () => void): { ok: boolean; message: string } {
  try {
    f();
    return { ok: true, message: '' };
  } catch (e) {
    if (e instanceof WebAssembly.RuntimeError) traps.push(`${label}: ${e.message}`);
    return { ok: false, message: e instanceof Error ? e.message : String(e) };
  }
}

beforeAll(() => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
  // The cases come from the native test suite's generator (one source of truth).
  execFileSync('cargo', ['build', '--profile', 'opt', '--bin', 'mmdb-cases'], { cwd: CORE, stdio: 'ignore' });
  dir = fs.mkdtempSync(path.join(os.tmpdir(), 'mm-hostile-'));
  execFileSync(CASES_BIN, [dir], { stdio: 'ignore' });
  cases = JSON.parse(fs.readFileSync(path.join(dir, 'cases.json'), 'utf8')) as Case[];
}, 600_000);

describe('hostile input in WASM', () => {
  it('every BVH case and .mmdb mutation gets the native verdict and message, with no trap', () => {
    expect(cases.filter((c) => c.kind === 'bvh').length).toBeGreaterThanOrEqual(60);
    expect(cases.filter((c) => c.kind === 'mmdb').length).toBeGreaterThanOrEqual(2000);
    const disagreements: string[] = [];
    let played = 0;
    const walk = createDrive();
    for (const c of cases) {
      const bytes = new Uint8Array(fs.readFileSync(path.join(dir, c.file)));
      const r = outcome(c.file, () => {
        if (c.kind === 'bvh') {
          bvh_info('case.bvh', bytes);
          return;
        }
        const db = Database.fromBytes(bytes, 'case.mmdb');
        try {
          const runtime = new CharacterRuntime(db);
          for (let i = 0; i < 30; i++) {
            walk.moveX = Math.sin(i);
            walk.moveZ = 1;
            runtime.setDrive(walk);
            runtime.update(1 / 60);
          }
          if (!runtime.worldPositions.every(Number.isFinite)) throw new Error('non-finite pose');
          runtime.free();
          played++;
        } finally {
          db.release();
        }
      });
      const verdict = r.ok ? 'ok' : 'error';
      if (verdict !== c.native) disagreements.push(`${c.file}: wasm ${verdict} (${r.message}), native ${c.native} (${c.message})`);
      else if (!r.ok && c.message && !r.message.endsWith(c.message) && !c.message.endsWith(r.message.replace(/^case\.mmdb: /, ''))) {
        disagreements.push(`${c.file}: wasm says ${JSON.stringify(r.message)}, native ${JSON.stringify(c.message)}`);
      }
    }
    expect(disagreements.slice(0, 20)).toEqual([]);
    expect(traps).toEqual([]);
    expect(played).toBeGreaterThan(100);
    console.log(`${cases.length} cases agree with native (${played} databases played a character), 0 traps`);
  }, 600_000);

  it('garbage runtime inputs are refused or repaired, never a trap or a NaN', () => {
    const db = Database.fromBytes(new Uint8Array(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.mmdb'))), 'locomotion.mmdb');
    const runtime = new CharacterRuntime(db);
    const bad = [NaN, Infinity, -Infinity, 1e38, -1e38, -1];
    const input = createDrive();
    for (const x of bad) {
      input.moveX = x;
      input.faceZ = x;
      runtime.setDrive(input);
      runtime.update(x);
      runtime.setDrive({ ...input, mode: 'tracked', headX: x, headZ: 0, velocityX: x, velocityZ: x, yaw: x, bend: x, clampDistance: x });
      runtime.update(1 / 60);
      runtime.teleport(x, x, x);
      runtime.setDrive({ ...input, hipsDrop: x });
      runtime.update(1 / 60);
      outcome('path', () => runtime.setPath(Float32Array.of(0, 0, x, 1), Float32Array.of(1), false));
      outcome('settings', () => runtime.setSettings({ playback_speed: x } as never));
      runtime.update(1 / 60);
      expect(runtime.worldPositions.every(Number.isFinite), `after ${x}`).toBe(true);
      expect(runtime.root.every(Number.isFinite), `root after ${x}`).toBe(true);
    }
    expect(outcome('path', () => runtime.setPath(Float32Array.of(0, 0, NaN, 1), Float32Array.of(1), false)).message).toMatch(/path/i);
    expect(runtime.faults().rejectedInputs).toBeGreaterThan(10);
    // Too many characters for one crowd: an error, not gigabytes.
    expect(outcome('crowd', () => new Crowd(db, 1e9)).message).toMatch(/at most/);
    runtime.free();
    db.release();
    expect(traps).toEqual([]);
  });

  it('afterwards the same module still animates a character on the shipped database', () => {
    const db = Database.fromBytes(new Uint8Array(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.mmdb'))), 'locomotion.mmdb');
    const runtime = new CharacterRuntime(db);
    const input = createDrive();
    input.moveZ = 1;
    runtime.setDrive(input);
    for (let i = 0; i < 180; i++) runtime.update(1 / 60);
    expect(runtime.root[2]).toBeGreaterThan(1.5); // 3 s of walking
    expect(runtime.worldPositions.every(Number.isFinite)).toBe(true);
    expect(runtime.transitions).toBeGreaterThan(0);
    runtime.free();
    db.release();
    expect(liveObjects()).toMatchObject({ characters: 0, crowds: 0 });
  });
});
