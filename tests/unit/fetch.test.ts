// fetchBytes (web/src/fetch.ts) against a real local server: progress with the decoded size of a
// compressed body, an HTML page where a binary was expected (by type or by its first bytes), an
// HTTP error and a refused connection all name the URL, and a download that stops sending is
// reported as stalled (then completes).
import http from 'node:http';
import type { AddressInfo } from 'node:net';
import zlib from 'node:zlib';
import { afterAll, beforeAll, describe, expect, it } from 'vitest';
import { type FetchProgress, fetchBytes } from '../../web/src/fetch.ts';

const body = Buffer.from('MMDB'.repeat(50_000));
let server: http.Server;
let base = '';

beforeAll(async () => {
  server = http.createServer((req, res) => {
    const url = req.url ?? '';
    if (url === '/db.mmdb') {
      const br = zlib.brotliCompressSync(body);
      res.writeHead(200, { 'Content-Type': 'application/octet-stream', 'Content-Encoding': 'br', 'Content-Length': br.length, 'X-Decoded-Length': body.length });
      res.end(br);
    } else if (url === '/html-typed.mmdb') {
      res.writeHead(200, { 'Content-Type': 'text/html' }).end('<!doctype html><p>app</p>');
    } else if (url === '/html-untyped.mmdb') {
      res.writeHead(200, { 'Content-Type': 'application/octet-stream' }).end('\n  <!DOCTYPE html><html><body>fallback</body></html>');
    } else if (url === '/slow.mmdb') {
      res.writeHead(200, { 'Content-Type': 'application/octet-stream', 'Content-Length': 8 });
      res.write('MMDB');
      setTimeout(() => res.end('MMDB'), 700);
    } else res.writeHead(404, { 'Content-Type': 'text/plain' }).end('not found');
  });
  await new Promise<void>((r) => server.listen(0, '127.0.0.1', r));
  base = `http://127.0.0.1:${(server.address() as AddressInfo).port}`;
});
afterAll(() => new Promise<void>((r) => server.close(() => r())));

describe('fetchBytes', () => {
  it('reports progress against the decoded size of a compressed body, and a last `done` event', async () => {
    const events: FetchProgress[] = [];
    const bytes = await fetchBytes(`${base}/db.mmdb`, { stage: 'database', onProgress: (p) => events.push(p) });
    expect(bytes.length).toBe(body.length);
    expect(events[0]).toMatchObject({ stage: 'database', url: `${base}/db.mmdb`, total: body.length });
    expect(events.at(-1)).toMatchObject({ loaded: body.length, total: body.length, done: true });
    expect(events.every((e) => e.loaded <= body.length)).toBe(true);
  });

  it('an HTML page (by its type or its first bytes), an HTTP error and a refused connection name the URL', async () => {
    await expect(fetchBytes(`${base}/html-typed.mmdb`, { stage: 'database' })).rejects.toThrow(`could not load the database ${base}/html-typed.mmdb: not found (the server answered with an HTML page)`);
    await expect(fetchBytes(`${base}/html-untyped.mmdb`, { stage: 'database' })).rejects.toThrow(`could not load the database ${base}/html-untyped.mmdb: not found (the server answered with an HTML page)`);
    await expect(fetchBytes(`${base}/missing.glb`, { stage: 'avatar' })).rejects.toThrow(`could not load the avatar ${base}/missing.glb: HTTP 404`);
    await expect(fetchBytes('http://127.0.0.1:9/x.mmdb', { stage: 'database' })).rejects.toThrow(/could not fetch the database http:\/\/127\.0\.0\.1:9\/x\.mmdb: .*offline, or the server is down/);
  });

  it('says `stalled` when nothing arrives for stallMs, then finishes', async () => {
    const events: FetchProgress[] = [];
    const bytes = await fetchBytes(`${base}/slow.mmdb`, { stage: 'database', stallMs: 300, onProgress: (p) => events.push(p) });
    expect(new TextDecoder().decode(bytes)).toBe('MMDBMMDB');
    const stalled = events.find((e) => e.stalled);
    expect(stalled).toMatchObject({ stage: 'database', loaded: 4, total: 8 });
    expect(events.at(-1)).toMatchObject({ done: true, loaded: 8 });
  });
});
