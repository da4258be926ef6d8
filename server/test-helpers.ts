/** Loopback helpers for the room server's tests: a server on 127.0.0.1:0 and a raw ws client. */
import { createServer, type Server } from 'node:http';
import type { AddressInfo } from 'node:net';
import { WebSocket } from 'ws';
import {
  createMoveStep,
  createRoomId,
  encodeState,
  quantizeTrackedStep,
  decodeServerMessage,
  unbatch,
  encodeJoin,
  encodeMove,
  quantizeMoveStep,
  CloseCode,
  type JoinInfo,
  type MoveStep,
  type ServerMessage,
} from '../web/src/rooms/protocol.ts';
import { attachRooms, roomsRequestHandler, type RoomsHandle, type RoomsOptions } from './rooms.ts';

export interface TestServer {
  server: Server;
  rooms: RoomsHandle;
  port: number;
  origin: string;
  url(roomId: string): string;
  close(): Promise<void>;
}

export async function startServer(options: RoomsOptions = {}): Promise<TestServer> {
  const handler = roomsRequestHandler();
  const server = createServer((req, res) => {
    if (!handler(req, res)) {
      res.writeHead(404);
      res.end();
    }
  });
  const rooms = attachRooms(server, { rejectOtherUpgrades: true, ...options });
  await new Promise<void>((resolve) => server.listen(0, '127.0.0.1', resolve));
  const port = (server.address() as AddressInfo).port;
  return {
    server,
    rooms,
    port,
    origin: `http://127.0.0.1:${port}`,
    url: (id) => `ws://127.0.0.1:${port}/rooms/${id}`,
    close: async () => {
      await rooms.close();
      server.closeAllConnections();
      await new Promise<void>((resolve) => server.close(() => resolve()));
    },
  };
}

export const testJoin = (name: string, extra: Partial<JoinInfo> = {}): JoinInfo => ({
  name,
  avatar: { kind: 'builtin', id: 0 },
  database: 'locomotion',
  height: 0,
  mode: 'desktop',
  devices: { keyboard: true },
  style: 'neutral',
  ...extra,
});

export function moveBytes(seq: number, rootX: number, steps = 3): Uint8Array {
  const s: MoveStep[] = [];
  for (let i = 0; i < steps; i++) s.push(quantizeMoveStep({ ...createMoveStep(), ticks: 120, moveX: 0, moveZ: 1 }));
  return encodeMove({ seq, time: seq * 50, rootX, rootZ: 0, rootYaw: 0, steps: s });
}

/**
 * A member's first message as `RoomClient` sends it (the protocol's contract: a restart STATE
 * first, so receivers never start blind). Across processes a member's steps are relayed only
 * after a STATE of it (docs/rooms.md, "Several processes").
 */
export function stateBytes(seq: number, rootX: number, restart = true): Uint8Array {
  const move = quantizeMoveStep({ ...createMoveStep(), moveX: 0, moveZ: 1 });
  const tracked = quantizeTrackedStep({ ticks: 0, headX: rootX, headZ: 0, velocityX: 0, velocityZ: 0, yaw: 0, body: false, hipsDrop: 0, bend: 0 });
  return encodeState({ seq, time: seq * 50, frame: 1, rootX, rootZ: 0, rootYaw: 0, drive: 'move', pathTime: 0, scale: 1, alpha: 0.2, move, tracked, restart });
}

/** A raw client: every server message decoded (undecodable ones recorded as errors). */
export class TestClient {
  readonly messages: ServerMessage[] = [];
  readonly decodeErrors: string[] = [];
  /** WebSocket frames received (a BATCH is one frame of several messages). */
  frames = 0;
  closed: { code: number; reason: string; at: number } | null = null;
  memberId = 0;
  private waiters: (() => void)[] = [];

  private constructor(readonly ws: WebSocket) {
    ws.binaryType = 'nodebuffer';
    ws.on('message', (data: Buffer) => {
      try {
        this.frames++;
        for (const part of unbatch(new Uint8Array(data.buffer, data.byteOffset, data.byteLength))) {
          const m = decodeServerMessage(part);
          if (m.type === 'welcome') this.memberId = m.memberId;
          this.messages.push(m);
        }
      } catch (e) {
        this.decodeErrors.push(String(e));
      }
      this.wake();
    });
    ws.on('close', (code, reason) => {
      this.closed = { code, reason: reason.toString(), at: performance.now() };
      this.wake();
    });
    ws.on('error', () => {});
  }

  private wake(): void {
    const w = this.waiters;
    this.waiters = [];
    for (const f of w) f();
  }

  static open(url: string, origin: string | undefined): Promise<TestClient> {
    return new Promise((resolve, reject) => {
      const ws = new WebSocket(url, origin === undefined ? {} : { origin });
      ws.once('open', () => resolve(new TestClient(ws)));
      ws.once('unexpected-response', (_req, res) => {
        reject(new Error(`HTTP ${res.statusCode}`));
        ws.terminate();
      });
      ws.once('error', reject);
    });
  }

  /** Opens, joins, and waits for the welcome. */
  static async join(server: TestServer, roomId: string, name: string, extra: Partial<JoinInfo> = {}): Promise<TestClient> {
    const c = await TestClient.open(server.url(roomId), server.origin);
    c.send(encodeJoin(testJoin(name, extra)));
    await c.waitFor((m) => m.type === 'welcome');
    return c;
  }

  /**
   * Opens `url`, joins as `name` and waits for the welcome; a close with "try again" (1013: the
   * rooms bus or its id bucket not ready yet, e.g. JetStream electing after a NATS start) is
   * answered as the room client answers it — join again — until `ms` is spent. `made` receives
   * every socket opened (to close them after the test).
   */
  static async joinRetrying(url: string, origin: string, name: string, ms: number, made: (c: TestClient) => void = () => {}): Promise<TestClient> {
    const deadline = performance.now() + ms;
    for (;;) {
      const c = await TestClient.open(url, origin);
      made(c);
      c.send(encodeJoin(testJoin(name)));
      const left = Math.max(0, deadline - performance.now());
      const welcomed = c.waitFor((m) => m.type === 'welcome', left).then(() => true as const);
      const closed = c.waitClosed(left).then((x) => x.code);
      welcomed.catch(() => {});
      closed.catch(() => {});
      const got = await Promise.race([welcomed, closed]);
      if (got === true) return c;
      if (got !== CloseCode.tryAgain || performance.now() > deadline) throw new Error(`${name}: closed ${got} before its welcome`);
      await new Promise((r) => setTimeout(r, 200));
    }
  }

  send(bytes: Uint8Array | string): void {
    if (this.ws.readyState === this.ws.OPEN) this.ws.send(bytes);
  }

  /**
   * Resolves with the first message (from `from` on) matching `pred`; rejects after `ms`. The
   * default is generous (a CI machine running suites side by side delays NATS and JetStream by
   * seconds); a test that times something passes its own bound.
   */
  waitFor(pred: (m: ServerMessage) => boolean, ms = 10_000, from = 0): Promise<ServerMessage> {
    return new Promise((resolve, reject) => {
      const deadline = setTimeout(() => reject(new Error(`timed out after ${ms} ms waiting for a message`)), ms);
      const check = () => {
        const m = this.messages.slice(from).find(pred);
        if (m) {
          clearTimeout(deadline);
          resolve(m);
        } else this.waiters.push(check);
      };
      check();
    });
  }

  waitClosed(ms = 10_000): Promise<{ code: number; reason: string; at: number }> {
    return new Promise((resolve, reject) => {
      const deadline = setTimeout(() => reject(new Error(`not closed after ${ms} ms`)), ms);
      const check = () => {
        if (this.closed) {
          clearTimeout(deadline);
          resolve(this.closed);
        } else this.waiters.push(check);
      };
      check();
    });
  }

  relays(from?: number) {
    return this.messages.flatMap((m) => (m.type === 'relay' && (from === undefined || m.from === from) ? [m] : []));
  }

  close(): void {
    this.ws.close();
  }
}

export const sleep = (ms: number) => new Promise((r) => setTimeout(r, ms));

/**
 * Waits until `done()` holds, polling every 20 ms, at most `ms` (then returns; the test's own
 * assertions say what is missing). A fixed sleep is a race on a loaded machine.
 */
export async function settle(done: () => boolean, ms = 10_000): Promise<void> {
  const end = performance.now() + ms;
  while (!done() && performance.now() < end) await sleep(20);
}
export { createRoomId };
