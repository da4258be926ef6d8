// The production static server (server/static.ts) and the site server around it (serve.ts):
// encodings negotiated from precompressed siblings, types, caching, 304, ranges, HEAD, 404s
// that are never HTML, paths kept inside the root, and the rooms on the same origin.
import fs from 'node:fs';
import http from 'node:http';
import os from 'node:os';
import path from 'node:path';
import zlib from 'node:zlib';
import { afterAll, beforeAll, describe, expect, it } from 'vitest';
import { acceptedEncodings, chooseEncoding } from './static.ts';
import { type SiteServer, startSiteServer } from './serve.ts';

let dir: string;
let server: SiteServer;
const body = Buffer.from('motion '.repeat(4000));

interface Answer {
  status: number;
  headers: http.IncomingHttpHeaders;
  body: Buffer;
}

function request(p: string, headers: Record<string, string> = {}, method = 'GET'): Promise<Answer> {
  return new Promise((resolve, reject) => {
    const req = http.request(`${server.url}${p}`, { method, headers }, (res) => {
      const chunks: Buffer[] = [];
      res.on('data', (c: Buffer) => chunks.push(c));
      res.on('end', () => resolve({ status: res.statusCode ?? 0, headers: res.headers, body: Buffer.concat(chunks) }));
    });
    req.on('error', reject);
    req.end();
  });
}

beforeAll(async () => {
  dir = fs.mkdtempSync(path.join(os.tmpdir(), 'mm-static-'));
  fs.mkdirSync(path.join(dir, 'assets'));
  fs.mkdirSync(path.join(dir, 'databases'));
  fs.writeFileSync(path.join(dir, 'index.html'), '<!doctype html><title>site</title>');
  fs.writeFileSync(path.join(dir, 'databases', 'db.mmdb'), body);
  fs.writeFileSync(path.join(dir, 'databases', 'db.mmdb.br'), zlib.brotliCompressSync(body));
  fs.writeFileSync(path.join(dir, 'databases', 'db.mmdb.gz'), zlib.gzipSync(body));
  fs.writeFileSync(path.join(dir, 'assets', 'main-AbCd12_-.js'), 'export {};');
  fs.writeFileSync(path.join(dir, 'core.wasm'), Buffer.from([0, 0x61, 0x73, 0x6d, 1, 0, 0, 0]));
  fs.writeFileSync(path.join(dir, 'mm-avatar.js'), "import './assets/main-AbCd12_-.js';");
  fs.writeFileSync(path.join(dir, 'page.css'), 'body { margin: 0 }');
  fs.writeFileSync(path.join(dir, 'sw.js'), 'self.addEventListener("fetch", () => {});');
  fs.writeFileSync(path.join(dir, '.secret'), 'no');
  server = await startSiteServer({ root: dir, port: 0, host: '127.0.0.1' });
});
afterAll(async () => {
  await server?.close();
  fs.rmSync(dir, { recursive: true, force: true });
});

describe('Accept-Encoding', () => {
  it('parses q-values and prefers brotli, then gzip', () => {
    expect([...acceptedEncodings('gzip;q=0.5, br;q=0.9, *;q=0')]).toEqual([['gzip', 0.5], ['br', 0.9], ['*', 0]]);
    expect(chooseEncoding('gzip, deflate, br', ['br', 'gzip'])).toBe('br');
    expect(chooseEncoding('gzip, br;q=0', ['br', 'gzip'])).toBe('gzip');
    expect(chooseEncoding('br', ['gzip'])).toBeNull();
    expect(chooseEncoding('*', ['gzip'])).toBe('gzip');
    expect(chooseEncoding(undefined, ['br', 'gzip'])).toBeNull();
  });
});

describe('the static server', () => {
  it('sends the brotli sibling with its encoding, Vary, the decoded length and the right type', async () => {
    const r = await request('/databases/db.mmdb', { 'accept-encoding': 'gzip, br' });
    expect(r.status).toBe(200);
    expect(r.headers['content-encoding']).toBe('br');
    expect(r.headers.vary).toBe('Accept-Encoding');
    expect(r.headers['content-type']).toBe('application/octet-stream');
    expect(Number(r.headers['x-decoded-length'])).toBe(body.length);
    expect(Number(r.headers['content-length'])).toBe(r.body.length);
    expect(r.body.length).toBeLessThan(body.length / 10);
    expect(zlib.brotliDecompressSync(r.body).equals(body)).toBe(true);
    expect(r.headers['cache-control']).toBe('no-cache');
  });

  it('gzip when only gzip is accepted; the identity body when nothing is', async () => {
    const gz = await request('/databases/db.mmdb', { 'accept-encoding': 'gzip' });
    expect(gz.headers['content-encoding']).toBe('gzip');
    expect(zlib.gunzipSync(gz.body).equals(body)).toBe(true);
    const plain = await request('/databases/db.mmdb');
    expect(plain.headers['content-encoding']).toBeUndefined();
    expect(plain.body.equals(body)).toBe(true);
    expect(plain.headers.vary).toBe('Accept-Encoding');
  });

  it('revalidates with the ETag of the encoding sent (304)', async () => {
    const first = await request('/databases/db.mmdb', { 'accept-encoding': 'br' });
    const again = await request('/databases/db.mmdb', { 'accept-encoding': 'br', 'if-none-match': first.headers.etag! });
    expect(again.status).toBe(304);
    expect(again.body.length).toBe(0);
    const other = await request('/databases/db.mmdb', { 'accept-encoding': 'gzip', 'if-none-match': first.headers.etag! });
    expect(other.status).toBe(200); // a different body: a different tag
  });

  it('immutable for content-hashed and ?v= versioned URLs; types for JS and WASM', async () => {
    const js = await request('/assets/main-AbCd12_-.js');
    expect(js.headers['cache-control']).toBe('public, max-age=31536000, immutable');
    expect(js.headers['content-type']).toBe('text/javascript; charset=utf-8');
    const versioned = await request('/databases/db.mmdb?v=0123456789abcdef');
    expect(versioned.headers['cache-control']).toContain('immutable');
    const wasm = await request('/core.wasm');
    expect(wasm.headers['content-type']).toBe('application/wasm');
    expect(wasm.headers['cache-control']).toBe('no-cache');
  });

  it('a script or style at a stable name: from the cache at once, revalidated behind it; never the service worker', async () => {
    const entry = await request('/mm-avatar.js');
    expect(entry.headers['cache-control']).toBe('max-age=0, stale-while-revalidate=86400');
    expect((await request('/page.css')).headers['cache-control']).toBe('max-age=0, stale-while-revalidate=86400');
    expect(entry.headers.etag).toBeTruthy();
    expect((await request('/sw.js')).headers['cache-control']).toBe('no-cache');
    expect((await request('/index.html')).headers['cache-control']).toBe('no-cache');
  });

  it('HEAD: the headers without a body; a byte range of the identity body', async () => {
    const head = await request('/databases/db.mmdb', {}, 'HEAD');
    expect(head.status).toBe(200);
    expect(Number(head.headers['content-length'])).toBe(body.length);
    expect(head.body.length).toBe(0);
    const part = await request('/databases/db.mmdb', { range: 'bytes=7-13', 'accept-encoding': 'br' });
    expect(part.status).toBe(206);
    expect(part.headers['content-range']).toBe(`bytes 7-13/${body.length}`);
    expect(part.headers['content-encoding']).toBeUndefined();
    expect(part.body.toString()).toBe('motion ');
    const tail = await request('/databases/db.mmdb', { range: 'bytes=-3' });
    expect(tail.body.toString()).toBe('on ');
    expect((await request('/databases/db.mmdb', { range: `bytes=${body.length}-` })).status).toBe(416);
  });

  it('a missing file is a plain-text 404 naming the path, never an HTML page', async () => {
    const r = await request('/databases/missing.mmdb');
    expect(r.status).toBe(404);
    expect(r.headers['content-type']).toMatch(/^text\/plain/);
    expect(r.body.toString()).toBe('not found: /databases/missing.mmdb');
  });

  it('serves index.html for a folder, and nothing outside the root, no dotfiles, no siblings', async () => {
    const index = await request('/');
    expect(index.headers['content-type']).toBe('text/html; charset=utf-8');
    expect(index.body.toString()).toContain('<title>site</title>');
    expect((await request('/databases')).status).toBe(301);
    for (const p of ['/../../etc/passwd', '/%2e%2e/%2e%2e/etc/passwd', '/.secret', '/databases/db.mmdb.br']) expect((await request(p)).status, p).toBe(404);
    expect((await request('/', {}, 'DELETE')).status).toBe(405);
  });

  it('creates room ids on the same origin (the room server is attached)', async () => {
    const r = await request('/rooms', {}, 'POST');
    expect(r.status).toBe(201);
    expect(JSON.parse(r.body.toString()).path).toMatch(/^\/rooms\/[A-Za-z0-9_-]{22}$/);
  });
});
