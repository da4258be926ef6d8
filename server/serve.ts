/**
 * `npm start`'s server: the built site (`dist/`, server/static.ts: precompressed, cached,
 * correct types) and the room server on the same origin (`/rooms/<id>`, server/rooms.ts).
 *
 *   node dist-server/serve.mjs [--port 5173] [--host 0.0.0.0] [--root dist] [--https] [--log-json]
 *
 * scripts/setup.mjs bundles this file with esbuild into `dist-server/serve.mjs` (Node 20 runs no
 * TypeScript) and starts it. `--https` uses a self-signed certificate made locally by
 * @vitejs/plugin-basic-ssl's `getCertificate` (the one the dev server uses, cached in
 * node_modules/.vite/basic-ssl): Quest Browser allows WebXR only on secure origins.
 * Prints one JSON line `{"type":"listening","port":…,"urls":[…]}` when ready; with --log-json one
 * `{"type":"response",…}` line per response (path, status, bytes, encoding: load benchmarks).
 */
import http from 'node:http';
import https from 'node:https';
import os from 'node:os';
import path from 'node:path';
import { attachRooms, roomsRequestHandler } from './rooms.ts';
import { staticHandler } from './static.ts';

export interface SiteServerOptions {
  root: string;
  port?: number;
  host?: string;
  /** PEM with the key and certificate: serve HTTPS (and WSS rooms). */
  certificate?: string;
  /** Extra headers on every file (tests: a Content-Security-Policy). */
  headers?: Record<string, string>;
  /** Share rooms with other processes over NATS (docs/rooms.md, "Several processes"); default the environment's ROOMS_NATS_URL. */
  nats?: string;
  /** Called when each response has been sent (load benchmarks count the bytes). */
  onResponse?: (r: { t: number; method: string; path: string; status: number; bytes: number }) => void;
}

export interface SiteServer {
  readonly port: number;
  readonly url: string;
  close(): Promise<void>;
}

/** Starts the site server; resolves once it listens. */
export async function startSiteServer(options: SiteServerOptions): Promise<SiteServer> {
  const files = staticHandler(options.root, { headers: options.headers });
  const roomsHttp = roomsRequestHandler();
  const handle = (req: http.IncomingMessage, res: http.ServerResponse) => {
    if (options.onResponse) {
      const report = options.onResponse;
      // Bytes on the wire, headers included (one request at a time per connection in HTTP/1.1).
      const before = req.socket.bytesWritten;
      res.once('finish', () => report({ t: Date.now(), method: req.method ?? '', path: req.url ?? '', status: res.statusCode, bytes: req.socket.bytesWritten - before }));
    }
    try {
      if (roomsHttp(req, res)) return;
      if (files(req, res)) return;
      res.writeHead(405, { Allow: 'GET, HEAD', 'Content-Type': 'text/plain' }).end('method not allowed');
    } catch (e) {
      if (!res.headersSent) res.writeHead(500, { 'Content-Type': 'text/plain' });
      res.end(`server error: ${e instanceof Error ? e.message : String(e)}`);
    }
  };
  const server = options.certificate ? https.createServer({ key: options.certificate, cert: options.certificate }, handle) : http.createServer(handle);
  const rooms = attachRooms(server, { rejectOtherUpgrades: true, nats: options.nats ?? process.env.ROOMS_NATS_URL });
  await new Promise<void>((resolve, reject) => {
    server.once('error', reject);
    server.listen(options.port ?? 5173, options.host ?? '127.0.0.1', () => resolve());
  });
  const address = server.address();
  const port = typeof address === 'object' && address ? address.port : (options.port ?? 5173);
  const scheme = options.certificate ? 'https' : 'http';
  const host = !options.host || options.host === '0.0.0.0' ? '127.0.0.1' : options.host;
  return {
    port,
    url: `${scheme}://${host}:${port}`,
    close: async () => {
      await rooms.close();
      server.closeAllConnections?.();
      await new Promise<void>((resolve) => server.close(() => resolve()));
    },
  };
}

function lanAddresses(): string[] {
  return Object.values(os.networkInterfaces())
    .flat()
    .filter((a): a is os.NetworkInterfaceInfo => !!a && a.family === 'IPv4' && !a.internal)
    .map((a) => a.address);
}

async function main(argv: string[]): Promise<void> {
  const opts = { port: 5173, host: '0.0.0.0', root: 'dist', https: false, logJson: false };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === '--port') opts.port = Number(argv[++i]);
    else if (a === '--host') opts.host = argv[++i];
    else if (a === '--root') opts.root = argv[++i];
    else if (a === '--https') opts.https = true;
    else if (a === '--log-json') opts.logJson = true;
    else throw new Error(`unknown argument ${a}`);
  }
  let certificate: string | undefined;
  if (opts.https) {
    const { getCertificate } = (await import('@vitejs/plugin-basic-ssl')) as unknown as { getCertificate(dir: string, name?: string): Promise<string> };
    certificate = await getCertificate(path.join('node_modules', '.vite', 'basic-ssl'), 'mm-avatar-dev');
  }
  const onResponse = opts.logJson ? (r: object) => console.log(JSON.stringify({ type: 'response', ...r })) : undefined;
  const server = await startSiteServer({ root: path.resolve(opts.root), port: opts.port, host: opts.host, certificate, onResponse });
  const scheme = opts.https ? 'https' : 'http';
  const urls = [`${scheme}://localhost:${server.port}/`, ...(opts.host === '0.0.0.0' ? lanAddresses().map((a) => `${scheme}://${a}:${server.port}/`) : [])];
  console.log(JSON.stringify({ type: 'listening', port: server.port, urls }));
  for (const u of urls) console.log(`  ${u}`);
  const stop = () => void server.close().then(() => process.exit(0));
  process.on('SIGINT', stop);
  process.on('SIGTERM', stop);
}

// Run as a program (the bundle), not when imported by tests.
const entry = process.argv[1] ? path.resolve(process.argv[1]) : '';
if (/serve\.(mjs|ts)$/.test(entry)) {
  main(process.argv.slice(2)).catch((e: unknown) => {
    console.error(`serve: ${e instanceof Error ? e.message : String(e)}`);
    process.exit(1);
  });
}
