/**
 * Where the library finds its default assets (the WASM module, the default database and
 * avatar, the orientation model): a base URL, by default the folder of the library's own module
 * as built (`dist/`: `mm-avatar.js` sits beside `mmcore_bg.wasm`, `databases/`, `avatars/`,
 * `models/`), set at build time and resolved against `import.meta.url` at run time; in the dev
 * server, the site root. `setAssetBase` overrides it (e.g. a CDN folder).
 */
declare const __MM_ASSET_BASE__: string | undefined;

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

/** URL of a default asset, e.g. `assetUrl('databases/locomotion.mmdb')`. */
export function assetUrl(path: string): URL {
  base ??= defaultBase();
  return new URL(path, base);
}

/** The shipped defaults. */
export const DEFAULT_DATABASE = 'databases/locomotion.mmdb';
export const DEFAULT_AVATAR = 'avatars/ubc_male.glb';
export const DEFAULT_ORIENTATION_MODEL = 'models/orientation.onnx';
