// `npm run lint`: every formatter in check mode and every linter, each finding a failure.
// `npm run format` (`node scripts/lint.mjs --fix`): the formatters rewrite the files instead.
//   Rust:       rustfmt (wasm-core/rustfmt.toml), clippy -D warnings natively (all targets: the
//               library, the CLI, tests, examples) and for wasm32 with simd128 (the binding layer
//               and the WASM lane code compile only there); lints allowed on purpose are in
//               wasm-core/Cargo.toml [lints.clippy].
//   Python:     ruff check and ruff format (training/ruff.toml), from training/.venv.
//   TypeScript: Biome's linter (biome.jsonc: its recommended rules, a few off on purpose, each
//               said why) and tsc --noEmit over the library, pages, server and tests. Biome's
//               formatter is not on yet (biome.jsonc says why).
// `npm test` runs it first (scripts/setup.mjs); it needs the venv that set-up makes.
// Prints "lint: N passed, M failed" last.
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';

const ROOT = path.resolve(import.meta.dirname, '..');
const CORE = path.join(ROOT, 'wasm-core');
const TRAINING = path.join(ROOT, 'training');
const RUFF = path.join(TRAINING, '.venv', 'bin', 'ruff');
const fix = process.argv.includes('--fix');
const wasmEnv = { ...process.env, CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_RUSTFLAGS: '-C target-feature=+simd128' };

const checks = [
  { name: 'rustfmt', cmd: 'cargo', args: ['fmt', ...(fix ? [] : ['--check'])], cwd: CORE },
  { name: 'clippy (native)', cmd: 'cargo', args: ['clippy', '--all-targets', '--profile', 'opt', '--quiet', '--', '-D', 'warnings'], cwd: CORE },
  {
    name: 'clippy (wasm32)',
    cmd: 'cargo',
    args: ['clippy', '--target', 'wasm32-unknown-unknown', '--lib', '--release', '--target-dir', 'target/wasm', '--quiet', '--', '-D', 'warnings'],
    cwd: CORE,
    env: wasmEnv,
  },
  { name: 'ruff check', cmd: RUFF, args: ['check', ...(fix ? ['--fix'] : []), '.'], cwd: TRAINING },
  { name: 'ruff format', cmd: RUFF, args: ['format', ...(fix ? [] : ['--check']), '.'], cwd: TRAINING },
  { name: 'biome lint', cmd: path.join(ROOT, 'node_modules', '.bin', 'biome'), args: ['lint', ...(fix ? ['--write'] : [])], cwd: ROOT },
  { name: 'tsc', cmd: path.join(ROOT, 'node_modules', '.bin', 'tsc'), args: ['--noEmit'], cwd: ROOT },
];

// Side by side, each check's output kept and printed whole when it ends: the two clippy runs
// use different target folders (cargo locks one for a whole build, host tools included) and,
// with tsc, spend most of their time on one core each. Each uses the profile and folder of a
// build set-up has made (the native one the CLI's and the tests' `opt`, the wasm32 one the release WASM
// build's target/wasm), so the host tools (proc macros) are not compiled again; the crate has no
// `cfg(debug_assertions)` code that the release profiles would leave unlinted. `--fix` runs them one at a time
// (formatters rewrite files the linters read).
function runCheck(c) {
  const t0 = performance.now();
  if (path.isAbsolute(c.cmd) && !fs.existsSync(c.cmd)) {
    return Promise.resolve({ c, ok: false, output: '', why: `${path.relative(ROOT, c.cmd)} is missing (run \`npm test\` or \`npm start\` once to set up)`, t0 });
  }
  return new Promise((resolve) => {
    let output = '';
    const child = spawn(c.cmd, c.args, { cwd: c.cwd, env: c.env ?? process.env, stdio: ['ignore', 'pipe', 'pipe'] });
    child.stdout.on('data', (b) => (output += b));
    child.stderr.on('data', (b) => (output += b));
    child.on('error', (e) => resolve({ c, ok: false, output, why: e.message, t0 }));
    child.on('close', (code) => resolve({ c, ok: code === 0, output, why: `exit ${code}`, t0 }));
  });
}

let passed = 0;
let failed = 0;
const report = ({ c, ok, output, why, t0 }) => {
  if (output) process.stdout.write(output.endsWith('\n') ? output : `${output}\n`);
  const s = ((performance.now() - t0) / 1000).toFixed(1);
  console.log(`[lint] ${c.name}: ${ok ? 'clean' : `FAILED (${why})`} in ${s}s`);
  if (ok) passed++;
  else failed++;
};
if (fix) {
  for (const c of checks) report(await runCheck(c));
} else {
  await Promise.all(checks.map((c) => runCheck(c).then(report)));
}
console.log(`lint: ${passed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
