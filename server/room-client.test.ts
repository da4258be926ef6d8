/** RoomClient + LocalAvatar + RemoteAvatar against the real room server on loopback. */
import { afterEach, describe, expect, it } from 'vitest';
import { WebSocket } from 'ws';
import { LocalAvatar } from '../web/src/rooms/local-avatar.ts';
import { CloseCode, type JoinInfo } from '../web/src/rooms/protocol.ts';
import { RemoteAvatar } from '../web/src/rooms/remote-avatar.ts';
import { RoomClient, type WebSocketLike } from '../web/src/rooms/room-client.ts';
import { TestCharacter } from '../web/src/rooms/testing.ts';
import { createRoomId, sleep, startServer, testJoin, type TestServer } from './test-helpers.ts';

let server: TestServer | null = null;
const clients: RoomClient[] = [];
afterEach(async () => {
  for (const c of clients.splice(0)) c.close();
  await server?.close();
  server = null;
});

interface Peer {
  client: RoomClient;
  sockets: WebSocket[];
  remotes: Map<number, { avatar: RemoteAvatar; character: TestCharacter }>;
  events: string[];
  notes: string[];
}

function peer(roomId: string, join: JoinInfo, extra: Partial<ConstructorParameters<typeof RoomClient>[0]> = {}): Peer {
  const sockets: WebSocket[] = [];
  const client = new RoomClient({
    roomId,
    join,
    url: server!.url(roomId),
    baseUrl: `${server!.origin}/index.html`,
    reconnect: { initialDelayMs: 50, maxDelayMs: 200 },
    createSocket: (url) => {
      const ws = new WebSocket(url, { origin: server!.origin });
      sockets.push(ws);
      return ws as unknown as WebSocketLike;
    },
    ...extra,
  });
  clients.push(client);
  const p: Peer = { client, sockets, remotes: new Map(), events: [], notes: [] };
  const add = (id: number) => {
    const character = new TestCharacter();
    p.remotes.set(id, { avatar: new RemoteAvatar(character), character });
  };
  client.on('welcome', (id, members) => {
    p.events.push(`welcome ${id} [${members.map((m) => m.id).join(',')}]`);
    p.remotes.clear();
    for (const m of members) add(m.id);
  });
  client.on('memberJoined', (m) => {
    p.events.push(`joined ${m.id}`);
    add(m.id);
  });
  client.on('memberLeft', (id, reason) => {
    p.events.push(`left ${id} ${reason}`);
    p.remotes.delete(id);
  });
  client.on('stream', (from, m, t) => p.remotes.get(from)?.avatar.receive(m, t));
  client.on('snapshot', (from, state, path) => p.remotes.get(from)?.avatar.applySnapshot(state, path));
  client.on('note', (n) => p.notes.push(n));
  client.connect();
  return p;
}

async function until(pred: () => boolean, ms = 3000) {
  const t0 = performance.now();
  while (!pred()) {
    if (performance.now() - t0 > ms) throw new Error('condition not met in time');
    await sleep(10);
  }
}

describe('RoomClient on the room server', () => {
  it('two members and a late joiner: remote avatars replay the sender exactly / converge', async () => {
    server = await startServer();
    const room = createRoomId();
    const b = peer(room, testJoin('b'));
    await until(() => b.client.status === 'open');
    const a = peer(room, testJoin('a'));
    await until(() => a.client.status === 'open' && b.remotes.has(a.client.memberId));
    const me = new TestCharacter();
    const local = new LocalAvatar(me, a.client.stream);
    let c: Peer | null = null;
    // 2 s of 60 Hz frames on A (walking a curve, running half the time); B and C play every frame.
    const t0 = performance.now();
    let last = t0;
    while (performance.now() - t0 < 2000) {
      await sleep(16);
      const now = performance.now();
      const t = (now - t0) / 1000;
      local.setMove({ moveX: Math.sin(t), moveZ: Math.cos(t), faceX: 0, faceZ: 1, run: t > 1, strafe: false });
      local.update((now - last) / 1000);
      last = now;
      if (!c && t > 0.8) c = peer(room, testJoin('c'));
      for (const p of [b, c]) for (const r of p?.remotes.values() ?? []) r.avatar.update(now, 1 / 60);
    }
    // A stops; everything it sent plays out.
    a.client.flush();
    const end = performance.now();
    while (performance.now() - end < 2500) {
      await sleep(16);
      const now = performance.now();
      for (const p of [b, c!]) for (const r of p.remotes.values()) r.avatar.update(now, 1 / 60);
    }
    const atB = b.remotes.get(a.client.memberId)!;
    expect(atB.character.updates).toBe(me.updates);
    expect(atB.character.rootX).toBe(me.rootX); // exact replay over a real socket
    expect(atB.character.rootZ).toBe(me.rootZ);
    expect(Math.hypot(me.rootX, me.rootZ)).toBeGreaterThan(1);
    const atC = c!.remotes.get(a.client.memberId)!;
    expect(c!.events[0]).toMatch(/^welcome \d+ \[\d+,\d+\]$/);
    expect(atC.avatar.ready).toBe(true);
    expect(atC.character.updates).toBeLessThan(me.updates); // it joined late…
    expect(Math.hypot(atC.character.displayX - me.rootX, atC.character.displayZ - me.rootZ)).toBeLessThan(0.0015); // …and shows A where A is
    expect(a.client.traffic.sentMessages).toBeGreaterThan(20); // ~40 at 20 Hz; fewer on a loaded machine
  });

  it('reconnects after a dropped connection: a new member id, announced left and joined', async () => {
    server = await startServer();
    const room = createRoomId();
    const b = peer(room, testJoin('b'));
    const a = peer(room, testJoin('a'));
    await until(() => a.client.status === 'open' && b.client.status === 'open' && b.remotes.size === 1);
    const firstId = a.client.memberId;
    const statuses: string[] = [];
    a.client.on('status', (s) => statuses.push(s));
    a.sockets[0].terminate(); // the network drops
    await until(() => a.client.status === 'open' && a.client.memberId !== 0 && a.client.memberId !== firstId);
    await until(() => b.remotes.has(a.client.memberId));
    expect(statuses).toEqual(['reconnecting', 'reconnecting', 'open']);
    expect(b.events).toContain(`left ${firstId} closed`);
    expect(b.events.at(-1)).toBe(`joined ${a.client.memberId}`);
    expect(a.sockets).toHaveLength(2);
  });

  it('screens avatar URLs: same origin and allow-listed pass, others become the built-in avatar with a note', async () => {
    server = await startServer();
    const room = createRoomId();
    const watcher = peer(room, testJoin('w'), { avatarAllowList: ['https://cdn.example/avatars/'] });
    await until(() => watcher.client.status === 'open');
    const urls = ['/avatars/ok.vrm', 'https://cdn.example/avatars/ok.glb', 'https://evil.example/x.vrm', 'https://cdn.example/other/x.vrm'];
    for (const [i, url] of urls.entries()) peer(room, testJoin(`p${i}`, { avatar: { kind: 'url', url } }));
    await until(() => watcher.client.members.size === 4);
    const byName = new Map([...watcher.client.members.values()].map((m) => [m.join.name, m.join.avatar]));
    expect(byName.get('p0')).toEqual({ kind: 'url', url: '/avatars/ok.vrm' });
    expect(byName.get('p1')).toEqual({ kind: 'url', url: 'https://cdn.example/avatars/ok.glb' });
    expect(byName.get('p2')).toEqual({ kind: 'builtin', id: 0 });
    expect(byName.get('p3')).toEqual({ kind: 'builtin', id: 0 });
    expect(watcher.notes.filter((n) => /not same-origin or allow-listed/.test(n))).toHaveLength(2);
  });

  it('a full room: the client reports the error and, out of attempts, stops', async () => {
    server = await startServer({ maxMembers: 1 });
    const room = createRoomId();
    const first = peer(room, testJoin('first'));
    await until(() => first.client.status === 'open');
    const errors: number[] = [];
    const second = peer(room, testJoin('second'), { reconnect: { maxAttempts: 0 } });
    second.client.on('error', (code) => errors.push(code));
    await until(() => second.client.status === 'closed');
    expect(errors).toContain(CloseCode.roomFull);
    expect(first.client.members.size).toBe(0);
  });

  it('refuses bad room ids and joins before opening anything', () => {
    expect(() => new RoomClient({ roomId: '../x', join: testJoin('a') })).toThrow(/room id/);
    expect(() => new RoomClient({ roomId: createRoomId(), join: testJoin('a\u0000') })).toThrow(/control/);
  });
});
