#!/usr/bin/env node
// `npm run bench [-- --json] [-- --seconds S]`: BVH parse speed (MB/s) and database build
// speed (frames/s), native (the mmdb CLI) and WASM in Node, on the same files in one run so
// the two are comparable under the same machine noise. Medians of repeated runs.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { execFileSync } from 'node:child_process';
import { fileURLToPath } from 'node:url';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const MOCAP = path.resolve(ROOT, '..', 'shared', 'mocap', 'cmu-asf');
const args = process.argv.slice(2);
const json = args.includes('--json');
const seconds = Number(args[args.indexOf('--seconds') + 1]) || 2;

const mmdb = path.join(ROOT, 'wasm-core', 'target', 'release', 'mmdb');
const pkg = path.join(ROOT, 'web', 'src', 'core', 'pkg');
for (const [what, p] of [['native CLI', mmdb], ['WASM package', path.join(pkg, 'mmcore.js')], ['mocap', MOCAP]]) {
  if (!fs.existsSync(p)) {
    console.error(`bench: ${what} missing at ${p}; run \`npm run build\` first (and keep ../shared beside the repo)`);
    process.exit(1);
  }
}

// The benchmark set: every subject-16 take (walks, runs, turns; 50 files, 13 MB, 14k frames).
const files = fs.readdirSync(MOCAP).filter((f) => /^cmu_16_\d+\.bvh$/.test(f)).sort().map((f) => path.join(MOCAP, f));

function median(values) {
  const s = [...values].sort((a, b) => a - b);
  return s[Math.floor(s.length / 2)];
}

/** Runs `fn` repeatedly for about `seconds` (at least 3 times); median milliseconds. */
function time(fn) {
  const times = [];
  const start = performance.now();
  while (times.length < 3 || (performance.now() - start < seconds * 1000 && times.length < 1000)) {
    const t = performance.now();
    fn();
    times.push(performance.now() - t);
  }
  return { ms: median(times), runs: times.length };
}

const nativeBench = (env = {}) =>
  JSON.parse(execFileSync(mmdb, ['bench', ...files, '--json', '--seconds', String(seconds)], { encoding: 'utf8', env: { ...process.env, ...env } }));
const native = nativeBench();
const native1 = nativeBench({ MMDB_THREADS: '1' });

const wasm = await import(path.join(pkg, 'mmcore.js'));
wasm.initSync({ module: fs.readFileSync(path.join(pkg, 'mmcore_bg.wasm')) });
const inputs = files.map((f) => [path.basename(f), new Uint8Array(fs.readFileSync(f))]);
const megabytes = inputs.reduce((n, [, b]) => n + b.length, 0) / 1e6;
const parse = time(() => {
  for (const [name, bytes] of inputs) wasm.bvh_info(name, bytes);
});
// Parse once into a builder, then time build() (build + serialize), as the native bench does.
const builder = new wasm.RawBuilder('{}');
for (const [name, bytes] of inputs) builder.add_bvh(name, bytes);
let databaseFrames = 0;
const build = time(() => {
  const bytes = builder.build();
  if (!databaseFrames) {
    const db = new wasm.RawDatabase(bytes);
    databaseFrames = db.num_frames();
    db.free();
  }
});
builder.free();

const rows = [
  { runtime: 'native', parse_mb_per_s: native.parse_mb_per_s, build_ms: native.build_ms, build_frames_per_s: native.build_source_frames_per_s },
  { runtime: 'native 1 thread', parse_mb_per_s: native1.parse_mb_per_s, build_ms: native1.build_ms, build_frames_per_s: native1.build_source_frames_per_s },
  {
    runtime: 'wasm (node)',
    parse_mb_per_s: megabytes / (parse.ms / 1000),
    build_ms: build.ms,
    build_frames_per_s: native.source_frames / (build.ms / 1000),
  },
];
const result = {
  files: files.length,
  megabytes,
  source_frames: native.source_frames,
  database_frames: native.database_frames,
  wasm_database_frames: databaseFrames,
  rows,
  target_native_build_frames_per_s: 200000,
};
if (json) {
  console.log(JSON.stringify(result, null, 2));
} else {
  console.log(
    `database build benchmark: ${files.length} BVH files (CMU subject 16), ${megabytes.toFixed(1)} MB, ` +
      `${native.source_frames} source frames at 120 fps → ${native.database_frames} database frames (60 fps, mirrored); medians`,
  );
  console.log('runtime          parse MB/s   build ms   build frames/s (source frames)');
  for (const r of rows) {
    console.log(
      `${r.runtime.padEnd(16)} ${r.parse_mb_per_s.toFixed(0).padStart(10)} ${r.build_ms.toFixed(1).padStart(10)} ${Math.round(r.build_frames_per_s).toString().padStart(16)}`,
    );
  }
  console.log(`target: ≥ 200000 frames/s native build (all ${os.availableParallelism()} cores) → ${rows[0].build_frames_per_s >= 200000 ? 'met' : 'MISSED'}`);
}
