/**
 * `RoomSession`s on the real engine (WASM in Node) connected to different room server processes
 * that share rooms over a real `nats-server`: copies are bit-exact across processes as on one, a
 * late joiner on a third process is exact from its first drawn frame, a leave is seen everywhere
 * within 2 s; a worker killed with SIGKILL behind one address: its members reconnect to the
 * survivors and everyone sees everyone again, exact, within 5 s; a NATS restart: relaying resumes.
 */
import fs from 'node:fs';
import path from 'node:path';
import { afterAll, afterEach, beforeAll, describe, expect, it } from 'vitest';
import { Database } from '../web/src/core/database.ts';
import { initWasmSync } from '../web/src/core/wasm.ts';
import { createRoomId, encodeJoin } from '../web/src/rooms/protocol.ts';
import { startNats, startRooms, type NatsServer, type RoomsProcess } from './nats-helpers.ts';
import { sessionPerson, type SessionPerson } from './session-helpers.ts';
import { moveBytes, settle, sleep, stateBytes, TestClient, testJoin } from './test-helpers.ts';

const ROOT = path.resolve(import.meta.dirname, '..');
let db: Database;
let nats: NatsServer;
const procs: RoomsProcess[] = [];
const people: Person[] = [];

beforeAll(async () => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
  db = Database.fromBytes(new Uint8Array(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.mmdb'))), 'locomotion.mmdb');
  nats = await startNats();
}, 30_000);
afterEach(async () => {
  for (const p of people.splice(0)) p.session.close();
  await Promise.all(procs.splice(0).map((p) => p.stop()));
});
afterAll(async () => {
  await nats?.close();
  db?.release();
});

interface Person extends SessionPerson {
  name: string;
  mode: 'desktop' | 'vr';
}

function person(server: RoomsProcess, roomId: string, mode: 'desktop' | 'vr', name: string): Person {
  const p = { name, mode, ...sessionPerson(db, server, roomId, mode, name) };
  people.push(p);
  return p;
}

function drive(p: Person, t: number): void {
  const phase = p.name.length * 0.37;
  if (p.mode === 'desktop') {
    const u = (t + phase) % 6;
    if (u < 1.5) p.character.setMove(0, 1);
    else if (u < 3) p.character.setMove(Math.sin(t), Math.cos(t), { run: true });
    else if (u < 4.5) p.character.setMove(1, 0, { face: { x: 0, z: 1 } });
    else p.character.setMove(0, 0);
  } else {
    const a = 0.5 * t + phase;
    p.character.setTracked(2 + 1.5 * Math.sin(a), 1.5 * Math.cos(a) - 1.5, 0.75 * Math.cos(a), -0.75 * Math.sin(a), a + Math.PI / 2);
  }
}

let clock = 0;
async function run(list: Person[], frames: number): Promise<void> {
  for (let f = 0; f < frames; f++) {
    clock += 1 / 60;
    for (const p of list) {
      drive(p, clock);
      p.character.update(1 / 60);
      p.session.update(1 / 60);
    }
    await sleep(16);
  }
}

/** Largest root distance (m) and yaw error (rad) of `viewer`'s drawn copy of `sender`, matched by sender time, from trace row `from` on. */
function errors(viewer: Person, sender: Person, from = 0, to?: number): { n: number; d: number; yaw: number; first: number } {
  const id = sender.session.client.memberId;
  const sent = new Map(sender.session.trace.sent.filter((r) => r[0] === id).map((r) => [r[1], r]));
  let n = 0;
  let d = 0;
  let yaw = 0;
  let first = NaN;
  for (const s of viewer.session.trace.shown.slice(from, to)) {
    const r = sent.get(s[1]);
    if (s[0] !== id || !r) continue;
    const e = Math.hypot(s[2] - r[2], s[3] - r[3]);
    if (n === 0) first = e;
    n++;
    d = Math.max(d, e);
    yaw = Math.max(yaw, Math.abs(Math.atan2(Math.sin(s[4] - r[4]), Math.cos(s[4] - r[4]))));
  }
  return { n, d, yaw, first };
}

/** Everyone in `group` draws every other member of the group (by their current ids) and no one else. */
const allSeen = (group: Person[]) =>
  group.every((p) => {
    if (!p.session.client.memberId) return false;
    const want = group.filter((q) => q !== p).map((q) => q.session.client.memberId);
    const have = [...p.session.members.values()];
    return have.length === want.length && want.every((id) => have.some((m) => m.id === id && m.remote?.shown));
  });

describe('RoomSession across room server processes (real WASM, real NATS)', () => {
  it('desktop on A and VR on B see each other exactly; a late joiner on C is exact from its first frame; a leave is seen within 2 s', async () => {
    const [a, b, c] = await Promise.all([0, 1, 2].map(() => startRooms({ nats: nats.url })));
    procs.push(a, b, c);
    const roomId = createRoomId();
    const desk = person(a, roomId, 'desktop', 'Desk');
    const vr = person(b, roomId, 'vr', 'Headset');
    for (let k = 0; k < 600 && !allSeen([desk, vr]); k++) await run([desk, vr], 1);
    expect(allSeen([desk, vr])).toBe(true);
    // Both copies are the senders' own floats once placed by a restart or a runtime state. On a
    // loaded machine the two joins can interleave so that a copy first plays steps whose restart
    // STATE went by before its viewer was admitted (close, not exact) until the runtime state its
    // join asked for arrives: measured from when both say exact (logged).
    const exact = () => [desk, vr].every((p) => [...p.session.members.values()].every((m) => m.remote?.exact));
    const tShown = performance.now();
    for (let k = 0; k < 600 && !exact(); k++) await run([desk, vr], 1);
    console.log(`both copies exact ${(performance.now() - tShown).toFixed(0)} ms after both were shown`);
    expect(exact()).toBe(true);
    const from = new Map([desk, vr].map((p) => [p, p.session.trace.shown.length]));
    await run([desk, vr], 300);
    for (const [viewer, sender] of [
      [desk, vr],
      [vr, desk],
    ]) {
      const e = errors(viewer, sender, from.get(viewer));
      console.log(`${sender.name} (process ${sender === desk ? 'A' : 'B'}) seen on ${viewer === desk ? 'A' : 'B'}: ${e.n} messages, root error max ${(e.d * 1000).toFixed(3)} mm, yaw max ${((e.yaw * 180) / Math.PI).toFixed(4)}°`);
      expect(e.n).toBeGreaterThan(50);
      expect(e.d).toBeLessThan(0.001);
      expect(e.yaw).toBeLessThan(0.001);
    }
    const late = person(c, roomId, 'desktop', 'Late');
    const three = [desk, vr, late];
    for (let k = 0; k < 600 && !allSeen(three); k++) await run(three, 1);
    expect(allSeen(three)).toBe(true);
    await run(three, 150);
    for (const sender of [desk, vr]) {
      const e = errors(late, sender);
      const copy = [...late.session.members.values()].find((m) => m.id === sender.session.client.memberId)!.remote!;
      console.log(`late joiner on C: copy of ${sender.name}: ${e.n} messages drawn, exact ${copy.exact}, first ${(e.first * 1000).toFixed(3)} mm, max ${(e.d * 1000).toFixed(3)} mm`);
      expect(copy.exact).toBe(true);
      expect(e.n).toBeGreaterThan(20);
      expect(e.d).toBeLessThan(0.001);
      expect(e.yaw).toBeLessThan(0.001);
    }
    const gone = desk.session.client.memberId;
    const t0 = performance.now();
    desk.session.close();
    while (performance.now() - t0 < 2000 && (vr.session.members.has(gone) || late.session.members.has(gone))) await run([vr, late], 1);
    const ms = performance.now() - t0;
    console.log(`leave on A seen on B and C after ${ms.toFixed(0)} ms`);
    expect(vr.session.members.has(gone) || late.session.members.has(gone)).toBe(false);
    for (const p of three) expect(p.notes.filter((n) => !/path was stopped/.test(n))).toEqual([]);
    for (const p of [a, b, c]) for (const s of p.stats.values()) expect(s.internalErrors).toBe(0);
  }, 120_000);

  it('failover: a worker killed (SIGKILL) with members in 3 rooms; they reconnect through the same address and all see each other again, exact, within 5 s', async () => {
    const front = await startRooms({ nats: nats.url, workers: 3 });
    procs.push(front);
    const rooms = [createRoomId(), createRoomId(), createRoomId()];
    const groups: Person[][] = [[], [], []];
    // Connect one at a time, rooms interleaved, so that the round robin spreads each room over the workers.
    for (let i = 0; i < 9; i++) {
      const r = (i + Math.floor(i / 3)) % 3;
      groups[r].push(person(front, rooms[r], i % 4 === 3 ? 'vr' : 'desktop', `P${i}-r${r}`));
      await run(people, 5);
    }
    for (let k = 0; k < 900 && !groups.every(allSeen); k++) await run(people, 1);
    expect(groups.every(allSeen)).toBe(true);
    await run(people, 60);
    // The worker with the most rooms (members in all three, if the round robin spread them so).
    await sleep(300);
    const victim = [...front.stats.values()].sort((x, y) => y.rooms - x.rooms || y.members - x.members)[0];
    console.log(`workers: ${[...front.stats.values()].map((s) => `pid ${s.pid}: ${s.members} members in ${s.rooms} rooms`).join('; ')}; killing ${victim.pid}`);
    expect(victim.rooms).toBe(3);
    const traceFrom = new Map(people.map((p) => [p, p.session.trace.shown.length]));
    const t0 = performance.now();
    process.kill(victim.pid, 'SIGKILL');
    await run(people, 10);
    let seenAt = NaN;
    while (performance.now() - t0 < 15_000) {
      await run(people, 1);
      if (groups.every(allSeen)) {
        seenAt = performance.now() - t0;
        break;
      }
    }
    console.log(`after SIGKILL: everyone sees everyone again (new ids, ghosts gone) after ${seenAt.toFixed(0)} ms`);
    expect(seenAt).toBeLessThan(5000);
    // Exact again: every copy computing its sender's own floats (placed by the sender's runtime
    // state). Three members rejoining at once ask everyone for it within a second, and a member
    // sends it at most once a second, so on a loaded machine a copy may first be shown from the
    // snapshot alone — close, not exact — until the runtime state comes (docs/rooms.md).
    const allExact = () => people.every((p) => [...p.session.members.values()].every((m) => !m.remote || m.remote.exact));
    while (performance.now() - t0 < 15_000 && !allExact()) await run(people, 1);
    const exactAt = performance.now() - t0;
    console.log(`after SIGKILL: every copy exact again after ${exactAt.toFixed(0)} ms`);
    expect(allExact()).toBe(true);
    expect(exactAt).toBeLessThan(5000);
    const exactFrom = new Map(people.map((p) => [p, p.session.trace.shown.length]));
    await run(people, 120);
    const worst = (from: Map<Person, number>, to?: Map<Person, number>) => {
      let w = 0;
      let rows = 0;
      for (const g of groups)
        for (const viewer of g)
          for (const sender of g) {
            if (viewer === sender) continue;
            const e = errors(viewer, sender, from.get(viewer), to?.get(viewer));
            rows += e.n;
            w = Math.max(w, e.d, e.yaw);
          }
      return { w, rows };
    };
    const before = worst(traceFrom, exactFrom);
    const after = worst(exactFrom);
    console.log(
      `after failover: until every copy was exact ${before.rows} drawn messages, worst root/yaw error ${(before.w * 1000).toFixed(3)} mm/mrad; ` +
        `from then ${after.rows} drawn messages matched, worst ${(after.w * 1000).toFixed(3)} mm/mrad`,
    );
    // Until then a copy shown is where the snapshot put it and the sender's steps took it:
    // centimetres (up to 5.7 cm measured in room-session.test.ts, docs/rooms.md).
    expect(before.w).toBeLessThan(0.1);
    expect(after.rows).toBeGreaterThan(9 * 2 * 30);
    expect(after.w).toBeLessThan(0.001);
    expect(front.exits.some((e) => e.pid === victim.pid && e.signal === 'SIGKILL')).toBe(true);
  }, 180_000);

  it('a NATS restart: the room servers reconnect and relaying across processes resumes within 5 s', async () => {
    const [a, b] = await Promise.all([0, 1].map(() => startRooms({ nats: nats.url })));
    procs.push(a, b);
    const roomId = createRoomId();
    const m1 = await TestClient.open(a.url(roomId), a.origin);
    const m2 = await TestClient.open(b.url(roomId), b.origin);
    try {
      m1.send(encodeJoin(testJoin('m1')));
      await m1.waitFor((m) => m.type === 'welcome');
      m2.send(encodeJoin(testJoin('m2')));
      await m2.waitFor((m) => m.type === 'welcome');
      await m1.waitFor((m) => m.type === 'memberJoined');
      m1.send(stateBytes(1, 1));
      m2.send(stateBytes(1, 2));
      let seq = 1;
      // A STATE every second, as a real client sends (RoomClient's stateIntervalMs): a process
      // that lost track of a member in the outage relays its steps again only after one.
      const talk = setInterval(() => {
        seq++;
        m1.send(seq % 20 ? moveBytes(seq, 1) : stateBytes(seq, 1, false));
        m2.send(seq % 20 ? moveBytes(seq, 2) : stateBytes(seq, 2, false));
      }, 50);
      try {
        await m2.waitFor((m) => m.type === 'relay' && m.from === m1.memberId);
        await nats.stop();
        await sleep(1000);
        const before = seq;
        const t0 = performance.now();
        await nats.start();
        const resumed = (to: TestClient, from: TestClient, who: string) =>
          to.waitFor((m) => m.type === 'relay' && m.from === from.memberId && m.message.seq > before + 1, 5000, 0).catch(() => {
            throw new Error(`${who}: no relay within 5 s of NATS being up again\n${a.log()}\n${b.log()}`);
          });
        await resumed(m2, m1, 'm1 → m2');
        await resumed(m1, m2, 'm2 → m1');
        console.log(`NATS restarted: relaying across processes resumed ${(performance.now() - t0).toFixed(0)} ms after it was up again`);
        expect(performance.now() - t0).toBeLessThan(5000);
        // A newcomer after the restart gets an id of its own (the id bucket is back).
        // (JetStream, which holds the id bucket, may still be starting: the join is retried as a client does.)
        const m3 = await TestClient.joinRetrying(b.url(roomId), b.origin, 'm3', 10_000);
        expect([m1.memberId, m2.memberId]).not.toContain(m3.memberId);
        m3.ws.terminate();
      } finally {
        clearInterval(talk);
      }
      // Members stayed members through the outage (or came back): both still relay to each other.
      await settle(() => m2.relays(m1.memberId).length > 0);
    } finally {
      m1.ws.terminate();
      m2.ws.terminate();
    }
  }, 60_000);
});
