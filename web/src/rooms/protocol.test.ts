import { describe, expect, it } from 'vitest';
import {
  angleToI16,
  createMoveStep,
  createRoomId,
  decodeClientMessage,
  decodeServerMessage,
  encodeBatch,
  encodeError,
  encodeJoin,
  encodeMemberJoined,
  encodeMemberLeft,
  encodeMove,
  encodePath,
  encodeRelay,
  encodeSnapshot,
  encodeState,
  encodeStateRequest,
  encodeTracked,
  encodeWelcome,
  i16ToAngle,
  isRoomId,
  MAX_CLIENT_MESSAGE_BYTES,
  MAX_MESSAGE_BYTES,
  MAX_RUNTIME_STATE_BYTES,
  MOVE_HEADER_BYTES,
  packQuat,
  PROTOCOL_VERSION,
  ProtocolError,
  quantizeMoveStep,
  quantizeTrackedStep,
  STATE_BYTES,
  TRACKED_HEADER_BYTES,
  TRACKED_STEP_BYTES,
  unbatch,
  unpackQuat,
  type JoinInfo,
  type MoveStep,
  type StateMessage,
  type TrackedStep,
  type RoomTrackerPose,
} from './protocol.ts';
import { measureBandwidth } from './bandwidth.ts';

const join: JoinInfo = {
  name: 'Ana Łucja 🚶',
  avatar: { kind: 'url', url: '/avatars/ana.vrm' },
  database: 'locomotion',
  height: 1.623,
  mode: 'vr',
  devices: { headset: true, leftController: true, rightController: true },
  style: 'angry',
};

function seeded(seed: number): () => number {
  let s = seed >>> 0;
  return () => {
    s = (s + 0x6d2b79f5) >>> 0;
    let t = s;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

function moveStep(ticks: number, mx: number, mz: number, fx: number, fz: number, run = false): MoveStep {
  return quantizeMoveStep({ ...createMoveStep(), ticks, moveX: mx, moveZ: mz, faceX: fx, faceZ: fz, run });
}

function trackers(): [RoomTrackerPose, RoomTrackerPose, RoomTrackerPose] {
  return [
    { tracked: true, fromHand: false, position: [1.2, 1.65, -3.4], rotation: [0, 0.3826834, 0, 0.9238795] },
    { tracked: true, fromHand: true, position: [1.0, 1.1, -3.2], rotation: [0.5, 0.5, 0.5, 0.5] },
    { tracked: false, fromHand: false, position: [1.4, 1.0, -3.3], rotation: [0, 0, 0, 1] },
  ];
}

const state: Omit<StateMessage, 'type'> = {
  seq: 40,
  time: 12_345,
  frame: 4321,
  rootX: 10.5,
  rootZ: -3.25,
  rootYaw: 2.5,
  drive: 'path',
  pathTime: 3.5,
  scale: 1.05,
  alpha: 0.2,
  move: moveStep(0, 0.6, 0.8, 0, 1, true),
  tracked: quantizeTrackedStep({ ticks: 0, headX: 10.6, headZ: -3.2, velocityX: 1.2, velocityZ: -0.3, yaw: 2.4, body: true, hipsDrop: 0.12, bend: 0.7 }),
};

describe('room ids', () => {
  it('are 22 base64url characters (128 bits), unique, and validated', () => {
    const ids = new Set<string>();
    for (let i = 0; i < 2000; i++) {
      const id = createRoomId();
      expect(id).toHaveLength(22);
      expect(isRoomId(id)).toBe(true);
      ids.add(id);
    }
    expect(ids.size).toBe(2000);
    for (const bad of ['', 'abc', 'A'.repeat(21) + 'B', 'A'.repeat(23), 'A'.repeat(21) + '/', '../../etc/passwdAAAAAA', 'A'.repeat(20) + '.A']) {
      expect(isRoomId(bad)).toBe(false);
    }
  });
});

describe('quantization', () => {
  it('angles: int16 error ≤ π/65536 and wraps', () => {
    let worst = 0;
    const rand = seeded(1);
    for (let i = 0; i < 100_000; i++) {
      const a = (rand() * 2 - 1) * 20;
      const back = i16ToAngle(angleToI16(a));
      const d = Math.abs(Math.atan2(Math.sin(a - back), Math.cos(a - back)));
      worst = Math.max(worst, d);
    }
    expect(worst).toBeLessThanOrEqual(Math.PI / 65536 + 1e-12);
    expect(angleToI16(Math.PI)).toBe(-32768);
    expect(angleToI16(NaN)).toBe(0);
  });

  it('move and facing: int8, facing direction error < 0.32°, move length never above 1', () => {
    let worst = 0;
    for (let i = 0; i < 100_000; i++) {
      const a = (i / 100_000) * 2 * Math.PI;
      const s = quantizeMoveStep({ ...createMoveStep(), moveX: Math.sin(a) * 1.3, moveZ: Math.cos(a) * 1.3, faceX: Math.sin(a), faceZ: Math.cos(a) });
      const d = Math.abs(Math.atan2(Math.sin(a - Math.atan2(s.faceX, s.faceZ)), Math.cos(a - Math.atan2(s.faceX, s.faceZ))));
      worst = Math.max(worst, d);
      expect(Math.hypot(s.moveX, s.moveZ)).toBeLessThanOrEqual(1);
    }
    const degrees = (worst * 180) / Math.PI;
    console.log(`int8 facing: worst direction error ${degrees.toFixed(3)}°`);
    expect(degrees).toBeLessThan(0.32);
    expect(degrees).toBeGreaterThan(0.1);
  });

  it('quaternions: smallest-three 32 bit, worst angular error < 0.24° over 200k random rotations', () => {
    const rand = seeded(7);
    const out = [0, 0, 0, 0];
    let worst = 0;
    let worstNorm = 0;
    for (let i = 0; i < 200_000; i++) {
      // Uniform random rotation (Shoemake).
      const u1 = rand();
      const u2 = rand() * 2 * Math.PI;
      const u3 = rand() * 2 * Math.PI;
      const q = [Math.sqrt(1 - u1) * Math.sin(u2), Math.sqrt(1 - u1) * Math.cos(u2), Math.sqrt(u1) * Math.sin(u3), Math.sqrt(u1) * Math.cos(u3)];
      unpackQuat(packQuat(q[0], q[1], q[2], q[3]), out);
      const dot = Math.min(1, Math.abs(q[0] * out[0] + q[1] * out[1] + q[2] * out[2] + q[3] * out[3]));
      worst = Math.max(worst, 2 * Math.acos(dot));
      worstNorm = Math.max(worstNorm, Math.abs(Math.hypot(out[0], out[1], out[2], out[3]) - 1));
    }
    expect(worstNorm).toBeLessThan(1e-12);
    const degrees = (worst * 180) / Math.PI;
    console.log(`smallest-three 10-bit: worst angular error ${degrees.toFixed(4)}°`);
    expect(degrees).toBeLessThan(0.24);
    expect(degrees).toBeGreaterThan(0.01); // it is a real quantization, not a float copy
    unpackQuat(packQuat(NaN, 0, 0, 0), out);
    expect(out).toEqual([0, 0, 0, 1]);
  });
});

describe('client messages round trip', () => {
  it('join', () => {
    const bytes = encodeJoin(join);
    expect(decodeClientMessage(bytes)).toEqual({ type: 'join', ...join });
    const builtin: JoinInfo = { name: '', avatar: { kind: 'builtin', id: 3 }, database: 'loco.v2', height: 0, mode: 'desktop', devices: { keyboard: true, pointer: true } };
    // No style is the neutral one (protocol 3).
    expect(decodeClientMessage(encodeJoin(builtin))).toEqual({ type: 'join', ...builtin, style: 'neutral' });
  });

  it('join rejects bad names, URLs, databases and heights', () => {
    const bad: Partial<JoinInfo>[] = [
      { name: 'evil\u202eeman' },
      { name: 'line\nbreak' },
      { name: 'x'.repeat(49) },
      { style: 'Angry!' },
      { style: 'x'.repeat(65) },
      { avatar: { kind: 'url', url: 'javascript:"<script>' } },
      { avatar: { kind: 'url', url: 'a b' } },
      { avatar: { kind: 'url', url: '/' + 'a'.repeat(600) } },
      { database: '../etc' },
      { database: '' },
      { height: 0.2 },
      { height: 3.5 },
    ];
    for (const patch of bad) expect(() => encodeJoin({ ...join, ...patch }), JSON.stringify(patch)).toThrow(ProtocolError);
  });

  it('move: decoded steps are exactly the quantized inputs; an unchanged step costs 1 byte', () => {
    const steps = [moveStep(120, 0.3, 0.4, 0, 1), moveStep(120, 0.3, 0.4, 0, 1), moveStep(121, 0.3, 0.4, 0.6, 0.8, true), { ...moveStep(119, 0, 0, 0.6, 0.8), path: true }];
    const bytes = encodeMove({ seq: 7, time: 99_000, rootX: -1.2346, rootZ: 1000.5, rootYaw: -1, steps });
    // header + first step full (7) + unchanged (1) + new dt and face (5) + new dt and move (5)
    expect(bytes.length).toBe(MOVE_HEADER_BYTES + 7 + 1 + 5 + 5);
    const m = decodeClientMessage(bytes);
    expect(m).toEqual({ type: 'move', seq: 7, time: 99_000, rootX: -1.235, rootZ: 1000.5, rootYaw: i16ToAngle(angleToI16(-1)), steps });
  });

  it('tracked: positions within 0.5 mm, steps exact after quantizeTrackedStep, 15 bytes a step', () => {
    const rand = seeded(3);
    const steps: TrackedStep[] = [];
    for (let i = 0; i < 5; i++) {
      steps.push(quantizeTrackedStep({ ticks: 80, headX: 1 + rand(), headZ: -3 + rand(), velocityX: rand() * 2 - 1, velocityZ: rand(), yaw: rand() * 6 - 3, body: i % 2 === 1, hipsDrop: rand() * 0.3, bend: rand() * 1.4 }));
    }
    const t = trackers();
    const bytes = encodeTracked({ seq: 3, time: 5, rootX: 1.3, rootZ: -3.3, rootYaw: 0.5, scale: 0.97, alpha: 0.3, trackers: t, steps });
    expect(bytes.length).toBe(TRACKED_HEADER_BYTES + 5 * TRACKED_STEP_BYTES);
    const m = decodeClientMessage(bytes);
    if (m.type !== 'tracked') throw new Error('type');
    expect(m.steps).toEqual(steps);
    expect(m.scale).toBe(Math.fround(0.97));
    expect(m.alpha).toBe(0.3);
    expect(m.rootX).toBe(1.3);
    m.trackers.forEach((d, i) => {
      expect(d.tracked).toBe(t[i].tracked);
      expect(d.fromHand).toBe(i > 0 && t[i].fromHand);
      for (let c = 0; c < 3; c++) expect(Math.abs(d.position[c] - t[i].position[c])).toBeLessThanOrEqual(0.0005 + 1e-9);
      const dot = Math.abs(d.rotation.reduce((s, v, c) => s + v * t[i].rotation[c], 0));
      expect(2 * Math.acos(Math.min(1, dot))).toBeLessThan((0.24 * Math.PI) / 180);
    });
    // A head 40 m from the root is out of the int16 mm range: the encoder refuses.
    expect(() => encodeTracked({ seq: 3, time: 5, rootX: 41, rootZ: 0, rootYaw: 0, scale: 1, alpha: 0.2, trackers: t, steps })).toThrow(/±32.767 m/);
  });

  it('path and state', () => {
    const points = new Float32Array([0, 0, 2, 0.5, 4.25, -3]);
    const path = decodeClientMessage(encodePath({ seq: 9, time: 1000, points, speeds: new Float32Array([1.4, 3.5, 1.4]), looped: true }));
    expect(path).toEqual({ type: 'path', seq: 9, time: 1000, points, speeds: new Float32Array([1.4, 3.5, 1.4]), looped: true });
    expect(() => encodePath({ seq: 9, time: 1000, points, speeds: new Float32Array([1.4, 3.5]), looped: true })).toThrow(ProtocolError);
    expect(() => encodePath({ seq: 9, time: 1000, points: new Float32Array([0, 0, NaN, 1]), speeds: new Float32Array([1]), looped: false })).toThrow(/not finite/);
    expect(() => encodePath({ seq: 9, time: 1000, points: new Float32Array([0, 0, 1, 1]), speeds: new Float32Array([50]), looped: false })).toThrow(/speed/);
    const bytes = encodeState(state);
    expect(bytes.length).toBe(STATE_BYTES);
    const s = decodeClientMessage(bytes);
    expect(s).toEqual({ type: 'state', ...state, restart: false, runtime: null, rootYaw: i16ToAngle(angleToI16(2.5)), scale: Math.fround(1.05), move: { ...state.move, ticks: 0 } });
    // A runtime state rides after the fixed part, opaque (the runtime checks it), bit 6 of the drive byte.
    const runtime = Uint8Array.from({ length: 4700 }, (_, i) => (i * 37) & 0xff);
    const full = encodeState({ ...state, runtime });
    expect(full.length).toBe(STATE_BYTES + 2 + 4700);
    const f = decodeClientMessage(full);
    if (f.type !== 'state') throw new Error('type');
    expect(f.runtime).toEqual(runtime);
    expect(f.drive).toBe(state.drive);
    expect(() => decodeClientMessage(full.subarray(0, full.length - 1))).toThrow(/runtime state/);
    const empty = full.slice();
    empty[STATE_BYTES] = empty[STATE_BYTES + 1] = 0;
    expect(() => decodeClientMessage(empty)).toThrow(/runtime state of 0 bytes/);
    expect(() => encodeState({ ...state, runtime: new Uint8Array(MAX_RUNTIME_STATE_BYTES + 1) })).toThrow(/runtime state/);
    // The largest STATE is the largest message; the server's frame limit is that size.
    expect(encodeState({ ...state, runtime: new Uint8Array(MAX_RUNTIME_STATE_BYTES) }).length).toBe(MAX_MESSAGE_BYTES);
  });
});

describe('server messages round trip', () => {
  it('welcome, joined, left, relay, snapshot, state request, error', () => {
    const j = encodeJoin(join);
    const welcome = decodeServerMessage(encodeWelcome(5, 16, [{ id: 2, join: j }, { id: 3, join: j }]));
    expect(welcome).toEqual({ type: 'welcome', memberId: 5, maxMembers: 16, members: [{ id: 2, join }, { id: 3, join }] });
    expect(decodeServerMessage(encodeMemberJoined(9, j))).toEqual({ type: 'memberJoined', member: { id: 9, join } });
    expect(decodeServerMessage(encodeMemberLeft(9, 'timeout'))).toEqual({ type: 'memberLeft', id: 9, reason: 'timeout' });
    const move = encodeMove({ seq: 1, time: 0, rootX: 0, rootZ: 0, rootYaw: 0, steps: [moveStep(120, 0, 1, 0, 1)] });
    const relay = decodeServerMessage(encodeRelay(4, move));
    expect(relay).toEqual({ type: 'relay', from: 4, message: decodeClientMessage(move) });
    const st = encodeState(state);
    const pth = encodePath({ seq: 2, time: 0, points: new Float32Array([0, 0, 1, 1]), speeds: new Float32Array([2]), looped: false });
    const snap = decodeServerMessage(encodeSnapshot(4, st, pth));
    expect(snap).toEqual({ type: 'snapshot', from: 4, state: decodeClientMessage(st), path: decodeClientMessage(pth) });
    expect(decodeServerMessage(encodeSnapshot(4, null, null))).toEqual({ type: 'snapshot', from: 4, state: null, path: null });
    expect(decodeServerMessage(encodeStateRequest())).toEqual({ type: 'stateRequest' });
    expect(decodeServerMessage(encodeError(4003, 'room full'))).toEqual({ type: 'error', code: 4003, reason: 'room full' });
    // A relay may not smuggle a JOIN or a server message.
    expect(() => decodeServerMessage(encodeRelay(4, j))).toThrow(ProtocolError);
    expect(() => decodeServerMessage(encodeRelay(4, encodeStateRequest()))).toThrow(ProtocolError);
  });
});

describe('batches', () => {
  it('a batch splits into its messages, in order; anything else is one message', () => {
    const move = encodeMove({ seq: 1, time: 0, rootX: 0, rootZ: 0, rootYaw: 0, steps: [moveStep(120, 0, 1, 0, 1)] });
    const parts = [encodeRelay(4, move), encodeMemberLeft(9, 'timeout'), encodeStateRequest(), encodeRelay(5, move)];
    const total = parts.reduce((n, p) => n + p.length, 0);
    const batch = encodeBatch(parts);
    expect(batch.length).toBe(2 + 2 * parts.length + total);
    const split = unbatch(batch.buffer.slice(0) as ArrayBuffer);
    expect(split.map((p) => Array.from(p))).toEqual(parts.map((p) => Array.from(p)));
    expect(split.map((p) => decodeServerMessage(p).type)).toEqual(['relay', 'memberLeft', 'stateRequest', 'relay']);
    const one = encodeRelay(4, move);
    expect(unbatch(one)).toEqual([one]);
    // decodeServerMessage names the mistake of decoding a batch whole.
    expect(() => decodeServerMessage(batch)).toThrow(/unbatch/);
  });

  it('a batch whose lengths do not add up, that nests a batch, or is empty is refused whole', () => {
    const parts = [encodeStateRequest(), encodeMemberLeft(2, 'closed')];
    const batch = encodeBatch(parts);
    expect(() => unbatch(batch.subarray(0, batch.length - 1))).toThrow(/claims 4 bytes, 3 left/);
    expect(() => unbatch(Uint8Array.from([...batch, 7]))).toThrow(/cut off/);
    expect(() => unbatch(encodeBatch([batch]))).toThrow(/itself a batch/);
    expect(() => unbatch(encodeBatch([]))).toThrow(/empty/);
    const old = batch.slice();
    old[0] = 3;
    expect(() => unbatch(old)).toThrow(ProtocolError);
  });
});

describe('malformed messages are rejected, never half-decoded', () => {
  const valid = () => [
    encodeJoin(join),
    encodeMove({ seq: 1, time: 0, rootX: 0, rootZ: 0, rootYaw: 0, steps: [moveStep(120, 0, 1, 0, 1), moveStep(120, 1, 0, 0, 1)] }),
    encodeTracked({ seq: 1, time: 0, rootX: 1, rootZ: 1, rootYaw: 0, scale: 1, alpha: 0.2, trackers: trackers(), steps: [quantizeTrackedStep({ ticks: 100, headX: 1, headZ: 1, velocityX: 0, velocityZ: 0, yaw: 0, body: false, hipsDrop: 0, bend: 0 })] }),
    encodePath({ seq: 1, time: 0, points: new Float32Array([0, 0, 1, 1]), speeds: new Float32Array([2]), looped: false }),
    encodeState(state),
  ];

  it('every truncation and one trailing byte throw ProtocolError', () => {
    let cases = 0;
    for (const bytes of valid()) {
      expect(() => decodeClientMessage(bytes)).not.toThrow();
      for (let n = 0; n < bytes.length; n++) {
        expect(() => decodeClientMessage(bytes.subarray(0, n)), `prefix ${n} of type ${bytes[1]}`).toThrow(ProtocolError);
        cases++;
      }
      const longer = new Uint8Array(bytes.length + 1);
      longer.set(bytes);
      expect(() => decodeClientMessage(longer)).toThrow(ProtocolError);
    }
    expect(cases).toBeGreaterThan(200);
  });

  it('wrong version, unknown type, seq 0, bad dt, too many steps, oversize, NaN', () => {
    const [, move, , path, st] = valid();
    const patch = (b: Uint8Array, at: number, value: number, width: 1 | 2 | 4 = 1) => {
      const c = b.slice();
      const v = new DataView(c.buffer);
      if (width === 1) v.setUint8(at, value);
      else if (width === 2) v.setUint16(at, value, true);
      else v.setUint32(at, value, true);
      return c;
    };
    expect(() => decodeClientMessage(patch(move, 0, 1))).toThrow(/version/);
    expect(() => decodeClientMessage(patch(move, 1, 0x7f))).toThrow(/unknown/);
    expect(() => decodeClientMessage(patch(move, 1, 0x80))).toThrow(/unknown/); // a server type from a client
    expect(() => decodeClientMessage(patch(move, 2, 0, 4))).toThrow(/seq 0/);
    // Step 0: flags at +0, dt at +1, move at +3, facing at +5.
    expect(() => decodeClientMessage(patch(move, MOVE_HEADER_BYTES + 1, 0, 2))).toThrow(/dt/);
    expect(() => decodeClientMessage(patch(move, MOVE_HEADER_BYTES + 1, 1801, 2))).toThrow(/dt/);
    expect(() => decodeClientMessage(patch(move, MOVE_HEADER_BYTES - 1, 65))).toThrow(/steps/);
    expect(() => decodeClientMessage(patch(move, MOVE_HEADER_BYTES, 0x40 | 12))).toThrow(/flag/);
    expect(() => decodeClientMessage(patch(move, MOVE_HEADER_BYTES, 0x20 | 12))).toThrow(/first step/);
    expect(() => decodeClientMessage(patch(move, MOVE_HEADER_BYTES + 3, 0x80))).toThrow(/move/);
    expect(() => decodeClientMessage(patch(move, MOVE_HEADER_BYTES + 3, 0x7f7f, 2))).toThrow(/move length/);
    expect(() => decodeClientMessage(patch(move, MOVE_HEADER_BYTES + 5, 0, 2))).toThrow(/facing length/);
    expect(() => decodeClientMessage(patch(path, 12, 0x7fc00000, 4))).toThrow(/not finite/);
    expect(() => decodeClientMessage(patch(st, 29, 0x7f800000, 4))).toThrow(/not finite/); // scale = +Inf
    expect(() => decodeClientMessage(patch(st, 24, 3))).toThrow(/drive/);
    expect(() => decodeClientMessage(new Uint8Array(MAX_MESSAGE_BYTES + 1))).toThrow(/at most/);
    const longMove = new Uint8Array(MAX_CLIENT_MESSAGE_BYTES + 1);
    longMove.set(move);
    expect(() => decodeClientMessage(longMove)).toThrow(/at most 1024 but a STATE/);
    expect(() => decodeServerMessage(new Uint8Array([PROTOCOL_VERSION, 0x82, 0, 0]))).toThrow(/member id/);
  });
});

describe('bandwidth per avatar (WebSocket framing counted)', () => {
  it('desktop at 60 Hz frames, 20 Hz messages: ≤ 2 KB/s; VR at 72/90 Hz frames, 30 Hz messages: ≤ 4 KB/s', () => {
    const rows = [
      measureBandwidth({ mode: 'desktop', frameHz: 60, sendHz: 20, seconds: 20, changeEveryFrame: false }),
      measureBandwidth({ mode: 'desktop', frameHz: 60, sendHz: 20, seconds: 20, changeEveryFrame: true }),
      measureBandwidth({ mode: 'desktop', frameHz: 144, sendHz: 20, seconds: 20, changeEveryFrame: true }),
      measureBandwidth({ mode: 'vr', frameHz: 72, sendHz: 30, seconds: 20, changeEveryFrame: true }),
      measureBandwidth({ mode: 'vr', frameHz: 90, sendHz: 30, seconds: 20, changeEveryFrame: true }),
    ];
    console.table(rows);
    const [idle, orbit, fast, vr72, vr90] = rows;
    for (const r of [idle, orbit, fast]) {
      expect(r.downBytesPerSecond).toBeLessThanOrEqual(2048);
      expect(r.upBytesPerSecond).toBeLessThanOrEqual(2048);
    }
    for (const r of [vr72, vr90]) {
      expect(r.downBytesPerSecond).toBeLessThanOrEqual(4096);
      expect(r.upBytesPerSecond).toBeLessThanOrEqual(4096);
    }
    // Real traffic, not an empty stream: 20 messages a second of 21+ bytes each at the least.
    expect(idle.downBytesPerSecond).toBeGreaterThan(20 * (MOVE_HEADER_BYTES + 5));
    expect(vr90.downBytesPerSecond).toBeGreaterThan(vr72.downBytesPerSecond);
  });
});
