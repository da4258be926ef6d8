/**
 * `RoomClient`: one member's connection to a room — `/rooms/<id>` on the page's origin (ws: on
 * http, wss: on https) — that joins, sends the local `InputStream` at a fixed rate (plus a STATE
 * every second and on request), reconnects with backoff, and reports members and their streams
 * as events. Everything received is decoded by the protocol module (untrusted: a message that
 * fails to decode is dropped with a note) and joins are screened (avatar URLs outside the
 * allow-list become the built-in avatar, with a note).
 *
 * Browser-safe: no Node imports. Tests inject `createSocket` (e.g. the `ws` package).
 */
import { InputStream } from './input-stream.ts';
import {
  CloseCode,
  decodeServerMessage,
  unbatch,
  encodeJoin,
  isRoomId,
  MAX_RUNTIME_STATE_BYTES,
  ProtocolError,
  type JoinInfo,
  type LeaveReasonName,
  type MemberInfo,
  type PathMessage,
  type StateMessage,
  type StreamMessage,
} from './protocol.ts';

/** The part of the WebSocket API the client uses (the browser's and `ws`'s both fit). */
export interface WebSocketLike {
  binaryType: string;
  readonly readyState: number;
  readonly bufferedAmount: number;
  onopen: ((ev: unknown) => void) | null;
  onmessage: ((ev: { data: unknown }) => void) | null;
  onclose: ((ev: { code: number; reason: string }) => void) | null;
  onerror: ((ev: unknown) => void) | null;
  send(data: Uint8Array): void;
  close(code?: number, reason?: string): void;
}

export type RoomStatus = 'connecting' | 'open' | 'reconnecting' | 'closed';

export interface RoomClientEvents {
  status: (status: RoomStatus, detail: string) => void;
  /** Joined (again, after a reconnect: every remote avatar starts over). */
  welcome: (memberId: number, members: MemberInfo[]) => void;
  memberJoined: (member: MemberInfo) => void;
  /** A member sent a new JOIN (profile change: avatar, height…). */
  memberUpdated: (member: MemberInfo) => void;
  /** `timeout`: silent for the server's idle timeout; `dropped`: broke a rule; `closed`: left or disconnected. */
  memberLeft: (id: number, reason: LeaveReasonName) => void;
  /** A relayed stream message, with its local arrival time (ms, the client's clock). */
  stream: (from: number, message: StreamMessage, arrivalMs: number) => void;
  snapshot: (from: number, state: StateMessage | null, path: PathMessage | null) => void;
  /** Remote data refused or patched over (never passed on as it was). */
  note: (text: string) => void;
  /** The server's error message or close reason. */
  error: (code: number, reason: string) => void;
  /** Someone joined (the server asked for a fresh STATE, sent already; one with the runtime state follows within a second). */
  stateRequested: () => void;
}

export interface RoomClientOptions {
  roomId: string;
  join: JoinInfo;
  /** Full WebSocket URL; default `${ws|wss}://${location.host}/rooms/<roomId>`. */
  url?: string;
  /** Messages a second; default 20 (desktop) or 30 (VR). */
  sendHz?: number;
  /** STATE every … ms; default 1000. */
  stateIntervalMs?: number;
  /** Reconnect backoff: first delay, cap, attempts (default 500 ms, 8 s, unlimited). */
  reconnect?: { initialDelayMs?: number; maxDelayMs?: number; maxAttempts?: number };
  /**
   * Avatar URLs accepted from others: same origin as `baseUrl`, or starting with one of these
   * prefixes (absolute URLs). Others are replaced by the built-in avatar 0, with a note.
   */
  avatarAllowList?: readonly string[];
  /** The page URL that relative avatar URLs resolve against; default `location.href`. */
  baseUrl?: string;
  createSocket?: (url: string) => WebSocketLike;
  now?: () => number;
  /**
   * The local character's runtime state after its last step (`CharacterRuntime.saveState`):
   * when someone joins, a STATE carries it so every copy continues from this member's own
   * floats (docs/rooms.md, "Late joiners"). At most one a second, however many join.
   */
  runtimeState?: () => Uint8Array | null;
}

/** Shortest time between two STATEs carrying the runtime state (~4.7 KB each; the server allows 12 KB/s). */
export const RUNTIME_STATE_INTERVAL_MS = 1000;

type Listeners = { [K in keyof RoomClientEvents]: Set<RoomClientEvents[K]> };

/** Close codes after which reconnecting cannot help (a bug or an incompatible build). */
const FINAL_CODES = new Set<number>([CloseCode.malformed, CloseCode.badVersion, CloseCode.notJoined, CloseCode.contentRefused]);

export class RoomClient {
  /** The local member's outgoing stream (kept across reconnects; `LocalAvatar` records into it). */
  readonly stream: InputStream;
  status: RoomStatus = 'closed';
  memberId = 0;
  readonly members = new Map<number, MemberInfo>();
  /** Bytes and messages sent and received (payload only). */
  readonly traffic = { sentBytes: 0, sentMessages: 0, receivedBytes: 0, receivedMessages: 0 };
  private readonly o: RoomClientOptions;
  private ws: WebSocketLike | null = null;
  private readonly listeners: Listeners = {
    status: new Set(),
    welcome: new Set(),
    memberJoined: new Set(),
    memberUpdated: new Set(),
    memberLeft: new Set(),
    stream: new Set(),
    snapshot: new Set(),
    note: new Set(),
    error: new Set(),
    stateRequested: new Set(),
  };
  private sendTimer: ReturnType<typeof setInterval> | null = null;
  private retryTimer: ReturnType<typeof setTimeout> | null = null;
  private attempts = 0;
  private wanted = false;
  private lastStateAt = -Infinity;
  private lastTickAt = -Infinity;
  /** Someone joined since the last STATE with the runtime state; when that one was sent. */
  private runtimeWanted = false;
  private lastRuntimeAt = -Infinity;
  private readonly now: () => number;

  constructor(options: RoomClientOptions) {
    if (!isRoomId(options.roomId)) throw new Error(`RoomClient: "${options.roomId}" is not a room id (22 base64url characters)`);
    encodeJoin(options.join); // throws on a name, URL or database the server would refuse
    this.o = options;
    this.now = options.now ?? (() => performance.now());
    this.stream = new InputStream(this.now);
  }

  on<K extends keyof RoomClientEvents>(event: K, fn: RoomClientEvents[K]): () => void {
    (this.listeners[event] as Set<RoomClientEvents[K]>).add(fn);
    return () => (this.listeners[event] as Set<RoomClientEvents[K]>).delete(fn);
  }

  private emit<K extends keyof RoomClientEvents>(event: K, ...args: Parameters<RoomClientEvents[K]>): void {
    for (const fn of this.listeners[event]) {
      try {
        (fn as (...a: Parameters<RoomClientEvents[K]>) => void)(...args);
      } catch (e) {
        console.error(`RoomClient ${event} listener threw`, e);
      }
    }
  }

  get url(): string {
    if (this.o.url) return this.o.url;
    const loc = globalThis.location;
    if (!loc) throw new Error('RoomClient: no page location; pass options.url');
    return `${loc.protocol === 'https:' ? 'wss' : 'ws'}://${loc.host}/rooms/${this.o.roomId}`;
  }

  get sendHz(): number {
    return this.o.sendHz ?? (this.o.join.mode === 'vr' ? 30 : 20);
  }

  /** Connects (and keeps reconnecting until `close()`). */
  connect(): void {
    this.wanted = true;
    if (this.ws) return;
    this.open();
  }

  /** Leaves the room for good. */
  close(): void {
    this.wanted = false;
    if (this.retryTimer) clearTimeout(this.retryTimer);
    this.retryTimer = null;
    this.stopSending();
    const ws = this.ws;
    this.ws = null;
    if (ws) {
      ws.onclose = null;
      ws.onmessage = null;
      ws.close(CloseCode.normal, 'left');
    }
    this.dropMembers();
    this.setStatus('closed', 'closed by the page');
  }

  /** This member's profile as the room knows it (what `updateJoin` last set). */
  get join(): Readonly<JoinInfo> {
    return this.o.join;
  }

  /**
   * A new profile whose runtime restarts with it (a new style): the steps recorded so far go
   * first, then the profile, then `restart()` (the page restarts its runtime) and a STATE with
   * the restart bit — the order every member sees, so each new copy starts from the restart and
   * computes the sender's floats. Before the welcome the profile simply waits for the join.
   */
  updateJoinAndRestart(join: JoinInfo, restart: () => void): void {
    encodeJoin(join);
    this.o.join = join;
    if (!this.memberId) return;
    this.flush();
    this.sendRaw(encodeJoin(join));
    restart();
    this.stream.queueState(true);
    this.lastStateAt = this.now();
    this.flush();
  }

  /** Changes the profile (e.g. after height calibration); re-announced to the room. */
  updateJoin(join: JoinInfo): void {
    encodeJoin(join);
    this.o.join = join;
    if (this.memberId) this.sendRaw(encodeJoin(join));
  }

  private setStatus(s: RoomStatus, detail: string): void {
    this.status = s;
    this.emit('status', s, detail);
  }

  private open(): void {
    this.setStatus(this.attempts === 0 ? 'connecting' : 'reconnecting', this.url);
    let ws: WebSocketLike;
    try {
      ws = this.o.createSocket ? this.o.createSocket(this.url) : (new WebSocket(this.url) as unknown as WebSocketLike);
    } catch (e) {
      this.scheduleRetry(`cannot open: ${e instanceof Error ? e.message : String(e)}`);
      return;
    }
    this.ws = ws;
    ws.binaryType = 'arraybuffer';
    ws.onopen = () => {
      this.sendRaw(encodeJoin(this.o.join));
    };
    ws.onmessage = (ev) => this.onMessage(ev.data);
    ws.onerror = () => {};
    ws.onclose = (ev) => {
      if (this.ws !== ws) return;
      this.ws = null;
      this.memberId = 0;
      this.stopSending();
      this.dropMembers();
      if (ev.code >= 4000) this.emit('error', ev.code, ev.reason);
      if (!this.wanted) return this.setStatus('closed', ev.reason);
      if (FINAL_CODES.has(ev.code)) {
        this.wanted = false;
        return this.setStatus('closed', `closed ${ev.code}: ${ev.reason}`);
      }
      this.scheduleRetry(`closed ${ev.code}${ev.reason ? `: ${ev.reason}` : ''}`, ev.code === CloseCode.roomFull);
    };
  }

  private scheduleRetry(detail: string, slow = false): void {
    const r = this.o.reconnect ?? {};
    const max = r.maxAttempts ?? Infinity;
    if (this.attempts >= max) {
      this.wanted = false;
      this.setStatus('closed', `${detail}; gave up after ${this.attempts} attempts`);
      return;
    }
    const initial = r.initialDelayMs ?? 500;
    const cap = r.maxDelayMs ?? 8000;
    const base = slow ? cap : Math.min(cap, initial * 2 ** this.attempts);
    const delay = base * (0.5 + 0.5 * Math.random());
    this.attempts++;
    this.setStatus('reconnecting', `${detail}; retry in ${Math.round(delay)} ms`);
    this.retryTimer = setTimeout(() => {
      this.retryTimer = null;
      if (this.wanted) this.open();
    }, delay);
  }

  private dropMembers(): void {
    for (const id of [...this.members.keys()]) {
      this.members.delete(id);
      this.emit('memberLeft', id, 'closed');
    }
  }

  private screen(m: MemberInfo): MemberInfo {
    const a = m.join.avatar;
    if (a.kind === 'url' && !this.avatarAllowed(a.url)) {
      this.emit('note', `member ${m.id} (${m.join.name}): avatar ${a.url} is not same-origin or allow-listed; using the built-in avatar`);
      return { id: m.id, join: { ...m.join, avatar: { kind: 'builtin', id: 0 } } };
    }
    return m;
  }

  /** Same origin as the page, or under an allow-listed prefix. */
  avatarAllowed(url: string): boolean {
    const base = this.o.baseUrl ?? globalThis.location?.href;
    let resolved: URL;
    try {
      resolved = base ? new URL(url, base) : new URL(url);
    } catch {
      return false;
    }
    if (resolved.protocol !== 'https:' && resolved.protocol !== 'http:') return false;
    if (base && resolved.origin === new URL(base).origin) return true;
    return (this.o.avatarAllowList ?? []).some((prefix) => resolved.href.startsWith(prefix));
  }

  private onMessage(data: unknown): void {
    const t = this.now();
    if (!(data instanceof ArrayBuffer)) {
      this.emit('note', 'a non-binary message from the server was dropped');
      return;
    }
    this.traffic.receivedBytes += data.byteLength;
    let parts: Uint8Array[];
    try {
      parts = unbatch(data);
    } catch (e) {
      this.emit('note', `dropped a server frame: ${e instanceof ProtocolError ? e.message : String(e)}`);
      return;
    }
    for (const part of parts) this.onServerMessage(part, t);
  }

  private onServerMessage(data: Uint8Array, t: number): void {
    this.traffic.receivedMessages++;
    let m: ReturnType<typeof decodeServerMessage>;
    try {
      m = decodeServerMessage(data);
    } catch (e) {
      this.emit('note', `dropped a server message: ${e instanceof ProtocolError ? e.message : String(e)}`);
      return;
    }
    switch (m.type) {
      case 'welcome': {
        this.memberId = m.memberId;
        this.attempts = 0;
        this.members.clear();
        const members = m.members.map((x) => this.screen(x));
        for (const x of members) this.members.set(x.id, x);
        this.setStatus('open', `member ${m.memberId}`);
        this.emit('welcome', m.memberId, members);
        // Our stream starts over for the room: a STATE (and the path being followed) first. It
        // carries the restart bit: the page restarted its runtime on 'welcome' (RoomSession), so
        // copies restart fresh from it and compute the same floats (any other STATE places a
        // copy playing the sender's frame, close but not exact).
        this.stream.restart();
        this.stream.queueState(true);
        this.lastStateAt = t;
        this.runtimeWanted = false;
        this.flush();
        this.startSending();
        break;
      }
      case 'memberJoined': {
        const member = this.screen(m.member);
        const known = this.members.has(member.id);
        this.members.set(member.id, member);
        this.emit(known ? 'memberUpdated' : 'memberJoined', member);
        break;
      }
      case 'memberLeft':
        if (this.members.delete(m.id)) this.emit('memberLeft', m.id, m.reason);
        break;
      case 'relay':
        if (!this.members.has(m.from)) {
          this.emit('note', `a message from unknown member ${m.from} was dropped`);
          break;
        }
        this.emit('stream', m.from, m.message, t);
        break;
      case 'snapshot':
        if (this.members.has(m.from)) this.emit('snapshot', m.from, m.state, m.path);
        break;
      case 'stateRequest':
        this.runtimeWanted = true;
        this.queueState(t);
        this.flush();
        this.emit('stateRequested');
        break;
      case 'error':
        this.emit('error', m.code, m.reason);
        break;
    }
  }

  private startSending(): void {
    this.stopSending();
    this.sendTimer = setInterval(() => this.tick(), 1000 / this.sendHz);
  }

  private stopSending(): void {
    if (this.sendTimer) clearInterval(this.sendTimer);
    this.sendTimer = null;
  }

  /**
   * Sends what is due if the send timer is late (call once a frame). A page whose frames take
   * seconds (software rendering, a busy machine) can starve its timers — browsers run rendering
   * first — and a member silent for the server's idle timeout is dropped.
   */
  pump(): void {
    if (this.sendTimer && this.now() - this.lastTickAt >= 1000 / this.sendHz) this.tick();
  }

  private tick(): void {
    const t = this.now();
    this.lastTickAt = t;
    const runtimeDue = this.runtimeWanted && t - this.lastRuntimeAt >= RUNTIME_STATE_INTERVAL_MS;
    if (runtimeDue || t - this.lastStateAt >= (this.o.stateIntervalMs ?? 1000)) this.queueState(t);
    this.flush();
  }

  /** A STATE now; with the runtime state if someone is waiting for it and the interval allows. */
  private queueState(t: number): void {
    let runtime: Uint8Array | null = null;
    if (this.runtimeWanted && t - this.lastRuntimeAt >= RUNTIME_STATE_INTERVAL_MS && this.o.runtimeState) {
      this.runtimeWanted = false;
      this.lastRuntimeAt = t;
      try {
        runtime = this.o.runtimeState();
      } catch (e) {
        this.emit('note', `the runtime state could not be saved: ${String(e)}`);
      }
      if (runtime && runtime.length > MAX_RUNTIME_STATE_BYTES) {
        this.emit('note', `the runtime state is ${runtime.length} bytes (at most ${MAX_RUNTIME_STATE_BYTES}): newcomers' copies are placed from the snapshot only`);
        runtime = null;
      }
    }
    this.stream.queueState(false, runtime);
    this.lastStateAt = t;
  }

  /** Sends what the stream has queued (the send timer calls this; exposed for tests). */
  flush(): void {
    for (const bytes of this.stream.flush()) this.sendRaw(bytes);
  }

  private sendRaw(bytes: Uint8Array): void {
    const ws = this.ws;
    if (ws?.readyState !== 1) return;
    ws.send(bytes);
    this.traffic.sentBytes += bytes.length;
    this.traffic.sentMessages++;
  }
}
