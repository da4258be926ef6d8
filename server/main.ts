/**
 * The room server alone on a port (load tests, a dedicated rooms process): serves nothing but
 * `/rooms/<id>` (WebSocket) and `POST /rooms` (a new room id).
 *
 *   node_modules/.bin/esbuild server/main.ts --bundle --platform=node --format=esm --outfile=/tmp/rooms.mjs \
 *     --external:bufferutil --external:utf-8-validate \
 *     "--banner:js=import { createRequire as __cr } from 'node:module'; const require = __cr(import.meta.url);"
 *   node /tmp/rooms.mjs --port 8787 [--host 127.0.0.1] [--max-members 16]
 *        [--allow-origin https://example.com]… [--allow-no-origin] [--stats-ms 1000]
 *
 * Prints one JSON line `{"type":"listening","port":…}`, then with --stats-ms one
 * `{"type":"stats",…}` line per interval (CPU ms, memory, message counts) for the load test.
 */
import { createServer } from 'node:http';
import { attachRooms, roomsRequestHandler } from './rooms.ts';

function parseArgs(argv: string[]) {
  const args = { port: 8787, host: '127.0.0.1', maxMembers: 16, allowedOrigins: [] as string[], allowNoOrigin: false, statsMs: 0 };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    const value = () => {
      const v = argv[++i];
      if (v === undefined) throw new Error(`${a} needs a value`);
      return v;
    };
    if (a === '--port') args.port = Number(value());
    else if (a === '--host') args.host = value();
    else if (a === '--max-members') args.maxMembers = Number(value());
    else if (a === '--allow-origin') args.allowedOrigins.push(value());
    else if (a === '--allow-no-origin') args.allowNoOrigin = true;
    else if (a === '--stats-ms') args.statsMs = Number(value());
    else throw new Error(`unknown argument ${a}`);
  }
  return args;
}

const args = parseArgs(process.argv.slice(2));
const handler = roomsRequestHandler();
const server = createServer((req, res) => {
  if (handler(req, res)) return;
  res.writeHead(404, { 'Content-Type': 'text/plain' });
  res.end('Not Found');
});
const rooms = attachRooms(server, {
  maxMembers: args.maxMembers,
  allowedOrigins: args.allowedOrigins,
  allowNoOrigin: args.allowNoOrigin,
  rejectOtherUpgrades: true,
  log: (e) => {
    if (e.kind === 'error') console.error(JSON.stringify({ type: 'log', ...e }));
  },
});

server.listen(args.port, args.host, () => {
  const address = server.address();
  const port = typeof address === 'object' && address ? address.port : args.port;
  console.log(JSON.stringify({ type: 'listening', host: args.host, port }));
});

if (args.statsMs > 0) {
  const t0 = performance.now();
  setInterval(() => {
    const cpu = process.cpuUsage();
    const mem = process.memoryUsage();
    console.log(
      JSON.stringify({
        type: 'stats',
        t: Math.round(performance.now() - t0),
        cpuUserMs: cpu.user / 1000,
        cpuSystemMs: cpu.system / 1000,
        rss: mem.rss,
        heapUsed: mem.heapUsed,
        ...rooms.stats(),
      }),
    );
  }, args.statsMs).unref();
}

const stop = () => {
  void rooms.close().then(() => server.close(() => process.exit(0)));
  setTimeout(() => process.exit(0), 2000).unref();
};
process.on('SIGINT', stop);
process.on('SIGTERM', stop);
