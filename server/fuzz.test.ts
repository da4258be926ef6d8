/**
 * Hostile clients against a real room server on loopback: ≥ 10,000 malformed, oversized,
 * out-of-order, flooding and cheating messages while well-behaved members talk in two rooms.
 * The server must stay up with no internal error, the good members of the attacked room must
 * get every message of each other, unchanged and in order, and the other room must see nothing
 * but its own member.
 */
import { afterEach, expect, it } from 'vitest';
import { WebSocket } from 'ws';
import {
  createMoveStep,
  encodeJoin,
  encodeMove,
  encodePath,
  encodeState,
  encodeTracked,
  quantizeMoveStep,
  quantizeTrackedStep,
} from '../web/src/rooms/protocol.ts';
import { seededRandom } from '../web/src/bench/queries.ts';
import { startNats, startRooms, type RoomsProcess } from './nats-helpers.ts';
import { createRoomId, moveBytes, settle, sleep, startServer, stateBytes, TestClient, testJoin, type TestServer } from './test-helpers.ts';

let server: TestServer | null = null;
afterEach(async () => {
  await server?.close();
  server = null;
});

const rand = seededRandom(2024);
const int = (n: number) => Math.floor(rand() * n);
const randomBytes = (n: number) => Uint8Array.from({ length: n }, () => int(256));

function validSamples(): Uint8Array[] {
  const step = quantizeMoveStep({ ...createMoveStep(), ticks: 120, moveX: 0.5, moveZ: 0.5 });
  return [
    encodeJoin(testJoin('h')),
    encodeMove({ seq: 1, time: 50, rootX: 1, rootZ: 2, rootYaw: 0.5, steps: [step, step, { ...step, ticks: 121 }] }),
    encodeTracked({
      seq: 1,
      time: 33,
      rootX: 1,
      rootZ: 1,
      rootYaw: 0,
      scale: 1,
      alpha: 0.2,
      trackers: [0, 1, 2].map(() => ({ tracked: true, fromHand: false, position: [1, 1.6, 1] as [number, number, number], rotation: [0, 0, 0, 1] as [number, number, number, number] })) as never,
      steps: [quantizeTrackedStep({ ticks: 80, headX: 1, headZ: 1, velocityX: 0.2, velocityZ: 0, yaw: 0, hipsDrop: 0, bend: 0 })],
    }),
    encodePath({ seq: 1, time: 0, points: new Float32Array([0, 0, 1, 1, 2, 0]), speeds: new Float32Array([1, 2]), looped: false }),
    encodeState({ seq: 1, time: 0, frame: 1, rootX: 0, rootZ: 0, rootYaw: 0, drive: 'move', pathTime: 0, scale: 1, alpha: 0.2, move: step, tracked: quantizeTrackedStep({ ticks: 0, headX: 0, headZ: 0, velocityX: 0, velocityZ: 0, yaw: 0, hipsDrop: 0, bend: 0 }) }),
    // With a runtime state (opaque to the server: its length is what is checked).
    encodeState({ seq: 1, time: 0, frame: 1, rootX: 0, rootZ: 0, rootYaw: 0, drive: 'move', pathTime: 0, scale: 1, alpha: 0.2, move: step, tracked: quantizeTrackedStep({ ticks: 0, headX: 0, headZ: 0, velocityX: 0, velocityZ: 0, yaw: 0, hipsDrop: 0, bend: 0 }), runtime: randomBytes(600) }),
  ];
}

function mutate(b: Uint8Array): Uint8Array {
  const c = b.slice();
  const flips = 1 + int(4);
  for (let i = 0; i < flips; i++) c[int(c.length)] ^= 1 << int(8);
  return c;
}

type Kind = (samples: Uint8Array[]) => { join: boolean; messages: (Uint8Array | string)[] };
const BURST = 25;
const kinds: Record<string, Kind> = {
  random: () => ({ join: rand() < 0.5, messages: Array.from({ length: BURST }, () => randomBytes(int(300))) }),
  mutated: (s) => ({ join: true, messages: Array.from({ length: BURST }, () => mutate(s[1 + int(s.length - 1)])) }),
  mutatedJoin: (s) => ({ join: false, messages: Array.from({ length: BURST }, () => mutate(s[0])) }),
  truncated: (s) => ({ join: true, messages: Array.from({ length: BURST }, () => { const b = s[int(s.length)]; return b.subarray(0, int(b.length)); }) }),
  // Over the 1 KiB limit of all but a STATE (decoded and refused), or over the frame limit (ws closes with 1009).
  oversized: () => ({ join: true, messages: Array.from({ length: BURST }, () => randomBytes(1025 + int(20_000))) }),
  text: () => ({ join: true, messages: Array.from({ length: BURST }, () => 'x'.repeat(int(100))) }),
  beforeJoin: () => ({ join: false, messages: Array.from({ length: BURST }, (_, i) => moveBytes(i + 1, 7)) }),
  outOfOrder: () => ({ join: true, messages: Array.from({ length: BURST }, (_, i) => moveBytes(BURST - i, 7)) }),
  duplicate: () => ({ join: true, messages: Array.from({ length: BURST }, () => moveBytes(3, 7)) }),
  badVersion: (s) => ({ join: false, messages: Array.from({ length: BURST }, () => { const b = s[int(s.length)].slice(); b[0] = 2 + int(250); return b; }) }),
  flood: () => ({ join: true, messages: Array.from({ length: 6 * BURST }, (_, i) => moveBytes(i + 1, 7, 1)) }),
  timeCheat: () => {
    const steps = Array.from({ length: 64 }, () => quantizeMoveStep({ ...createMoveStep(), ticks: 1800 }));
    return { join: true, messages: Array.from({ length: BURST }, (_, i) => encodeMove({ seq: i + 1, time: (i + 1) * 16000, rootX: 0, rootZ: 0, rootYaw: 0, steps })) };
  },
};

async function hostile(url: string, origin: string, kind: Kind, samples: Uint8Array[]): Promise<number> {
  const ws = new WebSocket(url, { origin });
  ws.on('error', () => {});
  const opened = await new Promise<boolean>((resolve) => {
    ws.once('open', () => resolve(true));
    ws.once('error', () => resolve(false));
    ws.once('unexpected-response', () => resolve(false));
  });
  if (!opened) return 0;
  const { join, messages } = kind(samples);
  let sent = 0;
  if (join) ws.send(encodeJoin(testJoin('hostile')));
  for (const m of messages) {
    if (ws.readyState !== ws.OPEN) break;
    ws.send(m);
    sent++;
  }
  await new Promise<void>((resolve) => {
    const t = setTimeout(resolve, 400);
    ws.once('close', () => {
      clearTimeout(t);
      resolve();
    });
  });
  ws.terminate();
  return sent;
}

/**
 * The good members' steady talk: a MOVE each every 50 ms after sequence number `from` (rootX
 * says the room: 100 + id in room A for g1 and g2, 300 + id in room B for g3). `stop()` returns
 * the last sequence number sent.
 */
function talk(g1: TestClient, g2: TestClient, g3: TestClient, from: number): { stop(): number } {
  let seq = from;
  const timer = setInterval(() => {
    seq++;
    g1.send(moveBytes(seq, 100 + g1.memberId));
    g2.send(moveBytes(seq, 100 + g2.memberId));
    g3.send(moveBytes(seq, 300 + g3.memberId));
  }, 50);
  return {
    stop: () => {
      clearInterval(timer);
      return seq;
    },
  };
}

it('survives 10,000+ hostile messages; good members unaffected; nothing crosses rooms', async () => {
  // The listeners only listen: on a busy machine the hostile phase outlasts the 5 s idle timeout
  // that would drop a silent member.
  server = await startServer({ idleTimeoutMs: 120_000 });
  const roomA = createRoomId();
  const roomB = createRoomId();
  const listener = await TestClient.join(server, roomA, 'listener');
  const g1 = await TestClient.join(server, roomA, 'g1');
  const g2 = await TestClient.join(server, roomA, 'g2');
  const listenerB = await TestClient.join(server, roomB, 'listenerB');
  const g3 = await TestClient.join(server, roomB, 'g3');
  const good = talk(g1, g2, g3, 0);
  let seq = 0;
  const samples = validSamples();
  const names = Object.keys(kinds);
  let hostileSent = 0;
  let connections = 0;
  const t0 = performance.now();
  try {
    while (hostileSent < 10_000) {
      const wave = names.map((name) => hostile(server!.url(roomA), server!.origin, kinds[name], samples));
      connections += wave.length;
      for (const n of await Promise.all(wave)) hostileSent += n;
    }
  } finally {
    seq = good.stop();
  }
  const seconds = (performance.now() - t0) / 1000;
  const pairs = [
    [listener, g1],
    [listener, g2],
    [g1, g2],
    [g2, g1],
  ] as const;
  await settle(() => pairs.every(([receiver, sender]) => receiver.relays(sender.memberId).length >= seq));
  const stats = server.rooms.stats();
  console.log(
    `fuzz: ${hostileSent} hostile messages from ${connections} connections in ${seconds.toFixed(1)} s; ` +
      `server read ${stats.messagesIn} (${stats.ignoredAfterDrop} after their sender was dropped); dropped ${JSON.stringify(stats.dropped)}; ` +
      `good members sent ${seq} each`,
  );
  expect(hostileSent).toBeGreaterThanOrEqual(10_000);
  expect(stats.internalErrors).toBe(0);
  expect(Object.values(stats.dropped).reduce((a, b) => a + b, 0)).toBeGreaterThan(connections * 0.6);

  // The good members of room A got each other's every message, unchanged and in order.
  const expectSeqs = Array.from({ length: seq }, (_, i) => i + 1);
  for (const [receiver, sender] of pairs) {
    const got = receiver.relays(sender.memberId);
    expect(got.map((r) => r.message.seq)).toEqual(expectSeqs);
    for (const r of got) if (r.message.type === 'move') expect(r.message.rootX).toBe(100 + sender.memberId);
  }
  expect(listener.decodeErrors).toEqual([]);
  // No message from room B ever reached room A, and room B heard only its own member.
  for (const c of [listener, g1, g2]) for (const r of c.relays()) if (r.message.type === 'move') expect(r.message.rootX).toBeLessThan(300);
  // (welcome, g3 joining, the state request that a join triggers, then g3's stream and nothing else)
  expect(listenerB.messages.map((m) => m.type).slice(0, 3)).toEqual(['welcome', 'memberJoined', 'stateRequest']);
  expect(listenerB.messages.slice(3).every((m) => m.type === 'relay' && m.from === g3.memberId)).toBe(true);
  expect(listenerB.relays(g3.memberId).map((r) => r.message.seq)).toEqual(expectSeqs);
  for (const r of listenerB.relays()) if (r.message.type === 'move') expect(r.message.rootX).toBe(300 + g3.memberId);

  // Still serving: a newcomer joins room A and is heard.
  const late = await TestClient.join(server, roomA, 'late');
  late.send(moveBytes(1, 42));
  await listener.waitFor((m) => m.type === 'relay' && m.from === late.memberId);
  expect(server.rooms.membersOf(roomA).sort()).toEqual([listener.memberId, g1.memberId, g2.memberId, late.memberId].sort());
  for (const c of [listener, g1, g2, listenerB, g3, late]) c.ws.terminate();
}, 120_000);

it('across three processes sharing rooms over NATS: hostile messages at every process; good members unaffected; nothing crosses rooms or processes', async () => {
  const nats = await startNats();
  const ps = await Promise.all([0, 1, 2].map(() => startRooms({ nats: nats.url, args: ['--idle-timeout-ms', '120000'] })));
  const open = async (p: RoomsProcess, room: string, name: string) => {
    const c = await TestClient.open(p.url(room), p.origin);
    c.send(encodeJoin(testJoin(name)));
    await c.waitFor((m) => m.type === 'welcome');
    return c;
  };
  const roomA = createRoomId();
  const roomB = createRoomId();
  const all: TestClient[] = [];
  try {
    const listener = await open(ps[0], roomA, 'listener');
    const g1 = await open(ps[1], roomA, 'g1');
    const g2 = await open(ps[2], roomA, 'g2');
    const listenerB = await open(ps[2], roomB, 'listenerB');
    const g3 = await open(ps[0], roomB, 'g3');
    all.push(listener, g1, g2, listenerB, g3);
    await settle(() => listener.messages.filter((m) => m.type === 'memberJoined').length >= 2 && listenerB.messages.some((m) => m.type === 'memberJoined'));
    // The good members start as clients do: a STATE first (across processes, steps follow a STATE).
    g1.send(stateBytes(1, 100 + g1.memberId));
    g2.send(stateBytes(1, 100 + g2.memberId));
    g3.send(stateBytes(1, 300 + g3.memberId));
    const good = talk(g1, g2, g3, 1);
    let seq = 1;
    const samples = validSamples();
    const names = Object.keys(kinds);
    let hostileSent = 0;
    let wave = 0;
    try {
      while (hostileSent < 5_000) {
        const p = ps[wave++ % 3];
        for (const n of await Promise.all(names.map((name) => hostile(p.url(roomA), p.origin, kinds[name], samples)))) hostileSent += n;
      }
    } finally {
      seq = good.stop();
    }
    const pairs = [
      [listener, g1],
      [listener, g2],
      [g1, g2],
      [g2, g1],
    ] as const;
    await settle(() => pairs.every(([receiver, sender]) => receiver.relays(sender.memberId).length >= seq) && listenerB.relays(g3.memberId).length >= seq);
    await sleep(500); // one more stats line from each process
    const stats = ps.map((p) => [...p.stats.values()][0]);
    console.log(`fuzz across processes: ${hostileSent} hostile messages in ${wave} waves over 3 processes; internal errors ${stats.map((s) => s.internalErrors).join('/')}; refused ${stats.map((s) => JSON.stringify(s.refused)).join(' ')}; good members sent ${seq} each`);
    expect(hostileSent).toBeGreaterThanOrEqual(5_000);
    for (const p of ps) expect(p.child.exitCode).toBeNull();
    for (const s of stats) expect(s.internalErrors).toBe(0);
    const expectSeqs = Array.from({ length: seq }, (_, i) => i + 1);
    for (const [receiver, sender] of pairs) {
      const got = receiver.relays(sender.memberId);
      expect(got.map((r) => r.message.seq)).toEqual(expectSeqs);
      for (const r of got) if (r.message.type === 'move') expect(r.message.rootX).toBe(100 + sender.memberId);
    }
    // Room A's members heard nothing of room B, and room B only its own member (on another process).
    for (const c of [listener, g1, g2]) for (const r of c.relays()) if (r.message.type === 'move') expect(r.message.rootX).toBeLessThan(300);
    expect(listenerB.relays().every((r) => r.from === g3.memberId)).toBe(true);
    expect(listenerB.relays(g3.memberId).map((r) => r.message.seq)).toEqual(expectSeqs);
    expect(listenerB.messages.filter((m) => m.type === 'memberJoined').map((m) => m.type === 'memberJoined' && m.member.id)).toEqual([g3.memberId]);
    // Still serving on every process.
    for (const p of ps) {
      const late = await open(p, roomA, 'late');
      all.push(late);
    }
  } finally {
    for (const c of all) c.ws.terminate();
    await Promise.all(ps.map((p) => p.stop()));
    await nats.close();
  }
}, 180_000);
