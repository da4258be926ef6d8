/**
 * Fetching the library's inputs with progress and clear failures: every message names the URL;
 * a server's HTML page where a binary was expected (a dev server's SPA fallback for a missing
 * file) counts as missing; a download that receives nothing for `stallMs` says so (progress
 * with `stalled`); versioned URLs (`?v=<hash>`) come from and go to the library's cache
 * (cache.ts).
 */
import { assetBytes } from './assets.ts';
import { cachedBytes, preloaded, storeBytes } from './cache.ts';

/** Progress of one download: `loaded` of `total` bytes (`total` 0 when the server did not say). */
export interface FetchProgress {
  stage: string;
  url: string;
  loaded: number;
  total: number;
  /** Nothing arrived for `stallMs` (the download is still waiting; a later event clears it). */
  stalled?: boolean;
  /** The last event of a successful download. */
  done?: boolean;
  /** The bytes came from the library's cache, not the network. */
  cached?: boolean;
}

export interface FetchOptions {
  /** What is being fetched, for messages and progress (`database`, `avatar`…). */
  stage?: string;
  onProgress?: (p: FetchProgress) => void;
  signal?: AbortSignal;
  /** Milliseconds without a byte after which progress reports `stalled`; default 5000. */
  stallMs?: number;
  /** Expected size, when the server sends it compressed (its Content-Length is then the encoded size). */
  expectedBytes?: number;
  /** Use the library's cache for versioned URLs; default true. */
  cache?: boolean;
  /**
   * A download in the background (a first part's whole): the request goes out at once, while
   * the library's cache is looked at (the request is dropped on a hit), so a main thread busy
   * after the first frame does not hold it back.
   */
  background?: boolean;
}

/** HTML where binary data was expected: `<!doctype html`, `<html`, `<head`, `<body` after whitespace. */
function looksLikeHtml(bytes: Uint8Array): boolean {
  const head = new TextDecoder().decode(bytes.subarray(0, 64)).trimStart().toLowerCase();
  return /^<(!doctype html|html|head|body|!--)/.test(head);
}

/** Fetches `url` as bytes, reporting progress; rejects with an Error that names the URL. */
export async function fetchBytes(url: string | URL, options: FetchOptions = {}): Promise<Uint8Array> {
  const href = String(url);
  const stage = options.stage ?? 'file';
  const report = (p: Omit<FetchProgress, 'stage' | 'url'>) => options.onProgress?.({ stage, url: href, ...p });
  const useCache = options.cache !== false;
  let early: Promise<Response> | null = null;
  const drop = options.background ? new AbortController() : null;
  if (drop) {
    options.signal?.addEventListener('abort', () => drop.abort(), { once: true });
    early = fetch(href, { signal: drop.signal });
    early.catch(() => undefined); // awaited below, or dropped
  }
  const fromCache = async () => {
    const hit = await cachedBytes(href);
    if (hit) {
      report({ loaded: hit.length, total: hit.length, done: true, cached: true });
      mark(`mm:fetched:${stage}`);
    }
    return hit;
  };
  // A URL the page preloads is fetched, not read from the cache: the fetch takes the preloaded
  // response (begun with the HTML; on a repeat visit the site's service worker answers it from
  // the same cache), where a direct read would leave it unused — a second read of each asset
  // and a console warning about it on every repeat visit.
  if (useCache && !preloaded(href)) {
    const hit = await fromCache();
    if (hit) {
      drop?.abort();
      return hit;
    }
  }

  // Stall watch: from the request until the last byte, any 5 s with nothing new is reported.
  const stallMs = options.stallMs ?? 5000;
  let loaded = 0;
  const expected = options.expectedBytes || assetBytes(href);
  let total = expected;
  let lastByte = performance.now();
  let stalled = false;
  const watch = setInterval(() => {
    if (!stalled && performance.now() - lastByte >= stallMs) {
      stalled = true;
      report({ loaded, total, stalled: true });
    }
  }, Math.min(1000, stallMs / 2));
  try {
    let response: Response;
    try {
      response = await (early ?? fetch(href, { signal: options.signal }));
    } catch (e) {
      if (options.signal?.aborted) throw e;
      const hit = useCache ? await fromCache() : null; // offline, preloaded: the cache still has it
      if (hit) return hit;
      throw new Error(`could not fetch the ${stage} ${href}: ${e instanceof Error ? e.message : String(e)} (offline, or the server is down?)`);
    }
    const type = response.headers.get('content-type') ?? '';
    if (!response.ok) throw new Error(`could not load the ${stage} ${href}: HTTP ${response.status} ${response.statusText}`.trim());
    if (type.includes('text/html')) throw new Error(`could not load the ${stage} ${href}: not found (the server answered with an HTML page)`);
    const encoded = !!response.headers.get('content-encoding')?.replace(/identity/i, '').trim();
    const decoded = Number(response.headers.get('x-decoded-length')) || 0;
    total = encoded ? decoded || expected : Number(response.headers.get('content-length')) || expected;
    lastByte = performance.now();
    let bytes: Uint8Array;
    // Nobody watching the progress (a download in the background: a first part's whole): the
    // browser gathers the body off the main thread, which a busy frame loop would otherwise
    // pace chunk by chunk (2.7 s for the 5 MB whole on localhost under software WebGL).
    if (!response.body || !options.onProgress) {
      bytes = new Uint8Array(await response.arrayBuffer());
      loaded = bytes.length;
    } else {
      const reader = response.body.getReader();
      const chunks: Uint8Array[] = [];
      report({ loaded: 0, total });
      for (;;) {
        const { done, value } = await reader.read();
        if (done) break;
        chunks.push(value);
        loaded += value.length;
        lastByte = performance.now();
        stalled = false;
        report({ loaded, total });
      }
      bytes = chunks.length === 1 ? chunks[0] : new Uint8Array(loaded);
      if (chunks.length !== 1) {
        let o = 0;
        for (const c of chunks) {
          bytes.set(c, o);
          o += c.length;
        }
      }
    }
    if (looksLikeHtml(bytes)) throw new Error(`could not load the ${stage} ${href}: not found (the server answered with an HTML page)`);
    report({ loaded: bytes.length, total: bytes.length, done: true });
    mark(`mm:fetched:${stage}`);
    // Into the cache once the page is idle (at most 3 s later): not in the way of the first frame.
    if (useCache) whenIdle(() => void storeBytes(href, bytes, type || undefined));
    return bytes;
  } finally {
    clearInterval(watch);
  }
}

function whenIdle(fn: () => void): void {
  if (typeof requestIdleCallback === 'function') requestIdleCallback(fn, { timeout: 3000 });
  else setTimeout(fn, 500);
}

/** A performance mark where the timeline exists (load benchmarks read them: scripts/bench-load.mjs). */
export function mark(name: string): void {
  if (typeof performance !== 'undefined' && typeof performance.mark === 'function' && typeof window !== 'undefined') performance.mark(name);
}

/** The message of anything thrown (wasm-bindgen may throw strings). */
export function errorMessage(e: unknown): string {
  return e instanceof Error ? e.message : String(e);
}
