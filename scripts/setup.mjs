#!/usr/bin/env node
// One entry point for a fresh machine and for every later run: `npm start`, `npm test`,
// `npm run build` all come here. Each step checks whether its output is already up to date and
// skips itself, so a second run with nothing changed takes a few seconds.
//
//   node scripts/setup.mjs build   set up everything and build dist/ (the site, dist/mm-avatar.js,
//                                  the module build dist/lib/ with types), then stop
//   node scripts/setup.mjs start   set up (dist/ included), then serve the built site on port 5173 in the
//                                  foreground (server/serve.ts: precompressed, cached, the rooms on the
//                                  same origin); `start --https` serves HTTPS with a self-signed
//                                  certificate (WebXR)
//   node scripts/setup.mjs dev     set up, then run the vite dev server (port 5173; `dev --https` too)
//   node scripts/setup.mjs test    set up (plus Chromium and the Python venv), then run every test
//                                  suite, continuing after a failure; prints a summary table and
//                                  a last line `N passed, M failed`; exits non-zero on any failure
//
// Environment:
//   SETUP_SKIP=step,step   skip named steps: npm, rust-target, wasm-bindgen, wasm, cli, databases,
//                          avatars, dist, server, chromium, nats, venv, recordings, cargo-tests (for working on
//                          one part while another is broken)
//   TEST_SUITES=a,b        run only these suites: lint, cargo, vitest, pytest, playwright
//
// Node builtins only: this runs before node_modules exists.

import { spawn, spawnSync } from 'node:child_process';
import { createHash } from 'node:crypto';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const CORE = path.join(ROOT, 'wasm-core');
const SHARED_MOCAP = path.resolve(ROOT, '..', 'shared', 'mocap');
const SHARED_AVATARS = path.resolve(ROOT, '..', 'shared', 'avatars');
const WASM_TARGET = 'wasm32-unknown-unknown';
/**
 * The WASM build's own target folder: cargo locks a target folder for a whole build, so in the
 * native builds' folder the WASM build waited for the CLI's.
 */
const WASM_TARGET_DIR = path.join(CORE, 'target', 'wasm');
const WASM_OUT = path.join(WASM_TARGET_DIR, WASM_TARGET, 'release', 'mmcore.wasm');
const PKG_DIR = path.join(ROOT, 'web', 'src', 'core', 'pkg');
const MMDB_BIN = path.join(CORE, 'target', 'opt', process.platform === 'win32' ? 'mmdb.exe' : 'mmdb');
const VENV = path.join(ROOT, 'training', '.venv');

const mode = process.argv[2] ?? 'build';
if (!['build', 'start', 'dev', 'test'].includes(mode)) {
  console.error(`usage: node scripts/setup.mjs build|start|dev|test   (got "${mode}")`);
  process.exit(2);
}
const skipped = new Set((process.env.SETUP_SKIP ?? '').split(',').map((s) => s.trim()).filter(Boolean));

// ---------------------------------------------------------------- helpers

const t0All = performance.now();
const secs = (t0) => `${((performance.now() - t0) / 1000).toFixed(1)}s`;
const log = (msg) => console.log(`[setup] ${msg}`);

class StepError extends Error {}

/** mtime in ms, or -Infinity when the file does not exist. */
function mtime(p) {
  try {
    return fs.statSync(p).mtimeMs;
  } catch {
    return -Infinity;
  }
}

/** Newest mtime of any file under `dir` (recursive), or -Infinity. */
function newestUnder(dir) {
  let newest = -Infinity;
  const walk = (d) => {
    for (const e of fs.readdirSync(d, { withFileTypes: true })) {
      const p = path.join(d, e.name);
      if (e.isDirectory()) walk(p);
      else newest = Math.max(newest, mtime(p));
    }
  };
  if (fs.existsSync(dir)) walk(dir);
  return newest;
}

/**
 * Runs a command with output streamed to this terminal (or, with `logFile`, written there and
 * shown only if it fails: a step running beside others); throws StepError on failure.
 */
function run(cmd, args, { logFile, ...opts } = {}) {
  const shown = [cmd, ...args].map((a) => (/\s/.test(a) ? JSON.stringify(a) : a)).join(' ');
  log(`  $ ${shown}${opts.cwd && opts.cwd !== ROOT ? `   (in ${path.relative(ROOT, opts.cwd)})` : ''}${logFile ? `   (output: ${path.relative(ROOT, logFile)})` : ''}`);
  return new Promise((resolve, reject) => {
    const fd = logFile ? fs.openSync(logFile, 'w') : null;
    const child = spawn(cmd, args, { cwd: ROOT, stdio: fd === null ? 'inherit' : ['ignore', fd, fd], ...opts });
    if (fd !== null) {
      fs.closeSync(fd);
      child.on('close', (code) => code !== 0 && process.stdout.write(fs.readFileSync(logFile, 'utf8').slice(-20_000)));
    }
    child.on('error', (e) => reject(new StepError(`${cmd}: ${e.message}`)));
    child.on('close', (code, signal) => {
      if (code === 0) resolve();
      else reject(new StepError(`\`${shown}\` failed (${signal ?? `exit ${code}`})`));
    });
  });
}

/**
 * Runs a command, streaming its output and also capturing it (for parsing test summaries).
 * Resolves with { code, output }; never rejects.
 */
function runCapture(cmd, args, opts = {}) {
  const shown = [cmd, ...args].join(' ');
  log(`  $ ${shown}${opts.cwd && opts.cwd !== ROOT ? `   (in ${path.relative(ROOT, opts.cwd)})` : ''}`);
  return new Promise((resolve) => {
    let output = '';
    let child;
    try {
      child = spawn(cmd, args, { cwd: ROOT, stdio: ['ignore', 'pipe', 'pipe'], ...opts });
    } catch (e) {
      resolve({ code: -1, output: String(e) });
      return;
    }
    child.stdout.on('data', (b) => {
      output += b;
      process.stdout.write(b);
    });
    child.stderr.on('data', (b) => {
      output += b;
      process.stderr.write(b);
    });
    child.on('error', (e) => {
      output += `\n${cmd}: ${e.message}\n`;
      console.error(`${cmd}: ${e.message}`);
    });
    child.on('close', (code, signal) => resolve({ code: code ?? (signal ? 128 : -1), output }));
  });
}

/** Synchronous, quiet command: { status, stdout } (status -1 when it cannot be started). */
function probe(cmd, args, opts = {}) {
  const r = spawnSync(cmd, args, { cwd: ROOT, encoding: 'utf8', ...opts });
  if (r.error) return { status: -1, stdout: '' };
  return { status: r.status, stdout: `${r.stdout ?? ''}${r.stderr ?? ''}` };
}

/**
 * Runs one setup step. `fn` returns a string saying why it skipped (nothing to do), or
 * undefined after doing the work.
 */
async function step(id, title, fn) {
  const t0 = performance.now();
  if (skipped.has(id)) {
    log(`${title}: skipped (SETUP_SKIP=${id})`);
    return;
  }
  const skipReason = await fn();
  if (skipReason) log(`${title}: up to date, ${skipReason} (${secs(t0)})`);
  else log(`${title}: done (${secs(t0)})`);
}

// ---------------------------------------------------------------- steps

async function stepNpm() {
  await step('npm', 'npm packages', async () => {
    const marker = path.join(ROOT, 'node_modules', '.package-lock.json');
    const lock = path.join(ROOT, 'package-lock.json');
    const have = mtime(marker);
    if (have >= mtime(lock) && have >= mtime(path.join(ROOT, 'package.json'))) {
      return 'node_modules matches package-lock.json';
    }
    // `npm install`, not `npm ci`: the registry here lacks some other platforms' optional
    // binaries (e.g. @rollup/rollup-darwin-*), so the lock file lists only the ones it served and
    // `npm ci` rejects it as out of sync. `npm install` follows the lock all the same.
    await run('npm', ['install', '--no-audit', '--no-fund']);
    // npm may leave the marker's mtime untouched when nothing changed; touch it so the next
    // run skips.
    if (fs.existsSync(marker)) {
      const now = new Date();
      fs.utimesSync(marker, now, now);
    }
  });
}

async function stepRustTarget() {
  await step('rust-target', `Rust target ${WASM_TARGET}`, async () => {
    const r = probe('rustup', ['target', 'list', '--installed']);
    if (r.status === 0 && r.stdout.split(/\s+/).includes(WASM_TARGET)) return 'installed';
    if (r.status === -1) throw new StepError('rustup not found: install Rust from https://rustup.rs first');
    await run('rustup', ['target', 'add', WASM_TARGET]);
  });
}

/** The exact wasm-bindgen version pinned in wasm-core/Cargo.toml (`wasm-bindgen = "=X"`). */
function pinnedWasmBindgenVersion() {
  const toml = fs.readFileSync(path.join(CORE, 'Cargo.toml'), 'utf8');
  const m =
    toml.match(/^\s*wasm-bindgen\s*=\s*"=?\s*([0-9][0-9A-Za-z.+-]*)"/m) ??
    toml.match(/^\s*wasm-bindgen\s*=\s*\{[^}\n]*version\s*=\s*"=?\s*([0-9][0-9A-Za-z.+-]*)"/m);
  if (!m) throw new StepError('wasm-core/Cargo.toml has no `wasm-bindgen = "=X.Y.Z"` dependency line');
  return m[1];
}

/** Path of the wasm-bindgen CLI: cargo's bin dir first (where `cargo install` puts it), else PATH. */
function wasmBindgenBin() {
  const cargoBin = path.join(process.env.CARGO_HOME ?? path.join(os.homedir(), '.cargo'), 'bin', 'wasm-bindgen');
  return fs.existsSync(cargoBin) ? cargoBin : 'wasm-bindgen';
}

/** PIDs of other processes running `cargo install wasm-bindgen-cli` (Linux only). */
function otherWasmBindgenInstalls() {
  const pids = [];
  try {
    for (const pid of fs.readdirSync('/proc')) {
      if (!/^\d+$/.test(pid) || Number(pid) === process.pid) continue;
      try {
        const cmd = fs.readFileSync(`/proc/${pid}/cmdline`, 'utf8').split('\0');
        if (cmd.some((a) => /(^|\/)cargo$/.test(a)) && cmd.includes('install') && cmd.includes('wasm-bindgen-cli')) {
          pids.push(Number(pid));
        }
      } catch {
        /* process exited */
      }
    }
  } catch {
    /* no /proc */
  }
  return pids;
}

async function stepWasmBindgen(logFile) {
  await step('wasm-bindgen', 'wasm-bindgen CLI', async () => {
    const want = pinnedWasmBindgenVersion();
    const current = () => probe(wasmBindgenBin(), ['--version']).stdout.trim().split(/\s+/)[1];
    if (current() === want) return `version ${want}`;
    // Another shell may be installing it right now: wait instead of compiling it twice.
    let others = otherWasmBindgenInstalls();
    if (others.length) {
      log(`  another \`cargo install wasm-bindgen-cli\` is running (pid ${others.join(', ')}); waiting for it`);
      while (others.length) {
        await new Promise((r) => setTimeout(r, 5000));
        others = otherWasmBindgenInstalls();
      }
      if (current() === want) return;
    }
    log(`  installing wasm-bindgen-cli ${want} (have: ${current() ?? 'none'}); this compiles it from source (~1.5 minutes on 2 cores)`);
    // --debug: the unoptimized CLI compiles in half the time (86 s against 181 s on 2 cores) and
    // still binds our module in half a second, to the same bytes as the optimized one.
    // --locked first (reproducible); the registry here lacks one crate version the CLI's lockfile
    // pins (webpki-roots 1.0.11), so fall back to resolving compatible versions.
    // --force: cargo's own record may say it is installed when the binary is gone.
    const install = ['install', 'wasm-bindgen-cli', '--version', `=${want}`, '--debug', '--force'];
    try {
      await run('cargo', [...install, '--locked'], { logFile });
    } catch {
      log('  --locked install failed; retrying with freshly resolved dependencies');
      await run('cargo', install, { logFile });
    }
    if (current() !== want) throw new StepError(`wasm-bindgen --version still does not report ${want} after install`);
  });
}

async function stepWasmBuild(logFile) {
  await step('wasm', 'WASM build (cargo)', async () => {
    // The flag goes in the target-specific variable, not RUSTFLAGS, so the host tools built
    // beside it (proc macros, which the wasm32 clippy reuses) are not invalidated by alternating flags.
    const env = { ...process.env, CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_RUSTFLAGS: '-C target-feature=+simd128' };
    if (process.env.RUSTFLAGS) log('  note: RUSTFLAGS is set and overrides the simd128 target flag');
    await run('cargo', ['build', '--release', '--target', WASM_TARGET, '--lib', '--target-dir', WASM_TARGET_DIR], { cwd: CORE, env, logFile });
  });
}

async function stepWasmBindings() {
  await step('wasm', 'WASM bindings (wasm-bindgen)', async () => {
    const out = path.join(PKG_DIR, 'mmcore_bg.wasm');
    if (!fs.existsSync(WASM_OUT)) throw new StepError(`cargo produced no ${path.relative(ROOT, WASM_OUT)}`);
    if (mtime(out) > mtime(WASM_OUT) && fs.existsSync(path.join(PKG_DIR, 'mmcore.js'))) {
      return `${path.relative(ROOT, out)} is newer than the cargo output`;
    }
    // --omit-default-module-path: the library passes the module's URL itself (assets.ts), so no
    // `new URL('mmcore_bg.wasm', import.meta.url)` is left for a bundler to inline or rewrite.
    await run(wasmBindgenBin(), ['--target', 'web', '--omit-default-module-path', '--out-dir', PKG_DIR, '--out-name', 'mmcore', WASM_OUT]);
  });
  await step('wasm', 'WASM module served beside the other assets (public/mmcore_bg.wasm)', async () => {
    // The library fetches its module from its asset folder (web/src/assets.ts): the site root
    // in development, the folder of dist/mm-avatar.js when built.
    const src = path.join(PKG_DIR, 'mmcore_bg.wasm');
    const out = path.join(ROOT, 'public', 'mmcore_bg.wasm');
    if (mtime(out) >= mtime(src)) return 'public/mmcore_bg.wasm is current';
    fs.copyFileSync(src, out);
  });
}

async function stepCli(logFile) {
  await step('cli', 'native CLI (mmdb)', async () => {
    // The `opt` profile (wasm-core/Cargo.toml): the test binaries reuse its library.
    await run('cargo', ['build', '--profile', 'opt', '--bin', 'mmdb'], { cwd: CORE, logFile });
  });
}

async function stepDatabases() {
  await step('databases', 'databases', async () => {
    if (!fs.existsSync(SHARED_MOCAP)) {
      throw new StepError(
        `the mocap folder ${SHARED_MOCAP} is missing: the databases are built from ../shared/mocap ` +
          '(the shared/ folder must sit beside this repository)',
      );
    }
    const dir = path.join(ROOT, 'databases');
    const configs = fs.existsSync(dir) ? fs.readdirSync(dir).filter((f) => f.endsWith('.json')).sort() : [];
    if (configs.length === 0) return 'no databases/*.json configs';
    if (!fs.existsSync(MMDB_BIN)) throw new StepError(`${path.relative(ROOT, MMDB_BIN)} is missing (the cli step builds it)`);
    const inputsTime = Math.max(mtime(MMDB_BIN), newestUnder(SHARED_MOCAP));
    const outDir = path.join(ROOT, 'public', 'databases');
    fs.mkdirSync(outDir, { recursive: true });
    let built = 0;
    for (const cfg of configs) {
      const name = cfg.replace(/\.json$/, '');
      const out = path.join(outDir, `${name}.mmdb`);
      const cfgPath = path.join(dir, cfg);
      if (mtime(out) > Math.max(inputsTime, mtime(cfgPath))) continue;
      const t0 = performance.now();
      await run(MMDB_BIN, ['build', '--config', path.relative(ROOT, cfgPath), '-o', path.relative(ROOT, out)]);
      log(`  built ${path.relative(ROOT, out)} (${secs(t0)})`);
      built++;
    }
    writeDatabaseIndex(configs.map((c) => c.replace(/\.json$/, '')), outDir);
    if (built === 0) return `${configs.length} database(s) newer than their inputs`;
  });
}

/**
 * public/databases/index.json: the databases this site serves (one per databases/*.json config
 * whose .mmdb is built), with size and content hash; the demo offers exactly these. Rewritten
 * only when its content changes (its mtime feeds the dist step).
 */
function writeDatabaseIndex(names, outDir) {
  const databases = [];
  for (const name of names) {
    const file = `${name}.mmdb`;
    const p = path.join(outDir, file);
    if (!fs.existsSync(p)) continue;
    const bytes = fs.readFileSync(p);
    databases.push({ name, file, bytes: bytes.length, sha256: createHash('sha256').update(bytes).digest('hex').slice(0, 16) });
  }
  const text = `${JSON.stringify({ databases }, null, 2)}\n`;
  const index = path.join(outDir, 'index.json');
  if (fs.existsSync(index) && fs.readFileSync(index, 'utf8') === text) return;
  fs.writeFileSync(index, text);
  log(`  wrote ${path.relative(ROOT, index)} (${databases.map((d) => d.file).join(', ')})`);
}

async function stepAvatars() {
  await step('avatars', 'avatars (public/avatars, compressed for the web)', async () => {
    if (!fs.existsSync(SHARED_AVATARS)) return `no ${SHARED_AVATARS} folder`;
    const glbs = fs.readdirSync(SHARED_AVATARS).filter((f) => f.toLowerCase().endsWith('.glb')).sort();
    if (glbs.length === 0) return 'no ../shared/avatars/*.glb';
    const outDir = path.join(ROOT, 'public', 'avatars');
    fs.mkdirSync(outDir, { recursive: true });
    // The shipped avatar goes out compressed (scripts/compress-avatar.mjs, @gltf-transform:
    // meshopt geometry, WebP textures ≤ 512 px, data maps ≤ 256); redone when the source or the script is newer.
    const script = path.join(ROOT, 'scripts', 'compress-avatar.mjs');
    let written = 0;
    for (const f of glbs) {
      const src = path.join(SHARED_AVATARS, f);
      const out = path.join(outDir, f);
      if (mtime(out) > Math.max(mtime(src), mtime(script))) continue;
      fs.rmSync(out, { force: true }); // an older copy may be read-only (copied with its mode)
      await run(process.execPath, [script, src, out]);
      written++;
    }
    if (written === 0) return `${glbs.length} avatar(s) newer than ../shared/avatars and the compressor`;
  });
}

async function stepDist() {
  await step('dist', 'dist/ (site, mm-avatar.js, the module build and its types)', async () => {
    const dist = path.join(ROOT, 'dist');
    const stamp = path.join(dist, '.build-stamp');
    const inputs = [
      newestUnder(path.join(ROOT, 'web', 'src')),
      ...embedExamples().map((f) => mtime(f)),
      newestUnder(path.join(ROOT, 'public')),
      newestUnder(path.join(ROOT, 'web', 'sw')),
      ...['index.html', 'viewer.html', 'vr.html', 'crowd.html', 'bench.html', 'vite.config.ts', 'tsconfig.json', 'tsconfig.lib.json', 'package.json', 'scripts/precompress.mjs'].map((f) => mtime(path.join(ROOT, f))),
    ];
    if (mtime(stamp) > Math.max(...inputs)) return 'dist/ is newer than its sources';
    const vite = path.join(ROOT, 'node_modules', '.bin', 'vite');
    fs.rmSync(dist, { recursive: true, force: true });
    // The site (every page, public/ copied beside it), the standalone element and the module
    // for bundlers next to it (vite.config.ts has the three modes), and types.
    // Side by side: they write to different files (only the site copies public/; the module
    // build empties dist/lib/ alone) and each has single-threaded stretches.
    await Promise.all([
      run(vite, ['build', '--logLevel', 'warn']),
      run(vite, ['build', '--mode', 'element', '--logLevel', 'warn']),
      run(vite, ['build', '--mode', 'lib', '--logLevel', 'warn']),
      run(path.join(ROOT, 'node_modules', '.bin', 'tsc'), ['-p', 'tsconfig.lib.json']),
    ]);
    fs.mkdirSync(path.join(dist, 'examples'), { recursive: true });
    for (const f of embedExamples()) fs.copyFileSync(f, path.join(dist, 'examples', path.basename(f)));
    // .br/.gz beside every compressible file (cached by content hash) and the service worker.
    await run(process.execPath, [path.join(ROOT, 'scripts', 'precompress.mjs'), dist]);
    fs.writeFileSync(stamp, `${new Date().toISOString()}\n`);
  });
}

/**
 * The embedding example served with the site (examples/embed.*: the files at the top of
 * examples/); the bundler apps in its folders are built by their own tests (tests/e2e/package.spec.ts).
 */
function embedExamples() {
  const dir = path.join(ROOT, 'examples');
  return fs.readdirSync(dir, { withFileTypes: true }).filter((e) => e.isFile()).map((e) => path.join(dir, e.name));
}

/** The production server (server/serve.ts and what it imports) bundled for Node: dist-server/serve.mjs. */
const SERVER_BUNDLE = path.join(ROOT, 'dist-server', 'serve.mjs');
async function stepServer() {
  await step('server', 'site server (dist-server/serve.mjs)', async () => {
    const inputs = Math.max(newestUnder(path.join(ROOT, 'server')), newestUnder(path.join(ROOT, 'web', 'src', 'rooms')), mtime(path.join(ROOT, 'package-lock.json')));
    if (mtime(SERVER_BUNDLE) > inputs) return 'dist-server/serve.mjs is newer than server/';
    const esbuild = path.join(ROOT, 'node_modules', '.bin', 'esbuild');
    // Packages stay external: the bundle runs inside this checkout, beside node_modules.
    await run(esbuild, ['server/serve.ts', '--bundle', '--platform=node', '--format=esm', '--target=node20', '--packages=external', `--outfile=${path.relative(ROOT, SERVER_BUNDLE)}`, '--log-level=warning']);
  });
}

async function stepChromium() {
  await step('chromium', 'Chromium (Debian package)', async () => {
    if (fs.existsSync('/usr/bin/chromium')) return '/usr/bin/chromium exists';
    const sudo = process.getuid?.() === 0 ? [] : ['sudo'];
    const env = { ...process.env, DEBIAN_FRONTEND: 'noninteractive' };
    const apt = (args) => (sudo.length ? run('sudo', ['apt-get', ...args], { env }) : run('apt-get', args, { env }));
    await apt(['update']);
    await apt(['install', '-y', '--no-install-recommends', 'chromium', 'fonts-liberation']);
  });
}

/** nats-server for the multi-process room tests (server/multi-process*.test.ts start it on loopback). */
async function stepNats() {
  await step('nats', 'NATS server (Debian package nats-server)', async () => {
    for (const p of ['/usr/sbin/nats-server', '/usr/bin/nats-server', '/usr/local/bin/nats-server']) if (fs.existsSync(p)) return `${p} exists`;
    const sudo = process.getuid?.() === 0 ? [] : ['sudo'];
    const env = { ...process.env, DEBIAN_FRONTEND: 'noninteractive' };
    const apt = (args) => (sudo.length ? run('sudo', ['apt-get', ...args], { env }) : run('apt-get', args, { env }));
    await apt(['update']);
    await apt(['install', '-y', '--no-install-recommends', 'nats-server']);
  });
}

/**
 * uv installs the venv's wheels: PyTorch's ~3 GB (its CUDA libraries come with it from PyPI) took
 * pip 110–140 s of a busy core downloading, unpacking and byte-compiling on a bare machine, uv
 * 33 s with nothing in its cache (parallel downloads and unpacking), plus ~20 s to byte-compile.
 * Pinned here, and part of the venv's stamp.
 */
const UV_VERSION = '0.13.9';
/** The install command (it and the version are part of the venv's stamp). */
const UV_INSTALL = ['pip', 'install', '--compile-bytecode'];

/**
 * The venv (training/.venv): made with pip, filled by uv (pip if uv cannot be had), then every
 * package the code imports is imported once (a check that the install works).
 */
async function stepVenv(logFile) {
  await step('venv', 'Python venv (training/.venv)', async () => {
    const req = path.join(ROOT, 'training', 'requirements.txt');
    if (!fs.existsSync(req)) return 'no training/requirements.txt';
    const hash = createHash('sha256').update(`uv ${UV_VERSION} ${UV_INSTALL.join(' ')}\n`).update(fs.readFileSync(req)).digest('hex');
    const stamp = path.join(VENV, '.requirements.sha256');
    const py = path.join(VENV, 'bin', 'python');
    if (fs.existsSync(py) && fs.existsSync(stamp) && fs.readFileSync(stamp, 'utf8').trim() === hash) {
      return 'requirements.txt unchanged';
    }
    if (!fs.existsSync(py)) await run('python3', ['-m', 'venv', VENV]);
    fs.mkdirSync(path.dirname(logFile), { recursive: true });
    const pip = ['-m', 'pip', 'install', '--disable-pip-version-check'];
    try {
      await run(py, [...pip, `uv==${UV_VERSION}`], { logFile });
      // uv reads its own settings: the system's certificates as pip uses them, pip's index if set.
      const env = { ...process.env, UV_NATIVE_TLS: '1' };
      if (process.env.PIP_INDEX_URL && !env.UV_INDEX_URL) env.UV_INDEX_URL = process.env.PIP_INDEX_URL;
      // --compile-bytecode, as pip does: uv otherwise leaves it to the first import, which writes
      // nothing where PYTHONDONTWRITEBYTECODE is set (as on this machine), so every Python process
      // compiled torch again (`import torch` 5.2 s against 1.9 s; pytest 64–72 s against 56 s).
      await run(path.join(VENV, 'bin', 'uv'), [...UV_INSTALL, '--python', py, '-r', req], { logFile, env });
    } catch (e) {
      log(`  uv could not install the requirements (${e.message}); pip instead`);
      await run(py, [...pip, '-r', req], { logFile });
    }
    await run(py, ['-c', 'import numpy, torch, onnx, onnxscript, onnxruntime, matplotlib, pytest'], { logFile });
    fs.writeFileSync(stamp, `${hash}\n`);
  });
}

async function stepRecordings() {
  await step('recordings', 'VR recordings (public/recordings, synthetic from held-in mocap)', async () => {
    const py = path.join(VENV, 'bin', 'python');
    if (!fs.existsSync(py)) return 'no training/.venv (made in test mode)';
    const script = path.join(ROOT, 'training', 'make_recordings.py');
    if (!fs.existsSync(script)) return 'no training/make_recordings.py';
    const index = path.join(ROOT, 'public', 'recordings', 'index.json');
    // The generator is the script and the tracker simulation it runs (a calibration change there
    // changes every recording).
    const sources = [script, MMDB_BIN, ...['data.py', 'simulate.py', 'motion_classes.py', 'geometry.py'].map((f) => path.join(ROOT, 'training', 'orientation', f))];
    if (sources.every((f) => mtime(index) > mtime(f))) return `${path.relative(ROOT, index)} is newer than its generator`;
    await run(py, [script, '--force'], { cwd: path.join(ROOT, 'training') });
  });
}

/** The cargo suite's command (built ahead by set-up, then run by the suite). */
const CARGO_TEST = ['test', '--profile', 'opt', '--no-fail-fast'];
const suiteSelected = (id) => {
  const only = (process.env.TEST_SUITES ?? '').split(',').map((s) => s.trim()).filter(Boolean);
  return only.length === 0 || only.includes(id);
};

/**
 * `npm test`: the Rust test binaries compiled during set-up, beside the recordings, the WASM
 * build's single-threaded LTO and dist, which leave a core free; the cargo suite then only runs
 * them (and the lint's native clippy reuses their host tools).
 */
async function stepTestBuild(logFile) {
  await step('cargo-tests', 'Rust test binaries (built ahead for the cargo suite)', async () => {
    if (!suiteSelected('cargo')) return 'the cargo suite is not selected';
    try {
      await run('cargo', [...CARGO_TEST, '--no-run'], { cwd: CORE, logFile });
    } catch {
      // Not a set-up failure: the cargo suite builds them again and reports the error, while
      // the other suites still run.
      return 'did not build; the cargo suite will say why';
    }
  });
}

// ---------------------------------------------------------------- test suites

const stripAnsi = (s) => s.replace(/\x1b\[[0-9;?]*[A-Za-z]/g, '');
const num = (re, text) => {
  const m = text.match(re);
  return m ? Number(m[1]) : 0;
};

/** Each parser returns { passed, failed } from a runner's output, or null when it finds no summary. */
const parsers = {
  cargo(out) {
    // One `test result:` line per test binary (unit, each integration file, doc tests).
    const lines = [...out.matchAll(/test result: \w+\. (\d+) passed; (\d+) failed/g)];
    if (lines.length === 0) return null;
    return lines.reduce((a, m) => ({ passed: a.passed + Number(m[1]), failed: a.failed + Number(m[2]) }), { passed: 0, failed: 0 });
  },
  lint(out) {
    const m = out.match(/^lint: (\d+) passed, (\d+) failed$/m);
    return m ? { passed: Number(m[1]), failed: Number(m[2]) } : null;
  },
  vitest(out) {
    // "      Tests  1 failed | 12 passed (13)"
    const m = out.match(/^\s*Tests\s+([^\n]*)\(\d+\)\s*$/m);
    if (!m) return null;
    return { passed: num(/(\d+) passed/, m[1]), failed: num(/(\d+) failed/, m[1]) };
  },
  pytest(out) {
    // "3 passed, 1 failed, 2 errors in 0.41s" (possibly between ===== rules)
    const lines = out.split('\n').filter((l) => /\b(passed|failed|errors?|no tests ran)\b.* in [\d.]+s/.test(l));
    if (lines.length === 0) return null;
    const last = lines[lines.length - 1];
    if (/no tests ran/.test(last)) return null;
    return { passed: num(/(\d+) passed/, last), failed: num(/(\d+) failed/, last) + num(/(\d+) errors?/, last) };
  },
  playwright(out) {
    // list reporter: "  2 passed (8.1s)", "  1 failed", "  1 flaky" on their own lines
    const passed = out.match(/^\s*(\d+) passed\b/m);
    const failed = out.match(/^\s*(\d+) (?:failed|interrupted)\s*$/m);
    const flaky = out.match(/^\s*(\d+) flaky\s*$/m);
    if (!passed && !failed && !flaky) return null;
    return { passed: (passed ? Number(passed[1]) : 0) + (flaky ? Number(flaky[1]) : 0), failed: failed ? Number(failed[1]) : 0 };
  },
};

async function runSuites() {
  const bin = (name) => path.join(ROOT, 'node_modules', '.bin', name);
  const suites = [
    // Formatters and linters first: a finding fails `npm test` (scripts/lint.mjs).
    { id: 'lint', title: 'lint (rustfmt, clippy, ruff, biome, tsc)', cmd: process.execPath, args: [path.join(ROOT, 'scripts', 'lint.mjs')] },
    { id: 'cargo', title: 'cargo test (wasm-core)', cmd: 'cargo', args: CARGO_TEST, cwd: CORE },
    { id: 'vitest', title: 'vitest', cmd: bin('vitest'), args: ['run'] },
    // Two processes, whole files each (their module fixtures fit and train once): 80 s → 46 s.
    { id: 'pytest', title: 'pytest (training)', cmd: path.join(VENV, 'bin', 'pytest'), args: ['-q', '-n', '2', '--dist', 'loadfile'], cwd: path.join(ROOT, 'training') },
    { id: 'playwright', title: 'playwright', cmd: bin('playwright'), args: ['test'] },
  ].filter((s) => suiteSelected(s.id));

  const results = [];
  for (const s of suites) {
    const t0 = performance.now();
    console.log(`\n[test] ===== ${s.title} =====`);
    let code;
    let output;
    if (s.cwd && !fs.existsSync(s.cwd)) {
      code = -1;
      output = '';
      console.log(`[test] ${path.relative(ROOT, s.cwd)}/ does not exist`);
    } else if (path.isAbsolute(s.cmd) && !fs.existsSync(s.cmd)) {
      code = -1;
      output = '';
      console.log(`[test] ${path.relative(ROOT, s.cmd)} does not exist`);
    } else {
      ({ code, output } = await runCapture(s.cmd, s.args, { cwd: s.cwd ?? ROOT }));
    }
    const counts = parsers[s.id](stripAnsi(output));
    let note = '';
    let passed = 0;
    let failed = 0;
    if (counts) {
      ({ passed, failed } = counts);
      if (code !== 0 && failed === 0) {
        // The runner failed outside any test (compile error, pytest exit 5, crash): count it.
        failed = 1;
        note = `exit ${code}`;
      }
    } else {
      failed = 1;
      note = code === 0 ? 'no test summary found' : `exit ${code}, no test summary found`;
      if (s.id === 'pytest' && code === 5) note = 'exit 5: no tests collected';
    }
    const ok = code === 0 && failed === 0;
    results.push({ title: s.title, ok, passed, failed, time: secs(t0), note });
    console.log(`[test] ${s.title}: ${ok ? 'passed' : 'FAILED'} (${passed} passed, ${failed} failed${note ? `; ${note}` : ''}) in ${secs(t0)}`);
  }

  // Summary table.
  const rows = [['suite', 'result', 'passed', 'failed', 'time', 'note'], ...results.map((r) => [r.title, r.ok ? 'passed' : 'FAILED', String(r.passed), String(r.failed), r.time, r.note])];
  const widths = rows[0].map((_, c) => Math.max(...rows.map((r) => r[c].length)));
  const fmtRow = (r) => r.map((cell, c) => cell.padEnd(widths[c])).join('  ').trimEnd();
  console.log('\n' + fmtRow(rows[0]));
  console.log(widths.map((w) => '-'.repeat(w)).join('  '));
  for (const r of rows.slice(1)) console.log(fmtRow(r));
  const totalPassed = results.reduce((a, r) => a + r.passed, 0);
  const totalFailed = results.reduce((a, r) => a + r.failed, 0);
  console.log(`\ntotal time ${secs(t0All)}`);
  console.log(`${totalPassed} passed, ${totalFailed} failed`);
  return results.every((r) => r.ok) && totalFailed === 0 ? 0 : 1;
}

// ---------------------------------------------------------------- main

async function main() {
  log(`mode: ${mode}`);
  const logs = path.join(ROOT, 'test-results');
  fs.mkdirSync(logs, { recursive: true });
  // Lanes side by side from the start (2 cores; the lanes that run beside the streamed one write
  // their output to a file, shown if they fail):
  // - system packages (Chromium, nats-server) and the Python venv: downloads and unpacking;
  // - npm packages;
  // - native: the CLI and the databases it builds; then, side by side, the recordings (the
  //   venv's Python and the CLI; one core) and (`npm test`) the Rust test binaries;
  // - the wasm-bindgen CLI (compiled from source where it is missing);
  // - WASM (streamed, in its own target folder): the release build, its long single-threaded
  //   LTO leaving a core to the others, then its bindings.
  // Each lane is awaited where the next step needs it; a failure is reported there.
  const lane = (p) => {
    p.catch(() => undefined);
    return p;
  };
  const system = lane(mode === 'test' ? stepChromium().then(stepNats) : Promise.resolve());
  const venv = lane(mode === 'test' ? stepVenv(path.join(logs, 'pip-install.log')) : Promise.resolve());
  const npm = lane(stepNpm());
  await stepRustTarget();
  const databases = lane(stepCli(path.join(logs, 'setup-cli.log')).then(stepDatabases));
  const recordings = lane(Promise.all([databases, venv]).then(() => (mode === 'build' ? undefined : stepRecordings())));
  const testBuild = lane(mode === 'test' ? databases.then(() => stepTestBuild(path.join(logs, 'setup-cargo-tests.log'))) : Promise.resolve());
  const bindgen = lane(stepWasmBindgen(path.join(logs, 'wasm-bindgen-install.log')));
  await stepWasmBuild();
  await bindgen;
  await stepWasmBindings();
  await npm;
  await stepAvatars();
  await recordings;
  if (mode !== 'dev') await stepDist();
  if (mode !== 'dev') await stepServer();
  await system;
  await venv;
  await testBuild;
  log(`setup finished in ${secs(t0All)}`);

  if (mode === 'build') return 0;
  if (mode === 'start' || mode === 'dev') {
    // `--https`: a self-signed certificate made locally (@vitejs/plugin-basic-ssl; the built
    // site's server reuses its getCertificate and cache); Quest Browser allows WebXR only on
    // secure origins. Listening on 0.0.0.0 makes the page reachable from a headset on the LAN.
    const https = process.argv.slice(3).includes('--https');
    if (https) log('HTTPS on: open https://<this machine\'s LAN address>:5173/vr.html on the headset and accept the certificate warning');
    let child;
    if (mode === 'start') {
      log('serving the built site (dist/) on port 5173; `npm run dev` runs the vite dev server instead');
      child = spawn(process.execPath, [SERVER_BUNDLE, '--port', '5173', '--host', '0.0.0.0', '--root', 'dist', ...(https ? ['--https'] : [])], { cwd: ROOT, stdio: 'inherit' });
    } else {
      const env = https ? { ...process.env, VITE_HTTPS: '1' } : process.env;
      child = spawn(path.join(ROOT, 'node_modules', '.bin', 'vite'), ['--host', '0.0.0.0', '--port', '5173'], { cwd: ROOT, stdio: 'inherit', env });
    }
    for (const sig of ['SIGINT', 'SIGTERM']) process.on(sig, () => child.kill(sig));
    return new Promise((resolve) => child.on('close', (code) => resolve(code ?? 0)));
  }
  return runSuites();
}

main().then(
  (code) => process.exit(code),
  (e) => {
    if (e instanceof StepError) console.error(`\n[setup] ERROR: ${e.message}`);
    else console.error(e);
    process.exit(1);
  },
);
