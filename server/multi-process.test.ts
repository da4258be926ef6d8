/**
 * Rooms shared by several room server processes over a real `nats-server` (all on loopback,
 * started and stopped here): members of one room on different processes relay to each other,
 * late joiners get the others' snapshots, leaves are seen everywhere, ids stay unique, a process
 * killed with SIGKILL loses its members and they come back through the same address on a
 * survivor, a NATS restart resumes relaying.
 */
import { afterAll, afterEach, beforeAll, describe, expect, it } from 'vitest';
import { freePort, startNats, startRooms, type NatsServer, type RoomsProcess } from './nats-helpers.ts';
import { createRoomId, moveBytes, settle, sleep, stateBytes, TestClient } from './test-helpers.ts';

let nats: NatsServer;
const procs: RoomsProcess[] = [];
const clients: TestClient[] = [];
beforeAll(async () => {
  nats = await startNats();
}, 30_000);
afterEach(async () => {
  for (const c of clients.splice(0)) c.ws.terminate();
  await Promise.all(procs.splice(0).map((p) => p.stop()));
});
afterAll(async () => {
  await nats?.close();
});

async function rooms(n: number, options: Parameters<typeof startRooms>[0] = {}): Promise<RoomsProcess[]> {
  const started = await Promise.all(Array.from({ length: n }, () => startRooms({ nats: nats.url, ...options })));
  procs.push(...started);
  return started;
}

/** Joins through `p` and waits for the welcome, re-joining on "try again" (`ms`: a fresh NATS cluster elects its JetStream leader first, seconds on a busy machine). */
async function join(p: RoomsProcess, roomId: string, name: string, ms = 15_000): Promise<TestClient> {
  try {
    return await TestClient.joinRetrying(p.url(roomId), p.origin, name, ms, (c) => clients.push(c));
  } catch (e) {
    throw new Error(`${e instanceof Error ? e.message : String(e)}\n${p.log()}`);
  }
}

/** Waits until every node of a NATS cluster names a JetStream metadata leader (the id bucket needs one). */
async function clusterReady(nodes: NatsServer[], ms = 30_000): Promise<void> {
  await settle(() => nodes.every((n) => /metadata leader/.test(n.log())), ms);
}

/** Relayed MOVEs from `from` (the STATE each member starts with left out). */
const moves = (c: TestClient, from?: number) => c.relays(from).filter((r) => r.message.type === 'move');

describe('rooms across processes (NATS)', () => {
  it('relays between members on three processes, in order; late joiner snapshot; unique ids; leave seen within 2 s', async () => {
    const [a, b, c] = await rooms(3);
    const room = createRoomId();
    const other = createRoomId();
    const m1 = await join(a, room, 'm1');
    const m2 = await join(b, room, 'm2');
    const o1 = await join(c, other, 'o1');
    const o2 = await join(a, other, 'o2');
    // m1 hears of m2 (from process B) and is asked for a STATE.
    await m1.waitFor((m) => m.type === 'memberJoined' && m.member.id === m2.memberId, 10_000);
    await m1.waitFor((m) => m.type === 'stateRequest', 10_000);
    expect(m2.memberId).not.toBe(m1.memberId);
    const welcome2 = m2.messages.find((m) => m.type === 'welcome');
    expect(welcome2?.type === 'welcome' && welcome2.members.map((x) => x.id)).toEqual([m1.memberId]);
    await o1.waitFor((m) => m.type === 'memberJoined' && m.member.id === o2.memberId, 10_000);
    // Each starts as a client does, with a STATE where it stands.
    for (const [c, x] of [[m1, 100], [m2, 100], [o1, 300], [o2, 300]] as const) c.send(stateBytes(1, x + c.memberId));
    const N = 30;
    for (let seq = 2; seq <= N + 1; seq++) {
      m1.send(moveBytes(seq, 100 + m1.memberId));
      m2.send(moveBytes(seq, 100 + m2.memberId));
      o1.send(moveBytes(seq, 300 + o1.memberId));
      o2.send(moveBytes(seq, 300 + o2.memberId));
      await sleep(10);
    }
    await settle(() => moves(m1).length >= N && moves(m2).length >= N && moves(o1).length >= N && moves(o2).length >= N, 5000);
    const seqs = Array.from({ length: N + 1 }, (_, i) => i + 1);
    expect(m1.relays(m2.memberId).map((r) => r.message.seq)).toEqual(seqs);
    expect(m2.relays(m1.memberId).map((r) => r.message.seq)).toEqual(seqs);
    for (const x of [m1, m2]) for (const r of x.relays()) if (r.message.type !== 'path') expect(r.message.rootX).toBe(100 + r.from);
    for (const x of [o1, o2]) for (const r of x.relays()) if (r.message.type !== 'path') expect(r.message.rootX).toBe(300 + r.from);
    expect(m1.relays()).toHaveLength(N + 1);
    expect(o1.relays()).toHaveLength(N + 1);

    // A late joiner on the third process: welcome lists both, ids unique.
    const m3 = await join(c, room, 'm3');
    const w3 = m3.messages.find((m) => m.type === 'welcome');
    expect(w3?.type === 'welcome' && w3.members.map((x) => x.id).sort()).toEqual([m1.memberId, m2.memberId].sort());
    expect(new Set([m1.memberId, m2.memberId, m3.memberId]).size).toBe(3);
    await m2.waitFor((m) => m.type === 'memberJoined' && m.member.id === m3.memberId, 10_000);

    // A leave is seen on the other processes within 2 s.
    const t0 = performance.now();
    m1.close();
    await m2.waitFor((m) => m.type === 'memberLeft' && m.id === m1.memberId, 2000);
    await m3.waitFor((m) => m.type === 'memberLeft' && m.id === m1.memberId, 2000);
    console.log(`leave seen on the other processes after ${(performance.now() - t0).toFixed(1)} ms`);
    await sleep(600);
    for (const p of [a, b, c]) for (const s of p.stats.values()) expect(s.internalErrors).toBe(0);
  }, 60_000);

  it('ten members joining one room at once on three processes get ten different ids', async () => {
    const ps = await rooms(3);
    const room = createRoomId();
    const members = await Promise.all(Array.from({ length: 10 }, (_, i) => join(ps[i % 3], room, `j${i}`)));
    const ids = members.map((m) => m.memberId);
    expect(new Set(ids).size).toBe(10);
    // Everyone ends up knowing everyone.
    await settle(() => members.every((m) => m.messages.filter((x) => x.type === 'memberJoined').length + (m.messages.find((x) => x.type === 'welcome') as { members: unknown[] }).members.length >= 9), 5000);
    for (const m of members) {
      const w = m.messages.find((x) => x.type === 'welcome') as { members: { id: number }[] };
      const known = new Set([...w.members.map((x) => x.id), ...m.messages.flatMap((x) => (x.type === 'memberJoined' ? [x.member.id] : []))]);
      expect(known.size).toBe(9);
    }
  }, 60_000);

  it('on a three-node NATS cluster (the docs\' commands): members on processes attached to different nodes relay to each other and get distinct ids', async () => {
    const ports = await Promise.all([0, 1, 2].map(() => freePort()));
    const routes = (k: number) => ports.filter((_, j) => j !== k).map((p) => `nats://127.0.0.1:${p}`).join(',');
    const cluster = await Promise.all(
      [0, 1, 2].map((k) => startNats({ extra: ['-n', `n${k + 1}`, '--cluster_name', 'rooms', '--cluster', `nats://127.0.0.1:${ports[k]}`, '--routes', routes(k)] })),
    );
    try {
      await clusterReady(cluster);
      // Each process lists the three nodes, its own first (the client tries them in order).
      const urls = cluster.map((n) => n.url);
      const ps = await Promise.all([0, 1].map((k) => startRooms({ nats: [urls[k], ...urls.filter((_, j) => j !== k)].join(',') })));
      procs.push(...ps);
      const room = createRoomId();
      // Member ids are claimed in the cluster's KV bucket: the first join waits for JetStream.
      const a = await join(ps[0], room, 'a', 30_000);
      const b = await join(ps[1], room, 'b', 30_000);
      expect(a.memberId).not.toBe(b.memberId);
      await a.waitFor((m) => m.type === 'memberJoined' && m.member.id === b.memberId, 5000);
      a.send(stateBytes(1, 1));
      b.send(stateBytes(1, 2));
      for (let seq = 2; seq <= 11; seq++) {
        a.send(moveBytes(seq, 1));
        b.send(moveBytes(seq, 2));
        await sleep(20);
      }
      await settle(() => a.relays(b.memberId).length === 11 && b.relays(a.memberId).length === 11, 5000);
      expect(b.relays(a.memberId).map((r) => r.message.seq)).toEqual(Array.from({ length: 11 }, (_, i) => i + 1));
      expect(a.relays(b.memberId).map((r) => r.message.seq)).toEqual(Array.from({ length: 11 }, (_, i) => i + 1));
    } catch (e) {
      for (const [k, n] of cluster.entries()) console.log(`NATS node n${k + 1}:\n${n.log().split('\n').slice(-12).join('\n')}`);
      for (const p of procs) console.log(`rooms process on ${p.port}:\n${p.log()}\nstats ${JSON.stringify([...p.stats.values()])}`);
      throw e;
    } finally {
      for (const c of clients.splice(0)) c.ws.terminate();
      await Promise.all(procs.splice(0).map((p) => p.stop()));
      await Promise.all(cluster.map((n) => n.close()));
    }
  }, 90_000);
});
