/**
 * Fetching the library's inputs with progress and clear failures: every message names the URL;
 * a server's HTML page where a binary was expected (a dev server's SPA fallback for a missing
 * file) counts as missing.
 */

/** Progress of one download: `loaded` of `total` bytes (`total` 0 when the server did not say). */
export interface FetchProgress {
  stage: string;
  url: string;
  loaded: number;
  total: number;
}

export interface FetchOptions {
  /** What is being fetched, for messages and progress (`database`, `avatar`…). */
  stage?: string;
  onProgress?: (p: FetchProgress) => void;
  signal?: AbortSignal;
}

/** Fetches `url` as bytes, reporting progress; rejects with an Error that names the URL. */
export async function fetchBytes(url: string | URL, options: FetchOptions = {}): Promise<Uint8Array> {
  const href = String(url);
  const stage = options.stage ?? 'file';
  let response: Response;
  try {
    response = await fetch(href, { signal: options.signal });
  } catch (e) {
    if (options.signal?.aborted) throw e;
    throw new Error(`could not fetch the ${stage} ${href}: ${e instanceof Error ? e.message : String(e)}`);
  }
  const type = response.headers.get('content-type') ?? '';
  if (!response.ok) throw new Error(`could not load the ${stage} ${href}: HTTP ${response.status} ${response.statusText}`.trim());
  if (type.includes('text/html')) throw new Error(`could not load the ${stage} ${href}: not found (the server answered with an HTML page)`);
  const total = Number(response.headers.get('content-length')) || 0;
  const report = (loaded: number) => options.onProgress?.({ stage, url: href, loaded, total });
  if (!response.body) {
    const bytes = new Uint8Array(await response.arrayBuffer());
    report(bytes.length);
    return bytes;
  }
  const reader = response.body.getReader();
  const chunks: Uint8Array[] = [];
  let loaded = 0;
  report(0);
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    chunks.push(value);
    loaded += value.length;
    report(loaded);
  }
  if (chunks.length === 1) return chunks[0];
  const bytes = new Uint8Array(loaded);
  let o = 0;
  for (const c of chunks) {
    bytes.set(c, o);
    o += c.length;
  }
  return bytes;
}

/** The message of anything thrown (wasm-bindgen may throw strings). */
export function errorMessage(e: unknown): string {
  return e instanceof Error ? e.message : String(e);
}
