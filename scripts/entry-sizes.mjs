// What each of the package's entries costs an app that imports it: every entry of the module
// build (dist/lib/, the `exports` of package.json) bundled as an app's bundler would (esbuild,
// minified, `three` left out: the app has it anyway), gzip-compressed. "static" is what loads
// with the import; "lazy" what the entry imports on demand (onnxruntime-web in the VR entry).
// Also the WASM module. `npm run bench -- --load` prints these;
// `node scripts/entry-sizes.mjs [dist]` alone too.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import zlib from 'node:zlib';

const ROOT = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');

const gzip = (bytes) => zlib.gzipSync(bytes, { level: 9 }).length;

/** The package's JS entries: `exports` subpaths that point into dist/lib/. */
function entries() {
  const pkg = JSON.parse(fs.readFileSync(path.join(ROOT, 'package.json'), 'utf8'));
  const out = [];
  for (const [subpath, target] of Object.entries(pkg.exports)) {
    const file = typeof target === 'string' ? target : target.import;
    if (typeof file === 'string' && file.startsWith('./dist/lib/')) out.push({ name: subpath === '.' ? pkg.name : `${pkg.name}/${subpath.slice(2)}`, file: file.slice(2) });
  }
  return out;
}

/** Bundles `files` together as an app's bundler would; the static closure of each, and the lazy rest. */
async function bundle(files) {
  const esbuild = await import('esbuild');
  const outdir = fs.mkdtempSync(path.join(os.tmpdir(), 'mm-entry-'));
  try {
    const result = await esbuild.build({
      entryPoints: files,
      bundle: true,
      format: 'esm',
      splitting: true,
      minify: true,
      target: 'es2022',
      outdir,
      external: ['three', 'three/*'],
      metafile: true,
      logLevel: 'silent',
    });
    const outputs = result.metafile.outputs;
    const size = new Map(Object.keys(outputs).filter((k) => k.endsWith('.js')).map((k) => {
      const bytes = fs.readFileSync(path.resolve(k));
      return [k, { raw: bytes.length, gzip: gzip(bytes) }];
    }));
    const closure = (file) => {
      const key = Object.keys(outputs).find((k) => outputs[k].entryPoint && path.resolve(outputs[k].entryPoint) === path.resolve(file));
      const seen = new Set();
      const walk = (k) => {
        if (seen.has(k)) return;
        seen.add(k);
        for (const i of outputs[k].imports) if (i.kind === 'import-statement' && !i.external) walk(i.path);
      };
      walk(key);
      return seen;
    };
    return { size, closures: files.map(closure) };
  } finally {
    fs.rmSync(outdir, { recursive: true, force: true });
  }
}

const total = (size, keys) => [...keys].reduce((a, k) => ({ raw: a.raw + size.get(k).raw, gzip: a.gzip + size.get(k).gzip }), { raw: 0, gzip: 0 });

/**
 * { entries: [{ name, static, lazy, overRoot }], wasm } (each {raw, gzip} bytes): `static` what
 * the entry loads when imported alone, `lazy` what it may import later, `overRoot` what it adds to
 * an app that imports the root entry too (null for the root).
 */
export async function entrySizes(dist = path.join(ROOT, 'dist')) {
  const list = entries().map((e) => ({ ...e, path: path.join(dist, '..', e.file) }));
  for (const e of list) if (!fs.existsSync(e.path)) throw new Error(`entry sizes: ${path.relative(ROOT, e.path)} missing; run \`npm run build\` first`);
  const root = list[0];
  const rows = [];
  for (const e of list) {
    const alone = await bundle([e.path]);
    const [closure] = alone.closures;
    const lazy = [...alone.size.keys()].filter((k) => !closure.has(k));
    let overRoot = null;
    if (e !== root) {
      const both = await bundle([root.path, e.path]);
      overRoot = total(both.size, [...both.closures[1]].filter((k) => !both.closures[0].has(k)));
    }
    rows.push({ name: e.name, static: total(alone.size, closure), lazy: total(alone.size, lazy), overRoot });
  }
  const wasmBytes = fs.readFileSync(path.join(dist, 'mmcore_bg.wasm'));
  return { entries: rows, wasm: { raw: wasmBytes.length, gzip: gzip(wasmBytes) } };
}

export function printEntrySizes({ entries: rows, wasm }) {
  const kb = (n) => `${(n / 1e3).toFixed(1)} kB`;
  console.log('package entries (dist/lib bundled by esbuild, minified, three left out; gzip -9):');
  for (const r of rows) {
    const over = r.overRoot ? `   with mm-avatar: +${kb(r.overRoot.gzip)}` : '';
    console.log(`  ${r.name.padEnd(20)} static ${kb(r.static.gzip).padStart(9)} gzip (${kb(r.static.raw).padStart(9)})   lazy ${kb(r.lazy.gzip).padStart(9)} gzip${over}`);
  }
  console.log(`  ${'WASM core'.padEnd(20)}        ${kb(wasm.gzip).padStart(9)} gzip (${kb(wasm.raw)})`);
}

if (process.argv[1] && path.resolve(process.argv[1]) === fileURLToPath(import.meta.url)) {
  const arg = process.argv.slice(2).find((a) => !a.startsWith('--'));
  const dist = arg ? path.resolve(arg) : undefined;
  const sizes = await entrySizes(dist);
  if (process.argv.includes('--json')) console.log(JSON.stringify(sizes, null, 2));
  else printEntrySizes(sizes);
}
