#!/usr/bin/env node
// After `vite build` (scripts/setup.mjs' dist step): `node scripts/precompress.mjs [dist]`
//
// 1. Writes `file.br` and `file.gz` beside every compressible file of the built site (text,
//    JSON, JS, WASM, .mmdb, .glb, .onnx) when that saves ≥ 5 %, for the production server
//    (server/static.ts) to send as they are. Brotli quality 11 (window 2^24) and gzip 9 up to
//    8 MB; above, brotli 5 and gzip 6 (on the 35 MB database brotli 5 takes 6 s for 9.58 MB where
//    9 takes 45–150 s for 9.66 MB and 11 about 160 s for 8.92 MB; gzip 6 = gzip 9 within 0.1 %).
//    Outputs are cached by content hash in node_modules/.cache/mm-precompress/, so a rebuild
//    with unchanged assets only copies them back.
// 2. Writes `sw.js`, the site's service worker, from web/sw/sw.js with the content hashes of
//    the site's shell filled in (the cache is versioned by them; see that file).
//
// Node builtins only.
import { createHash } from 'node:crypto';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { promisify } from 'node:util';
import zlib from 'node:zlib';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const DIST = path.resolve(process.argv[2] ?? path.join(ROOT, 'dist'));
const CACHE = path.join(ROOT, 'node_modules', '.cache', 'mm-precompress');
const COMPRESSIBLE = /\.(html|js|mjs|css|json|map|svg|txt|md|wasm|mmdb|glb|vrm|onnx)$/i;
/** Folders of dist/ that are the npm package's, not the site's (never served compressed). */
const SKIP = new Set(['lib', 'types']);
const BIG = 8e6;

const sha = (bytes) => createHash('sha256').update(bytes).digest('hex');

function walk(dir, out = []) {
  for (const e of fs.readdirSync(dir, { withFileTypes: true })) {
    if (e.name.startsWith('.')) continue;
    const p = path.join(dir, e.name);
    if (e.isDirectory()) {
      if (!(dir === DIST && SKIP.has(e.name))) walk(p, out);
    } else out.push(p);
  }
  return out;
}

// Asynchronous: zlib runs them on libuv's thread pool, so the files encode side by side (a fresh
// build's brotli 11 on one core was the setup's longest single-threaded tail).
const brotliCompress = promisify(zlib.brotliCompress);
const gzipCompress = promisify(zlib.gzip);

function brotli(bytes) {
  const big = bytes.length > BIG;
  return brotliCompress(bytes, {
    params: {
      [zlib.constants.BROTLI_PARAM_QUALITY]: big ? 5 : 11,
      [zlib.constants.BROTLI_PARAM_LGWIN]: 24,
      [zlib.constants.BROTLI_PARAM_SIZE_HINT]: bytes.length,
    },
  });
}

const gzip = (bytes) => gzipCompress(bytes, { level: bytes.length > BIG ? 6 : 9 });

const t0 = performance.now();
fs.mkdirSync(CACHE, { recursive: true });
const files = walk(DIST);
let written = 0;
let cached = 0;
let rawTotal = 0;
let brTotal = 0;
const hashes = new Map();
const jobs = [];
for (const file of files) {
  if (/\.(br|gz)$/.test(file)) continue;
  const bytes = fs.readFileSync(file);
  const hash = sha(bytes);
  hashes.set(path.relative(DIST, file).split(path.sep).join('/'), hash);
  if (!COMPRESSIBLE.test(file) || bytes.length < 1024) continue;
  for (const [ext, encode] of [['.br', brotli], ['.gz', gzip]]) {
    jobs.push(
      (async () => {
        const out = file + ext;
        const key = path.join(CACHE, `${hash}.${bytes.length > BIG ? 'b5g6' : 'b11g9'}${ext}`); // content and settings
        let encoded;
        if (fs.existsSync(key)) {
          encoded = fs.readFileSync(key);
          cached++;
        } else {
          encoded = await encode(bytes);
          fs.writeFileSync(key, encoded);
          written++;
        }
        if (ext === '.br') {
          rawTotal += bytes.length;
          brTotal += Math.min(bytes.length, encoded.length);
        }
        if (encoded.length > bytes.length * 0.95) fs.rmSync(out, { force: true });
        else fs.writeFileSync(out, encoded);
      })(),
    );
  }
}
await Promise.all(jobs);

// The service worker: its shell list is every page, script, style and small asset of the site
// (not the databases, avatars, recordings or onnxruntime's 14 MB module, which are cached as
// they are used), and its version is a hash over all of them.
const template = fs.readFileSync(path.join(ROOT, 'web', 'sw', 'sw.js'), 'utf8');
const shell = [...hashes.keys()]
  .filter((f) => /\.(html|js|css|json)$/.test(f) && !/^(recordings|databases)\//.test(f) && f !== 'sw.js')
  .filter((f) => fs.statSync(path.join(DIST, f)).size < 2e6)
  .sort();
const version = sha([...hashes.entries()].sort().map(([f, h]) => `${f} ${h}`).join('\n')).slice(0, 16);
const sw = template.replace('self.__MM_VERSION__', JSON.stringify(version)).replace('self.__MM_SHELL__', JSON.stringify(['./', ...shell]));
fs.writeFileSync(path.join(DIST, 'sw.js'), sw);
for (const [ext, encode] of [['.br', brotli], ['.gz', gzip]]) fs.writeFileSync(path.join(DIST, `sw.js${ext}`), await encode(Buffer.from(sw)));

const mb = (n) => (n / 1e6).toFixed(1);
console.log(
  `[precompress] ${files.length} files: ${written} encoded, ${cached} from the cache; compressible ${mb(rawTotal)} MB → ${mb(brTotal)} MB brotli; ` +
    `sw.js version ${version}, ${shell.length + 1} shell files (${((performance.now() - t0) / 1000).toFixed(1)} s)`,
);
