/**
 * The decoders on 200,000 mutated and random inputs: they either return a message whose every
 * number is finite and in range, or throw a ProtocolError — never another exception, never a
 * half-decoded value.
 */
import { expect, it } from 'vitest';
import {
  createMoveStep,
  decodeClientMessage,
  decodeServerMessage,
  encodeJoin,
  encodeMemberJoined,
  encodeMove,
  encodePath,
  encodeRelay,
  encodeSnapshot,
  encodeState,
  encodeTracked,
  encodeWelcome,
  encodeBatch,
  MAX_PATH_COORD,
  PROTOCOL_VERSION,
  ProtocolError,
  quantizeMoveStep,
  unbatch,
  quantizeTrackedStep,
  type ClientMessage,
} from './protocol.ts';
import { seededRandom } from '../bench/queries.ts';

function finiteEverywhere(v: unknown): boolean {
  if (typeof v === 'number') return Number.isFinite(v);
  if (v instanceof Float32Array) return v.every(Number.isFinite);
  if (Array.isArray(v)) return v.every(finiteEverywhere);
  if (v && typeof v === 'object') return Object.values(v).every(finiteEverywhere);
  return true;
}

function checkClient(m: ClientMessage): void {
  expect(finiteEverywhere(m)).toBe(true);
  if (m.type === 'move') for (const s of m.steps) expect(Math.hypot(s.moveX, s.moveZ)).toBeLessThanOrEqual(1.0001);
  if (m.type === 'move' || m.type === 'tracked') for (const s of m.steps) expect(s.ticks >= 1 && s.ticks <= 1800).toBe(true);
  if (m.type === 'path') for (const p of m.points) expect(Math.abs(p)).toBeLessThanOrEqual(MAX_PATH_COORD);
  if (m.type === 'tracked' || m.type === 'state') expect(m.scale >= 0.1 && m.scale <= 10).toBe(true);
}

it('200,000 mutated or random inputs: a valid message or a ProtocolError, nothing else', () => {
  const rand = seededRandom(99);
  const int = (n: number) => Math.floor(rand() * n);
  const step = quantizeMoveStep({ ...createMoveStep(), ticks: 120, moveX: 0.3, moveZ: 0.9 });
  const tracked = quantizeTrackedStep({ ticks: 80, headX: 1, headZ: 2, velocityX: 1, velocityZ: 0, yaw: 1, body: false, hipsDrop: 0.1, bend: 0.5 });
  const pose = { tracked: true, fromHand: false, position: [1, 1.6, 2] as [number, number, number], rotation: [0, 0.38, 0, 0.92] as [number, number, number, number] };
  const join = encodeJoin({ name: 'Zoë', avatar: { kind: 'url', url: '/a.vrm' }, database: 'locomotion', height: 1.7, mode: 'vr', devices: { headset: true } });
  const client = [
    join,
    encodeMove({ seq: 5, time: 250, rootX: 1, rootZ: 2, rootYaw: 1, steps: [step, { ...step, ticks: 121, run: true }, { ...step, moveX: 0 }] }),
    encodeTracked({ seq: 5, time: 250, rootX: 1, rootZ: 2, rootYaw: 1, scale: 1.1, alpha: 0.2, trackers: [pose, pose, pose], steps: [tracked, tracked] }),
    encodePath({ seq: 5, time: 250, points: new Float32Array([0, 0, 1, 1, 2, 0]), speeds: new Float32Array([1, 2, 3]), looped: true }),
    encodeState({ seq: 5, time: 250, frame: 9, rootX: 1, rootZ: 2, rootYaw: 1, drive: 'tracked', pathTime: 0, scale: 1, alpha: 0.2, move: step, tracked }),
  ];
  const server = [encodeWelcome(3, 16, [{ id: 1, join }]), encodeMemberJoined(2, join), encodeRelay(2, client[2]), encodeSnapshot(2, client[4], client[3])];
  const relays = [encodeRelay(2, client[1]), encodeRelay(3, client[2])];
  server.push(encodeBatch(relays));
  let valid = 0;
  let rejected = 0;
  for (let i = 0; i < 200_000; i++) {
    const fromServer = i % 4 === 3;
    const pool = fromServer ? server : client;
    let b: Uint8Array;
    const how = i % 5;
    if (how === 0) b = Uint8Array.from({ length: int(80) }, () => int(256));
    else {
      b = pool[int(pool.length)].slice();
      if (how === 1) b = b.subarray(0, int(b.length + 1));
      const flips = 1 + int(6);
      for (let k = 0; k < flips && b.length; k++) b[int(b.length)] = how === 2 ? int(256) : b[int(b.length)] ^ (1 << int(8));
      if (how === 4 && b.length > 2) b[0] = PROTOCOL_VERSION; // keep the version, so the body's checks run
    }
    try {
      if (fromServer) {
        for (const part of unbatch(b)) {
          const m = decodeServerMessage(part);
          expect(finiteEverywhere(m)).toBe(true);
          if (m.type === 'relay') checkClient(m.message);
        }
      } else checkClient(decodeClientMessage(b));
      valid++;
    } catch (e) {
      if (!(e instanceof ProtocolError)) throw new Error(`input ${Array.from(b).join(',')} threw ${String(e)}`);
      rejected++;
    }
  }
  console.log(`decoder fuzz: ${valid} decoded (all in range), ${rejected} rejected with a ProtocolError`);
  expect(valid + rejected).toBe(200_000);
  expect(valid).toBeGreaterThan(1000); // mutations that stay valid exist and were checked
  expect(rejected).toBeGreaterThan(100_000);
});
