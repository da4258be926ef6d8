/**
 * Where the library finds its default assets (the WASM module, the default database and
 * avatar, the orientation models).
 *
 * - **The package for bundlers** (`dist/lib/`, `npm i mm-avatar`): each shipped asset is named by
 *   a literal `new URL('../<file>', import.meta.url)` in the built module, the pattern vite,
 *   webpack 5 and parcel follow to copy the file into the app's output by themselves (no
 *   copying step, no configuration); the app's bundler then rewrites the URL to where it put
 *   the file. The literals are in this module (`PACKAGED`) and in the VR entry's (vr/assets.ts),
 *   written relative to `dist/lib/`, where the built modules sit beside `../mmcore_bg.wasm`,
 *   `../databases/`, `../avatars/`, `../models/`. Only the entries that use an asset name it,
 *   so a desktop app never carries the VR models.
 * - **The one-tag build** (`dist/mm-avatar.js`) and **the site** find them in a base folder set
 *   at build time (`__MM_ASSET_BASE__`: beside `mm-avatar.js`, one folder up from the site's
 *   `assets/`) resolved against `import.meta.url` at run time; the dev server, at the site root.
 * - `setAssetBase(url)` overrides all of them (a CDN folder, a bundler that does not follow the
 *   pattern: rollup and esbuild without a plugin).
 */
declare const __MM_ASSET_BASE__: string | undefined;
/**
 * Content hashes and sizes of the default assets of a build (vite.config.ts), e.g.
 * `{"databases/locomotion.mmdb": {"v": "1f2e…", "bytes": 34577008}}`: their URLs get `?v=<hash>`,
 * so caches may keep them for good (cache.ts, the server's `immutable`); none in development.
 */
declare const __MM_ASSET_VERSIONS__: Record<string, { v: string; bytes: number }> | undefined;
/** True in the package build for bundlers (`vite build --mode lib`). */
declare const __MM_PACKAGE__: boolean | undefined;

/** The package build: shipped assets are the literal URLs below, not a base folder. */
export const PACKAGE = typeof __MM_PACKAGE__ === 'boolean' && __MM_PACKAGE__;

/** The built-in base, relative to this module's URL ('/' in development). */
const BUILT_IN = typeof __MM_ASSET_BASE__ === 'string' ? __MM_ASSET_BASE__ : '/';

let base: URL | null = null;
/** Whether `setAssetBase` chose the base (it then wins over the package's literal URLs). */
let baseSet = false;

/** The page's URL, or undefined outside a page (Node: SSR, tests). Read when called, never at import. */
export function pageUrl(): string | undefined {
  return typeof location !== 'undefined' ? location.href : undefined;
}

function defaultBase(): URL {
  const here = import.meta.url;
  // An absolute path is relative to the page's origin; anything else to this module.
  return new URL(BUILT_IN, BUILT_IN.startsWith('/') ? (pageUrl() ?? here) : here);
}

/** Sets the folder the default assets are fetched from (absolute, or relative to the page). */
export function setAssetBase(url: string | URL): void {
  base = new URL(url, pageUrl());
  if (!base.pathname.endsWith('/')) base.pathname += '/';
  baseSet = true;
}

const VERSIONS = typeof __MM_ASSET_VERSIONS__ === 'object' && __MM_ASSET_VERSIONS__ ? __MM_ASSET_VERSIONS__ : {};

/**
 * The root entry's shipped assets in the package build, each a literal URL for the app's
 * bundler (`@vite-ignore`: our own build leaves them alone; the package build drops the comment,
 * vite.config.ts). Anywhere else the branch is removed at build time.
 */
const PACKAGED: Record<string, () => URL> = PACKAGE
  ? {
      'mmcore_bg.wasm': () => new URL(/* @vite-ignore */ '../mmcore_bg.wasm', import.meta.url),
      'databases/locomotion.mmdb': () => new URL(/* @vite-ignore */ '../databases/locomotion.mmdb', import.meta.url),
      'databases/locomotion.first.mmdb': () => new URL(/* @vite-ignore */ '../databases/locomotion.first.mmdb', import.meta.url),
      'avatars/ubc_male.glb': () => new URL(/* @vite-ignore */ '../avatars/ubc_male.glb', import.meta.url),
    }
  : {};

function versioned(url: URL, path: string): URL {
  const version = VERSIONS[path];
  if (version && !url.search && url.protocol !== 'data:') url.searchParams.set('v', version.v);
  return url;
}

/**
 * URL of a default asset, e.g. `assetUrl('databases/locomotion.mmdb')`; in a build, versioned by
 * its content hash (`…/locomotion.mmdb?v=1f2e3d4c5b6a7980`). In the package, a shipped asset's
 * URL is where the app's bundler put it (unless `setAssetBase` was called).
 */
export function assetUrl(path: string): URL {
  const packaged = baseSet ? undefined : PACKAGED[path];
  return packaged ? versioned(packaged(), path) : versioned(new URL(path, (base ??= defaultBase())), path);
}

/**
 * `assetUrl` for an asset only another entry ships (the VR entry's models): `packaged` is its
 * literal URL in the package build, null elsewhere. @internal
 */
export function shippedAssetUrl(path: string, packaged: (() => URL) | null): URL {
  return packaged && !baseSet ? versioned(packaged(), path) : assetUrl(path);
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

/**
 * `name`, a file beside the one at `url`: a default asset's sibling gets its own version (or
 * packaged URL), so a first part finds its whole wherever the build put it. @internal
 */
export function siblingAssetUrl(url: string, name: string): string {
  let href: string;
  try {
    href = new URL(url, pageUrl()).href;
  } catch {
    return name; // bytes named by a file name: resolved against the page
  }
  for (const path of new Set([...Object.keys(VERSIONS), ...Object.keys(PACKAGED)])) {
    if (assetUrl(path).href === href) return assetUrl(path.replace(/[^/]*$/, name)).href;
  }
  return new URL(name, href).href;
}

/** The shipped default database (`Character.create()` and `<mm-avatar>` without one start on its first part). */
export const DEFAULT_DATABASE = 'databases/locomotion.mmdb';
/**
 * Its first part: what the defaults load first, then the whole after the first frames
 * (`Character.whole()`). @internal
 */
export const DEFAULT_FIRST_PART = 'databases/locomotion.first.mmdb';
/** The shipped default avatar (`Character.create()` and `<mm-avatar>` without one load it). */
export const DEFAULT_AVATAR = 'avatars/ubc_male.glb';
