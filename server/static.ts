/**
 * The production static file server for `dist/` (`npm start`, server/serve.ts): Node's http
 * only, no framework.
 *
 * - Precompressed siblings: `file.br` / `file.gz` written at build time (scripts/precompress.mjs)
 *   are sent when the request's `Accept-Encoding` allows them (brotli first, q-values honoured),
 *   with `Content-Encoding` and `Vary: Accept-Encoding`; nothing is compressed per request.
 * - Content types for everything the site serves, `application/wasm` included (needed for
 *   streaming compilation).
 * - Caching: vite's content-hashed files (`assets/name-HASH.ext`) and URLs versioned by content
 *   (`?v=HASH`, the library's default assets) are `immutable` for a year; scripts and styles at
 *   a stable name (the element's `mm-avatar.js`, which only imports hashed parts; an example
 *   page's script and style) are used from the cache at once and revalidated behind it for a day
 *   (a returning visitor's page waits for no round trip for them; a new build shows one visit
 *   later); everything else (pages, the service worker, data) is `no-cache` with a strong `ETag`
 *   (a 304 when unchanged).
 * - `HEAD`, single `Range: bytes=a-b` requests (on the identity body), 405 for other methods.
 * - A missing file is a plain-text 404 naming the path: never an HTML page in place of a
 *   database (the dev server's fallback the library must otherwise guess at).
 * - Paths stay inside the root; dotfiles and the precompressed siblings themselves are not served.
 */
import fs from 'node:fs';
import type { IncomingMessage, ServerResponse } from 'node:http';
import path from 'node:path';

export const CONTENT_TYPES: Readonly<Record<string, string>> = {
  '.html': 'text/html; charset=utf-8',
  '.js': 'text/javascript; charset=utf-8',
  '.mjs': 'text/javascript; charset=utf-8',
  '.css': 'text/css; charset=utf-8',
  '.json': 'application/json; charset=utf-8',
  '.map': 'application/json; charset=utf-8',
  '.md': 'text/markdown; charset=utf-8',
  '.txt': 'text/plain; charset=utf-8',
  '.ts': 'text/plain; charset=utf-8',
  '.wasm': 'application/wasm',
  '.mmdb': 'application/octet-stream',
  '.onnx': 'application/octet-stream',
  '.glb': 'model/gltf-binary',
  '.vrm': 'model/gltf-binary',
  '.gltf': 'model/gltf+json',
  '.bvh': 'text/plain; charset=utf-8',
  '.png': 'image/png',
  '.jpg': 'image/jpeg',
  '.webp': 'image/webp',
  '.svg': 'image/svg+xml',
  '.ico': 'image/x-icon',
};

/** `name-HASH.ext` as vite writes it under assets/ (8 url-safe base64 characters). */
const HASHED = /\/assets\/[^/]+-[A-Za-z0-9_-]{8}\.[a-z0-9]+$/;
const IMMUTABLE = 'public, max-age=31536000, immutable';
const REVALIDATE = 'no-cache';
const STALE_SUBRESOURCE = 'max-age=0, stale-while-revalidate=86400';

export interface StaticOptions {
  /** Extra headers on every file response (a Content-Security-Policy, say). */
  headers?: Record<string, string>;
}

/** The encodings this server has siblings for, in order of preference. */
const ENCODINGS = [
  { name: 'br', ext: '.br' },
  { name: 'gzip', ext: '.gz' },
] as const;

/** Parses `Accept-Encoding` into name → q (`*` included). */
export function acceptedEncodings(header: string | undefined): Map<string, number> {
  const out = new Map<string, number>();
  for (const part of (header ?? '').split(',')) {
    const [name, ...params] = part.trim().toLowerCase().split(';');
    if (!name) continue;
    const q = params.map((p) => p.trim()).find((p) => p.startsWith('q='));
    const value = q ? Number(q.slice(2)) : 1;
    out.set(name, Number.isFinite(value) ? value : 0);
  }
  return out;
}

/** The encoding to send for `header` among `available` (br before gzip), or null for identity. */
export function chooseEncoding(header: string | undefined, available: readonly string[]): string | null {
  const accepted = acceptedEncodings(header);
  let best: string | null = null;
  let bestQ = 0;
  for (const { name } of ENCODINGS) {
    if (!available.includes(name)) continue;
    const q = accepted.get(name) ?? accepted.get('*') ?? 0;
    if (q > bestQ) [best, bestQ] = [name, q];
  }
  return best;
}

function etagOf(stat: fs.Stats, encoding: string | null): string {
  return `"${stat.size.toString(36)}-${Math.floor(stat.mtimeMs).toString(36)}${encoding ? `-${encoding}` : ''}"`;
}

function plain(res: ServerResponse, status: number, text: string, head: boolean, extra: Record<string, string> = {}): void {
  res.writeHead(status, { 'Content-Type': 'text/plain; charset=utf-8', 'Content-Length': Buffer.byteLength(text), 'Cache-Control': 'no-store', ...extra });
  res.end(head ? undefined : text);
}

/**
 * A request handler serving `root`. Returns true when it answered (it answers every GET/HEAD,
 * with a 404 when there is no file); false for other methods so a host can route them on.
 */
export function staticHandler(root: string, options: StaticOptions = {}) {
  const base = path.resolve(root);
  return (req: IncomingMessage, res: ServerResponse): boolean => {
    if (req.method !== 'GET' && req.method !== 'HEAD') return false;
    const head = req.method === 'HEAD';
    let url: URL;
    let pathname: string;
    try {
      url = new URL(req.url ?? '/', 'http://x');
      pathname = decodeURIComponent(url.pathname);
    } catch {
      plain(res, 400, 'bad request path', head);
      return true;
    }
    if (pathname.includes('\0') || pathname.split('/').some((s) => s.startsWith('.') && s.length > 0) || /\.(br|gz)$/.test(pathname)) {
      plain(res, 404, `not found: ${pathname}`, head);
      return true;
    }
    let file = path.join(base, pathname);
    if (file !== base && !file.startsWith(base + path.sep)) {
      plain(res, 404, `not found: ${pathname}`, head);
      return true;
    }
    let stat: fs.Stats;
    try {
      stat = fs.statSync(file);
      if (stat.isDirectory()) {
        if (!pathname.endsWith('/')) {
          res.writeHead(301, { Location: `${url.pathname}/${url.search}`, 'Content-Length': 0 }).end();
          return true;
        }
        file = path.join(file, 'index.html');
        stat = fs.statSync(file);
      }
    } catch {
      plain(res, 404, `not found: ${pathname}`, head);
      return true;
    }
    const type = CONTENT_TYPES[path.extname(file).toLowerCase()] ?? 'application/octet-stream';
    const versioned = HASHED.test(pathname) || url.searchParams.has('v');
    const stableSubresource = /\.(m?js|css)$/.test(file) && path.basename(file) !== 'sw.js';
    const cacheControl = versioned ? IMMUTABLE : stableSubresource ? STALE_SUBRESOURCE : REVALIDATE;

    // Precompressed siblings (only when at least as new as the file: never a stale body).
    const siblings: { name: string; file: string; stat: fs.Stats }[] = [];
    for (const e of ENCODINGS) {
      try {
        const s = fs.statSync(file + e.ext);
        if (s.mtimeMs >= stat.mtimeMs) siblings.push({ name: e.name, file: file + e.ext, stat: s });
      } catch {
        /* none */
      }
    }
    const range = req.headers.range;
    const encoding = range ? null : chooseEncoding(req.headers['accept-encoding'] as string | undefined, siblings.map((s) => s.name));
    const chosen = encoding ? siblings.find((s) => s.name === encoding)! : null;
    const etag = etagOf(stat, encoding);
    const headers: Record<string, string | number> = {
      'Content-Type': type,
      'Cache-Control': cacheControl,
      ETag: etag,
      'Last-Modified': stat.mtime.toUTCString(),
      'Accept-Ranges': 'bytes',
      ...options.headers,
    };
    if (siblings.length) headers.Vary = 'Accept-Encoding';
    if (encoding) {
      headers['Content-Encoding'] = encoding;
      // The size after decoding, for progress bars (Content-Length is the encoded size).
      headers['X-Decoded-Length'] = stat.size;
    }

    const inm = req.headers['if-none-match'];
    if (inm?.split(',').some((t) => t.trim().replace(/^W\//, '') === etag)) {
      res.writeHead(304, headers).end();
      return true;
    }

    // One byte range of the identity body.
    if (range) {
      const m = /^bytes=(\d*)-(\d*)$/.exec(range.trim());
      let start = m && m[1] !== '' ? Number(m[1]) : NaN;
      let end = m && m[2] !== '' ? Number(m[2]) : stat.size - 1;
      if (m && m[1] === '' && m[2] !== '') [start, end] = [Math.max(0, stat.size - Number(m[2])), stat.size - 1];
      if (!m || !(start >= 0) || start > end || start >= stat.size) {
        res.writeHead(416, { 'Content-Range': `bytes */${stat.size}`, 'Content-Length': 0 }).end();
        return true;
      }
      end = Math.min(end, stat.size - 1);
      res.writeHead(206, { ...headers, 'Content-Range': `bytes ${start}-${end}/${stat.size}`, 'Content-Length': end - start + 1 });
      if (head) res.end();
      else fs.createReadStream(file, { start, end }).pipe(res);
      return true;
    }

    const body = chosen ?? { file, stat };
    headers['Content-Length'] = body.stat.size;
    res.writeHead(200, headers);
    if (head) {
      res.end();
      return true;
    }
    const stream = fs.createReadStream(body.file);
    stream.on('error', () => res.destroy());
    stream.pipe(res);
    return true;
  };
}
