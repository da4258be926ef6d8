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
import { type IncomingMessage, type Server as HttpServer, type ServerResponse } from 'node:http';
import { type Server as HttpsServer } from 'node:https';
import { type Duplex } from 'node:stream';
import { WebSocketServer, type RawData, type WebSocket } from 'ws';
import {
  CloseCode,
  createRoomId,
  decodeClientMessage,
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
  stepSeconds,
  type LeaveReasonName,
} from '../web/src/rooms/protocol.ts';
import { DEFAULT_LIMITS, TokenBucket, type RateLimits } from './rate-limit.ts';

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
  /** Time (ms) a connection has to send its JOIN. Default 5000. */
  joinTimeoutMs?: number;
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
  kind: 'drop' | 'error' | 'reject';
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
}

export interface RoomsHandle {
  readonly options: Readonly<Required<Omit<RoomsOptions, 'log' | 'limits' | 'now'>>> & { limits: RateLimits };
  stats(): RoomsStats;
  /** Member ids of a room (tests, tools). */
  membersOf(roomId: string): number[];
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
  lastMessageAt: number;
  messages: TokenBucket;
  bytes: TokenBucket;
  steps: TokenBucket;
  simTime: TokenBucket;
  joins: TokenBucket;
  /** Set once the server decided to drop it (left already announced). */
  gone: boolean;
}

interface Room {
  id: string;
  connections: Set<Connection>;
  members: Map<number, Connection>;
  nextId: number;
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
    joinTimeoutMs: options.joinTimeoutMs ?? 5000,
    softBufferBytes: options.softBufferBytes ?? 256 * 1024,
    hardBufferBytes: options.hardBufferBytes ?? 1024 * 1024,
    rejectOtherUpgrades: options.rejectOtherUpgrades ?? false,
    maxConnections: options.maxConnections ?? 10_000,
    limits: { ...DEFAULT_LIMITS, ...options.limits },
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
    bytesOut: 0,
    skippedSlow: 0,
    dropped: {},
    rejected: 0,
    ignoredAfterDrop: 0,
    internalErrors: 0,
  };
  const wss = new WebSocketServer({ noServer: true, maxPayload: MAX_MESSAGE_BYTES, perMessageDeflate: false, clientTracking: false });
  const allowed = new Set(o.allowedOrigins.map((s) => s.toLowerCase()));

  const internal = (where: string, e: unknown, c?: Connection) => {
    stats.internalErrors++;
    log({ kind: 'error', room: c?.room.id, member: c?.id, reason: `${where}: ${e instanceof Error ? e.message : String(e)}` });
  };

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

  const accept = (ws: WebSocket, roomId: string) => {
    let room = rooms.get(roomId);
    if (!room) {
      room = { id: roomId, connections: new Set(), members: new Map(), nextId: 1 };
      rooms.set(roomId, room);
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
      lastMessageAt: t,
      messages: new TokenBucket(l.messagesPerSecond, l.messageBurst, t),
      bytes: new TokenBucket(l.bytesPerSecond, l.byteBurst, t),
      steps: new TokenBucket(l.stepsPerSecond, l.stepBurst, t),
      simTime: new TokenBucket(l.simSecondsPerSecond, l.simSecondBurst, t),
      joins: new TokenBucket(l.joinsPerSecond, l.joinBurst, t),
      gone: false,
    };
    room.connections.add(c);
    connections.add(c);
    ws.on('message', (data, isBinary) => {
      try {
        onMessage(c, data, isBinary);
      } catch (e) {
        internal('message', e, c);
        drop(c, CloseCode.malformed, 'internal error', 'dropped');
      }
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
      log({ kind: 'drop', room: room.id, member: c.id, code: (e as { code?: number }).code, reason: e.message });
    });
  };

  const send = (c: Connection, bytes: Uint8Array) => {
    const ws = c.ws;
    if (ws.readyState !== ws.OPEN) return;
    const queued = ws.bufferedAmount;
    if (queued > o.hardBufferBytes) {
      drop(c, CloseCode.tooSlow, 'too slow: send queue over limit', 'dropped');
      return;
    }
    if (queued > o.softBufferBytes) {
      stats.skippedSlow++;
      return;
    }
    ws.send(bytes);
    stats.messagesOut++;
    stats.bytesOut += bytes.length;
  };

  const broadcast = (room: Room, from: Connection | null, bytes: Uint8Array) => {
    for (const m of room.members.values()) if (m !== from && !m.gone) send(m, bytes);
  };

  /** Announces `c` as left (once) and forgets it. */
  const remove = (c: Connection, reason: LeaveReasonName) => {
    const room = c.room;
    const wasMember = c.id !== 0 && room.members.get(c.id) === c;
    c.gone = true;
    if (wasMember) {
      room.members.delete(c.id);
      broadcast(room, null, encodeMemberLeft(c.id, reason));
    }
    room.connections.delete(c);
    connections.delete(c);
    if (room.connections.size === 0 && rooms.get(room.id) === room) rooms.delete(room.id);
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
      if (ws.readyState === ws.OPEN) ws.send(encodeError(code, reason));
      ws.close(code, reason.slice(0, 120));
      // Do not wait the close handshake's 30 s for a hostile peer.
      setTimeout(() => ws.terminate(), 1000).unref();
    } catch {
      ws.terminate();
    }
  };

  const onMessage = (c: Connection, data: RawData, isBinary: boolean) => {
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
    let m;
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
        // A profile update (e.g. a new calibrated height): re-announced with the same id.
        c.join = join;
        broadcast(room, c, encodeMemberJoined(c.id, join));
        return;
      }
      if (room.members.size >= o.maxMembers) return drop(c, CloseCode.roomFull, `room full (${o.maxMembers} members)`, 'dropped');
      const id = freeId(room);
      c.id = id;
      c.join = join;
      const others = [...room.members.values()];
      room.members.set(id, c);
      send(c, encodeWelcome(id, o.maxMembers, others.map((m) => ({ id: m.id, join: m.join! }))));
      for (const m of others) if (m.state || m.path) send(c, encodeSnapshot(m.id, m.state, m.path));
      const joined = encodeMemberJoined(id, join);
      const request = encodeStateRequest();
      for (const m of others) {
        send(m, joined);
        send(m, request);
      }
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
    if (m.type === 'state') c.state = Buffer.from(bytes);
    else if (m.type === 'path') c.path = Buffer.from(bytes);
    broadcast(room, c, encodeRelay(c.id, bytes));
  };

  const freeId = (room: Room): number => {
    for (let k = 0; k < 255; k++) {
      const id = ((room.nextId - 1 + k) % 255) + 1;
      if (!room.members.has(id)) {
        room.nextId = (id % 255) + 1;
        return id;
      }
    }
    throw new Error('no free member id'); // unreachable: maxMembers ≤ 64
  };

  const sweep = () => {
    try {
      const t = now();
      for (const c of connections) {
        if (c.gone) continue;
        if (c.id === 0 && t - c.connectedAt > o.joinTimeoutMs) drop(c, CloseCode.timeout, 'no JOIN in time', 'timeout');
        else if (c.id !== 0 && t - c.lastMessageAt > o.idleTimeoutMs) drop(c, CloseCode.timeout, `silent for ${o.idleTimeoutMs} ms`, 'timeout');
      }
    } catch (e) {
      internal('sweep', e);
    }
  };
  const timer = setInterval(sweep, 250);
  timer.unref();

  server.on('upgrade', onUpgrade);

  return {
    options: o,
    stats: () => {
      let members = 0;
      for (const r of rooms.values()) members += r.members.size;
      return { ...stats, dropped: { ...stats.dropped }, rooms: rooms.size, connections: connections.size, members };
    },
    membersOf: (roomId) => [...(rooms.get(roomId)?.members.keys() ?? [])],
    close: async () => {
      clearInterval(timer);
      server.off('upgrade', onUpgrade);
      for (const c of [...connections]) {
        remove(c, 'closed');
        c.ws.close(CloseCode.goingAway, 'server shutting down');
        setTimeout(() => c.ws.terminate(), 500).unref();
      }
      await new Promise<void>((resolve) => wss.close(() => resolve()));
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
