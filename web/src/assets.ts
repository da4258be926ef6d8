/**
 * Where the library finds its default assets (the WASM module, the default database and
 * avatar, the orientation model): a base URL, by default the folder of the library's own module
 * as built (`dist/`: `mm-avatar.js` sits beside `mmcore_bg.wasm`, `databases/`, `avatars/`,
 * `models/`), set at build time and resolved against `import.meta.url` at run time; in the dev
 * server, the site root. `setAssetBase` overrides it (e.g. a CDN folder).
 */
declare const __MM_ASSET_BASE__: string | undefined;
/**
 * Content hashes and sizes of the default assets of a build (vite.config.ts), e.g.
 * `{"databases/locomotion.mmdb": {"v": "1f2e…", "bytes": 34577008}}`: their URLs get `?v=<hash>`,
 * so caches may keep them for good (cache.ts, the server's `immutable`); none in development.
 */
declare const __MM_ASSET_VERSIONS__: Record<string, { v: string; bytes: number }> | undefined;

/** The built-in base, relative to this module's URL ('/' in development). */
const BUILT_IN = typeof __MM_ASSET_BASE__ === 'string' ? __MM_ASSET_BASE__ : '/';

let base: URL | null = null;

function defaultBase(): URL {
  const here = import.meta.url;
  const origin = typeof location !== 'undefined' ? location.href : here;
  // An absolute path is relative to the page's origin; anything else to this module.
  return new URL(BUILT_IN, BUILT_IN.startsWith('/') ? origin : here);
}

/** Sets the folder the default assets are fetched from (absolute, or relative to the page). */
export function setAssetBase(url: string | URL): void {
  base = new URL(url, typeof location !== 'undefined' ? location.href : undefined);
  if (!base.pathname.endsWith('/')) base.pathname += '/';
}

const VERSIONS = typeof __MM_ASSET_VERSIONS__ === 'object' && __MM_ASSET_VERSIONS__ ? __MM_ASSET_VERSIONS__ : {};

/**
 * URL of a default asset, e.g. `assetUrl('databases/locomotion.mmdb')`; in a build, versioned by
 * its content hash (`…/locomotion.mmdb?v=1f2e3d4c5b6a7980`).
 */
export function assetUrl(path: string): URL {
  base ??= defaultBase();
  const url = new URL(path, base);
  const version = VERSIONS[path];
  if (version && !url.search) url.searchParams.set('v', version.v);
  return url;
}

/** Whether this is a build with versioned assets (not the dev server). */
export function hasAssetVersions(): boolean {
  return Object.keys(VERSIONS).length > 0;
}

/** The size in bytes of a default asset as built (for progress when it is sent compressed), or 0. */
export function assetBytes(url: string | URL): number {
  const u = new URL(String(url), base ?? defaultBase());
  const v = u.searchParams.get('v');
  return v ? (Object.values(VERSIONS).find((e) => e.v === v)?.bytes ?? 0) : 0;
}

/** The shipped defaults. */
export const DEFAULT_DATABASE = 'databases/locomotion.mmdb';
/** The VR page's database (docs/database.md, `vr.json`): slow walks, steps, gestures, idle. */
export const DEFAULT_VR_DATABASE = 'databases/vr.mmdb';
export const DEFAULT_AVATAR = 'avatars/ubc_male.glb';
export const DEFAULT_ORIENTATION_MODEL = 'models/orientation.onnx';
/** The orientation model for one controller or none (recurrent; docs/orientation-model.md). */
export const DEFAULT_ORIENTATION_MODEL_FEWER_DEVICES = 'models/orientation_gru.onnx';
