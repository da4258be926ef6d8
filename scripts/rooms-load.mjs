#!/usr/bin/env node
/**
 * Room server load test (loopback only, bounded): bundles server/main.ts and
 * server/load-client.ts with esbuild, starts the server in one process and the clients in
 * another, runs 100 clients in 10 rooms for 60 s (all parameters below), and prints a table and
 * a JSON line: relay latency p50/p99, server CPU and memory, bytes/s per avatar.
 *
 *   node scripts/rooms-load.mjs [--clients 100] [--rooms 10] [--seconds 60] [--vr-every 3] [--json out.json]
 *   node scripts/rooms-load.mjs --seconds 8        # the short variant (CI)
 *   node scripts/rooms-load.mjs --processes 3 [--nats nats://127.0.0.1:4222] --clients 300 --rooms 30
 *
 * `--processes N` (N > 1): N room server processes sharing rooms over NATS (`--nats URL`, or a
 * nats-server started here on a loopback port and stopped after); client i joins room i mod
 * rooms on process (i + ⌊i / rooms⌋) mod N, so every room has members on different processes. Each
 * process's CPU, messages and relayed copies are reported, and every message sent in the
 * window must reach every other member of its room.
 */
import { spawn } from 'node:child_process';
import { existsSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { createServer as netServer } from 'node:net';
import { cpus, loadavg, tmpdir } from 'node:os';
import { join, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';
import { createInterface } from 'node:readline';
import { build } from 'esbuild';
import { randomBytes } from 'node:crypto';

/** A fresh room id: 16 random bytes as 22 base64url characters (protocol.ts's createRoomId). */
const createRoomId = () => randomBytes(16).toString('base64url');

const root = join(dirname(fileURLToPath(import.meta.url)), '..');
const opt = (name, fallback) => {
  const i = process.argv.indexOf(`--${name}`);
  return i < 0 ? fallback : process.argv[i + 1];
};
const clients = Number(opt('clients', 100));
const rooms = Number(opt('rooms', 10));
const seconds = Number(opt('seconds', 60));
const vrEvery = Number(opt('vr-every', 3));
const jsonOut = opt('json', null);
const processes = Number(opt('processes', 1));
let natsUrl = opt('nats', null);
if (!(processes >= 1 && processes <= 16)) throw new Error('processes 1–16');
if (!(clients > 0 && clients <= 2000 && rooms > 0 && seconds > 0 && seconds <= 600)) throw new Error('clients 1–2000, seconds 1–600');

const loadBefore = loadavg()[0];
const dir = mkdtempSync(join(tmpdir(), 'rooms-load-'));
await build({
  entryPoints: { main: join(root, 'server/main.ts'), 'load-client': join(root, 'server/load-client.ts') },
  bundle: true,
  platform: 'node',
  format: 'esm',
  target: 'node20',
  outdir: dir,
  outExtension: { '.js': '.mjs' },
  // ws's optional native add-ons are not installed; let it fall back to JS.
  external: ['bufferutil', 'utf-8-validate'],
  // ws is CommonJS: give the ESM bundle a `require` for Node's built-ins.
  banner: { js: "import { createRequire as __cr } from 'node:module'; const require = __cr(import.meta.url);" },
  logLevel: 'warning',
});

const lines = (child, onLine) => createInterface({ input: child.stdout }).on('line', (l) => {
  try {
    onLine(JSON.parse(l));
  } catch {
    process.stderr.write(`${l}\n`);
  }
});

// NATS for several processes: the one given, or a nats-server of our own on a loopback port.
let nats = null;
if (processes > 1 && !natsUrl) {
  const bin = ['/usr/sbin/nats-server', '/usr/bin/nats-server', '/usr/local/bin/nats-server'].find((p) => existsSync(p));
  if (!bin) throw new Error('--processes > 1 needs NATS: pass --nats URL or install nats-server (apt-get install nats-server)');
  const natsPort = await new Promise((resolve) => {
    const s = netServer();
    s.listen(0, '127.0.0.1', () => {
      const p = s.address().port;
      s.close(() => resolve(p));
    });
  });
  nats = spawn(bin, ['-a', '127.0.0.1', '-p', String(natsPort), '-js', '-sd', join(dir, 'nats')], { stdio: ['ignore', 'ignore', 'pipe'] });
  await new Promise((resolve, reject) => {
    createInterface({ input: nats.stderr }).on('line', (l) => /Server is ready/.test(l) && resolve());
    nats.once('exit', (code) => reject(new Error(`nats-server exited ${code}`)));
  });
  natsUrl = `nats://127.0.0.1:${natsPort}`;
}

const servers = [];
const stats = new Map(); // pid → stats lines
for (let k = 0; k < processes; k++) {
  const args = [join(dir, 'main.mjs'), '--port', '0', '--host', '127.0.0.1', '--stats-ms', '1000', '--max-members', '16'];
  if (processes > 1) args.push('--nats', natsUrl);
  const server = spawn(process.execPath, args, { stdio: ['ignore', 'pipe', 'inherit'], env: { ...process.env, ROOMS_NATS_URL: '' } });
  const port = await new Promise((resolve, reject) => {
    lines(server, (m) => {
      if (m.type === 'listening') resolve(m.port);
      else if (m.type === 'stats') {
        if (!stats.has(server.pid)) stats.set(server.pid, []);
        stats.get(server.pid).push(m);
      }
    });
    server.once('exit', (code) => reject(new Error(`server exited ${code}`)));
  });
  servers.push({ server, port });
}
const killTimer = setTimeout(() => {
  console.error('load test overran its time; stopping');
  for (const { server } of servers) server.kill('SIGKILL');
  nats?.kill('SIGKILL');
  process.exit(2);
}, (seconds + 60) * 1000);

// The clients, in processes of their own: one Node process cannot receive much more than ~30 000
// relays a second, so K = ⌈clients / 100⌉ processes, each with whole rooms (latency on one clock).
/** nats-server's CPU (user + system clock ticks, /proc) over the window, when we started it. */
const natsCpu = { start: NaN, end: NaN, t0: 0, t1: 0 };
const natsTicks = () => {
  if (!nats) return NaN;
  const now = performance.now();
  if (Number.isNaN(natsCpu.start)) natsCpu.t0 = now;
  else natsCpu.t1 = now;
  try {
    const f = readFileSync(`/proc/${nats.pid}/stat`, 'utf8').split(') ')[1].split(' ');
    return Number(f[11]) + Number(f[12]); // utime, stime (fields 14, 15)
  } catch {
    return NaN;
  }
};
const clientParts = Math.max(1, Number(opt('client-processes', Math.ceil(clients / 100))));
const roomIdList = Array.from({ length: rooms }, () => createRoomId()).join(',');
const parts = [];
for (let part = 0; part < clientParts; part++) {
  const child = spawn(
    process.execPath,
    [join(dir, 'load-client.mjs'), '--url', servers.map((x) => `ws://127.0.0.1:${x.port}`).join(','), '--origin', servers.map((x) => `http://127.0.0.1:${x.port}`).join(','), '--clients', String(clients), '--rooms', String(rooms), '--seconds', String(seconds), '--vr-every', String(vrEvery), '--room-ids', roomIdList, '--parts', String(clientParts), '--part', String(part)],
    { stdio: ['ignore', 'pipe', 'inherit'] },
  );
  const entry = { child, result: null };
  lines(child, (m) => {
    if (m.type === 'result') entry.result = m;
    else if (m.type === 'measuring' && part === 0) natsCpu.start = natsTicks();
    else if (m.type === 'measured' && part === 0) natsCpu.end = natsTicks();
  });
  parts.push(entry);
}
const codes = await Promise.all(parts.map(({ child }) => new Promise((resolve) => child.once('exit', resolve))));
const clientCode = codes.find((c) => c !== 0) ?? 0;
// One result from the parts: histograms and byte counts added up.
let result = null;
if (parts.every((p) => p.result)) {
  const rs = parts.map((p) => p.result);
  const bucket = rs[0].histogramBucketMs;
  const hist = new Map();
  for (const r of rs) for (const [b, n] of r.histogram) hist.set(b, (hist.get(b) ?? 0) + n);
  const samples = rs.reduce((s, r) => s + r.latencySamples, 0);
  const sorted = [...hist.entries()].sort((a, b) => a[0] - b[0]);
  const pct = (p) => {
    let acc = 0;
    for (const [b, n] of sorted) {
      acc += n;
      if (acc >= p * samples) return (b + 0.5) * bucket;
    }
    return Infinity;
  };
  const overflow = rs.reduce((s, r) => s + r.latencyOverflow, 0);
  const measured = Math.max(...rs.map((r) => r.measuredSeconds));
  const mode = (k) => {
    const avatars = rs.reduce((s, r) => s + r[k].avatars, 0);
    const up = rs.reduce((s, r) => s + r[k].upBytes, 0);
    const down = rs.reduce((s, r) => s + r[k].downBytes, 0);
    const pairs = rs.reduce((s, r) => s + r[k].pairs, 0);
    return { avatars, upBytesPerSecond: Math.round(up / avatars / measured), downBytesPerSecondPerReceiver: Math.round(down / pairs / measured) };
  };
  result = {
    seconds: Math.round(measured * 10) / 10,
    latencySamples: samples,
    latencyMs: { p50: pct(0.5), p90: pct(0.9), p99: pct(0.99), p999: pct(0.999), max: overflow ? '>2000' : (sorted[sorted.length - 1][0] + 1) * bucket },
    desktop: mode('desktop'),
    vr: mode('vr'),
    delivery: { expected: rs.reduce((s, r) => s + r.delivery.expected, 0), delivered: rs.reduce((s, r) => s + r.delivery.delivered, 0), missing: rs.reduce((s, r) => s + r.delivery.missing, 0) },
    clientErrors: rs.reduce((s, r) => s + r.clientErrors, 0),
    joinRetries: rs.reduce((s, r) => s + r.joinRetries, 0),
    closedEarly: rs.reduce((s, r) => s + r.closedEarly, 0),
    clientCpuPercent: Math.round(rs.reduce((s, r) => s + r.clientCpuMs, 0) / (measured * 1000) * 1000) / 10,
  };
}
await new Promise((r) => setTimeout(r, 1100)); // one more stats line
for (const { server } of servers) server.kill('SIGTERM');
await Promise.all(servers.map(({ server }) => new Promise((resolve) => (server.exitCode !== null ? resolve() : server.once('exit', resolve)))));
if (nats) {
  nats.kill('SIGTERM');
  await new Promise((resolve) => nats.once('exit', resolve));
}
clearTimeout(killTimer);
rmSync(dir, { recursive: true, force: true });
if (clientCode !== 0 || !result) throw new Error(`load client failed (exit ${clientCode})`);

// Server numbers over the measured window: the stats lines inside it (all members joined).
const summarize = (lines) => {
  const total = clients / processes;
  const most = Math.max(...lines.map((s) => s.members));
  // The lines with (nearly) every member in: the measured window (a member or two may be between a drop and its rejoin).
  const inWindow = lines.filter((s, i) => i > 0 && s.members >= most - 2 && s.members > 0);
  if (inWindow.length < 2) throw new Error(`no measured window: members ${lines.map((s) => s.members).join(',')}`);
  const first = inWindow[Math.min(2, inWindow.length - 1)];
  const last = inWindow[inWindow.length - 1];
  const wall = (last.t - first.t) / 1000;
  const cpuMs = last.cpuUserMs + last.cpuSystemMs - (first.cpuUserMs + first.cpuSystemMs);
  const msgsIn = last.messagesIn - first.messagesIn;
  const msgsOut = last.messagesOut - first.messagesOut;
  return {
    members: last.members,
    membersExpected: total,
    remoteMembers: last.remoteMembers,
    windowSeconds: Math.round(wall * 10) / 10,
    cpuPercentOfOneCore: Math.round((cpuMs / (wall * 1000)) * 1000) / 10,
    rssMiBMax: Math.round(Math.max(...inWindow.map((s) => s.rss)) / 1048576 * 10) / 10,
    heapMiBMax: Math.round(Math.max(...inWindow.map((s) => s.heapUsed)) / 1048576 * 10) / 10,
    messagesInPerSecond: Math.round(msgsIn / wall),
    messagesOutPerSecond: Math.round(msgsOut / wall),
    framesOutPerSecond: Math.round((last.framesOut - first.framesOut) / wall),
    busOutPerSecond: Math.round((last.busOut - first.busOut) / wall),
    busInPerSecond: Math.round((last.busIn - first.busIn) / wall),
    busUnknown: last.busUnknown,
    bytesOutPerSecond: Math.round((last.bytesOut - first.bytesOut) / wall),
    cpuMicrosecondsPerMessageIn: Math.round((cpuMs * 1000) / msgsIn * 10) / 10,
    cpuMicrosecondsPerRelayedCopy: Math.round((cpuMs * 1000) / msgsOut * 100) / 100,
    skippedSlow: last.skippedSlow,
    dropped: last.dropped,
    refused: last.refused,
    internalErrors: last.internalErrors,
  };
};
if (process.env.LOAD_DEBUG) for (const l of stats.values()) console.error(l.map((s) => s.members).join(","));
const perProcess = [...stats.values()].map(summarize);
const serverSummary = perProcess[0];
const natsCpuPercent = Math.round(((natsCpu.end - natsCpu.start) * 10) / (natsCpu.t1 - natsCpu.t0) * 1000) / 10; // ticks of 10 ms
const report = { clients, rooms, processes, nats: processes > 1 ? natsUrl : null, natsCpuPercent, perProcess, delivery: result.delivery, seconds: result.seconds, vrEvery, latencyMs: result.latencyMs, latencySamples: result.latencySamples, server: serverSummary, desktop: result.desktop, vr: result.vr, clientErrors: result.clientErrors, closedEarly: result.closedEarly, clientProcessCpuPercent: result.clientCpuPercent,
  machine: { cores: cpus().length, loadAverage1mBefore: Math.round(loadBefore * 100) / 100, loadAverage1mAfter: Math.round(loadavg()[0] * 100) / 100 } };

const row = (k, v) => `| ${k} | ${v} |`;
console.log(
  [
    `| rooms load test: ${clients} clients in ${rooms} rooms, ${result.seconds} s measured | |`,
    '|---|---|',
    row('relay latency p50 / p90 / p99 / max (ms)', `${result.latencyMs.p50.toFixed(2)} / ${result.latencyMs.p90.toFixed(2)} / ${result.latencyMs.p99.toFixed(2)} / ${result.latencyMs.max}`),
    row(`latency samples; load client processes (${clientParts}) CPU (% of one core, together)`, `${result.latencySamples}; ${result.clientCpuPercent}`),
    row('delivered / expected (messages sent in the window × other members of the room)', `${result.delivery.delivered} / ${result.delivery.expected}`),
    ...perProcess.flatMap((p, k) => [
      row(`${processes > 1 ? `process ${k + 1}: ` : ''}server CPU (% of one core)`, p.cpuPercentOfOneCore),
      row(`${processes > 1 ? `process ${k + 1}: ` : ''}server RSS / heap max (MiB)`, `${p.rssMiBMax} / ${p.heapMiBMax}`),
      row(`${processes > 1 ? `process ${k + 1}: ` : ''}messages in / relayed copies out per s${processes > 1 ? ' / bus out / bus in' : ''}`, `${p.messagesInPerSecond} / ${p.messagesOutPerSecond}${processes > 1 ? ` / ${p.busOutPerSecond} / ${p.busInPerSecond}` : ''}`),
      row(`${processes > 1 ? `process ${k + 1}: ` : ''}WebSocket frames out per s (a frame: one message or a batch)`, p.framesOutPerSecond),
      row(`${processes > 1 ? `process ${k + 1}: ` : ''}server CPU µs per message in / per copy out`, `${p.cpuMicrosecondsPerMessageIn} / ${p.cpuMicrosecondsPerRelayedCopy}`),
    ]),
    row(`desktop avatars (${result.desktop.avatars}): up / down per receiver (B/s)`, `${result.desktop.upBytesPerSecond} / ${result.desktop.downBytesPerSecondPerReceiver}`),
    row(`VR avatars (${result.vr.avatars}): up / down per receiver (B/s)`, `${result.vr.upBytesPerSecond} / ${result.vr.downBytesPerSecondPerReceiver}`),
    row('machine: cores; 1-min load average before / after (other work on the machine)', `${report.machine.cores}; ${report.machine.loadAverage1mBefore} / ${report.machine.loadAverage1mAfter}`),
    row('joins tried again (closed before the welcome)', result.joinRetries),
    ...(processes > 1 ? [row('nats-server CPU (% of one core; NaN: not ours)', natsCpuPercent)] : []),
    row('dropped / refused / skipped slow / internal errors (/ bus messages from members not known yet) / client errors', perProcess.map((p) => `${JSON.stringify(p.dropped)} / ${JSON.stringify(p.refused)} / ${p.skippedSlow} / ${p.internalErrors}${processes > 1 ? ` / ${p.busUnknown}` : ''}`).join('; ') + ` / ${result.clientErrors}`),
  ].join('\n'),
);
console.log(JSON.stringify(report));
if (jsonOut) writeFileSync(jsonOut, `${JSON.stringify(report, null, 2)}\n`);
