#!/usr/bin/env node
// The character runtime's cost: per-character update (median, p95) and characters per 4 ms,
// natively (mmdb bench-runtime) and in WASM under Node, on the same database and script.
// Used by `npm run bench`; runnable alone: `node scripts/bench-runtime.mjs [--json]`.
import fs from 'node:fs';
import path from 'node:path';
import { execFileSync } from 'node:child_process';
import { fileURLToPath } from 'node:url';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const DB = path.join(ROOT, 'public', 'databases', 'locomotion.mmdb');
const PKG = path.join(ROOT, 'web', 'src', 'core', 'pkg');

/** The same input script as `mmdb bench-runtime`: zig-zag, back-run, stop, every 2 s. */
function input(step) {
  const phase = Math.floor(step / 60 / 2) % 4;
  const dir = [[0.7, 0.7], [-0.7, 0.7], [0, -1], [0, 0]][phase];
  return [dir[0], dir[1], phase === 2];
}

const quantile = (sorted, q) => sorted[Math.min(sorted.length - 1, Math.floor(sorted.length * q))];

export async function benchRuntime() {
  const native = JSON.parse(execFileSync(path.join(ROOT, 'wasm-core/target/release/mmdb'), ['bench-runtime', DB, '--json'], { encoding: 'utf8' }));
  const wasm = await import(path.join(PKG, 'mmcore.js'));
  wasm.initSync({ module: fs.readFileSync(path.join(PKG, 'mmcore_bg.wasm')) });
  const bytes = new Uint8Array(fs.readFileSync(DB));

  const one = new wasm.RawCrowd(bytes, 1);
  const times = [];
  for (let step = 0; step < 3600; step++) {
    const [x, z, run] = input(step);
    one.set_input(0, x, z, 0, 1, run, false);
    const t = performance.now();
    one.update(1 / 60);
    times.push(performance.now() - t);
  }
  one.free();
  times.sort((a, b) => a - b);

  const n = 256;
  const crowd = new wasm.RawCrowd(bytes, n);
  const crowdTimes = [];
  for (let step = 0; step < 240; step++) {
    for (let i = 0; i < n; i++) {
      const [x, z, run] = input(step + 37 * i);
      crowd.set_input(i, x, z, 0, 1, run, false);
    }
    const t = performance.now();
    crowd.update(1 / 60);
    crowdTimes.push(performance.now() - t);
  }
  crowd.free();
  crowdTimes.sort((a, b) => a - b);
  const perCharacter = quantile(crowdTimes, 0.5) / n;
  return [
    { runtime: 'native', update_ms_median: native.update_ms_median, update_ms_p95: native.update_ms_p95, characters_in_4ms: native.characters_in_4ms },
    // performance.now() in Node has µs resolution; single-update medians are a few µs.
    { runtime: 'wasm (node)', update_ms_median: quantile(times, 0.5), update_ms_p95: quantile(times, 0.95), characters_in_4ms: Math.floor(4 / perCharacter) },
  ];
}

if (import.meta.url === `file://${process.argv[1]}`) {
  const rows = await benchRuntime();
  if (process.argv.includes('--json')) console.log(JSON.stringify(rows, null, 2));
  else {
    console.log('character update (locomotion.mmdb, AABB search)   median ms   p95 ms   characters in 4 ms');
    for (const r of rows) console.log(`${r.runtime.padEnd(48)} ${r.update_ms_median.toFixed(4).padStart(9)} ${r.update_ms_p95.toFixed(4).padStart(8)} ${String(r.characters_in_4ms).padStart(20)}`);
  }
}
