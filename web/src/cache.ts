/**
 * The library's own cache of its versioned assets (Cache Storage, no service worker needed, so
 * it works in any page that embeds `<mm-avatar>`): a URL whose query has `v=<content hash>` (the
 * default WASM module, database, avatar and model of a build, see assets.ts) names bytes that
 * never change, so a repeat visit takes them from here without asking the network, offline too.
 * A new build has new hashes: older versions of the same file are deleted when a new one is
 * stored. Anything else goes through the browser's HTTP cache as usual.
 *
 * Cache Storage exists only in secure contexts (https, localhost); elsewhere, or when storage is
 * refused, every function here quietly does nothing.
 */

/** The Cache Storage cache the library's assets live in (the site's service worker reads it too). */
export const ASSET_CACHE = 'mm-avatar-assets';

/** Whether `url` names immutable bytes (a `v=` content hash in its query). */
export function isVersioned(url: string | URL): boolean {
  try {
    return new URL(String(url), typeof location !== 'undefined' ? location.href : undefined).searchParams.has('v');
  } catch {
    return false;
  }
}

function storage(): CacheStorage | null {
  try {
    return typeof caches !== 'undefined' && typeof isSecureContext !== 'undefined' && isSecureContext ? caches : null;
  } catch {
    return null;
  }
}

/** Whether the page preloads `href` (a `<link rel="preload">`): it is then fetched, not read from here. */
export function preloaded(href: string): boolean {
  if (typeof document === 'undefined') return false;
  const absolute = new URL(href, location.href).href;
  for (const link of document.querySelectorAll<HTMLLinkElement>('link[rel="preload"]')) if (link.href === absolute) return true;
  return false;
}

/** The cached bytes of a versioned URL, or null. */
export async function cachedBytes(url: string): Promise<Uint8Array | null> {
  const cs = storage();
  if (!cs || !isVersioned(url)) return null;
  try {
    const hit = await (await cs.open(ASSET_CACHE)).match(url);
    return hit ? new Uint8Array(await hit.arrayBuffer()) : null;
  } catch {
    return null;
  }
}

/** Stores the bytes of a versioned URL and drops other versions of the same file. Never throws. */
export async function storeBytes(url: string, bytes: Uint8Array, contentType = 'application/octet-stream'): Promise<void> {
  const cs = storage();
  if (!cs || !isVersioned(url)) return;
  try {
    const cache = await cs.open(ASSET_CACHE);
    const target = new URL(url);
    const keys = await cache.keys();
    // Already there (fetched through a preload the service worker answered from here): no rewrite.
    if (keys.some((request) => request.url === target.href)) return;
    for (const request of keys) {
      const u = new URL(request.url);
      if (u.origin === target.origin && u.pathname === target.pathname && u.search !== target.search) await cache.delete(request);
    }
    const body = new Uint8Array(bytes); // a copy: the caller's view may live in WASM memory
    await cache.put(url, new Response(body, { headers: { 'content-type': contentType, 'content-length': String(body.length) } }));
  } catch {
    /* quota, private mode: the next visit downloads again */
  }
}
