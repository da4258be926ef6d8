/**
 * The shared-rooms wire protocol (docs/rooms.md), defined once for the browser client and the
 * Node room server: binary, little-endian, versioned, one protocol message per WebSocket binary
 * message. Decoding validates every length, range and string and throws a `ProtocolError`
 * naming what is wrong; nothing out of range is ever returned. No three.js, WASM or Node
 * imports (types only): this file runs in both places.
 *
 * Determinism contract (docs/rooms.md, "Replaying the sender's steps"): a sender streams every
 * simulation step it took — its `dt` in ticks of 1/7200 s and the runtime input of that step,
 * both already quantized — and drives its own character with exactly the decoded values
 * (`LocalAvatar` does this). A receiver replaying the same steps on the same database and
 * settings then computes the same motion; the sender's reported root corrects what differs.
 */

import type { DriveMode, MoveInput, TrackedInput } from '../core/drive.ts';

export type { DriveMode };

// ------------------------------------------------------------------ constants

/**
 * 4: the server may pack several messages for one receiver into a BATCH frame (`encodeBatch`); a
 * build that speaks 3 would drop those frames, so the version says it.
 */
export const PROTOCOL_VERSION = 4;

/** Client → server message types. */
export const MsgType = {
  join: 0x01,
  move: 0x10,
  tracked: 0x11,
  path: 0x12,
  state: 0x13,
  // Server → client.
  welcome: 0x80,
  memberJoined: 0x81,
  memberLeft: 0x82,
  relay: 0x83,
  snapshot: 0x84,
  stateRequest: 0x85,
  error: 0x86,
  /** Several server messages for one receiver in one WebSocket frame (`encodeBatch`, `unbatch`). */
  batch: 0x87,
} as const;

/** WebSocket close codes the server uses (4000–4999 are the application's). */
export const CloseCode = {
  normal: 1000,
  goingAway: 1001,
  /** ws closes an over-long message itself with 1009. */
  tooBig: 1009,
  malformed: 4000,
  badVersion: 4001,
  rateLimited: 4002,
  roomFull: 4003,
  timeout: 4004,
  notJoined: 4005,
  tooSlow: 4006,
  /** Kept sending values no receiver would take (positions beyond the room, impossible speeds, frames out of range, runtime states that do not parse). */
  contentRefused: 4007,
  /** The rooms bus (NATS between server processes) is unavailable: try again later. */
  tryAgain: 1013,
} as const;

/** Why a member left (`memberLeft`). */
export const LeaveReason = { closed: 0, timeout: 1, dropped: 2 } as const;
export type LeaveReasonName = keyof typeof LeaveReason;

/** Simulation time unit: 1/7200 s divides 1/60, 1/72, 1/90, 1/120 and 1/144 s exactly. */
export const TICKS_PER_SECOND = 7200;
/** Longest step a sender may take (0.25 s = 1800 ticks); the runtime clamps long frames anyway. */
export const MAX_DT_TICKS = 1800;
export const MAX_STEPS = 64;
export const MAX_PATH_POINTS = 64;
export const MAX_NAME_BYTES = 48;
export const MAX_URL_BYTES = 512;
export const MAX_DATABASE_BYTES = 64;
/** The largest client → server message but a STATE (a TRACKED message with 64 steps is 953 bytes). */
export const MAX_CLIENT_MESSAGE_BYTES = 1024;
/** The largest runtime state a STATE carries (a 32-joint character's is 4.6 KB). */
export const MAX_RUNTIME_STATE_BYTES = 16_000;
/**
 * The runtime state's version (`STATE_VERSION` in wasm-core/src/runtime/character/state.rs, the second
 * u32 of its header): the room server checks it (server/content.ts); a test compares it with
 * what the runtime writes.
 */
export const RUNTIME_STATE_VERSION = 6;
export const MAX_MEMBERS_LIMIT = 64;
/** Positions relative to a message origin are int16 mm: ±32.767 m. */
export const MAX_RELATIVE_MM = 32767;
/** Path keypoints and speeds: |x|, |z| ≤ 100 km; speeds in (0, 20] m/s. */
export const MAX_PATH_COORD = 100_000;
export const MAX_PATH_SPEED = 20;
/** Room metres per database unit: [0.1, 10]. */
export const MIN_SCALE = 0.1;
export const MAX_SCALE = 10;
/** Calibrated eye height, mm: 0 = not calibrated, else [500, 2600]. */
export const MIN_HEIGHT_MM = 500;
export const MAX_HEIGHT_MM = 2600;

/** Fixed sizes (bytes) of the fixed-layout messages. */
export const STREAM_HEADER_BYTES = 10;
export const MOVE_HEADER_BYTES = 21;
export const TRACKED_HEADER_BYTES = 57;
export const TRACKED_STEP_BYTES = 15;
export const STATE_BYTES = 52;
/** The largest message of all: a STATE with the largest runtime state (the server's frame limit). */
export const MAX_MESSAGE_BYTES = STATE_BYTES + 2 + MAX_RUNTIME_STATE_BYTES;

export class ProtocolError extends Error {
  constructor(
    message: string,
    readonly code: number = CloseCode.malformed,
  ) {
    super(message);
    this.name = 'ProtocolError';
  }
}

const fail = (message: string, code?: number): never => {
  throw new ProtocolError(message, code);
};

// ------------------------------------------------------------------ quantization

/** Integer millimetres of metres (non-finite → 0). */
export function toMm(m: number): number {
  return Number.isFinite(m) ? Math.round(m * 1000) : 0;
}
export function fromMm(q: number): number {
  return q / 1000;
}

/** int16 of an angle (rad) wrapped to [−π, π): q · π / 32768; error ≤ π/65536 ≈ 0.0027°. */
export function angleToI16(rad: number): number {
  if (!Number.isFinite(rad)) return 0;
  let q = Math.round((rad / Math.PI) * 32768) % 65536;
  if (q >= 32768) q -= 65536;
  if (q < -32768) q += 65536;
  return q;
}
export function i16ToAngle(q: number): number {
  return (q * Math.PI) / 32768;
}

const SMALLEST_THREE_RANGE = Math.SQRT1_2;
// 1023 levels (0…1022): zero is exact, so the identity round-trips exactly.
const SMALLEST_THREE_MAX = 1022;

/**
 * A unit quaternion (x, y, z, w) in 32 bits, "smallest three": 2 bits name the largest
 * component (dropped, made positive by negating q), the other three in 10 bits each over
 * [−1/√2, 1/√2]. Angular error < 0.24° (measured over 200k rotations in the tests). A zero or non-finite
 * quaternion packs as the identity.
 */
export function packQuat(x: number, y: number, z: number, w: number): number {
  const n = Math.hypot(x, y, z, w);
  if (!(n > 1e-9) || !Number.isFinite(n)) return packQuat(0, 0, 0, 1);
  const c = [x / n, y / n, z / n, w / n];
  let largest = 0;
  for (let i = 1; i < 4; i++) if (Math.abs(c[i]) > Math.abs(c[largest])) largest = i;
  const sign = c[largest] < 0 ? -1 : 1;
  let bits = largest;
  let shift = 2;
  for (let i = 0; i < 4; i++) {
    if (i === largest) continue;
    const v = (c[i] * sign + SMALLEST_THREE_RANGE) / (2 * SMALLEST_THREE_RANGE);
    const q = Math.max(0, Math.min(SMALLEST_THREE_MAX, Math.round(v * SMALLEST_THREE_MAX)));
    bits |= q << shift;
    shift += 10;
  }
  return bits >>> 0;
}

/** Unpacks `packQuat` into `out` (x, y, z, w), a unit quaternion. */
export function unpackQuat(bits: number, out: Float64Array | number[], offset = 0): void {
  const largest = bits & 3;
  let shift = 2;
  let sum = 0;
  for (let i = 0; i < 4; i++) {
    if (i === largest) continue;
    const q = (bits >>> shift) & 0x3ff;
    const v = (q / SMALLEST_THREE_MAX) * 2 * SMALLEST_THREE_RANGE - SMALLEST_THREE_RANGE;
    out[offset + i] = v;
    sum += v * v;
    shift += 10;
  }
  out[offset + largest] = Math.sqrt(Math.max(0, 1 - sum));
  // Out-of-range codes (the three can sum above 1) renormalize to a unit quaternion.
  const n = Math.hypot(out[offset], out[offset + 1], out[offset + 2], out[offset + 3]);
  for (let i = 0; i < 4; i++) out[offset + i] /= n;
}

// ------------------------------------------------------------------ room ids

/** 16 random bytes (128 bits) as 22 base64url characters. */
export function createRoomId(): string {
  const bytes = new Uint8Array(16);
  globalThis.crypto.getRandomValues(bytes);
  const alphabet = 'ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_';
  let out = '';
  let acc = 0;
  let bits = 0;
  for (const b of bytes) {
    acc = (acc << 8) | b;
    bits += 8;
    while (bits >= 6) {
      bits -= 6;
      out += alphabet[(acc >> bits) & 63];
    }
    acc &= (1 << bits) - 1;
  }
  if (bits > 0) out += alphabet[(acc << (6 - bits)) & 63];
  return out;
}

/** A canonical 128-bit base64url id: 22 characters, the last carrying 2 bits (A, Q, g or w). */
export const ROOM_ID_PATTERN = /^[A-Za-z0-9_-]{21}[AQgw]$/;
export function isRoomId(id: string): boolean {
  return ROOM_ID_PATTERN.test(id);
}

// ------------------------------------------------------------------ message types

export type AvatarChoice = { kind: 'builtin'; id: number } | { kind: 'url'; url: string };

/** The devices a member drives with (bits of the JOIN message's device byte). */
export interface DeviceSet {
  keyboard?: boolean;
  gamepad?: boolean;
  /** Pointer (mouse/touch): path clicks. */
  pointer?: boolean;
  headset?: boolean;
  leftController?: boolean;
  rightController?: boolean;
  /** Hand tracking: grips derived from hands. */
  hands?: boolean;
}
const DEVICE_BITS: (keyof DeviceSet)[] = ['keyboard', 'gamepad', 'pointer', 'headset', 'leftController', 'rightController', 'hands'];

export type DeviceMode = 'desktop' | 'vr';

export interface JoinInfo {
  /** Display name, ≤ 48 UTF-8 bytes, no control or bidi-override characters. */
  name: string;
  avatar: AvatarChoice;
  /** Database id (e.g. "locomotion"): [A-Za-z0-9._-]{1,64}. */
  database: string;
  /** Calibrated eye height, m (0 = not calibrated; else 0.5–2.6). Resolution 1 mm. */
  height: number;
  mode: DeviceMode;
  devices: DeviceSet;
  /**
   * The motion style the member's character prefers (`Character.setStyle`): its copies play the
   * same one. 1–64 of [a-z0-9_-]; absent or empty: `neutral`. (Protocol 3.)
   */
  style?: string;
}

/** A style as the JOIN message carries it. */
const STYLE_PATTERN = /^[a-z0-9_-]{1,64}$/;

/** Fields every stream message (move, tracked, path, state) carries. */
export interface StreamHeader {
  /** Per-member sequence number, one space for all stream messages, starting at 1. */
  seq: number;
  /** Sender time, ms since the sender's stream start (u32), at the end of the last step. */
  time: number;
}

/** One desktop simulation step, decoded: the exact values the sender's runtime used (the move input, quantized). */
export interface MoveStep extends MoveInput {
  /** Step, ticks of 1/7200 s (1–1800). */
  ticks: number;
  /** Following the last PATH (move and face are ignored). */
  path: boolean;
}

export interface MoveMessage extends StreamHeader {
  type: 'move';
  /** The sender's root after the last step: m (1 mm) and yaw rad. */
  rootX: number;
  rootZ: number;
  rootYaw: number;
  steps: MoveStep[];
}

/**
 * One VR simulation step: the tracked input (room metres), quantized — head centre on the floor
 * 1 mm, its ground velocity 1 mm/s (±32.767 m/s), the body yaw (from the sender's orientation
 * network or heuristic) int16, the hips drop 1 mm (0–65.535 m).
 */
export interface TrackedStep extends TrackedInput {
  ticks: number;
}

/** One tracker's pose as a room carries it: position (m, room) and rotation (x, y, z, w). */
export interface RoomTrackerPose {
  tracked: boolean;
  /** Left/right only: the grip is derived from a tracked hand, not a controller. */
  fromHand: boolean;
  position: [number, number, number];
  rotation: [number, number, number, number];
}

export interface TrackedMessage extends StreamHeader {
  type: 'tracked';
  rootX: number;
  rootZ: number;
  rootYaw: number;
  /** Room metres per database unit (the sender's avatar scale × retarget scale). */
  scale: number;
  /** Clamp distance α, m (1 cm). */
  alpha: number;
  /** head, left, right: the sample at the message's time (display: head and arms). */
  trackers: [RoomTrackerPose, RoomTrackerPose, RoomTrackerPose];
  steps: TrackedStep[];
}

export interface PathMessage extends StreamHeader {
  type: 'path';
  /** Keypoints (x, z interleaved), database units, float32 exactly as the runtime gets them. */
  points: Float32Array;
  /** Speed of each segment (m/s): count − 1 segments, count when looped. */
  speeds: Float32Array;
  looped: boolean;
}

const DRIVES: DriveMode[] = ['move', 'path', 'tracked'];
const STATE_RESTART = 0x80;
const STATE_RUNTIME = 0x40;

/** A member's compact state: the late-join snapshot and a periodic drift reference. */
export interface StateMessage extends StreamHeader {
  type: 'state';
  /** Database frame playing. */
  frame: number;
  rootX: number;
  rootZ: number;
  rootYaw: number;
  drive: DriveMode;
  /**
   * The sender restarted its runtime here (a fresh runtime at this root): receivers restart
   * their copies too, which from then on compute the sender's floats (the drive byte's bit 7).
   */
  restart?: boolean;
  /** Seconds since the current path started (drive 'path'). */
  pathTime: number;
  scale: number;
  alpha: number;
  /** The last move step's input (ticks 0). */
  move: MoveStep;
  /** The last tracked step's input (ticks 0). */
  tracked: TrackedStep;
  /**
   * The sender's whole runtime state after its last step (`CharacterRuntime.saveState`), or
   * null: sent when a member joins, so every copy continues from the sender's own floats (the
   * drive byte's bit 6; `u16` length + bytes after the fixed part).
   */
  runtime?: Uint8Array | null;
}

export type StreamMessage = MoveMessage | TrackedMessage | PathMessage | StateMessage;
export type ClientMessage = ({ type: 'join' } & JoinInfo) | StreamMessage;

export interface MemberInfo {
  id: number;
  join: JoinInfo;
}

export type ServerMessage =
  | { type: 'welcome'; memberId: number; maxMembers: number; members: MemberInfo[] }
  | { type: 'memberJoined'; member: MemberInfo }
  | { type: 'memberLeft'; id: number; reason: LeaveReasonName }
  | { type: 'relay'; from: number; message: StreamMessage }
  | { type: 'snapshot'; from: number; state: StateMessage | null; path: PathMessage | null }
  | { type: 'stateRequest' }
  | { type: 'error'; code: number; reason: string };

// ------------------------------------------------------------------ byte helpers

const textEncoder = new TextEncoder();
const textDecoder = new TextDecoder('utf-8', { fatal: true });

// C0/C1 controls and the bidi overrides/isolates (a name must not reorder the page's text).
// eslint-disable-next-line no-control-regex
const FORBIDDEN_TEXT = /[\u0000-\u001f\u007f-\u009f\u202a-\u202e\u2066-\u2069]/;
const DATABASE_PATTERN = /^[A-Za-z0-9._-]{1,64}$/;
// Printable ASCII without spaces, quotes, backslash or angle brackets.
const URL_PATTERN = /^[!#-&(-;=?-[\]-~]+$/;

function utf8(s: string): Uint8Array {
  return textEncoder.encode(s);
}

/** A reader over one message that throws ProtocolError past the end. */
class Reader {
  offset: number;
  constructor(
    readonly view: DataView,
    offset: number,
  ) {
    this.offset = offset;
  }
  need(n: number, what: string): void {
    if (this.offset + n > this.view.byteLength) fail(`truncated ${what} (needs ${n} bytes at ${this.offset}, message has ${this.view.byteLength})`);
  }
  u8(what: string): number {
    this.need(1, what);
    return this.view.getUint8(this.offset++);
  }
  u16(what: string): number {
    this.need(2, what);
    const v = this.view.getUint16(this.offset, true);
    this.offset += 2;
    return v;
  }
  i16(what: string): number {
    this.need(2, what);
    const v = this.view.getInt16(this.offset, true);
    this.offset += 2;
    return v;
  }
  u32(what: string): number {
    this.need(4, what);
    const v = this.view.getUint32(this.offset, true);
    this.offset += 4;
    return v;
  }
  i32(what: string): number {
    this.need(4, what);
    const v = this.view.getInt32(this.offset, true);
    this.offset += 4;
    return v;
  }
  f32(what: string): number {
    this.need(4, what);
    const v = this.view.getFloat32(this.offset, true);
    this.offset += 4;
    if (!Number.isFinite(v)) fail(`${what} is not finite`);
    return v;
  }
  bytes(n: number, what: string): Uint8Array {
    this.need(n, what);
    const b = new Uint8Array(this.view.buffer, this.view.byteOffset + this.offset, n);
    this.offset += n;
    return b;
  }
  text(n: number, what: string): string {
    const b = this.bytes(n, what);
    let s: string;
    try {
      s = textDecoder.decode(b);
    } catch {
      return fail(`${what} is not UTF-8`);
    }
    if (FORBIDDEN_TEXT.test(s)) fail(`${what} has control or bidi-override characters`);
    return s;
  }
  end(what: string): void {
    if (this.offset !== this.view.byteLength) fail(`${what} has ${this.view.byteLength - this.offset} trailing bytes`);
  }
}

/** A writer into a growable scratch buffer; `finish()` returns a fresh copy of the bytes. */
class Writer {
  private buffer: ArrayBuffer;
  private view: DataView;
  offset = 0;
  constructor(capacity = 1024) {
    this.buffer = new ArrayBuffer(capacity);
    this.view = new DataView(this.buffer);
  }
  reset(): this {
    this.offset = 0;
    return this;
  }
  private room(n: number): void {
    if (this.offset + n <= this.buffer.byteLength) return;
    const bigger = new ArrayBuffer(Math.max(this.buffer.byteLength * 2, this.offset + n));
    new Uint8Array(bigger).set(new Uint8Array(this.buffer, 0, this.offset));
    this.buffer = bigger;
    this.view = new DataView(bigger);
  }
  u8(v: number): void {
    this.room(1);
    this.view.setUint8(this.offset++, v);
  }
  u16(v: number): void {
    this.room(2);
    this.view.setUint16(this.offset, v, true);
    this.offset += 2;
  }
  i16(v: number): void {
    this.room(2);
    this.view.setInt16(this.offset, v, true);
    this.offset += 2;
  }
  u32(v: number): void {
    this.room(4);
    this.view.setUint32(this.offset, v >>> 0, true);
    this.offset += 4;
  }
  i32(v: number): void {
    this.room(4);
    this.view.setInt32(this.offset, v, true);
    this.offset += 4;
  }
  f32(v: number): void {
    this.room(4);
    this.view.setFloat32(this.offset, v, true);
    this.offset += 4;
  }
  bytes(b: Uint8Array): void {
    this.room(b.length);
    new Uint8Array(this.buffer, this.offset, b.length).set(b);
    this.offset += b.length;
  }
  finish(): Uint8Array {
    return new Uint8Array(this.buffer.slice(0, this.offset));
  }
}

const scratch = new Writer(2048);

const clampI16 = (v: number) => Math.max(-32768, Math.min(32767, v));
const checkRange = (v: number, lo: number, hi: number, what: string) => {
  if (!(v >= lo && v <= hi)) fail(`${what} = ${v} is outside [${lo}, ${hi}]`);
};

function viewOf(bytes: Uint8Array | ArrayBuffer): DataView {
  return bytes instanceof ArrayBuffer ? new DataView(bytes) : new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
}

function header(w: Writer, type: number): void {
  w.u8(PROTOCOL_VERSION);
  w.u8(type);
}

function readHeader(r: Reader): number {
  const version = r.u8('version');
  if (version !== PROTOCOL_VERSION) fail(`protocol version ${version} (this build speaks ${PROTOCOL_VERSION})`, CloseCode.badVersion);
  return r.u8('type');
}

// ------------------------------------------------------------------ JOIN

export function encodeJoin(j: JoinInfo): Uint8Array {
  const w = scratch.reset();
  header(w, MsgType.join);
  const name = utf8(j.name);
  if (name.length > MAX_NAME_BYTES) fail(`name is ${name.length} bytes (at most ${MAX_NAME_BYTES})`);
  w.u8(name.length);
  w.bytes(name);
  if (j.avatar.kind === 'builtin') {
    w.u8(0);
    w.u8(j.avatar.id);
  } else {
    const url = utf8(j.avatar.url);
    if (url.length > MAX_URL_BYTES) fail(`avatar URL is ${url.length} bytes (at most ${MAX_URL_BYTES})`);
    w.u8(1);
    w.u16(url.length);
    w.bytes(url);
  }
  const db = utf8(j.database);
  w.u8(db.length);
  w.bytes(db);
  w.u16(j.height > 0 ? Math.round(j.height * 1000) : 0);
  w.u8(j.mode === 'vr' ? 1 : 0);
  let devices = 0;
  DEVICE_BITS.forEach((k, i) => {
    if (j.devices[k]) devices |= 1 << i;
  });
  w.u8(devices);
  const style = utf8(j.style ?? 'neutral');
  if (!STYLE_PATTERN.test(j.style ?? 'neutral')) fail('style must be 1–64 of [a-z0-9_-]');
  w.u8(style.length);
  w.bytes(style);
  const out = w.finish();
  decodeJoinBody(new Reader(viewOf(out), 2)); // the encoder never emits what the decoder rejects
  return out;
}

function decodeJoinBody(r: Reader): JoinInfo {
  const nameLength = r.u8('name length');
  if (nameLength > MAX_NAME_BYTES) fail(`name is ${nameLength} bytes (at most ${MAX_NAME_BYTES})`);
  const name = r.text(nameLength, 'name');
  const kind = r.u8('avatar kind');
  let avatar: AvatarChoice;
  if (kind === 0) avatar = { kind: 'builtin', id: r.u8('built-in avatar') };
  else if (kind === 1) {
    const n = r.u16('avatar URL length');
    if (n < 1 || n > MAX_URL_BYTES) fail(`avatar URL is ${n} bytes (1–${MAX_URL_BYTES})`);
    const url = r.text(n, 'avatar URL');
    if (!URL_PATTERN.test(url)) fail('avatar URL has characters outside printable ASCII');
    avatar = { kind: 'url', url };
  } else return fail(`avatar kind ${kind} (0 built-in, 1 URL)`);
  const dbLength = r.u8('database length');
  const database = r.text(dbLength, 'database');
  if (!DATABASE_PATTERN.test(database)) fail('database id must be 1–64 of [A-Za-z0-9._-]');
  const heightMm = r.u16('height');
  if (heightMm !== 0) checkRange(heightMm, MIN_HEIGHT_MM, MAX_HEIGHT_MM, 'height (mm)');
  const mode = r.u8('mode');
  if (mode > 1) fail(`mode ${mode} (0 desktop, 1 vr)`);
  const bits = r.u8('devices');
  if (bits >= 1 << DEVICE_BITS.length) fail(`device bits 0x${bits.toString(16)} has unknown devices`);
  const devices: DeviceSet = {};
  DEVICE_BITS.forEach((k, i) => {
    if (bits & (1 << i)) devices[k] = true;
  });
  const styleLength = r.u8('style length');
  const style = styleLength === 0 ? 'neutral' : r.text(styleLength, 'style');
  if (!STYLE_PATTERN.test(style)) fail('style must be 1–64 of [a-z0-9_-]');
  r.end('join');
  return { name, avatar, database, height: heightMm / 1000, mode: mode === 1 ? 'vr' : 'desktop', devices, style };
}

// ------------------------------------------------------------------ stream messages

function streamHeader(w: Writer, type: number, h: StreamHeader): void {
  header(w, type);
  w.u32(h.seq);
  w.u32(h.time);
}

function readStream(r: Reader): StreamHeader {
  const seq = r.u32('seq');
  if (seq === 0) fail('seq 0 (sequences start at 1)');
  return { seq, time: r.u32('time') };
}

function readTicks(r: Reader): number {
  const ticks = r.u16('dt');
  if (ticks < 1 || ticks > MAX_DT_TICKS) fail(`step dt ${ticks} ticks is outside [1, ${MAX_DT_TICKS}]`);
  return ticks;
}

const MOVE_RUN = 1;
const MOVE_STRAFE = 2;
const MOVE_HAS_MOVE = 4;
const MOVE_HAS_FACE = 8;
const MOVE_PATH = 16;
const MOVE_SAME_DT = 32;
const MOVE_FLAGS = MOVE_RUN | MOVE_STRAFE | MOVE_HAS_MOVE | MOVE_HAS_FACE | MOVE_PATH | MOVE_SAME_DT;

/** int8 of a value in [-1, 1] (q / 127): stick resolution 1/127, facing direction error < 0.31° (measured). */
export function unitToI8(v: number): number {
  if (!Number.isFinite(v)) return 0;
  return Math.max(-127, Math.min(127, Math.round(v * 127)));
}
export function i8ToUnit(q: number): number {
  return q / 127;
}

/** A desktop step of zero: standing, facing +Z. */
export function createMoveStep(): MoveStep {
  return { ticks: 0, moveX: 0, moveZ: 0, faceX: 0, faceZ: 1, run: false, strafe: false, path: false };
}

export function createTrackedStep(): TrackedStep {
  return { ticks: 0, headX: 0, headZ: 0, velocityX: 0, velocityZ: 0, yaw: 0, body: false, hipsDrop: 0, bend: 0 };
}

/**
 * Quantizes a move input in place to what the wire carries (the sender must drive with it):
 * the move clamped to length 1, the facing normalized (a zero facing becomes +Z), both int8.
 */
export function quantizeMoveStep(s: MoveStep): MoveStep {
  let mx = Number.isFinite(s.moveX) ? s.moveX : 0;
  let mz = Number.isFinite(s.moveZ) ? s.moveZ : 0;
  const m = Math.hypot(mx, mz);
  if (m > 1) {
    mx /= m;
    mz /= m;
  }
  s.moveX = i8ToUnit(unitToI8(mx));
  s.moveZ = i8ToUnit(unitToI8(mz));
  if (Math.hypot(s.moveX, s.moveZ) > 1) {
    // (90, 90)/127 is 1.002 long; shorten the longer axis by one step.
    if (Math.abs(s.moveX) >= Math.abs(s.moveZ)) s.moveX = i8ToUnit(unitToI8(s.moveX) - Math.sign(s.moveX));
    else s.moveZ = i8ToUnit(unitToI8(s.moveZ) - Math.sign(s.moveZ));
  }
  const f = Math.hypot(s.faceX, s.faceZ);
  const fx = f > 1e-6 && Number.isFinite(f) ? s.faceX / f : 0;
  const fz = f > 1e-6 && Number.isFinite(f) ? s.faceZ / f : 1;
  s.faceX = i8ToUnit(unitToI8(fx));
  s.faceZ = i8ToUnit(unitToI8(fz));
  return s;
}

/** Torso bend on the wire: u8 in half degrees (0–127.5°; the runtime bends at most 80°). */
function bendToU8(bend: number): number {
  return Number.isFinite(bend) ? Math.max(0, Math.min(255, Math.round((bend * 360) / Math.PI))) : 0;
}
function u8ToBend(q: number): number {
  return (q * Math.PI) / 360;
}

/**
 * The hips drop and the body flag share a u16: bits 0–14 the drop in mm (0–32.767 m), bit 15 set
 * when the step is the tracked hips' (body tracking).
 */
function dropToU16(drop: number, body: boolean): number {
  return Math.max(0, Math.min(0x7fff, toMm(drop))) | (body ? 0x8000 : 0);
}
function dropFromU16(q: number): { hipsDrop: number; body: boolean } {
  return { hipsDrop: fromMm(q & 0x7fff), body: (q & 0x8000) !== 0 };
}

/** Quantizes a tracked step in place (positions to absolute mm, velocity mm/s, yaw int16, drop mm, bend ½°). */
export function quantizeTrackedStep(s: TrackedStep): TrackedStep {
  s.headX = fromMm(toMm(s.headX));
  s.headZ = fromMm(toMm(s.headZ));
  s.velocityX = fromMm(clampI16(toMm(s.velocityX)));
  s.velocityZ = fromMm(clampI16(toMm(s.velocityZ)));
  s.yaw = i16ToAngle(angleToI16(s.yaw));
  s.hipsDrop = fromMm(dropToU16(s.hipsDrop, false));
  s.body = s.body === true;
  s.bend = u8ToBend(bendToU8(s.bend));
  return s;
}

function writeMoveInput(w: Writer, s: MoveStep, flags: number, hasMove: boolean, hasFace: boolean): void {
  w.u8(flags | (s.run ? MOVE_RUN : 0) | (s.strafe ? MOVE_STRAFE : 0) | (hasMove ? MOVE_HAS_MOVE : 0) | (hasFace ? MOVE_HAS_FACE : 0) | (s.path ? MOVE_PATH : 0));
}

/**
 * Step layout: flags (u8), then dt (u16 ticks) unless "same dt", move (2 × int8) if changed,
 * facing (2 × int8) if changed. The first step of every message is complete (dt, move and
 * facing), so a message decodes on its own; a steady step is 1 byte.
 */
export function encodeMove(m: Omit<MoveMessage, 'type'>): Uint8Array {
  if (m.steps.length > MAX_STEPS) fail(`${m.steps.length} steps (at most ${MAX_STEPS})`);
  const w = scratch.reset();
  streamHeader(w, MsgType.move, m);
  w.i32(toMm(m.rootX));
  w.i32(toMm(m.rootZ));
  w.i16(angleToI16(m.rootYaw));
  w.u8(m.steps.length);
  let prev: MoveStep | null = null;
  for (const s of m.steps) {
    const mx = unitToI8(s.moveX);
    const mz = unitToI8(s.moveZ);
    const fx = unitToI8(s.faceX);
    const fz = unitToI8(s.faceZ);
    const hasMove = !prev || mx !== unitToI8(prev.moveX) || mz !== unitToI8(prev.moveZ);
    const hasFace = !prev || fx !== unitToI8(prev.faceX) || fz !== unitToI8(prev.faceZ);
    const sameDt = prev !== null && prev.ticks === s.ticks;
    writeMoveInput(w, s, sameDt ? MOVE_SAME_DT : 0, hasMove, hasFace);
    if (!sameDt) w.u16(s.ticks);
    if (hasMove) {
      w.u8(mx & 0xff);
      w.u8(mz & 0xff);
    }
    if (hasFace) {
      w.u8(fx & 0xff);
      w.u8(fz & 0xff);
    }
    prev = s;
  }
  const out = w.finish();
  return out;
}

function readI8Unit(r: Reader, what: string): number {
  const q = (r.u8(what) << 24) >> 24;
  if (q === -128) fail(`${what} is outside [-1, 1]`);
  return i8ToUnit(q);
}

function readMoveInput(r: Reader, s: MoveStep, flags: number, what: string): void {
  s.run = (flags & MOVE_RUN) !== 0;
  s.strafe = (flags & MOVE_STRAFE) !== 0;
  s.path = (flags & MOVE_PATH) !== 0;
  if (flags & MOVE_HAS_MOVE) {
    s.moveX = readI8Unit(r, 'move x');
    s.moveZ = readI8Unit(r, 'move z');
    const n = Math.hypot(s.moveX, s.moveZ);
    if (n > 1.0001) fail(`${what} move length ${n.toFixed(4)} > 1`);
  }
  if (flags & MOVE_HAS_FACE) {
    s.faceX = readI8Unit(r, 'face x');
    s.faceZ = readI8Unit(r, 'face z');
    const n = Math.hypot(s.faceX, s.faceZ);
    if (n < 0.98 || n > 1.02) fail(`${what} facing length ${n.toFixed(3)} is not 1`);
  }
}

function decodeMoveBody(r: Reader, h: StreamHeader): MoveMessage {
  const rootX = fromMm(r.i32('root x'));
  const rootZ = fromMm(r.i32('root z'));
  const rootYaw = i16ToAngle(r.i16('root yaw'));
  const n = r.u8('step count');
  if (n > MAX_STEPS) fail(`${n} steps (at most ${MAX_STEPS})`);
  const steps: MoveStep[] = [];
  for (let i = 0; i < n; i++) {
    const flags = r.u8('step flags');
    if (flags & ~MOVE_FLAGS) fail(`step ${i} has unknown flag bits`);
    if (i === 0 && (flags & (MOVE_HAS_MOVE | MOVE_HAS_FACE | MOVE_SAME_DT)) !== (MOVE_HAS_MOVE | MOVE_HAS_FACE)) fail('the first step must carry dt, move and facing');
    const s: MoveStep = i === 0 ? createMoveStep() : { ...steps[i - 1] };
    if (!(flags & MOVE_SAME_DT)) s.ticks = readTicks(r);
    readMoveInput(r, s, flags, `step ${i}`);
    steps.push(s);
  }
  r.end('move');
  return { type: 'move', ...h, rootX, rootZ, rootYaw, steps };
}

const TRACKER_TRACKED = [1, 2, 4];
const TRACKER_HAND = [0, 8, 16];

export function encodeTracked(m: Omit<TrackedMessage, 'type'>): Uint8Array {
  if (m.steps.length > MAX_STEPS) fail(`${m.steps.length} steps (at most ${MAX_STEPS})`);
  checkRange(m.scale, MIN_SCALE, MAX_SCALE, 'scale');
  const w = scratch.reset();
  streamHeader(w, MsgType.tracked, m);
  // Origin: the root (1 mm); every other position is int16 mm relative to it.
  const ox = toMm(m.rootX);
  const oz = toMm(m.rootZ);
  const rel = (v: number, o: number, what: string) => {
    const d = toMm(v) - o;
    if (Math.abs(d) > MAX_RELATIVE_MM) fail(`${what} is ${(d / 1000).toFixed(1)} m from the root (at most ±32.767 m)`);
    return d;
  };
  w.i32(ox);
  w.i32(oz);
  w.i16(angleToI16(m.rootYaw));
  w.f32(m.scale);
  w.u8(Math.max(0, Math.min(255, Math.round(m.alpha * 100))));
  let flags = 0;
  m.trackers.forEach((t, i) => {
    if (t.tracked) flags |= TRACKER_TRACKED[i];
    if (t.fromHand && i > 0) flags |= TRACKER_HAND[i];
  });
  w.u8(flags);
  m.trackers.forEach((t, i) => {
    w.i16(rel(t.position[0], ox, `tracker ${i} x`));
    w.i16(clampI16(toMm(t.position[1])));
    w.i16(rel(t.position[2], oz, `tracker ${i} z`));
    w.u32(packQuat(t.rotation[0], t.rotation[1], t.rotation[2], t.rotation[3]));
  });
  w.u8(m.steps.length);
  for (const s of m.steps) {
    w.u16(s.ticks);
    w.i16(rel(s.headX, ox, 'head x'));
    w.i16(rel(s.headZ, oz, 'head z'));
    w.i16(clampI16(toMm(s.velocityX)));
    w.i16(clampI16(toMm(s.velocityZ)));
    w.i16(angleToI16(s.yaw));
    w.u16(dropToU16(s.hipsDrop, s.body));
    w.u8(bendToU8(s.bend));
  }
  return w.finish();
}

function readScale(r: Reader): number {
  const scale = r.f32('scale');
  checkRange(scale, MIN_SCALE, MAX_SCALE, 'scale');
  return scale;
}

function decodeTrackedBody(r: Reader, h: StreamHeader): TrackedMessage {
  const ox = r.i32('root x');
  const oz = r.i32('root z');
  const rootYaw = i16ToAngle(r.i16('root yaw'));
  const scale = readScale(r);
  const alpha = r.u8('alpha') / 100;
  const flags = r.u8('tracker flags');
  if (flags >= 32) fail('tracker flags has unknown bits');
  const q = [0, 0, 0, 0];
  const trackers = [0, 1, 2].map((i): RoomTrackerPose => {
    const x = fromMm(ox + r.i16('tracker x'));
    const y = fromMm(r.i16('tracker y'));
    const z = fromMm(oz + r.i16('tracker z'));
    unpackQuat(r.u32('tracker rotation'), q);
    return {
      tracked: (flags & TRACKER_TRACKED[i]) !== 0,
      fromHand: (flags & TRACKER_HAND[i]) !== 0,
      position: [x, y, z],
      rotation: [q[0], q[1], q[2], q[3]],
    };
  }) as [RoomTrackerPose, RoomTrackerPose, RoomTrackerPose];
  const n = r.u8('step count');
  if (n > MAX_STEPS) fail(`${n} steps (at most ${MAX_STEPS})`);
  const steps: TrackedStep[] = [];
  for (let i = 0; i < n; i++) {
    steps.push({
      ticks: readTicks(r),
      headX: fromMm(ox + r.i16('head x')),
      headZ: fromMm(oz + r.i16('head z')),
      velocityX: fromMm(r.i16('velocity x')),
      velocityZ: fromMm(r.i16('velocity z')),
      yaw: i16ToAngle(r.i16('yaw')),
      ...dropFromU16(r.u16('hips drop')),
      bend: u8ToBend(r.u8('torso bend')),
    });
  }
  r.end('tracked');
  return { type: 'tracked', ...h, rootX: fromMm(ox), rootZ: fromMm(oz), rootYaw, scale, alpha, trackers, steps };
}

export function encodePath(m: Omit<PathMessage, 'type'>): Uint8Array {
  const count = m.points.length / 2;
  const w = scratch.reset();
  streamHeader(w, MsgType.path, m);
  w.u8(m.looped ? 1 : 0);
  w.u8(count);
  for (let i = 0; i < m.points.length; i++) w.f32(m.points[i]);
  for (let i = 0; i < m.speeds.length; i++) w.f32(m.speeds[i]);
  const out = w.finish();
  decodeClientMessage(out); // validates counts and ranges; throws what the receiver would
  return out;
}

function decodePathBody(r: Reader, h: StreamHeader): PathMessage {
  const flags = r.u8('path flags');
  if (flags > 1) fail('path flags has unknown bits');
  const looped = flags === 1;
  const count = r.u8('point count');
  if (count < 2 || count > MAX_PATH_POINTS) fail(`${count} path points (2–${MAX_PATH_POINTS})`);
  const points = new Float32Array(count * 2);
  for (let i = 0; i < points.length; i++) {
    points[i] = r.f32('path point');
    if (Math.abs(points[i]) > MAX_PATH_COORD) fail(`path point ${points[i]} is beyond ±${MAX_PATH_COORD}`);
  }
  const speeds = new Float32Array(looped ? count : count - 1);
  for (let i = 0; i < speeds.length; i++) {
    speeds[i] = r.f32('path speed');
    if (!(speeds[i] > 0 && speeds[i] <= MAX_PATH_SPEED)) fail(`path speed ${speeds[i]} is outside (0, ${MAX_PATH_SPEED}]`);
  }
  r.end('path');
  return { type: 'path', ...h, points, speeds, looped };
}

export function encodeState(m: Omit<StateMessage, 'type'>): Uint8Array {
  checkRange(m.scale, MIN_SCALE, MAX_SCALE, 'scale');
  const w = scratch.reset();
  streamHeader(w, MsgType.state, m);
  w.u32(m.frame);
  const ox = toMm(m.rootX);
  const oz = toMm(m.rootZ);
  w.i32(ox);
  w.i32(oz);
  w.i16(angleToI16(m.rootYaw));
  const runtime = m.runtime ?? null;
  w.u8(DRIVES.indexOf(m.drive) | (m.restart ? STATE_RESTART : 0) | (runtime ? STATE_RUNTIME : 0));
  w.f32(m.pathTime);
  w.f32(m.scale);
  w.u8(Math.max(0, Math.min(255, Math.round(m.alpha * 100))));
  const s = m.move;
  writeMoveInput(w, s, 0, true, true);
  w.u8(unitToI8(s.moveX) & 0xff);
  w.u8(unitToI8(s.moveZ) & 0xff);
  w.u8(unitToI8(s.faceX) & 0xff);
  w.u8(unitToI8(s.faceZ) & 0xff);
  const t = m.tracked;
  w.i16(clampI16(toMm(t.headX) - ox));
  w.i16(clampI16(toMm(t.headZ) - oz));
  w.i16(clampI16(toMm(t.velocityX)));
  w.i16(clampI16(toMm(t.velocityZ)));
  w.i16(angleToI16(t.yaw));
  w.u16(dropToU16(t.hipsDrop, t.body));
  w.u8(bendToU8(t.bend));
  if (runtime) {
    if (runtime.length < 1 || runtime.length > MAX_RUNTIME_STATE_BYTES) fail(`runtime state of ${runtime.length} bytes (1–${MAX_RUNTIME_STATE_BYTES})`);
    w.u16(runtime.length);
    w.bytes(runtime);
  }
  return w.finish();
}

function decodeStateBody(r: Reader, h: StreamHeader): StateMessage {
  const frame = r.u32('frame');
  if (frame >= 1 << 24) fail(`frame ${frame} is beyond 2^24`);
  const ox = r.i32('root x');
  const oz = r.i32('root z');
  const rootYaw = i16ToAngle(r.i16('root yaw'));
  const driveByte = r.u8('drive');
  const driveIndex = driveByte & ~(STATE_RESTART | STATE_RUNTIME);
  if (driveIndex >= DRIVES.length) fail(`drive ${driveIndex} (0 move, 1 path, 2 tracked; bit 6 runtime state, bit 7 restart)`);
  const pathTime = r.f32('path time');
  checkRange(pathTime, 0, 86400, 'path time (s)');
  const scale = readScale(r);
  const alpha = r.u8('alpha') / 100;
  const move = createMoveStep();
  const flags = r.u8('move flags');
  if ((flags & ~MOVE_FLAGS) || (flags & (MOVE_HAS_MOVE | MOVE_HAS_FACE | MOVE_SAME_DT)) !== (MOVE_HAS_MOVE | MOVE_HAS_FACE)) fail('state move flags');
  readMoveInput(r, move, flags, 'state move');
  const tracked: TrackedStep = {
    ticks: 0,
    headX: fromMm(ox + r.i16('head dx')),
    headZ: fromMm(oz + r.i16('head dz')),
    velocityX: fromMm(r.i16('velocity x')),
    velocityZ: fromMm(r.i16('velocity z')),
    yaw: i16ToAngle(r.i16('yaw')),
    ...dropFromU16(r.u16('hips drop')),
    bend: u8ToBend(r.u8('torso bend')),
  };
  let runtime: Uint8Array | null = null;
  if (driveByte & STATE_RUNTIME) {
    const n = r.u16('runtime state length');
    if (n < 1 || n > MAX_RUNTIME_STATE_BYTES) fail(`runtime state of ${n} bytes (1–${MAX_RUNTIME_STATE_BYTES})`);
    runtime = r.bytes(n, 'runtime state').slice(); // the runtime checks its contents
  }
  r.end('state');
  return { type: 'state', ...h, frame, rootX: fromMm(ox), rootZ: fromMm(oz), rootYaw, drive: DRIVES[driveIndex], restart: (driveByte & STATE_RESTART) !== 0, pathTime, scale, alpha, move, tracked, runtime };
}

/**
 * Decodes and validates a client → server message (the server runs this on every message;
 * receivers run it again on relayed ones). Throws ProtocolError.
 */
export function decodeClientMessage(bytes: Uint8Array | ArrayBuffer): ClientMessage {
  const view = viewOf(bytes);
  if (view.byteLength > MAX_MESSAGE_BYTES) fail(`message is ${view.byteLength} bytes (at most ${MAX_MESSAGE_BYTES})`);
  const r = new Reader(view, 0);
  const type = readHeader(r);
  if (type !== MsgType.state && view.byteLength > MAX_CLIENT_MESSAGE_BYTES) fail(`message is ${view.byteLength} bytes (at most ${MAX_CLIENT_MESSAGE_BYTES} but a STATE)`);
  if (type === MsgType.join) return { type: 'join', ...decodeJoinBody(r) };
  return decodeStream(r, type);
}

function decodeStream(r: Reader, type: number): StreamMessage {
  switch (type) {
    case MsgType.move:
      return decodeMoveBody(r, readStream(r));
    case MsgType.tracked:
      return decodeTrackedBody(r, readStream(r));
    case MsgType.path:
      return decodePathBody(r, readStream(r));
    case MsgType.state:
      return decodeStateBody(r, readStream(r));
    default:
      return fail(`unknown client message type 0x${type.toString(16)}`);
  }
}

/** Total simulated seconds of a stream message's steps (0 for path and state). */
export function stepSeconds(m: StreamMessage): number {
  if (m.type !== 'move' && m.type !== 'tracked') return 0;
  let ticks = 0;
  for (const s of m.steps) ticks += s.ticks;
  return ticks / TICKS_PER_SECOND;
}

// ------------------------------------------------------------------ server → client

/**
 * Server messages embed client bytes the server has validated (JOIN, stream messages): it
 * forwards them without re-encoding, and clients decode them with the same checks.
 */
export function encodeWelcome(memberId: number, maxMembers: number, members: { id: number; join: Uint8Array }[]): Uint8Array {
  let size = 5;
  for (const m of members) size += 3 + m.join.length;
  const out = new Uint8Array(size);
  const v = new DataView(out.buffer);
  out[0] = PROTOCOL_VERSION;
  out[1] = MsgType.welcome;
  out[2] = memberId;
  out[3] = maxMembers;
  out[4] = members.length;
  let o = 5;
  for (const m of members) {
    out[o] = m.id;
    v.setUint16(o + 1, m.join.length, true);
    out.set(m.join, o + 3);
    o += 3 + m.join.length;
  }
  return out;
}

function prefixed(type: number, id: number, body: Uint8Array): Uint8Array {
  const out = new Uint8Array(3 + body.length);
  out[0] = PROTOCOL_VERSION;
  out[1] = type;
  out[2] = id;
  out.set(body, 3);
  return out;
}

export function encodeMemberJoined(id: number, join: Uint8Array): Uint8Array {
  return prefixed(MsgType.memberJoined, id, join);
}

/** A relayed stream message: 3 bytes (version, type, sender id) + the sender's bytes. */
export function encodeRelay(from: number, message: Uint8Array): Uint8Array {
  return prefixed(MsgType.relay, from, message);
}

export function encodeMemberLeft(id: number, reason: LeaveReasonName): Uint8Array {
  return new Uint8Array([PROTOCOL_VERSION, MsgType.memberLeft, id, LeaveReason[reason]]);
}

export function encodeSnapshot(from: number, state: Uint8Array | null, path: Uint8Array | null): Uint8Array {
  const s = state ?? new Uint8Array(0);
  const p = path ?? new Uint8Array(0);
  const out = new Uint8Array(7 + s.length + p.length);
  const v = new DataView(out.buffer);
  out[0] = PROTOCOL_VERSION;
  out[1] = MsgType.snapshot;
  out[2] = from;
  v.setUint16(3, s.length, true);
  out.set(s, 5);
  v.setUint16(5 + s.length, p.length, true);
  out.set(p, 7 + s.length);
  return out;
}

export function encodeStateRequest(): Uint8Array {
  return new Uint8Array([PROTOCOL_VERSION, MsgType.stateRequest]);
}

export function encodeError(code: number, reason: string): Uint8Array {
  const text = utf8(reason.slice(0, 120));
  const out = new Uint8Array(5 + text.length);
  out[0] = PROTOCOL_VERSION;
  out[1] = MsgType.error;
  new DataView(out.buffer).setUint16(2, code, true);
  out[4] = text.length;
  out.set(text, 5);
  return out;
}

function checkMemberId(id: number): number {
  if (id < 1 || id > MAX_MEMBERS_LIMIT * 4) fail(`member id ${id} is out of range`);
  return id;
}

function embedded(r: Reader, n: number, what: string): Reader {
  const b = r.bytes(n, what);
  return new Reader(new DataView(b.buffer, b.byteOffset, b.byteLength), 0);
}

function decodeEmbeddedJoin(r: Reader): JoinInfo {
  if (readHeader(r) !== MsgType.join) fail('embedded join has another type');
  return decodeJoinBody(r);
}

/** Decodes and validates a server → client message (clients treat it as untrusted). */
export function decodeServerMessage(bytes: Uint8Array | ArrayBuffer): ServerMessage {
  const view = viewOf(bytes);
  const r = new Reader(view, 0);
  const type = readHeader(r);
  switch (type) {
    case MsgType.welcome: {
      const memberId = checkMemberId(r.u8('member id'));
      const maxMembers = r.u8('max members');
      const count = r.u8('member count');
      if (count > MAX_MEMBERS_LIMIT) fail(`${count} members`);
      const members: MemberInfo[] = [];
      for (let i = 0; i < count; i++) {
        const id = checkMemberId(r.u8('member id'));
        const n = r.u16('join length');
        members.push({ id, join: decodeEmbeddedJoin(embedded(r, n, 'join')) });
      }
      r.end('welcome');
      return { type: 'welcome', memberId, maxMembers, members };
    }
    case MsgType.memberJoined: {
      const id = checkMemberId(r.u8('member id'));
      return { type: 'memberJoined', member: { id, join: decodeEmbeddedJoin(r) } };
    }
    case MsgType.memberLeft: {
      const id = checkMemberId(r.u8('member id'));
      const code = r.u8('reason');
      const reason = (Object.keys(LeaveReason) as LeaveReasonName[]).find((k) => LeaveReason[k] === code);
      if (!reason) fail(`leave reason ${code}`);
      r.end('member left');
      return { type: 'memberLeft', id, reason: reason! };
    }
    case MsgType.relay: {
      const from = checkMemberId(r.u8('member id'));
      const inner = embedded(r, view.byteLength - r.offset, 'relayed message');
      const innerType = readHeader(inner);
      if (inner.view.byteLength > (innerType === MsgType.state ? MAX_MESSAGE_BYTES : MAX_CLIENT_MESSAGE_BYTES)) fail('relayed message is too long');
      return { type: 'relay', from, message: decodeStream(inner, innerType) };
    }
    case MsgType.snapshot: {
      const from = checkMemberId(r.u8('member id'));
      const sn = r.u16('state length');
      let state: StateMessage | null = null;
      if (sn > 0) {
        const sr = embedded(r, sn, 'state');
        if (readHeader(sr) !== MsgType.state) fail('snapshot state has another type');
        state = decodeStateBody(sr, readStream(sr));
      }
      const pn = r.u16('path length');
      let path: PathMessage | null = null;
      if (pn > 0) {
        const pr = embedded(r, pn, 'path');
        if (readHeader(pr) !== MsgType.path) fail('snapshot path has another type');
        path = decodePathBody(pr, readStream(pr));
      }
      r.end('snapshot');
      return { type: 'snapshot', from, state, path };
    }
    case MsgType.stateRequest:
      r.end('state request');
      return { type: 'stateRequest' };
    case MsgType.error: {
      const code = r.u16('error code');
      const n = r.u8('reason length');
      const reason = r.text(n, 'reason');
      r.end('error');
      return { type: 'error', code, reason };
    }
    case MsgType.batch:
      return fail('a batch holds several messages: split it with unbatch() first');
    default:
      return fail(`unknown server message type 0x${type.toString(16)}`);
  }
}

// ------------------------------------------------------------------ batches

/** Bytes a message adds to a BATCH (its u16 length); the batch itself adds 2 (version, type). */
export const BATCH_ENTRY_BYTES = 2;
export const BATCH_HEADER_BYTES = 2;

/**
 * Packs server messages for one receiver into one frame: `[version, 0x87, (u16 length, message)…]`.
 * Why: a WebSocket frame costs the server a write and the receiver an event however small it is;
 * in a busy room most frames are 60–200-byte relays, so the frame, not the bytes, is the cost
 * (docs/rooms.md "Batches"). A batch holds no batch.
 */
export function encodeBatch(messages: readonly Uint8Array[]): Uint8Array {
  let total = 0;
  for (const m of messages) total += m.length;
  const out = new Uint8Array(BATCH_HEADER_BYTES + BATCH_ENTRY_BYTES * messages.length + total);
  out[0] = PROTOCOL_VERSION;
  out[1] = MsgType.batch;
  let o = BATCH_HEADER_BYTES;
  for (const m of messages) {
    if (m.length > 0xffff) fail(`a ${m.length}-byte message does not fit a batch`);
    out[o] = m.length & 0xff;
    out[o + 1] = m.length >> 8;
    out.set(m, o + 2);
    o += BATCH_ENTRY_BYTES + m.length;
  }
  return out;
}

/**
 * The server messages in one frame: the frame itself, or a BATCH's messages (views into it, in
 * order). Throws a `ProtocolError` on a batch whose lengths do not add up (or that nests one); the
 * messages themselves are checked by `decodeServerMessage`.
 */
export function unbatch(bytes: Uint8Array | ArrayBuffer): Uint8Array[] {
  const b = bytes instanceof ArrayBuffer ? new Uint8Array(bytes) : bytes;
  if (b.length < 2 || b[1] !== MsgType.batch) return [b];
  if (b[0] !== PROTOCOL_VERSION) fail(`protocol version ${b[0]} (this build speaks ${PROTOCOL_VERSION})`, CloseCode.badVersion);
  const out: Uint8Array[] = [];
  let o = BATCH_HEADER_BYTES;
  while (o < b.length) {
    if (o + BATCH_ENTRY_BYTES > b.length) fail(`batch: a length at byte ${o} is cut off`);
    const n = b[o] | (b[o + 1] << 8);
    o += BATCH_ENTRY_BYTES;
    if (n < 2 || o + n > b.length) fail(`batch: message ${out.length} at byte ${o} claims ${n} bytes, ${b.length - o} left`);
    if (b[o + 1] === MsgType.batch) fail(`batch: message ${out.length} is itself a batch`);
    out.push(b.subarray(o, o + n));
    o += n;
  }
  if (out.length === 0) fail('batch: empty');
  return out;
}

// ------------------------------------------------------------------ framing (bandwidth)

/** WebSocket frame header bytes for a payload (RFC 6455 §5.2); clients add a 4-byte mask. */
export function websocketFrameOverhead(payloadBytes: number, masked: boolean): number {
  const base = payloadBytes < 126 ? 2 : payloadBytes < 65536 ? 4 : 10;
  return base + (masked ? 4 : 0);
}
