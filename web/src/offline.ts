/**
 * `registerOfflineCache()`: the site's service worker (`sw.js` beside the built pages, written by
 * scripts/precompress.mjs) for repeat visits from Cache Storage and offline use after the first.
 * Pages call it after their first frame, so installing it never competes with the first load.
 * A no-op in development (no built `sw.js`), without service workers, or on insecure origins;
 * never throws. Embedding pages need none of this: the library caches its own versioned assets
 * (cache.ts).
 */
import { assetUrl, hasAssetVersions } from './assets.ts';

export async function registerOfflineCache(url: string | URL = assetUrl('sw.js')): Promise<ServiceWorkerRegistration | null> {
  if (!hasAssetVersions() || typeof navigator === 'undefined' || !('serviceWorker' in navigator) || !isSecureContext) return null;
  try {
    return await navigator.serviceWorker.register(url, { scope: new URL('./', url).pathname });
  } catch (e) {
    console.warn(`offline cache unavailable (${String(url)}): ${e instanceof Error ? e.message : String(e)}`);
    return null;
  }
}
