import { createHash } from 'node:crypto';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import basicSsl from '@vitejs/plugin-basic-ssl';
import { type Plugin, type Rollup, transformWithEsbuild } from 'vite';
import { defineConfig } from 'vitest/config';
import { roomsPlugin } from './server/vite-plugin.ts';

const root = fileURLToPath(new URL('.', import.meta.url));

/**
 * One config, three builds (`npm run build` runs them all, scripts/setup.mjs):
 * - `vite build` (mode `production`): the site — every page — into `dist/`, assets beside it;
 * - `vite build --mode element`: `dist/mm-avatar.js` (and its parts in `dist/assets/`), the
 *   standalone element with three.js bundled, finding its assets (WASM, default database and
 *   avatar) beside `mm-avatar.js`;
 * - `vite build --mode lib`: `dist/lib/`, the module for bundlers, `three` left to the app.
 * `__MM_ASSET_BASE__` is where the library's default assets are, relative to the built module
 * (web/src/assets.ts); in development they are at the site root.
 */
/**
 * `__MM_ASSET_VERSIONS__` (builds only): content hash and size of each default asset in
 * `public/` (the WASM module, databases, avatars, models), so the library asks for
 * `…/locomotion.mmdb?v=<hash>`, which caches keep for good (web/src/assets.ts, cache.ts).
 */
function assetVersions(): Record<string, { v: string; bytes: number }> {
  const out: Record<string, { v: string; bytes: number }> = {};
  const add = (rel: string) => {
    const bytes = fs.readFileSync(path.join(root, 'public', rel));
    out[rel] = { v: createHash('sha256').update(bytes).digest('hex').slice(0, 16), bytes: bytes.length };
  };
  if (fs.existsSync(path.join(root, 'public', 'mmcore_bg.wasm'))) add('mmcore_bg.wasm');
  for (const [dir, ext] of [['databases', /\.mmdb$/], ['avatars', /\.(glb|vrm)$/], ['models', /\.onnx$/]] as const) {
    const d = path.join(root, 'public', dir);
    if (fs.existsSync(d)) for (const f of fs.readdirSync(d).filter((f) => ext.test(f)).sort()) add(`${dir}/${f}`);
  }
  return out;
}

/**
 * The package build's asset URLs: the source writes each shipped asset as
 * `new URL(/* @vite-ignore *\/ '../<file>', import.meta.url)` so that this build leaves it alone
 * (vite would inline the file into the JS); the comment is dropped after bundling (by the
 * minifier, or here), so the
 * app's bundler (vite, webpack 5, parcel) sees the plain pattern and copies the file. The build
 * fails when a chunk keeps a URL the app's bundler could not follow.
 */
function packagedAssetUrls(): Plugin {
  const ignored = /new URL\(\s*\/\*\s*@vite-ignore\s*\*\/\s*/g;
  return {
    name: 'mm-packaged-asset-urls',
    enforce: 'post',
    renderChunk(code, chunk) {
      const out = code.replace(ignored, 'new URL(');
      for (const m of out.matchAll(/new URL\(([^,()]*),\s*import\.meta\.url\s*\)/g)) {
        if (!/^\s*(['"])\.\.\/[\w./-]+\1\s*$/.test(m[1])) this.error(`${chunk.fileName}: ${m[0]} is not a literal '../file' URL`);
      }
      return out === code ? null : { code: out, map: null };
    },
  };
}

/**
 * The site's pages ask for their core, database (its first part) and avatar only once their
 * scripts have run; a `<link rel="preload">` per asset (build only: the versioned URL the
 * library will request, `as="fetch"` + `crossorigin` to match its `fetch()`) starts them with
 * the HTML instead, while the scripts download and parse.
 */
function preloadFirstAssets(versions: Record<string, { v: string }>): Plugin {
  const first = (db: string) => ['mmcore_bg.wasm', `databases/${db}.first.mmdb`, 'avatars/ubc_male.glb'];
  const pages: Record<string, string[]> = { 'index.html': first('locomotion'), 'vr.html': first('vr') };
  return {
    name: 'mm-preload-first-assets',
    transformIndexHtml(_html, ctx) {
      const assets = (pages[path.basename(ctx.filename)] ?? []).filter((a) => versions[a]);
      const attrs = (a: string) => ({ rel: 'preload', as: 'fetch', crossorigin: '', href: `${a}?v=${versions[a].v}` });
      return assets.map((a) => ({ tag: 'link', attrs: attrs(a), injectTo: 'head-prepend' as const }));
    },
  };
}

// The app's three.js (not a copy some dependency carries, as the XR emulator's UI does).
const THREE_CORE = path.join(root, 'node_modules/three/build/three.core.js');
const THREE_MODULE = path.join(root, 'node_modules/three/build/three.module.js');

/**
 * The element's script in parts the browser compiles side by side: `mm-avatar.js` only imports
 * (register.ts); three.js' two halves (`assets/mm-avatar-three-*.js`, the renderer, and
 * `…-three-core-*.js`) and the library with its loaders (`…-element-*.js`),
 * 0.25-0.4 MB each, are compiled on the cores there are as they arrive (one 1 MB script was one
 * ~90 ms compile on one core before the page could start). What is imported only on demand
 * (three-vrm, for a VRM avatar) stays a chunk of its own, fetched when used.
 */
const elementChunk: Rollup.GetManualChunk = (id, meta) => {
  if (id === THREE_MODULE) return 'three';
  if (id === THREE_CORE) return 'three-core';
  const info = meta.getModuleInfo(id);
  if (!info || (info.importers.length === 0 && info.dynamicImporters.length > 0)) return undefined; // lazy
  return id.endsWith('/element/register.ts') ? undefined : 'element';
};

/**
 * The element build is one standalone script, not a module for bundlers: Vite's library mode
 * keeps an ES build's whitespace (for the pure annotations an app's bundler shakes by), but nothing
 * shakes this file again, so it is minified whole — 1.45 → 0.91 MB (0.76 MB before a first frame).
 */
function minifyStandalone(): Plugin {
  return {
    name: 'mm-minify-standalone',
    // After every renderChunk (Vite's own would print the whitespace back).
    async generateBundle(_options, bundle) {
      for (const chunk of Object.values(bundle)) {
        if (chunk.type !== 'chunk') continue;
        chunk.code = (await transformWithEsbuild(chunk.code, chunk.fileName, { minify: true, format: 'esm', target: 'es2022' })).code;
      }
    },
  };
}

/**
 * The scripts a page runs before its first frame (its entries and what they import, not the
 * parts imported on demand: rooms, the VR emulator, onnxruntime, three-vrm) start with V8's
 * explicit compile hint, `//# allFunctionsCalledOnLoad`: V8 compiles every function in them
 * while the script streams in, on a background thread, instead of each on the main thread the
 * first time it is called. Most of what they hold runs before the first frame (three.js'
 * renderer, the loaders, the library), and a first visit and the next one — before the browser
 * keeps a code cache, from the third — compiled 75-110 ms of functions lazily on the main thread
 * (traced: the embed page's warm visit), all of it in the way of the first frame. Browsers
 * without the hint read a comment. After minification (a comment it would drop). The element
 * build only: the site's pages come from their service worker's cache on a repeat visit, whose
 * scripts the browser compiled with a code cache when the worker stored them, and the hint
 * measured nothing there (the demo and the VR page throttled, 6 interleaved pairs each).
 *
 * Not on three.js' core classes (`…-three-core-*.js`): of their functions' code only 29 % runs
 * before the first frame (V8's precise coverage, the embed page's warm visit: 51 of 216 kB; the
 * renderer's part 56 %, the library's 66 %), and compiling the rest on a background thread took a
 * core from everything else the visit does on this 2-core machine (docs/history.md "Loading", stop 59).
 */
const COMPILE_HINT = '//# allFunctionsCalledOnLoad\n';
/** Initial chunks left to V8's lazy compile: little of them runs before the first frame. */
const NO_COMPILE_HINT = /(^|\/)mm-avatar-three-core-/;

function compileHints(): Plugin {
  return {
    name: 'mm-compile-hints',
    // After every other plugin's (Vite's preload helper puts its map of a chunk's on-demand
    // imports before its code): the hint must be the file's first line.
    generateBundle: {
      order: 'post',
      handler(_options, bundle) {
      const chunks = new Map<string, Rollup.OutputChunk>();
      for (const c of Object.values(bundle)) if (c.type === 'chunk') chunks.set(c.fileName, c);
      const initial = new Set<Rollup.OutputChunk>();
      const reach = (c: Rollup.OutputChunk | undefined): void => {
        if (!c || initial.has(c)) return;
        initial.add(c);
        for (const f of c.imports) reach(chunks.get(f));
      };
      for (const c of chunks.values()) if (c.isEntry) reach(c);
      for (const c of initial) if (!NO_COMPILE_HINT.test(c.fileName)) c.code = COMPILE_HINT + c.code;
      },
    },
  };
}

export default defineConfig(({ command, mode }) => {
  const build = command === 'build';
  const base = { root, publicDir: 'public' };
  const assets = build ? assetVersions() : {};
  const versions = build ? { __MM_ASSET_VERSIONS__: JSON.stringify(assets) } : {};
  if (build && mode === 'element') {
    return {
      ...base,
      publicDir: false,
      // The library's code lands in dist/assets/ (elementChunk): the assets are one folder up.
      define: { __MM_ASSET_BASE__: JSON.stringify('../'), ...versions },
      build: {
        outDir: 'dist',
        emptyOutDir: false,
        target: 'es2022',
        lib: { entry: 'web/src/element/register.ts', formats: ['es'], fileName: () => 'mm-avatar.js' },
        rollupOptions: { output: { chunkFileNames: 'assets/mm-avatar-[name]-[hash].js', manualChunks: elementChunk, hoistTransitiveImports: true } },
      },
      plugins: [minifyStandalone(), compileHints()],
    };
  }
  if (build && mode === 'lib') {
    return {
      ...base,
      publicDir: false,
      // __MM_PACKAGE__: the shipped assets are literal `new URL('../<file>', import.meta.url)`s
      // for the app's bundler (web/src/assets.ts), kept as they are by `packagedAssetUrls`.
      define: { __MM_ASSET_BASE__: JSON.stringify('../'), __MM_PACKAGE__: 'true', ...versions },
      plugins: [packagedAssetUrls()],
      build: {
        outDir: 'dist/lib',
        emptyOutDir: true,
        target: 'es2022',
        // One entry per `exports` path of package.json: the desktop library, the element
        // (registers itself), VR and rooms (so a desktop app never bundles them). Shared code
        // lands in shared chunks, so the entries share one WASM module and one set of classes.
        lib: { entry: { index: 'web/src/index.ts', element: 'web/src/element/register.ts', vr: 'web/src/vr/index.ts', rooms: 'web/src/rooms/index.ts' }, formats: ['es'] },
        rollupOptions: { external: [/^three($|\/)/, /^@pixiv\/three-vrm/, /^onnxruntime-web/] },
      },
    };
  }
  return {
    ...base,
    // Site modules land in dist/assets/: the shared assets are one folder up.
    define: build ? { __MM_ASSET_BASE__: JSON.stringify('../'), ...versions } : {},
    // `npm start -- --https` / `npm run dev -- --https` (VITE_HTTPS=1): a self-signed certificate
    // made locally, because Quest Browser allows WebXR only on secure origins. The room server
    // shares the dev server's origin (/rooms/<id>).
    plugins: [
      ...(process.env.VITE_HTTPS === '1' ? [basicSsl({ name: 'mm-avatar-dev' })] : []),
      roomsPlugin(),
      ...(build ? [preloadFirstAssets(assets)] : []),
    ],
    server: { port: 5173, fs: { allow: [root] } },
    build: {
      outDir: 'dist',
      emptyOutDir: false,
      target: 'es2022',
      rollupOptions: {
        input: { index: 'index.html', viewer: 'viewer.html', vr: 'vr.html', crowd: 'crowd.html', bench: 'bench.html' },
        // three.js' core half in a chunk of its own: a page's scripts then come in parts of at most
        // ~0.4 MB that compile side by side (its renderer half and the core were one 0.6 MB
        // chunk, the longest compile before a page could start; see elementChunk).
        output: { manualChunks: (id) => (id === THREE_CORE ? 'three-core' : undefined) },
      },
    },
    // onnxruntime-web ships its own wasm loader that pre-bundling breaks.
    // iwer and its devui are imported lazily (vr.html?emulate=1); pre-bundling them up front keeps
    // vite from re-optimizing mid-session and reloading the page.
    optimizeDeps: { exclude: ['onnxruntime-web'], include: ['iwer', '@iwer/devui'] },
    test: {
      include: ['tests/unit/**/*.test.ts', 'web/**/*.test.ts', 'server/**/*.test.ts'],
      environment: 'node',
      testTimeout: 30_000,
      // Most files wait on real servers, processes and sockets rather than compute: four files
      // at a time keep 2 cores busy (the suite took 103 s one file at a time, 35 s four at a time).
      maxWorkers: 4,
    },
  };
});
