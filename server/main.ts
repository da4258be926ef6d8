/**
 * The room server alone on a port (load tests, a dedicated rooms process): serves nothing but
 * `/rooms/<id>` (WebSocket) and `POST /rooms` (a new room id).
 *
 *   node_modules/.bin/esbuild server/main.ts --bundle --platform=node --format=esm --outfile=/tmp/rooms.mjs \
 *     --external:bufferutil --external:utf-8-validate \
 *     "--banner:js=import { createRequire as __cr } from 'node:module'; const require = __cr(import.meta.url);"
 *   node /tmp/rooms.mjs --port 8787 [--host 127.0.0.1] [--max-members 16]
 *        [--allow-origin https://example.com]… [--allow-no-origin] [--stats-ms 1000]
 *        [--nats nats://127.0.0.1:4222[,nats://…]] [--nats-prefix mmrooms] [--workers N] [--idle-timeout-ms 5000]
 *
 * `--nats` (or the environment's `ROOMS_NATS_URL`): share rooms with the other processes on that
 * NATS (docs/rooms.md, "Several processes"). `--workers N`: N processes behind this one port
 * (node:cluster; the primary hands each new connection to a live worker, and starts a new worker
 * when one dies) — with `--nats`, members of one room on different workers see each other.
 *
 * Prints one JSON line `{"type":"listening","port":…,"pid":…}` per process, then with --stats-ms
 * one `{"type":"stats","pid":…,…}` line per interval (CPU ms, memory, message counts).
 */
import cluster from 'node:cluster';
import { createServer } from 'node:http';
import { attachRooms, roomsRequestHandler } from './rooms.ts';

function parseArgs(argv: string[]) {
  const args = {
    port: 8787,
    host: '127.0.0.1',
    maxMembers: 16,
    allowedOrigins: [] as string[],
    allowNoOrigin: false,
    statsMs: 0,
    nats: process.env.ROOMS_NATS_URL ?? '',
    natsPrefix: process.env.ROOMS_NATS_PREFIX ?? 'mmrooms',
    workers: 0,
    idleTimeoutMs: 5000,
  };
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
    else if (a === '--nats') args.nats = value();
    else if (a === '--nats-prefix') args.natsPrefix = value();
    else if (a === '--workers') args.workers = Number(value());
    else if (a === '--idle-timeout-ms') args.idleTimeoutMs = Number(value());
    else throw new Error(`unknown argument ${a}`);
  }
  if (!(args.workers >= 0 && args.workers <= 64 && Number.isInteger(args.workers))) throw new Error('--workers: 0–64');
  return args;
}

const args = parseArgs(process.argv.slice(2));

if (args.workers > 0 && cluster.isPrimary) {
  // N workers behind one port: the primary accepts and hands connections round-robin.
  if (args.workers > 1 && !args.nats) console.error('--workers without --nats: members of one room on different workers will not see each other');
  let stopping = false;
  const fork = () => cluster.fork();
  for (let i = 0; i < args.workers; i++) fork();
  cluster.on('exit', (worker, code, signal) => {
    console.log(JSON.stringify({ type: 'worker-exit', pid: worker.process.pid, code, signal }));
    if (!stopping) setTimeout(fork, 500).unref();
  });
  const stop = () => {
    stopping = true;
    for (const w of Object.values(cluster.workers ?? {})) w?.process.kill('SIGTERM');
    setTimeout(() => process.exit(0), 2500).unref();
    cluster.on('exit', () => {
      if (Object.keys(cluster.workers ?? {}).length === 0) process.exit(0);
    });
  };
  process.on('SIGINT', stop);
  process.on('SIGTERM', stop);
} else {
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
    idleTimeoutMs: args.idleTimeoutMs,
    rejectOtherUpgrades: true,
    nats: args.nats ? { servers: args.nats, prefix: args.natsPrefix } : undefined,
    log: (e) => {
      if (e.kind === 'error' || e.kind === 'bus' || (e.kind === 'drop' && process.env.ROOMS_LOG_DROPS)) console.error(JSON.stringify({ type: 'log', pid: process.pid, ...e }));
    },
  });

  // With NATS, listen once connected: a connection before would wait for the bus anyway.
  void rooms.ready.then(() => {
    server.listen(args.port, args.host, () => {
      const address = server.address();
      const port = typeof address === 'object' && address ? address.port : args.port;
      console.log(JSON.stringify({ type: 'listening', host: args.host, port, pid: process.pid, proc: rooms.proc }));
    });
  });

  if (args.statsMs > 0) {
    const t0 = performance.now();
    setInterval(() => {
      const cpu = process.cpuUsage();
      const mem = process.memoryUsage();
      console.log(
        JSON.stringify({
          type: 'stats',
          pid: process.pid,
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
}
