/**
 * The room server: a WebSocket endpoint at `/rooms/<id>` (ws) on any Node http/https server —
 * the vite dev server (`roomsPlugin`), the production static server, or `server/main.ts` alone.
 * On an https server it is WSS with no change.
 *
 * It relays each member's stream to the other members of its room and keeps no motion state
 * but the late-join snapshot: each member's JOIN, last STATE and last PATH (opaque, validated
 * bytes). Every message is decoded and validated by the shared protocol module
 * (`web/src/rooms/protocol.ts`) and rate limited; a client that breaks a rule is closed with a
 * code and a reason and announced as left, without touching anyone else. Nothing crosses rooms:
 * a connection belongs to the one room its URL named. docs/rooms.md has the whole contract.
 */
import type { IncomingMessage, Server as HttpServer, ServerResponse } from 'node:http';
import type { Server as HttpsServer } from 'node:https';
import type { Duplex } from 'node:stream';
import { WebSocketServer, type RawData, type WebSocket } from 'ws';
import {
  BATCH_ENTRY_BYTES,
  CloseCode,
  createRoomId,
  decodeClientMessage,
  encodeBatch,
  encodeError,
  encodeMemberJoined,
  encodeMemberLeft,
  encodeRelay,
  encodeSnapshot,
  encodeStateRequest,
  encodeWelcome,
  isRoomId,
  MAX_MESSAGE_BYTES,
  MAX_MEMBERS_LIMIT,
  ProtocolError,
  LeaveReason,
  MsgType,
  stepSeconds,
  type LeaveReasonName,
} from '../web/src/rooms/protocol.ts';
import { ContentJudge, DEFAULT_CONTENT_LIMITS, type ContentCause, type ContentLimits } from './content.ts';
import { DEFAULT_LIMITS, TokenBucket, type RateLimits } from './rate-limit.ts';
import { BusKind, encodeMembers, NatsBus, type BusMember, type NatsBusOptions } from './rooms-nats.ts';

/** The largest BATCH frame the server writes (a message alone may be larger: a STATE is ≤ 16 KB). */
const MAX_BATCH_BYTES = 64 * 1024;

export interface RoomsOptions {
  /** URL prefix; rooms live at `${path}/<id>`. Default `/rooms`. */
  path?: string;
  /** Members a room holds (1–64). Default 16. */
  maxMembers?: number;
  /**
   * Origins allowed besides the server's own (exact `scheme://host[:port]`, e.g.
   * `https://example.com`). The same origin (the Origin header's host equals the Host header) is
   * always allowed.
   */
  allowedOrigins?: readonly string[];
  /** Accept connections without an Origin header (non-browser clients). Default false. */
  allowNoOrigin?: boolean;
  /** Silence (ms) after which a member is dropped and announced as left. Default 5000. */
  idleTimeoutMs?: number;
  /**
   * Time (ms) an open connection has to send its JOIN. Default 30 000. The socket is what is
   * watched, not the page: a connection whose TCP socket closes is gone at once, but a page busy
   * loading (its main thread blocked, so it neither sends its JOIN nor — in Chromium — reads
   * pings) keeps its connection for this long.
   */
  joinTimeoutMs?: number;
  /**
   * Content checks (server/content.ts): messages a receiver would refuse are dropped and counted
   * against the sender, warned and then closed (4007). Partial limits, or false to relay
   * whatever is well-formed (tests of the receivers' own checks).
   */
  content?: Partial<ContentLimits> | false;
  /**
   * Share rooms with other processes over NATS (docs/rooms.md, "Several processes"): the server
   * URL(s) or the bus options. Without it the server runs alone.
   */
  nats?: string | NatsBusOptions;
  /** With `nats`: another process's members count as gone after this long without its presence (ms). Default 3000. */
  peerTimeoutMs?: number;
  limits?: Partial<RateLimits>;
  /** Per recipient: above this many queued bytes relays to it are skipped. Default 256 KiB. */
  softBufferBytes?: number;
  /** Per recipient: above this many queued bytes it is closed as too slow. Default 1 MiB. */
  hardBufferBytes?: number;
  /** Destroy upgrade requests outside `path` (standalone server). Default false: leave them to other listeners (vite's HMR). */
  rejectOtherUpgrades?: boolean;
  /** Connections the whole server accepts. Default 10 000. */
  maxConnections?: number;
  /** Called for notable events (drops, errors); default: nothing. */
  log?: (event: RoomsLogEvent) => void;
  /** Clock (ms) for tests. Default `performance.now`. */
  now?: () => number;
}

export interface RoomsLogEvent {
  kind: 'drop' | 'error' | 'reject' | 'bus';
  room?: string;
  member?: number;
  code?: number;
  reason: string;
}

export interface RoomsStats {
  rooms: number;
  connections: number;
  members: number;
  messagesIn: number;
  bytesIn: number;
  /** Relayed/sent messages and bytes (payload, all recipients counted). */
  messagesOut: number;
  bytesOut: number;
  /** WebSocket frames sent: a frame carries one message or a BATCH of those queued in one turn. */
  framesOut: number;
  /** Relays skipped because the recipient's queue was over `softBufferBytes`. */
  skippedSlow: number;
  /** Connections closed by the server, by close code. */
  dropped: Record<number, number>;
  /** Upgrade requests refused (bad id, origin, capacity). */
  rejected: number;
  /** Messages that arrived from a connection already dropped (read, not looked at). */
  ignoredAfterDrop: number;
  /** Handler exceptions caught (a bug, not an attack: should stay 0). */
  internalErrors: number;
  /** Messages dropped by the content checks, by cause. */
  refused: Partial<Record<ContentCause, number>>;
  /** With `nats`: members held by other processes (in rooms this process has connections in), bus messages out and in, and whether it is connected. */
  remoteMembers: number;
  busOut: number;
  busIn: number;
  /** Stream messages from another process's member this process does not know (yet): not relayed. */
  busUnknown: number;
  busConnected: boolean;
}

export interface RoomsHandle {
  readonly options: Readonly<Required<Omit<RoomsOptions, 'log' | 'limits' | 'now' | 'content' | 'nats'>>> & { limits: RateLimits; content: ContentLimits | false };
  /** With `nats`: resolves once connected to NATS (the first time). */
  readonly ready: Promise<void>;
  /** With `nats`: this process's id on the bus. */
  readonly proc: string | null;
  stats(): RoomsStats;
  /** Member ids of a room held by this process (tests, tools). */
  membersOf(roomId: string): number[];
  /** With `nats`: member ids of a room held by other processes, as this process knows them. */
  remoteMembersOf(roomId: string): number[];
  /** Stops accepting, closes every connection (1001) and detaches from the server. */
  close(): Promise<void>;
}

interface Connection {
  ws: WebSocket;
  room: Room;
  /** 0 until joined. */
  id: number;
  join: Buffer | null;
  state: Buffer | null;
  path: Buffer | null;
  lastSeq: number;
  lastTime: number;
  connectedAt: number;
  /** When its WELCOME went out, and when its page had read it (the pong to a ping sent after it; 0 before). */
  joinedAt: number;
  welcomeReadAt: number;
  lastMessageAt: number;
  messages: TokenBucket;
  bytes: TokenBucket;
  steps: TokenBucket;
  simTime: TokenBucket;
  joins: TokenBucket;
  /** Set once the server decided to drop it (left already announced). */
  gone: boolean;
  /** Its JOIN waits for the room's members from the bus or an id claim: messages meanwhile wait here. */
  joining: boolean;
  backlog: { data: RawData; isBinary: boolean }[];
  content: ContentJudge | null;
  /** Content refusals warned about (once per cause). */
  warned: Set<string>;
  /** Messages for it queued in this turn of the event loop (sent together by `flush`). */
  outbox: Uint8Array[];
  outboxBytes: number;
}

/** A member held by another process (with `nats`). */
interface RemoteMember {
  id: number;
  proc: string;
  join: Buffer;
  state: Buffer | null;
  path: Buffer | null;
}

interface Room {
  id: string;
  connections: Set<Connection>;
  members: Map<number, Connection>;
  nextId: number;
  /** With `nats`: other processes' members, the processes last heard (ms), and the first sync. */
  remote: Map<number, RemoteMember>;
  peers: Map<string, number>;
  synced: Promise<void> | null;
  resyncing: boolean;
}

const ROOMS_LIMIT_PER_ROOM_FACTOR = 2;

/**
 * Attaches the room endpoint to `server` (http or https; WSS on https). Returns a handle with
 * stats and `close()`. The HTTP side (creating room ids) is `roomsRequestHandler`.
 */
export function attachRooms(server: HttpServer | HttpsServer, options: RoomsOptions = {}): RoomsHandle {
  const o = {
    path: (options.path ?? '/rooms').replace(/\/+$/, ''),
    maxMembers: Math.max(1, Math.min(MAX_MEMBERS_LIMIT, options.maxMembers ?? 16)),
    allowedOrigins: [...(options.allowedOrigins ?? [])],
    allowNoOrigin: options.allowNoOrigin ?? false,
    idleTimeoutMs: options.idleTimeoutMs ?? 5000,
    joinTimeoutMs: options.joinTimeoutMs ?? 30_000,
    softBufferBytes: options.softBufferBytes ?? 256 * 1024,
    hardBufferBytes: options.hardBufferBytes ?? 1024 * 1024,
    rejectOtherUpgrades: options.rejectOtherUpgrades ?? false,
    maxConnections: options.maxConnections ?? 10_000,
    peerTimeoutMs: options.peerTimeoutMs ?? 3000,
    limits: { ...DEFAULT_LIMITS, ...options.limits },
    content: options.content === false ? (false as const) : { ...DEFAULT_CONTENT_LIMITS, ...options.content },
  };
  const log = options.log ?? (() => {});
  const now = options.now ?? (() => performance.now());
  const rooms = new Map<string, Room>();
  const connections = new Set<Connection>();
  const stats: RoomsStats = {
    rooms: 0,
    connections: 0,
    members: 0,
    messagesIn: 0,
    bytesIn: 0,
    messagesOut: 0,
    framesOut: 0,
    bytesOut: 0,
    skippedSlow: 0,
    dropped: {},
    rejected: 0,
    ignoredAfterDrop: 0,
    internalErrors: 0,
    refused: {},
    remoteMembers: 0,
    busOut: 0,
    busIn: 0,
    busUnknown: 0,
    busConnected: false,
  };
  const wss = new WebSocketServer({ noServer: true, maxPayload: MAX_MESSAGE_BYTES, perMessageDeflate: false, clientTracking: false });
  const allowed = new Set(o.allowedOrigins.map((s) => s.toLowerCase()));

  const internal = (where: string, e: unknown, c?: Connection) => {
    stats.internalErrors++;
    log({ kind: 'error', room: c?.room.id, member: c?.id, reason: `${where}: ${e instanceof Error ? e.message : String(e)}` });
  };

  // ---- the bus (with `nats`): other processes' members of the rooms this process has connections in
  const natsOptions: NatsBusOptions | null = options.nats === undefined || options.nats === '' ? null : typeof options.nats === 'string' ? { servers: options.nats } : options.nats;
  const bus: NatsBus | null = natsOptions
    ? new NatsBus(natsOptions, {
        message: (roomId, proc, kind, member, body) => {
          try {
            onBus(roomId, proc, kind, member, body);
          } catch (e) {
            internal('bus', e);
          }
        },
        members: (roomId) => {
          const room = rooms.get(roomId);
          const list: BusMember[] = [];
          if (room) for (const m of room.members.values()) if (!m.gone && m.join) list.push({ id: m.id, join: m.join, state: m.state, path: m.path });
          return encodeMembers(list);
        },
        status: (connected, detail) => {
          log({ kind: connected ? 'bus' : 'drop', reason: detail });
          if (!connected) return;
          // (Re)connected: enter the rooms with connections (subscriptions made before the first
          // connect, and after a restart the others learn of our members from the presence).
          for (const room of rooms.values()) {
            bus!.enter(room.id);
            publishPresence(room);
          }
        },
      })
    : null;

  const refuse = (socket: Duplex, status: number, text: string) => {
    stats.rejected++;
    log({ kind: 'reject', code: status, reason: text });
    try {
      socket.end(`HTTP/1.1 ${status} ${text}\r\nConnection: close\r\nContent-Type: text/plain\r\nContent-Length: ${Buffer.byteLength(text)}\r\n\r\n${text}`);
    } catch {
      /* already gone */
    }
    socket.destroy();
  };

  const originAllowed = (req: IncomingMessage): boolean => {
    const origin = req.headers.origin;
    if (origin === undefined) return o.allowNoOrigin;
    if (allowed.has(origin.toLowerCase())) return true;
    try {
      return new URL(origin).host.toLowerCase() === String(req.headers.host ?? '').toLowerCase();
    } catch {
      return false;
    }
  };

  const onUpgrade = (req: IncomingMessage, socket: Duplex, head: Buffer) => {
    try {
      const url = req.url ?? '';
      const pathname = url.split('?')[0];
      if (!pathname.startsWith(`${o.path}/`)) {
        if (o.rejectOtherUpgrades) refuse(socket, 404, 'Not Found');
        return;
      }
      const id = pathname.slice(o.path.length + 1);
      if (!isRoomId(id)) return refuse(socket, 400, 'Bad room id');
      if (!originAllowed(req)) return refuse(socket, 403, 'Origin not allowed');
      if (connections.size >= o.maxConnections) return refuse(socket, 503, 'Server full');
      const existing = rooms.get(id);
      if (existing && existing.connections.size >= o.maxMembers * ROOMS_LIMIT_PER_ROOM_FACTOR) return refuse(socket, 503, 'Room busy');
      // TCP keepalive: a peer that vanished without closing is found by the kernel, not by the page.
      (socket as { setKeepAlive?: (on: boolean, ms: number) => void }).setKeepAlive?.(true, 5000);
      wss.handleUpgrade(req, socket, head, (ws) => {
        try {
          accept(ws, id);
        } catch (e) {
          internal('accept', e);
          ws.terminate();
        }
      });
    } catch (e) {
      internal('upgrade', e);
      socket.destroy();
    }
  };

  /** With the bus: asks the other processes for their members of `room` and takes them in. */
  const sync = async (room: Room, announce: boolean): Promise<void> => {
    if (!bus) return;
    await bus.ready;
    if (rooms.get(room.id) !== room) return;
    bus.enter(room.id);
    const replies = await bus.members(room.id);
    if (rooms.get(room.id) !== room) return;
    let added = false;
    for (const r of replies) {
      room.peers.set(r.proc, now());
      for (const m of r.members) added = addRemote(room, r.proc, m.id, Buffer.from(m.join), announce, m.state ? Buffer.from(m.state) : null, m.path ? Buffer.from(m.path) : null) || added;
    }
    // Members that came back (after a NATS outage) need a fresh STATE from their senders.
    if (added && announce) bus.publish(room.id, BusKind.stateRequest, 0, new Uint8Array(0));
  };

  const accept = (ws: WebSocket, roomId: string) => {
    let room = rooms.get(roomId);
    if (!room) {
      room = { id: roomId, connections: new Set(), members: new Map(), nextId: 1, remote: new Map(), peers: new Map(), synced: null, resyncing: false };
      rooms.set(roomId, room);
      if (bus) {
        const r = room;
        r.synced = sync(r, false).catch((e) => internal('sync', e));
      }
    }
    const t = now();
    const l = o.limits;
    const c: Connection = {
      ws,
      room,
      id: 0,
      join: null,
      state: null,
      path: null,
      lastSeq: 0,
      lastTime: 0,
      connectedAt: t,
      joinedAt: t,
      welcomeReadAt: 0,
      lastMessageAt: t,
      messages: new TokenBucket(l.messagesPerSecond, l.messageBurst, t),
      bytes: new TokenBucket(l.bytesPerSecond, l.byteBurst, t),
      steps: new TokenBucket(l.stepsPerSecond, l.stepBurst, t),
      simTime: new TokenBucket(l.simSecondsPerSecond, l.simSecondBurst, t),
      joins: new TokenBucket(l.joinsPerSecond, l.joinBurst, t),
      gone: false,
      joining: false,
      backlog: [],
      content: o.content ? new ContentJudge(o.content, t) : null,
      warned: new Set(),
      outbox: [],
      outboxBytes: 0,
    };
    room.connections.add(c);
    connections.add(c);
    const r = room;
    ws.on('message', (data, isBinary) => {
      try {
        onMessage(c, data, isBinary);
      } catch (e) {
        internal('message', e, c);
        drop(c, CloseCode.malformed, 'internal error', 'dropped');
      }
    });
    ws.on('pong', () => {
      if (c.id !== 0 && c.welcomeReadAt === 0) c.welcomeReadAt = now();
    });
    ws.on('close', () => {
      try {
        remove(c, 'closed');
      } catch (e) {
        internal('close', e, c);
      }
    });
    ws.on('error', (e) => {
      // ws reports protocol violations (bad frames, over maxPayload) here, then closes.
      log({ kind: 'drop', room: r.id, member: c.id, code: (e as { code?: number }).code, reason: e.message });
    });
  };

  // Sends are queued per receiver and written once per turn of the event loop (setImmediate runs
  // right after the turn's I/O callbacks: no timer, no added wait). What arrived in one turn for
  // one receiver leaves as one frame — a BATCH when it is several messages. Under load a turn
  // holds many senders' messages, and a frame, not its bytes, is what costs the server a write
  // and the receiver an event (docs/rooms.md "Batches").
  const queued = new Set<Connection>();
  let flushing = false;
  const send = (c: Connection, bytes: Uint8Array) => {
    const ws = c.ws;
    if (ws.readyState !== ws.OPEN) return;
    const backlog = ws.bufferedAmount + c.outboxBytes;
    if (backlog > o.hardBufferBytes) {
      drop(c, CloseCode.tooSlow, 'too slow: send queue over limit', 'dropped');
      return;
    }
    if (backlog > o.softBufferBytes) {
      stats.skippedSlow++;
      return;
    }
    c.outbox.push(bytes);
    c.outboxBytes += bytes.length;
    queued.add(c);
    stats.messagesOut++;
    stats.bytesOut += bytes.length;
    if (!flushing) {
      flushing = true;
      setImmediate(flushAll);
    }
  };

  /** Writes what is queued for `c`: one frame per message alone, else batches of ≤ 64 KiB. */
  const flush = (c: Connection) => {
    const box = c.outbox;
    const ws = c.ws;
    queued.delete(c);
    if (box.length === 0) return;
    try {
      if (ws.readyState !== ws.OPEN) return;
      if (box.length === 1) {
        ws.send(box[0]);
        stats.framesOut++;
        return;
      }
      let from = 0;
      let bytes = 0;
      for (let i = 0; i <= box.length; i++) {
        if (i === box.length || (i > from && bytes + BATCH_ENTRY_BYTES + box[i].length > MAX_BATCH_BYTES)) {
          ws.send(i - from === 1 ? box[from] : encodeBatch(box.slice(from, i)));
          stats.framesOut++;
          from = i;
          bytes = 0;
        }
        if (i < box.length) bytes += BATCH_ENTRY_BYTES + box[i].length;
      }
    } finally {
      box.length = 0;
      c.outboxBytes = 0;
    }
  };

  const flushAll = () => {
    flushing = false;
    for (const c of queued) {
      try {
        flush(c);
      } catch (e) {
        internal('flush', e, c);
      }
    }
  };

  const broadcast = (room: Room, from: Connection | null, bytes: Uint8Array) => {
    for (const m of room.members.values()) if (m !== from && !m.gone) send(m, bytes);
  };

  const publishPresence = (room: Room) => {
    if (!bus || room.members.size === 0) return;
    const ids = [...room.members.keys()];
    bus.publish(room.id, BusKind.presence, 0, Uint8Array.from([ids.length, ...ids]));
  };

  /** Announces `c` as left (once) and forgets it. */
  const remove = (c: Connection, reason: LeaveReasonName) => {
    const room = c.room;
    const wasMember = c.id !== 0 && room.members.get(c.id) === c;
    c.gone = true;
    c.backlog.length = 0;
    if (wasMember) {
      room.members.delete(c.id);
      broadcast(room, null, encodeMemberLeft(c.id, reason));
      if (bus) {
        bus.publish(room.id, BusKind.leave, c.id, Uint8Array.of(LeaveReason[reason]));
        bus.release(room.id, c.id);
      }
    }
    room.connections.delete(c);
    connections.delete(c);
    if (room.connections.size === 0 && rooms.get(room.id) === room) {
      rooms.delete(room.id);
      bus?.leave(room.id);
    }
  };

  /** Closes `c` with a code and reason, announcing it as left now (not when the close completes). */
  const drop = (c: Connection, code: number, reason: string, leave: LeaveReasonName) => {
    if (c.gone) return;
    stats.dropped[code] = (stats.dropped[code] ?? 0) + 1;
    log({ kind: 'drop', room: c.room.id, member: c.id, code, reason });
    remove(c, leave);
    const ws = c.ws;
    try {
      if (leave === 'timeout') {
        ws.terminate(); // a silent peer would not answer a close handshake
        return;
      }
      flush(c); // what was queued for it goes first, in order
      if (ws.readyState === ws.OPEN) ws.send(encodeError(code, reason));
      ws.close(code, reason.slice(0, 120));
      // Do not wait the close handshake's 30 s for a hostile peer.
      setTimeout(() => ws.terminate(), 1000).unref();
    } catch {
      ws.terminate();
    }
  };

  /** Ids in use in the room: this process's members and (with the bus) the others'. */
  const taken = (room: Room, id: number) => room.members.has(id) || room.remote.has(id);

  const freeId = (room: Room, after = 0): number => {
    for (let k = after; k < 255; k++) {
      const id = ((room.nextId - 1 + k) % 255) + 1;
      if (!taken(room, id)) return id;
    }
    return 0;
  };

  /** Takes a member into the room under `id`: welcome, snapshots, the others told and asked for a STATE. */
  const admit = (c: Connection, id: number, join: Buffer) => {
    const room = c.room;
    room.nextId = (id % 255) + 1;
    c.id = id;
    c.joinedAt = now();
    c.join = join;
    const others = [...room.members.values()];
    const remote = [...room.remote.values()];
    room.members.set(id, c);
    send(c, encodeWelcome(id, o.maxMembers, [...others.map((m) => ({ id: m.id, join: m.join! })), ...remote.map((m) => ({ id: m.id, join: m.join }))]));
    try {
      c.ws.ping(); // answered once the member's side has read the WELCOME (frames are read in order)
    } catch {
      /* closing */
    }
    for (const m of [...others, ...remote]) if (m.state || m.path) send(c, encodeSnapshot(m.id, m.state, m.path));
    const joined = encodeMemberJoined(id, join);
    const request = encodeStateRequest();
    for (const m of others) {
      send(m, joined);
      send(m, request);
    }
    bus?.publish(room.id, BusKind.join, id, join);
  };

  /** With the bus: the room's members from the others first, then an id no process holds (an atomic KV create). */
  const joinShared = async (c: Connection, join: Buffer) => {
    const room = c.room;
    c.joining = true;
    try {
      await room.synced;
      const deadline = now() + 5000;
      let id = 0;
      for (let k = 0; !c.gone && id === 0; ) {
        if (room.members.size + room.remote.size >= o.maxMembers) return drop(c, CloseCode.roomFull, `room full (${o.maxMembers} members)`, 'dropped');
        const candidate = freeId(room, k);
        if (candidate === 0) return drop(c, CloseCode.roomFull, 'room full (no free member id)', 'dropped');
        try {
          if (await bus!.claim(room.id, candidate)) {
            if (taken(room, candidate)) bus!.release(room.id, candidate); // someone announced it meanwhile
            else id = candidate;
          }
          k++;
        } catch (e) {
          if (now() > deadline) return drop(c, CloseCode.tryAgain, `rooms bus unavailable (${e instanceof Error ? e.message : String(e)})`, 'dropped');
          await new Promise((r) => setTimeout(r, 100));
        }
      }
      if (c.gone) {
        if (id) bus!.release(room.id, id);
        return;
      }
      admit(c, id, join);
    } finally {
      c.joining = false;
    }
    // What the member sent while its JOIN waited.
    const backlog = c.backlog;
    c.backlog = [];
    for (const b of backlog) {
      if (c.gone) break;
      try {
        onMessage(c, b.data, b.isBinary);
      } catch (e) {
        internal('message', e, c);
        drop(c, CloseCode.malformed, 'internal error', 'dropped');
      }
    }
  };

  const onMessage = (c: Connection, data: RawData, isBinary: boolean) => {
    if (c.joining) {
      if (c.backlog.length >= 64) return drop(c, CloseCode.rateLimited, 'rate limit: too many messages before the welcome', 'dropped');
      c.backlog.push({ data, isBinary });
      return;
    }
    const bytes = Array.isArray(data) ? Buffer.concat(data) : Buffer.isBuffer(data) ? data : Buffer.from(data);
    stats.messagesIn++;
    stats.bytesIn += bytes.length;
    if (c.gone) {
      stats.ignoredAfterDrop++; // already in flight when it was dropped
      return;
    }
    const t = now();
    if (!c.messages.take(1, t) || !c.bytes.take(bytes.length, t)) return drop(c, CloseCode.rateLimited, 'rate limit: too many messages or bytes', 'dropped');
    if (!isBinary) return drop(c, CloseCode.malformed, 'text messages are not part of the protocol', 'dropped');
    let m: ReturnType<typeof decodeClientMessage>;
    try {
      m = decodeClientMessage(bytes);
    } catch (e) {
      if (e instanceof ProtocolError) return drop(c, e.code, e.message, 'dropped');
      throw e;
    }
    c.lastMessageAt = t;
    const room = c.room;
    if (m.type === 'join') {
      if (!c.joins.take(1, t)) return drop(c, CloseCode.rateLimited, 'rate limit: too many joins', 'dropped');
      const join = Buffer.from(bytes);
      if (c.id !== 0) {
        // A profile update (e.g. a new calibrated height, a new style): re-announced with the same
        // id; the member's runtime restarts with it (its next STATE may carry the restart bit).
        c.join = join;
        c.content?.profileChanged();
        broadcast(room, c, encodeMemberJoined(c.id, join));
        bus?.publish(room.id, BusKind.update, c.id, join);
        return;
      }
      if (bus) {
        void joinShared(c, join);
        return;
      }
      if (room.members.size >= o.maxMembers) return drop(c, CloseCode.roomFull, `room full (${o.maxMembers} members)`, 'dropped');
      admit(c, freeId(room), join);
      return;
    }
    if (c.id === 0) return drop(c, CloseCode.notJoined, 'send JOIN first', 'dropped');
    if (m.seq <= c.lastSeq) return drop(c, CloseCode.malformed, `seq ${m.seq} after ${c.lastSeq}: sequence numbers must increase`, 'dropped');
    if (c.lastSeq !== 0 && m.time < c.lastTime) return drop(c, CloseCode.malformed, `time ${m.time} ms after ${c.lastTime} ms: the simulation clock must not go back`, 'dropped');
    if (m.type === 'move' || m.type === 'tracked') {
      if (!c.steps.take(m.steps.length, t) || !c.simTime.take(stepSeconds(m), t)) return drop(c, CloseCode.rateLimited, 'rate limit: simulation steps faster than real time', 'dropped');
    }
    c.lastSeq = m.seq;
    c.lastTime = m.time;
    const bad = c.content?.judge(m);
    if (bad) {
      // Not relayed, not cached: counted against the sender, warned once per cause, closed when the count outruns the allowance.
      stats.refused[bad.cause] = (stats.refused[bad.cause] ?? 0) + 1;
      c.content!.refused++;
      if (!c.content!.strikes.take(1, t)) return drop(c, CloseCode.contentRefused, `refused content: ${bad.reason} (${c.content!.refused} refused)`, 'dropped');
      if (!c.warned.has(bad.cause)) {
        c.warned.add(bad.cause);
        send(c, encodeError(CloseCode.contentRefused, `not relayed: ${bad.reason}; more will close the connection`.slice(0, 255)));
      }
      return;
    }
    if (m.type === 'state') c.state = Buffer.from(bytes);
    else if (m.type === 'path') c.path = Buffer.from(bytes);
    broadcast(room, c, encodeRelay(c.id, bytes));
    // Published even when no other process is known in the room yet: one may be joining right
    // now, and its copies must get this member's STATEs (NATS drops what nobody subscribed to).
    bus?.publish(room.id, BusKind.stream, c.id, bytes);
  };

  // ---- messages from the other processes

  /** Adds (or updates) another process's member; true if it was new. */
  const addRemote = (room: Room, proc: string, id: number, join: Buffer, announce: boolean, state: Buffer | null = null, path: Buffer | null = null): boolean => {
    if (room.members.has(id)) {
      // Two processes gave out one id: only possible if the KV claim was bypassed (a bug).
      internal('bus', new Error(`member id ${id} in room ${room.id} is held here and by ${proc}`));
      return false;
    }
    const known = room.remote.get(id);
    if (known && known.proc === proc) {
      if (!known.join.equals(join)) {
        known.join = join;
        if (announce) broadcast(room, null, encodeMemberJoined(id, join));
      }
      known.state = state ?? known.state;
      known.path = path ?? known.path;
      return false;
    }
    if (known) removeRemote(room, known, 'closed');
    room.remote.set(id, { id, proc, join, state, path });
    if (announce) {
      broadcast(room, null, encodeMemberJoined(id, join));
      if (state || path) broadcast(room, null, encodeSnapshot(id, state, path));
    }
    return true;
  };

  const removeRemote = (room: Room, m: RemoteMember, reason: LeaveReasonName) => {
    if (room.remote.get(m.id) !== m) return;
    room.remote.delete(m.id);
    broadcast(room, null, encodeMemberLeft(m.id, reason));
  };

  const onBus = (roomId: string, proc: string, kind: number, member: number, body: Uint8Array) => {
    const room = rooms.get(roomId);
    stats.busIn++;
    if (!room) return;
    room.peers.set(proc, now());
    switch (kind) {
      case BusKind.join:
      case BusKind.update: {
        const isNew = addRemote(room, proc, member, Buffer.from(body), true);
        if (kind === BusKind.join && !isNew) {
          // A rejoin under a known id (its process restarted the member): its copies start over.
          const m = room.remote.get(member);
          if (m?.proc === proc) broadcast(room, null, encodeMemberJoined(member, m.join));
        }
        if (kind === BusKind.join) broadcast(room, null, encodeStateRequest());
        break;
      }
      case BusKind.leave: {
        const m = room.remote.get(member);
        if (m && m.proc === proc) {
          room.remote.delete(member);
          const reason = (['closed', 'timeout', 'dropped'] as const)[body[0]] ?? 'closed';
          broadcast(room, null, encodeMemberLeft(member, reason));
        }
        break;
      }
      case BusKind.stream: {
        const m = room.remote.get(member);
        if (!m || m.proc !== proc || body.length < 2) {
          stats.busUnknown++; // not announced here yet: the next presence repairs it
          break;
        }
        const bytes = Buffer.from(body);
        if (body[1] === MsgType.state) m.state = bytes;
        else if (body[1] === MsgType.path) m.path = bytes;
        else if (!m.state) {
          // No STATE of this member has reached this process yet (it entered the room after the
          // member's restart STATE went by): its steps would start copies here from nowhere,
          // close but not exact. One process keeps "a member's first message is a STATE"; so do
          // we — the STATE its join asked for comes within a second.
          stats.busUnknown++;
          break;
        }
        broadcast(room, null, encodeRelay(member, bytes));
        break;
      }
      case BusKind.presence: {
        const ids = new Set(body.subarray(1, 1 + body[0]));
        for (const m of [...room.remote.values()]) if (m.proc === proc && !ids.has(m.id)) removeRemote(room, m, 'closed');
        let unknown = false;
        for (const id of ids) if (room.remote.get(id)?.proc !== proc) unknown = true;
        if (unknown && !room.resyncing && room.members.size > 0) {
          // A join we missed (a lost message, a NATS outage): ask again.
          room.resyncing = true;
          void sync(room, true)
            .catch((e) => internal('sync', e))
            .finally(() => (room.resyncing = false));
        }
        break;
      }
      case BusKind.stateRequest:
        broadcast(room, null, encodeStateRequest());
        break;
    }
  };

  let lastSweep = now();
  const sweep = () => {
    try {
      const t = now();
      // A sweep that comes late means this process was stalled (a busy machine): what the
      // members sent meanwhile may still be unread in the sockets (timers run before I/O), so
      // nobody is judged silent this time.
      const late = t - lastSweep > 1000;
      lastSweep = t;
      for (const c of connections) {
        if (c.gone || late) continue;
        if (c.id === 0 && !c.joining) {
          if (t - c.connectedAt > o.joinTimeoutMs) drop(c, CloseCode.timeout, `no JOIN in ${o.joinTimeoutMs} ms`, 'timeout');
        } else if (c.id !== 0) {
          if (c.welcomeReadAt === 0) {
            // Its page has not read its WELCOME yet (no answer to the ping sent after it: a busy
            // page's browser reads nothing): the join timeout, not the idle one.
            if (t - c.joinedAt > o.joinTimeoutMs) drop(c, CloseCode.timeout, `welcome not read in ${o.joinTimeoutMs} ms`, 'timeout');
            continue;
          }
          // A newcomer whose stream has started may go quiet while its page loads the others'
          // avatars (long tasks starve its timers): within its first joinTimeoutMs it has that long.
          const limit = c.lastSeq > 0 && t - c.welcomeReadAt < o.joinTimeoutMs ? o.joinTimeoutMs : o.idleTimeoutMs;
          if (t - Math.max(c.lastMessageAt, c.welcomeReadAt) > limit) drop(c, CloseCode.timeout, `silent for ${limit} ms`, 'timeout');
        }
      }
      if (bus && !late) {
        for (const room of rooms.values()) {
          for (const [proc, seen] of room.peers) {
            if (t - seen <= o.peerTimeoutMs) continue;
            // Its process went silent (died, or lost NATS): its members are gone for us.
            room.peers.delete(proc);
            for (const m of [...room.remote.values()]) if (m.proc === proc) removeRemote(room, m, 'timeout');
          }
        }
      }
    } catch (e) {
      internal('sweep', e);
    }
  };
  const timer = setInterval(sweep, 250);
  timer.unref();
  let presenceTimer: ReturnType<typeof setInterval> | null = null;
  let refreshTimer: ReturnType<typeof setInterval> | null = null;
  if (bus) {
    presenceTimer = setInterval(() => {
      for (const room of rooms.values()) publishPresence(room);
    }, 1000);
    presenceTimer.unref();
    const ttl = natsOptions!.idTtlMs ?? 10_000;
    refreshTimer = setInterval(() => {
      const keys: [string, number][] = [];
      for (const room of rooms.values()) for (const id of room.members.keys()) keys.push([room.id, id]);
      void bus.refresh(keys);
    }, ttl / 3);
    refreshTimer.unref();
  }

  server.on('upgrade', onUpgrade);

  return {
    options: o,
    ready: bus ? bus.ready : Promise.resolve(),
    proc: bus?.proc ?? null,
    stats: () => {
      let members = 0;
      let remoteMembers = 0;
      for (const r of rooms.values()) {
        members += r.members.size;
        remoteMembers += r.remote.size;
      }
      return {
        ...stats,
        dropped: { ...stats.dropped },
        refused: { ...stats.refused },
        rooms: rooms.size,
        connections: connections.size,
        members,
        remoteMembers,
        busOut: bus?.stats.published ?? 0,
        busConnected: bus?.connected ?? false,
      };
    },
    membersOf: (roomId) => [...(rooms.get(roomId)?.members.keys() ?? [])],
    remoteMembersOf: (roomId) => [...(rooms.get(roomId)?.remote.keys() ?? [])],
    close: async () => {
      clearInterval(timer);
      if (presenceTimer) clearInterval(presenceTimer);
      if (refreshTimer) clearInterval(refreshTimer);
      server.off('upgrade', onUpgrade);
      for (const c of [...connections]) {
        remove(c, 'closed');
        c.ws.close(CloseCode.goingAway, 'server shutting down');
        setTimeout(() => c.ws.terminate(), 500).unref();
      }
      await new Promise<void>((resolve) => wss.close(() => resolve()));
      if (bus) {
        // Let the leaves go out before the connection closes.
        await bus.close();
      }
    },
  };
}

/**
 * Connect-style HTTP handler: `POST <path>` answers 201 `{ "id": "<22 chars>", "path": "/rooms/<id>" }`
 * (a fresh 128-bit room id; the room exists once someone joins it). Anything else: `next()`.
 * Clients may equally make ids themselves (`createRoomId`).
 */
export function roomsRequestHandler(options: { path?: string } = {}) {
  const path = (options.path ?? '/rooms').replace(/\/+$/, '');
  return (req: IncomingMessage, res: ServerResponse, next?: () => void): boolean => {
    const pathname = (req.url ?? '').split('?')[0];
    if (req.method !== 'POST' || (pathname !== path && pathname !== `${path}/`)) {
      next?.();
      return false;
    }
    const id = createRoomId();
    const body = JSON.stringify({ id, path: `${path}/${id}` });
    res.writeHead(201, { 'Content-Type': 'application/json', 'Cache-Control': 'no-store', 'Content-Length': Buffer.byteLength(body) });
    res.end(body);
    return true;
  };
}
