/**
 * The room servers' bus: core NATS between room server processes (docs/rooms.md, "Several
 * processes"). This module is only the transport — a connection, a subject per room, a
 * request/reply for the room's current members and a JetStream KV bucket for member ids; what
 * the messages mean is `attachRooms`'s (server/rooms.ts).
 *
 * - `<prefix>.room.<id>`: every message about the room (joins, leaves, profile updates, each
 *   validated stream message, presence). Core NATS, at-most-once: receivers already survive a
 *   lost message (jitter buffer, drift correction), and a lost join or leave is repaired by the
 *   next presence (once a second).
 * - `<prefix>.sync.<id>`: a process that gets its first connection in a room asks the processes
 *   that hold members for them (JOIN, last STATE, last PATH) with a request/reply — the state
 *   stays with the process that holds the member, always fresh, nothing to expire.
 * - KV bucket `<prefix>-ids`, key `<room>.<member id>`: a member id is claimed with an atomic
 *   create, so two processes never give out the same id in a room; refreshed while the member
 *   is connected, it expires (TTL) when its process dies.
 *
 * Message layout: `u8 kind, u8 procLen, proc (ASCII), u8 member` + body.
 */
import { connect, type NatsConnection, type Subscription } from '@nats-io/transport-node';
import { Kvm, type KV } from '@nats-io/kv';

export const BusKind = {
  /** A new member (body: JOIN bytes): receivers announce it and ask their members for a STATE. */
  join: 1,
  /** A profile update (body: JOIN bytes). */
  update: 2,
  /** body: u8 leave reason (0 closed, 1 timeout, 2 dropped). */
  leave: 3,
  /** body: the member's validated stream message (MOVE/TRACKED/PATH/STATE), byte for byte. */
  stream: 4,
  /** body: u8 count + the sender process's member ids in the room (member byte 0). */
  presence: 5,
  /** Receivers ask their members for a STATE (member byte 0). */
  stateRequest: 6,
} as const;

export interface NatsBusOptions {
  /** NATS server URL(s), e.g. `nats://127.0.0.1:4222` or several (a cluster), comma-separated or a list. */
  servers: string | readonly string[];
  /** Subject and bucket prefix (several deployments on one NATS). Default `mmrooms`. */
  prefix?: string;
  /** A member id's claim lives this long without a refresh (ms). Default 10 000. */
  idTtlMs?: number;
  /** KV bucket replicas (1, 3 or 5; 3 on a NATS cluster keeps ids through a NATS node's loss). Default 1. */
  kvReplicas?: number;
}

export interface BusHandler {
  /** A message from another process about a room this process has entered. */
  message(roomId: string, proc: string, kind: number, member: number, body: Uint8Array): void;
  /** Another process asks for this process's members of `roomId` (encoded by `encodeMembers`). */
  members(roomId: string): Uint8Array;
  /** Connected (again) or lost. */
  status(connected: boolean, detail: string): void;
}

export interface BusMember {
  id: number;
  join: Uint8Array;
  state: Uint8Array | null;
  path: Uint8Array | null;
}

const enc = new TextEncoder();
const dec = new TextDecoder();

/** `u8 count` × `{u8 id, u16 joinLen, join, u16 stateLen, state, u16 pathLen, path}`. */
export function encodeMembers(members: readonly BusMember[]): Uint8Array {
  let size = 1;
  for (const m of members) size += 7 + m.join.length + (m.state?.length ?? 0) + (m.path?.length ?? 0);
  const out = new Uint8Array(size);
  const v = new DataView(out.buffer);
  out[0] = members.length;
  let o = 1;
  const put = (b: Uint8Array | null) => {
    v.setUint16(o, b?.length ?? 0, true);
    o += 2;
    if (b) out.set(b, o);
    o += b?.length ?? 0;
  };
  for (const m of members) {
    out[o++] = m.id;
    put(m.join);
    put(m.state);
    put(m.path);
  }
  return out;
}

/** The inverse of `encodeMembers`; throws on truncated bytes (another process's bug). */
export function decodeMembers(b: Uint8Array): BusMember[] {
  const v = new DataView(b.buffer, b.byteOffset, b.byteLength);
  const n = b[0] ?? 0;
  let o = 1;
  const take = () => {
    const len = v.getUint16(o, true);
    o += 2;
    if (o + len > b.length) throw new Error('members: truncated');
    const s = b.slice(o, o + len);
    o += len;
    return s;
  };
  const members: BusMember[] = [];
  for (let i = 0; i < n; i++) {
    if (o >= b.length) throw new Error('members: truncated');
    const id = b[o++];
    const join = take();
    const state = take();
    const path = take();
    members.push({ id, join, state: state.length ? state : null, path: path.length ? path : null });
  }
  return members;
}

export class NatsBus {
  /** This process's id on the bus (random). */
  readonly proc: string;
  readonly prefix: string;
  connected = false;
  /** Messages published and received, and replies to member requests sent. */
  readonly stats = { published: 0, publishedBytes: 0, received: 0, receivedBytes: 0, skippedDisconnected: 0, errors: 0 };
  private nc: NatsConnection | null = null;
  private kv: Promise<KV> | null = null;
  private readonly subs = new Map<string, Subscription[]>();
  private readonly header: Uint8Array;
  private closed = false;
  readonly ready: Promise<void>;

  constructor(
    private readonly o: NatsBusOptions,
    private readonly handler: BusHandler,
  ) {
    const bytes = crypto.getRandomValues(new Uint8Array(6));
    this.proc = Buffer.from(bytes).toString('base64url');
    this.prefix = o.prefix ?? 'mmrooms';
    if (!/^[A-Za-z0-9_-]{1,32}$/.test(this.prefix)) throw new Error(`rooms NATS prefix "${this.prefix}": 1–32 of [A-Za-z0-9_-]`);
    const p = enc.encode(this.proc);
    this.header = new Uint8Array(2 + p.length);
    this.header[1] = p.length;
    this.header.set(p, 2);
    this.ready = this.start();
    this.ready.catch(() => {});
  }

  private async start(): Promise<void> {
    const servers = typeof this.o.servers === 'string' ? this.o.servers.split(',').map((s) => s.trim()).filter(Boolean) : [...this.o.servers];
    const nc = await connect({
      servers,
      name: `mm-rooms ${this.proc}`,
      // Never give up: a NATS restart must not end the rooms' relaying (docs/rooms.md, Failover).
      maxReconnectAttempts: -1,
      reconnectTimeWait: 250,
      reconnectJitter: 100,
      waitOnFirstConnect: true,
      // Our own messages are not for us.
      noEcho: true,
      pingInterval: 2000,
      maxPingOut: 2,
    });
    if (this.closed) {
      await nc.close();
      return;
    }
    this.nc = nc;
    this.connected = true;
    this.handler.status(true, `connected to ${nc.getServer()}`);
    void (async () => {
      for await (const s of nc.status()) {
        if (s.type === 'disconnect') {
          this.connected = false;
          this.handler.status(false, `NATS disconnected (${String((s as { server?: string }).server ?? '')})`);
        } else if (s.type === 'reconnect') {
          this.connected = true;
          this.kv = null; // the bucket may be gone with a restarted server: opened (or made) again
          this.handler.status(true, `NATS reconnected (${String((s as { server?: string }).server ?? '')})`);
        }
      }
    })().catch(() => {});
  }

  private subject(kind: 'room' | 'sync', roomId: string): string {
    return `${this.prefix}.${kind}.${roomId}`;
  }

  /** Subscribes to a room's messages and member requests (while this process has connections in it). */
  enter(roomId: string): void {
    if (!this.nc || this.subs.has(roomId)) return;
    const nc = this.nc;
    const room = nc.subscribe(this.subject('room', roomId), {
      callback: (err, msg) => {
        if (err) return;
        const b = msg.data;
        this.stats.received++;
        this.stats.receivedBytes += b.length;
        try {
          const procLen = b[1];
          const proc = dec.decode(b.subarray(2, 2 + procLen));
          this.handler.message(roomId, proc, b[0], b[2 + procLen], b.subarray(3 + procLen));
        } catch {
          this.stats.errors++;
        }
      },
    });
    const sync = nc.subscribe(this.subject('sync', roomId), {
      callback: (err, msg) => {
        if (err) return;
        try {
          const body = this.handler.members(roomId);
          const out = new Uint8Array(this.header.length + body.length);
          out.set(this.header);
          out.set(body, this.header.length);
          msg.respond(out);
        } catch {
          this.stats.errors++;
        }
      },
    });
    this.subs.set(roomId, [room, sync]);
  }

  leave(roomId: string): void {
    for (const s of this.subs.get(roomId) ?? []) s.unsubscribe();
    this.subs.delete(roomId);
  }

  /** Whether this process has entered the room (subscribed). */
  entered(roomId: string): boolean {
    return this.subs.has(roomId);
  }

  publish(roomId: string, kind: number, member: number, body: Uint8Array): void {
    const nc = this.nc;
    if (!nc || !this.connected) {
      // While NATS is away the client would buffer and deliver late: old motion is worth nothing.
      this.stats.skippedDisconnected++;
      return;
    }
    const out = new Uint8Array(this.header.length + 1 + body.length);
    out.set(this.header);
    out[0] = kind;
    out[this.header.length] = member;
    out.set(body, this.header.length + 1);
    try {
      nc.publish(this.subject('room', roomId), out);
      this.stats.published++;
      this.stats.publishedBytes += out.length;
    } catch {
      this.stats.errors++;
    }
  }

  /**
   * The members the other processes hold in `roomId`: one reply per process, gathered until
   * replies stop coming for `stallMs` (none at all: NATS answers "no responders" at once).
   */
  async members(roomId: string, stallMs = 50, maxWaitMs = 1000): Promise<{ proc: string; members: BusMember[] }[]> {
    const nc = this.nc;
    if (!nc || !this.connected) return [];
    const out: { proc: string; members: BusMember[] }[] = [];
    try {
      const replies = await nc.requestMany(this.subject('sync', roomId), new Uint8Array(0), { strategy: 'stall', stall: stallMs, maxWait: maxWaitMs });
      for await (const m of replies) {
        const b = m.data;
        if (b.length < 2) continue;
        const procLen = b[1];
        out.push({ proc: dec.decode(b.subarray(2, 2 + procLen)), members: decodeMembers(b.subarray(2 + procLen)) });
      }
    } catch {
      // no responders (nobody else has the room) or NATS went away: what came is what there is
    }
    return out;
  }

  private bucket(): Promise<KV> {
    if (!this.nc) return Promise.reject(new Error('NATS not connected'));
    if (!this.kv) {
      const kv = new Kvm(this.nc).create(`${this.prefix}-ids`, { ttl: this.o.idTtlMs ?? 10_000, history: 1, storage: 'memory', replicas: this.o.kvReplicas ?? 1 });
      this.kv = kv;
      kv.catch(() => {
        if (this.kv === kv) this.kv = null;
      });
    }
    return this.kv;
  }

  /** Claims `<room>.<id>` for this process: true if it was free, false if another holds it; throws when NATS or JetStream is unavailable. */
  async claim(roomId: string, id: number): Promise<boolean> {
    if (!this.connected) throw new Error('NATS not connected');
    const kv = await this.bucket();
    try {
      await kv.create(`${roomId}.${id}`, enc.encode(this.proc));
      return true;
    } catch (e) {
      if (/wrong last sequence|key exists/i.test(String((e as Error)?.message))) return false;
      this.kv = null;
      throw e;
    }
  }

  /** Keeps claims alive (and puts them back after a NATS restart that lost the bucket). */
  async refresh(keys: readonly [string, number][]): Promise<void> {
    if (!this.connected || keys.length === 0) return;
    try {
      const kv = await this.bucket();
      await Promise.all(keys.map(([room, id]) => kv.put(`${room}.${id}`, enc.encode(this.proc))));
    } catch {
      this.kv = null;
    }
  }

  release(roomId: string, id: number): void {
    if (!this.connected) return;
    void this.bucket()
      .then((kv) => kv.delete(`${roomId}.${id}`))
      .catch(() => {});
  }

  async close(): Promise<void> {
    this.closed = true;
    const nc = this.nc;
    this.nc = null;
    this.connected = false;
    if (nc) await nc.close().catch(() => {});
  }
}
