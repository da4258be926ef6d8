/**
 * The round-trip property in WASM (issue 28; docs/robustness.md): the random build
 * configurations and BVH takes of `tests/roundtrip.rs` (written by `mmdb-cases --roundtrip`
 * with the native verdict of each) go through the page's builder, loader and runtime: what
 * `build` accepts must load and play — a finite pose, the root within α of the simulated
 * character — and WASM must agree with native on every verdict and message, with no trap.
 */
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { beforeAll, describe, expect, it } from 'vitest';
import { CharacterRuntime, Database, DatabaseBuilder, createDrive, initWasmSync, liveObjects } from '../../web/src/index.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const CORE = path.join(ROOT, 'wasm-core');
const CASES_BIN = path.join(CORE, 'target/opt/mmdb-cases'); // built by `npm test`'s cargo suite
/** Cases per run (the first of the native test's 600): bounded for `npm test`. */
const CASES = 200;

interface Case {
  dir: string;
  takes: string[];
  native: 'played' | 'refused';
  message: string | null;
  frames: number;
}

let dir = '';
let cases: Case[] = [];

beforeAll(() => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
  execFileSync('cargo', ['build', '--profile', 'opt', '--bin', 'mmdb-cases'], { cwd: CORE, stdio: 'ignore' });
  dir = fs.mkdtempSync(path.join(os.tmpdir(), 'mm-roundtrip-'));
  execFileSync(CASES_BIN, ['--roundtrip', dir, String(CASES)], { stdio: 'ignore' });
  cases = JSON.parse(fs.readFileSync(path.join(dir, 'roundtrip.json'), 'utf8')) as Case[];
}, 600_000);

describe('the round trip in WASM', () => {
  it('what the builder accepts, the loader loads and a character plays; verdicts agree with native', () => {
    expect(cases.length).toBe(CASES);
    const wrong: string[] = [];
    const input = createDrive();
    let played = 0;
    for (const c of cases) {
      const config = fs.readFileSync(path.join(dir, c.dir, 'config.json'), 'utf8');
      let builder: DatabaseBuilder | null = null;
      let db: Database | null = null;
      let runtime: CharacterRuntime | null = null;
      try {
        builder = new DatabaseBuilder(JSON.parse(config) as object);
        for (const t of c.takes) builder.addBvh(t, new Uint8Array(fs.readFileSync(path.join(dir, c.dir, t))));
        const bytes = builder.build();
        db = Database.fromBytes(bytes, 'built.mmdb'); // must load: the builder wrote it
        runtime = new CharacterRuntime(db);
        const alpha = runtime.settings()['clamp_distance'] as number;
        for (let step = 0; step < 120; step++) {
          const phase = Math.floor(step / 30) % 4;
          const a = step * 0.05;
          const amount = [1, 0.6, 0, 1][phase];
          [input.moveX, input.moveZ, input.faceX, input.faceZ] = [Math.sin(a) * amount, Math.cos(a) * amount, Math.cos(a), -Math.sin(a)];
          [input.run, input.strafe] = [phase === 3, phase === 1];
          runtime.setDrive(input);
          runtime.update(1 / 60);
          if (!runtime.worldPositions.every(Number.isFinite) || !runtime.root.every(Number.isFinite)) throw new Error(`non-finite output at step ${step}`);
          const [r, s] = [runtime.root, runtime.simulation];
          const gap = Math.hypot(r[0] - s[0], r[2] - s[2]);
          if (gap > alpha + 1e-3) throw new Error(`root ${gap} m from the simulation at step ${step} (α ${alpha})`);
        }
        played++;
        if (c.native !== 'played' || c.frames !== db.numFrames) wrong.push(`${c.dir}: WASM played ${db.numFrames} frames, native ${c.native} ${c.frames} (${c.message})`);
      } catch (e) {
        const message = e instanceof Error ? e.message : String(e);
        if (e instanceof WebAssembly.RuntimeError || c.native !== 'refused' || message !== c.message) wrong.push(`${c.dir}: WASM ${message}; native ${c.native} (${c.message}): ${config}`);
      } finally {
        runtime?.free();
        db?.release();
        builder?.free();
      }
    }
    expect(wrong.slice(0, 10)).toEqual([]);
    expect(played).toBeGreaterThan(CASES / 3);
    expect(liveObjects()).toMatchObject({ databases: 0, characters: 0, builders: 0 });
    console.log(`${CASES} random builds in WASM: ${played} built, loaded and played, ${CASES - played} refused as natively, 0 traps`);
  }, 600_000);
});
