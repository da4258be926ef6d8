/**
 * Load-test clients (run by scripts/rooms-load.mjs in a process of their own, loopback only):
 * `--clients` members in `--rooms` rooms, desktop ones stepping at 60 Hz and sending 20 Hz, VR
 * ones (every `--vr-every`-th) stepping at 90 Hz and sending 30 Hz, each a real `LocalAvatar` +
 * `InputStream` stream with a STATE a second. Measures relay latency (send → each receiver, one
 * clock: the same process) and bytes per avatar, then prints one JSON line.
 */
import { WebSocket } from 'ws';
import { InputStream } from '../web/src/rooms/input-stream.ts';
import { LocalAvatar } from '../web/src/rooms/local-avatar.ts';
import {
  BATCH_ENTRY_BYTES,
  BATCH_HEADER_BYTES,
  createRoomId,
  decodeServerMessage,
  encodeJoin,
  MsgType,
  websocketFrameOverhead,
  type RoomTrackerPose,
} from '../web/src/rooms/protocol.ts';
import { TestCharacter } from '../web/src/rooms/testing.ts';

function arg(name: string, fallback: number): number;
function arg(name: string, fallback: string): string;
function arg(name: string, fallback: number | string): number | string {
  const i = process.argv.indexOf(`--${name}`);
  if (i < 0) return fallback;
  return typeof fallback === 'number' ? Number(process.argv[i + 1]) : process.argv[i + 1];
}

// Several servers (comma-separated): client i goes to server (i + ⌊i / rooms⌋) mod n, so the members
// of every room are spread over the servers, evenly (the multi-process load test).
const bases = arg('url', 'ws://127.0.0.1:8787').split(',');
const origins = arg('origin', 'http://127.0.0.1:8787').split(',');
const numClients = arg('clients', 100);
const numRooms = arg('rooms', 10);
const seconds = arg('seconds', 60);
const warmup = arg('warmup', 2);
const vrEvery = arg('vr-every', 3);

const RING = 4096;
const HIST_BUCKET_MS = 0.05;
const histogram = new Uint32Array(Math.ceil(2000 / HIST_BUCKET_MS));
let latencySamples = 0;
let latencyOverflow = 0;
let measuring = false;

interface Client {
  index: number;
  room: number;
  vr: boolean;
  ws: WebSocket;
  memberId: number;
  stream: InputStream;
  local: LocalAvatar;
  character: TestCharacter;
  sentAt: Float64Array;
  /** Member id → that sender's mode, in this client's room. */
  modes: Map<number, boolean>;
  upBytes: number;
  downBytes: { desktop: number; vr: number };
  downPairs: { desktop: number; vr: number };
  joined: boolean;
  closed: boolean;
  errors: number;
  /** First seq sent while measuring (messages from then on must all arrive), and how many were sent. */
  firstSeq: number;
  sentMeasured: number;
  /** Relays received from each sender (by index) with seq ≥ that sender's firstSeq. */
  received: Uint32Array;
}

// Several client processes (`--parts K --part j`): this one runs the clients of the rooms r with
// r mod K = j, so every room's members are in one process and latency is measured on one clock.
const roomIds = arg('room-ids', '') ? arg('room-ids', '').split(',') : Array.from({ length: numRooms }, () => createRoomId());
const parts = arg('parts', 1);
const part = arg('part', 0);
const mine = (index: number) => (index % numRooms) % parts === part;
const clients: Client[] = [];
const byRoomAndId = new Map<string, Client>();
const trackers: RoomTrackerPose[] = [0, 1, 2].map(() => ({ tracked: true, fromHand: false, position: [0, 1.6, 0], rotation: [0, 0, 0, 1] }));

// Sends: 20 Hz desktop, 30 Hz VR, phases spread; a STATE every second — from the client's welcome
// on (a member silent while the others still connect would be dropped after the idle timeout).
const timers: ReturnType<typeof setInterval>[] = [];
function startSending(c: Client): void {
  const period = 1000 / (c.vr ? 30 : 20);
  let lastState = performance.now();
  timers.push(
    setTimeout(() => {
      timers.push(
        setInterval(() => {
          const now = performance.now();
          if (now - lastState >= 1000) {
            c.stream.queueState();
            lastState = now;
          }
          send(c, now);
        }, period),
      );
    }, Math.random() * period),
  );
}

let joinRetries = 0;

/** Opens client `index`; a connection closed before its welcome (the server busy: 1013) tries again, as `RoomClient` does. */
async function open(index: number): Promise<void> {
  for (let attempt = 0; ; attempt++) {
    try {
      return await openOnce(index);
    } catch (e) {
      if (attempt >= 5) throw e;
      joinRetries++;
      const i = clients.findIndex((c) => c.index === index);
      if (i >= 0) clients.splice(i, 1);
      await new Promise((r) => setTimeout(r, 500 * 2 ** attempt * (0.5 + Math.random() / 2)));
    }
  }
}

function openOnce(index: number): Promise<void> {
  const room = index % numRooms;
  const vr = index % vrEvery === vrEvery - 1;
  const server = (index + Math.floor(index / numRooms)) % bases.length;
  const ws = new WebSocket(`${bases[server]}/rooms/${roomIds[room]}`, { origin: origins[server % origins.length] });
  const stream = new InputStream();
  const character = new TestCharacter();
  const c: Client = {
    index,
    room,
    vr,
    ws,
    memberId: 0,
    stream,
    local: new LocalAvatar(character, stream),
    character,
    sentAt: new Float64Array(RING),
    modes: new Map(),
    upBytes: 0,
    downBytes: { desktop: 0, vr: 0 },
    downPairs: { desktop: 0, vr: 0 },
    joined: false,
    closed: false,
    errors: 0,
    firstSeq: Infinity,
    sentMeasured: 0,
    received: new Uint32Array(numClients),
  };
  clients.push(c);
  ws.binaryType = 'nodebuffer';
  return new Promise((resolve, reject) => {
    ws.on('open', () => {
      ws.send(encodeJoin({ name: `load ${index}`, avatar: { kind: 'builtin', id: index % 4 }, database: 'locomotion', height: vr ? 1.65 : 0, mode: vr ? 'vr' : 'desktop', devices: vr ? { headset: true, leftController: true, rightController: true } : { keyboard: true } }));
    });
    // One relay: count it, time it, and charge its bytes (`wire`: its share of the frame).
    const relayed = (data: Buffer, o: number, wire: number, now: number) => {
      // Header only: [version, 0x83, from, version, type, seq u32 …]
      const from = data[o + 2];
      const seq = data.readUInt32LE(o + 5);
      const sender = byRoomAndId.get(`${room}:${from}`);
      if (sender && seq >= sender.firstSeq) c.received[sender.index]++;
      if (measuring && sender) {
        const sent = sender.sentAt[seq % RING];
        if (sent > 0) {
          const ms = now - sent;
          const b = Math.floor(ms / HIST_BUCKET_MS);
          if (b < histogram.length) histogram[b]++;
          else latencyOverflow++;
          latencySamples++;
        }
        c.downBytes[sender.vr ? 'vr' : 'desktop'] += wire;
      }
    };
    const other = (bytes: Uint8Array) => {
      try {
        const m = decodeServerMessage(bytes);
        if (m.type === 'welcome') {
          c.memberId = m.memberId;
          c.joined = true;
          byRoomAndId.set(`${room}:${m.memberId}`, c);
          c.stream.queueState();
          startSending(c);
          resolve();
        } else if (m.type === 'stateRequest') c.stream.queueState();
      } catch {
        c.errors++;
      }
    };
    ws.on('message', (data: Buffer) => {
      const now = performance.now();
      const frame = data.length + websocketFrameOverhead(data.length, false);
      if (data[1] === MsgType.relay) return relayed(data, 0, frame, now);
      if (data[1] !== MsgType.batch) return other(new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
      // A batch, walked in place (the hot path: no views made for relays). Each relay is charged its
      // bytes, its length prefix and an equal share of the batch's header and frame.
      let count = 0;
      for (let o = BATCH_HEADER_BYTES; o + BATCH_ENTRY_BYTES <= data.length; o += BATCH_ENTRY_BYTES + data.readUInt16LE(o)) count++;
      const share = (frame - data.length + BATCH_HEADER_BYTES) / Math.max(1, count);
      for (let o = BATCH_HEADER_BYTES; o + BATCH_ENTRY_BYTES <= data.length; ) {
        const n = data.readUInt16LE(o);
        const at = o + BATCH_ENTRY_BYTES;
        if (n < 2 || at + n > data.length) {
          c.errors++;
          return;
        }
        if (data[at + 1] === MsgType.relay) relayed(data, at, n + BATCH_ENTRY_BYTES + share, now);
        else other(new Uint8Array(data.buffer, data.byteOffset + at, n));
        o = at + n;
      }
    });
    ws.on('close', () => {
      c.closed = true;
      if (!c.joined) reject(new Error(`client ${index} closed before joining`));
    });
    ws.on('error', () => c.errors++);
  });
}

function send(c: Client, now: number): void {
  if (!c.joined || c.closed) return;
  for (const bytes of c.stream.flush()) {
    const seq = new DataView(bytes.buffer, bytes.byteOffset).getUint32(2, true);
    c.sentAt[seq % RING] = now;
    if (measuring) {
      if (c.firstSeq === Infinity) c.firstSeq = seq;
      c.sentMeasured++;
    }
    c.ws.send(bytes);
    if (measuring) c.upBytes += bytes.length + websocketFrameOverhead(bytes.length, true);
  }
}

async function main() {
  // Connect in batches so the server is not asked for 100 handshakes in one tick.
  const t0 = performance.now();
  let simNow = t0;
  let vrSteps = 0;
  // Frames: desktop 60 Hz, VR 90 Hz (catching up from the one timer). A frame late by more than
  // 0.1 s takes 0.1 s, as a page does (`<mm-avatar>` clamps its dt): a load client starved by a
  // busy machine must not send seconds of steps at once (the server's simulated-time limit).
  const frame = setInterval(() => {
    const now = performance.now();
    const t = (now - t0) / 1000;
    simNow = Math.max(simNow, now - 100);
    vrSteps += ((now - simNow) / 1000) * 90;
    const vrNow = Math.floor(vrSteps);
    vrSteps -= vrNow;
    for (const c of clients) {
      if (!c.joined) continue; // its stream starts with its welcome
      const phase = c.index * 0.7;
      const steps = c.vr ? vrNow : 1;
      const dt = c.vr ? 1 / 90 : (now - simNow) / 1000;
      for (let s = 0; s < steps; s++) {
        const ang = t * 0.5 + phase;
        if (c.vr) {
          const x = Math.sin(ang) * 2;
          const z = Math.cos(ang) * 2;
          trackers[0].position = [x, 1.6, z];
          trackers[1].position = [x - 0.3, 1.1, z];
          trackers[2].position = [x + 0.3, 1.1, z];
          c.local.setTrackers(trackers);
          c.local.setTracked({ headX: x, headZ: z, velocityX: Math.cos(ang), velocityZ: -Math.sin(ang), yaw: ang + Math.PI / 2, hipsDrop: 0, bend: 0 }, 1, 0.2);
        } else c.local.setMove({ moveX: Math.sin(ang), moveZ: Math.cos(ang), faceX: 0, faceZ: 1, run: Math.sin(t + phase) > 0.5, strafe: false });
        c.local.update(dt);
      }
    }
    simNow = now;
  }, 1000 / 60);
  const indices = Array.from({ length: numClients }, (_, i) => i).filter(mine);
  for (let i = 0; i < indices.length; i += 10) await Promise.all(indices.slice(i, i + 10).map((k) => open(k)));
  await new Promise((r) => setTimeout(r, warmup * 1000));
  console.log(JSON.stringify({ type: 'measuring', at: Date.now() }));
  measuring = true;
  const m0 = performance.now();
  const cpu0 = process.cpuUsage();
  await new Promise((r) => setTimeout(r, seconds * 1000));
  // Sending stops with the window: every relay counted from here on was sent inside it.
  clearInterval(frame);
  for (const t of timers) clearInterval(t);
  measuring = false;
  const measured = (performance.now() - m0) / 1000;
  const cpu = process.cpuUsage(cpu0);
  const clientCpuPercent = Math.round(((cpu.user + cpu.system) / 1000 / (measured * 1000)) * 1000) / 10;
  console.log(JSON.stringify({ type: 'measured', at: Date.now() }));
  // Every message sent while measuring must reach every other member of its room: wait for the last ones.
  let expected = 0;
  let delivered = 0;
  const count = () => {
    expected = 0;
    delivered = 0;
    for (const r of clients)
      for (const s of clients) {
        if (s === r || s.room !== r.room) continue;
        expected += s.sentMeasured;
        delivered += Math.min(r.received[s.index], s.sentMeasured);
      }
  };
  // (Until all arrived, or nothing more came for 2 s: at most 20 s.)
  let last = -1;
  let still = 0;
  for (let k = 0; k < 200; k++) {
    count();
    if (delivered >= expected) break;
    still = delivered === last ? still + 1 : 0;
    if (still >= 20) break;
    last = delivered;
    await new Promise((r) => setTimeout(r, 100));
  }

  const pct = (p: number) => {
    const target = p * latencySamples;
    let acc = 0;
    for (let b = 0; b < histogram.length; b++) {
      acc += histogram[b];
      if (acc >= target) return (b + 0.5) * HIST_BUCKET_MS;
    }
    return Infinity;
  };
  let maxBucket = 0;
  for (let b = 0; b < histogram.length; b++) if (histogram[b]) maxBucket = b;
  const perMode = (vr: boolean) => {
    const senders = clients.filter((c) => c.vr === vr);
    const up = senders.reduce((s, c) => s + c.upBytes, 0) / senders.length / measured;
    // Downstream: bytes received from senders of this mode / (receiver, sender) pairs.
    let bytes = 0;
    let pairs = 0;
    for (const r of clients) {
      const inRoom = clients.filter((s) => s.room === r.room && s !== r && s.vr === vr).length;
      bytes += r.downBytes[vr ? 'vr' : 'desktop'];
      pairs += inRoom;
    }
    return { avatars: senders.length, upBytesPerSecond: Math.round(up), downBytesPerSecondPerReceiver: Math.round(bytes / pairs / measured), upBytes: senders.reduce((s, c) => s + c.upBytes, 0), downBytes: bytes, pairs };
  };
  const sparse: [number, number][] = [];
  for (let b = 0; b < histogram.length; b++) if (histogram[b]) sparse.push([b, histogram[b]]);
  const result = {
    type: 'result',
    clients: numClients,
    rooms: numRooms,
    seconds: Math.round(measured * 10) / 10,
    latencySamples,
    latencyOverflow,
    histogram: sparse,
    histogramBucketMs: HIST_BUCKET_MS,
    measuredSeconds: measured,
    latencyMs: { p50: pct(0.5), p90: pct(0.9), p99: pct(0.99), p999: pct(0.999), max: latencyOverflow ? '>2000' : (maxBucket + 1) * HIST_BUCKET_MS },
    desktop: perMode(false),
    vr: perMode(true),
    delivery: { expected, delivered, missing: expected - delivered },
    clientErrors: clients.reduce((s, c) => s + c.errors, 0),
    joinRetries,
    closedEarly: clients.filter((c) => c.closed).length,
    clientCpuPercent,
    clientCpuMs: (cpu.user + cpu.system) / 1000,
  };
  console.log(JSON.stringify(result));
  for (const c of clients) c.ws.close();
  setTimeout(() => process.exit(0), 500);
}

main().catch((e) => {
  console.error(e);
  process.exit(1);
});
