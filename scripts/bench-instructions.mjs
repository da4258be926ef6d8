// `node scripts/bench-instructions.mjs [PKG_DIR …]`: x86 instructions per character update of
// the WASM runtime in V8, counted — not timed — so two builds compare to about a per cent on a machine
// whose speed swings by half between hours. Each PKG_DIR is a wasm-bindgen output (default:
// this checkout's web/src/core/pkg; `--compare REV` in bench.mjs leaves REV's in
// wasm-core/target/compare-REV/pkg). Node runs the crowd of 256 on the bench's pinned recipe
// under valgrind's cachegrind with V8's optimizing compiler only (no Liftoff, no tier-up: the
// same machine code every run); the count of 130 steps is subtracted from that of 230, so
// loading and compiling cancel out, and the rest is divided by 100 × 256 updates. Repeats agree
// within 1.3 % (36,040 / 35,878; 28,170 / 28,344 / 27,994: the collector's timing still varies).
// Needs valgrind (`apt-get install valgrind`) and bench-databases/ (`npm run bench`).
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { crowdInput } from './crowd-input.mjs';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const DATABASE = path.join(ROOT, 'bench-databases', 'locomotion-2026-11.mmdb');
const CROWD = 256;

if (process.argv[2] === '--steps') {
  // The child: the crowd under the runtime benchmarks' input script.
  const [, , , steps, pkg] = process.argv;
  const wasm = await import(path.join(pkg, 'mmcore.js'));
  wasm.initSync({ module: fs.readFileSync(path.join(pkg, 'mmcore_bg.wasm')) });
  const crowd = new wasm.RawCrowd(new wasm.RawDatabase(new Uint8Array(fs.readFileSync(DATABASE))), CROWD);
  for (let step = 0; step < Number(steps); step++) {
    for (let i = 0; i < CROWD; i++) {
      const [x, z, run] = crowdInput(step + 37 * i);
      crowd.set_input(i, x, z, 0, 1, run, false);
    }
    crowd.update(1 / 60);
  }
  process.exit(0);
}

if (spawnSync('valgrind', ['--version']).status !== 0) {
  console.error('bench-instructions: valgrind is not installed (apt-get install valgrind)');
  process.exit(1);
}
if (!fs.existsSync(DATABASE)) {
  console.error(`bench-instructions: ${path.relative(ROOT, DATABASE)} is missing: run \`npm run bench\` once`);
  process.exit(1);
}
const pkgs = process.argv.slice(2).length ? process.argv.slice(2) : [path.join(ROOT, 'web', 'src', 'core', 'pkg')];
for (const pkg of pkgs) {
  const refs = (steps) => {
    const r = spawnSync(
      'valgrind',
      ['--tool=cachegrind', '--cache-sim=no', '--smc-check=all-non-file', '--cachegrind-out-file=/dev/null',
        process.execPath, '--no-liftoff', '--no-wasm-tier-up', '--single-threaded', fileURLToPath(import.meta.url), '--steps', String(steps), path.resolve(pkg)],
      { encoding: 'utf8' },
    );
    const m = /I\s+refs:\s+([\d,]+)/.exec(r.stderr);
    if (r.status !== 0 || !m) throw new Error(`valgrind over ${pkg} failed:\n${r.stderr.slice(-2000)}`);
    return Number(m[1].replaceAll(',', ''));
  };
  const perUpdate = (refs(230) - refs(130)) / (100 * CROWD);
  console.log(`${path.relative(ROOT, path.resolve(pkg)) || pkg}: ${Math.round(perUpdate)} instructions per character update (V8, TurboFan)`);
}
