/**
 * Real NATS and real room server processes for the multi-process tests, all on loopback and
 * stopped by the tests: `nats-server` (Debian's package; `npm test` installs it, see
 * scripts/setup.mjs) with JetStream in a temporary folder, and `server/main.ts` bundled once
 * per test file and started as separate Node processes (`--workers N`: N behind one port).
 */
import { spawn, type ChildProcess } from 'node:child_process';
import { existsSync, mkdtempSync, rmSync } from 'node:fs';
import { createServer } from 'node:net';
import { tmpdir } from 'node:os';
import { dirname, join } from 'node:path';
import { createInterface } from 'node:readline';
import { fileURLToPath } from 'node:url';
import { build } from 'esbuild';

const ROOT = join(dirname(fileURLToPath(import.meta.url)), '..');

export function natsServerBinary(): string {
  for (const p of ['/usr/sbin/nats-server', '/usr/bin/nats-server', '/usr/local/bin/nats-server']) if (existsSync(p)) return p;
  throw new Error('nats-server is not installed: `npm test` installs it (apt-get install nats-server), or install it by hand');
}

/** A free loopback port (bound and released: another process could take it meanwhile, rarely). */
export function freePort(): Promise<number> {
  return new Promise((resolve, reject) => {
    const s = createServer();
    s.once('error', reject);
    s.listen(0, '127.0.0.1', () => {
      const port = (s.address() as { port: number }).port;
      s.close(() => resolve(port));
    });
  });
}

export interface NatsServer {
  port: number;
  url: string;
  /** Stops it (SIGTERM, then SIGKILL), keeping the port for `start`. */
  stop(): Promise<void>;
  start(): Promise<void>;
  /** Stops it for good and removes its folder. */
  close(): Promise<void>;
  /** What it printed (its log: cluster routes, JetStream elections), for a failing test to show. */
  log(): string;
}

const exited = (child: ChildProcess) => new Promise<void>((resolve) => (child.exitCode !== null || child.signalCode !== null ? resolve() : child.once('exit', () => resolve())));

async function stopChild(child: ChildProcess | null, signal: NodeJS.Signals = 'SIGTERM'): Promise<void> {
  if (!child || child.exitCode !== null || child.signalCode !== null) return;
  child.kill(signal);
  const t = setTimeout(() => child.kill('SIGKILL'), 3000);
  await exited(child);
  clearTimeout(t);
}

/** `nats-server` on 127.0.0.1 with JetStream (the member-id bucket); `extra` adds flags (a cluster). */
export async function startNats(options: { port?: number; extra?: string[] } = {}): Promise<NatsServer> {
  const port = options.port ?? (await freePort());
  const dir = mkdtempSync(join(tmpdir(), 'nats-test-'));
  let child: ChildProcess | null = null;
  let output = '';
  const start = async () => {
    child = spawn(natsServerBinary(), ['-a', '127.0.0.1', '-p', String(port), '-js', '-sd', dir, ...(options.extra ?? [])], { stdio: ['ignore', 'ignore', 'pipe'] });
    const c = child;
    await new Promise<void>((resolve, reject) => {
      const timer = setTimeout(() => reject(new Error(`nats-server did not start in 10 s:\n${output}`)), 10_000);
      createInterface({ input: c.stderr! }).on('line', (l) => {
        output += `${l}\n`;
        if (/Server is ready/.test(l)) {
          clearTimeout(timer);
          resolve();
        }
      });
      c.once('exit', (code) => {
        clearTimeout(timer);
        reject(new Error(`nats-server exited ${code}:\n${output}`));
      });
    });
  };
  await start();
  return {
    port,
    url: `nats://127.0.0.1:${port}`,
    stop: () => stopChild(child),
    start,
    log: () => output,
    close: async () => {
      await stopChild(child);
      rmSync(dir, { recursive: true, force: true });
    },
  };
}

let bundle: Promise<string> | null = null;

/** server/main.ts bundled for Node (once per test file). */
export function roomsBundle(): Promise<string> {
  if (!bundle) {
    const dir = mkdtempSync(join(tmpdir(), 'rooms-bundle-'));
    const out = join(dir, 'main.mjs');
    bundle = build({
      entryPoints: [join(ROOT, 'server/main.ts')],
      bundle: true,
      platform: 'node',
      format: 'esm',
      target: 'node20',
      outfile: out,
      external: ['bufferutil', 'utf-8-validate'],
      banner: { js: "import { createRequire as __cr } from 'node:module'; const require = __cr(import.meta.url);" },
      logLevel: 'warning',
    }).then(() => out);
    process.once('exit', () => rmSync(dir, { recursive: true, force: true }));
  }
  return bundle;
}

export interface StatsLine {
  pid: number;
  members: number;
  rooms: number;
  remoteMembers: number;
  internalErrors: number;
  messagesIn: number;
  messagesOut: number;
  refused: Record<string, number>;
  dropped: Record<string, number>;
  busConnected: boolean;
  [k: string]: unknown;
}

export interface RoomsProcess {
  port: number;
  origin: string;
  /** Worker pids (the process itself without --workers). */
  pids: number[];
  url(roomId: string): string;
  /** The latest stats line per pid. */
  stats: Map<number, StatsLine>;
  exits: { pid: number; code: number | null; signal: string | null }[];
  child: ChildProcess;
  stop(): Promise<void>;
  /** What it wrote to stderr, for a failing test to show. */
  log(): string;
}

/** Starts `server/main.ts` on a loopback port: `--nats url`, `--workers N`, stats every `statsMs`. */
export async function startRooms(options: { nats?: string; workers?: number; port?: number; statsMs?: number; args?: string[] } = {}): Promise<RoomsProcess> {
  const main = await roomsBundle();
  const port = options.port ?? (await freePort());
  const args = [main, '--port', String(port), '--host', '127.0.0.1', '--stats-ms', String(options.statsMs ?? 250), ...(options.args ?? [])];
  if (options.nats) args.push('--nats', options.nats);
  if (options.workers) args.push('--workers', String(options.workers));
  const child = spawn(process.execPath, args, { stdio: ['ignore', 'pipe', 'pipe'], env: { ...process.env, ROOMS_NATS_URL: '' } });
  const stats = new Map<number, StatsLine>();
  const exits: RoomsProcess['exits'] = [];
  const pids: number[] = [];
  let errors = '';
  createInterface({ input: child.stderr! }).on('line', (l) => {
    errors += `${l}\n`;
    if (process.env.ROOMS_TEST_LOG) console.error(l);
  });
  const want = options.workers || 1;
  await new Promise<void>((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`rooms process did not listen in 15 s:\n${errors}`)), 15_000);
    createInterface({ input: child.stdout! }).on('line', (l) => {
      let m: { type: string; pid: number; code: number | null; signal: string | null };
      try {
        m = JSON.parse(l);
      } catch {
        return;
      }
      if (m.type === 'listening') {
        if (!pids.includes(m.pid)) pids.push(m.pid);
        if (pids.length >= want) {
          clearTimeout(timer);
          resolve();
        }
      } else if (m.type === 'stats') stats.set(m.pid, m as unknown as StatsLine);
      else if (m.type === 'worker-exit') {
        exits.push({ pid: m.pid, code: m.code, signal: m.signal });
        const i = pids.indexOf(m.pid);
        if (i >= 0) pids.splice(i, 1);
        stats.delete(m.pid);
      }
    });
    child.once('exit', (code) => {
      clearTimeout(timer);
      reject(new Error(`rooms process exited ${code}:\n${errors}`));
    });
  });
  return {
    port,
    origin: `http://127.0.0.1:${port}`,
    pids,
    url: (id) => `ws://127.0.0.1:${port}/rooms/${id}`,
    stats,
    exits,
    child,
    stop: () => stopChild(child),
    log: () => errors,
  };
}
