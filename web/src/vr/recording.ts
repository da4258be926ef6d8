/**
 * Recorded tracker sessions (docs/vr-recording.md): the HMD and both controller grip poses per
 * frame with timestamps and tracked flags, and the body joints where the headset tracked the
 * body — exactly the `TrackerSample`s the live pipeline consumes — so a VR session can be
 * replayed on the desktop page without a headset. Two encodings of one versioned format: JSON
 * (readable, diffable) and a compact little-endian binary (`MMTR` magic). Loading validates
 * everything and names what is wrong.
 */
import { validateRecordingValues } from '../core/recording.ts';
import { BODY_JOINTS, NUM_BODY_JOINTS, NUM_TRACKERS, type TrackerSample } from './tracker-sample.ts';

export const RECORDING_FORMAT = 'mm-vr-recording';
export const RECORDING_VERSION = 1;
const MAGIC = 0x52544d4d; // 'MMTR' read as a little-endian u32
/** The binary version with body joints (a recording without them is written as version 1). */
const BINARY_BODY_VERSION = 2;
const HEADER_BYTES = 16;

/** Free-form facts about a recording (device, frame rate, calibrated eye height, source…). */
export type RecordingMeta = Record<string, string | number | boolean>;

/** A recording in memory: SoA over frames, the layout of `TrackerSample` repeated. */
export interface Recording {
  readonly frames: number;
  /** Seconds, strictly increasing. */
  readonly time: Float64Array;
  /** frames × 3 trackers × (x, y, z), m, local-floor space. */
  readonly position: Float64Array;
  /** frames × 3 trackers × (x, y, z, w). */
  readonly rotation: Float64Array;
  /** frames × 3 trackers: 1 tracked, 0 not. */
  readonly tracked: Uint8Array;
  readonly meta: RecordingMeta;
  /** Optional ground truth (synthetic recordings from mocap; JSON only). */
  readonly truth?: RecordingTruth;
  /** Optional body joints (WebXR body tracking, or synthetic from mocap). */
  readonly body?: RecordingBody;
}

/** Tracked body joints per frame (docs/vr-recording.md, `body`). */
export interface RecordingBody {
  /** WebXR body joint names (`BODY_JOINTS` when the page recorded them). */
  readonly joints: readonly string[];
  /** frames × joints × (x, y, z), m, local-floor space. */
  readonly position: Float64Array;
  /** frames × joints × (x, y, z, w). */
  readonly rotation: Float64Array;
  /** frames × joints: 1 tracked, 0 not. */
  readonly tracked: Uint8Array;
}

/** What the user's body really did, per frame (docs/vr-recording.md, `truth`). */
export interface RecordingTruth {
  /** Body (virtual-root) yaw, rad, 0 = +Z; unwrapped. */
  readonly bodyYaw: Float64Array;
  /** Root floor position, frames × (x, z), m. */
  readonly root: Float64Array;
}

export class RecordingError extends Error {
  constructor(source: string, message: string) {
    super(`${source}: ${message}`);
    this.name = 'RecordingError';
  }
}

/**
 * Checks lengths, finiteness, time order and unit quaternions; throws a RecordingError. The
 * checks are the runtime's (`validateRecordingValues`, through WASM: `initWasm()` first), the
 * very code `mmdb replay` runs, so both accept the same recordings.
 */
export function validateRecording(r: Recording, source = 'recording'): void {
  try {
    validateRecordingValues(r);
  } catch (e) {
    throw new RecordingError(source, e instanceof Error ? e.message : String(e));
  }
}

// ------------------------------------------------------------------ JSON

/** JSON text of a recording (flat SoA arrays; positions rounded to 0.1 mm, rotations to 1e-6). */
export function encodeRecordingJson(r: Recording): string {
  const round = (a: ArrayLike<number>, digits: number) => Array.from(a, (v) => Number(v.toFixed(digits)));
  return JSON.stringify({
    format: RECORDING_FORMAT,
    version: RECORDING_VERSION,
    trackers: ['head', 'left', 'right'],
    frames: r.frames,
    meta: r.meta,
    time: round(r.time, 6),
    position: round(r.position, 5),
    rotation: round(r.rotation, 6),
    tracked: Array.from(r.tracked),
    ...(r.truth ? { truth: { bodyYaw: round(r.truth.bodyYaw, 5), root: round(r.truth.root, 5) } } : {}),
    ...(r.body ? { body: { joints: r.body.joints, position: round(r.body.position, 5), rotation: round(r.body.rotation, 6), tracked: Array.from(r.body.tracked) } } : {}),
  });
}

function fromJson(text: string, source: string): Recording {
  let data: unknown;
  try {
    data = JSON.parse(text);
  } catch (e) {
    throw new RecordingError(source, `not JSON (${e instanceof Error ? e.message : String(e)})`);
  }
  const fail = (m: string): never => {
    throw new RecordingError(source, m);
  };
  if (typeof data !== 'object' || data === null || Array.isArray(data)) fail('expected a JSON object');
  const o = data as Record<string, unknown>;
  if (o.format !== RECORDING_FORMAT) fail(`"format" must be "${RECORDING_FORMAT}" (got ${JSON.stringify(o.format)})`);
  if (o.version !== RECORDING_VERSION) fail(`unsupported version ${JSON.stringify(o.version)} (this page reads version ${RECORDING_VERSION})`);
  // `obj[name]` as numbers, or what is wrong with it (`"body.position"[4] is not a number`).
  const numbersIn = (obj: Record<string, unknown>, prefix: string, name: string): number[] => {
    const v = obj[name];
    if (!Array.isArray(v)) fail(`"${prefix}${name}" must be an array of numbers`);
    const a = v as unknown[];
    for (let i = 0; i < a.length; i++) if (typeof a[i] !== 'number') fail(`"${prefix}${name}"[${i}] is not a number`);
    return a as number[];
  };
  const numbers = (name: string): number[] => numbersIn(o, '', name);
  const meta = o.meta ?? {};
  if (typeof meta !== 'object' || meta === null || Array.isArray(meta)) fail('"meta" must be an object');
  const frames = o.frames;
  if (typeof frames !== 'number') fail('"frames" must be a number');
  let truth: RecordingTruth | undefined;
  if (o.truth !== undefined) {
    const t = o.truth as Record<string, unknown>;
    if (typeof t !== 'object' || t === null || Array.isArray(t)) fail('"truth" must be an object');
    const arr = (name: string): Float64Array => {
      const v = t[name];
      if (!Array.isArray(v) || v.some((x) => typeof x !== 'number')) fail(`"truth.${name}" must be an array of numbers`);
      return Float64Array.from(v as number[]);
    };
    truth = { bodyYaw: arr('bodyYaw'), root: arr('root') };
  }
  let body: RecordingBody | undefined;
  if (o.body !== undefined) {
    const b = o.body as Record<string, unknown>;
    if (typeof b !== 'object' || b === null || Array.isArray(b)) fail('"body" must be an object');
    const joints = b.joints;
    if (!Array.isArray(joints) || joints.length === 0 || joints.some((j) => typeof j !== 'string')) fail('"body.joints" must be an array of names');
    const arr = (name: string): number[] => numbersIn(b, 'body.', name);
    body = {
      joints: joints as string[],
      position: Float64Array.from(arr('position')),
      rotation: Float64Array.from(arr('rotation')),
      tracked: Uint8Array.from(arr('tracked').map((v) => (v === 0 || v === 1 ? v : 255))),
    };
  }
  return {
    truth,
    body,
    frames: frames as number,
    time: Float64Array.from(numbers('time')),
    position: Float64Array.from(numbers('position')),
    rotation: Float64Array.from(numbers('rotation')),
    tracked: Uint8Array.from(numbers('tracked').map((v) => (v === 0 || v === 1 ? v : 255))),
    meta: meta as RecordingMeta,
  };
}

// ------------------------------------------------------------------ binary

/**
 * Binary: header (u32 magic 'MMTR', u32 version, u32 frames, u32 meta byte length), the meta as
 * UTF-8 JSON padded to 8 bytes, then f64 time[frames], f32 position[frames×9],
 * f32 rotation[frames×12], u8 tracked[frames×3]. Little-endian. ~100 bytes per frame. Version 2
 * adds the body joints: u32 joints J, u32 names length L, the names as a UTF-8 JSON array (L
 * bytes), f32 position[frames×J×3], f32 rotation[frames×J×4], u8 tracked[frames×J].
 */
export function encodeRecordingBinary(r: Recording): Uint8Array {
  const meta = new TextEncoder().encode(JSON.stringify(r.meta));
  const metaPadded = Math.ceil(meta.length / 8) * 8;
  const n = r.frames;
  const b = r.body;
  const names = new TextEncoder().encode(b ? JSON.stringify(b.joints) : '');
  const bodyBytes = b ? 8 + names.length + n * b.joints.length * (12 + 16 + 1) : 0;
  const size = HEADER_BYTES + metaPadded + 8 * n + 4 * n * 9 + 4 * n * 12 + n * 3 + bodyBytes;
  const bytes = new Uint8Array(size);
  const view = new DataView(bytes.buffer);
  view.setUint32(0, MAGIC, true);
  view.setUint32(4, b ? BINARY_BODY_VERSION : RECORDING_VERSION, true);
  view.setUint32(8, n, true);
  view.setUint32(12, meta.length, true);
  bytes.set(meta, HEADER_BYTES);
  let o = HEADER_BYTES + metaPadded;
  for (let i = 0; i < n; i++, o += 8) view.setFloat64(o, r.time[i], true);
  for (let i = 0; i < n * 9; i++, o += 4) view.setFloat32(o, r.position[i], true);
  for (let i = 0; i < n * 12; i++, o += 4) view.setFloat32(o, r.rotation[i], true);
  bytes.set(r.tracked.subarray(0, n * 3), o);
  o += n * 3;
  if (b) {
    const j = b.joints.length;
    view.setUint32(o, j, true);
    view.setUint32(o + 4, names.length, true);
    bytes.set(names, o + 8);
    o += 8 + names.length;
    for (let i = 0; i < n * j * 3; i++, o += 4) view.setFloat32(o, b.position[i], true);
    for (let i = 0; i < n * j * 4; i++, o += 4) view.setFloat32(o, b.rotation[i], true);
    bytes.set(b.tracked.subarray(0, n * j), o);
  }
  return bytes;
}

function fromBinary(bytes: Uint8Array, source: string): Recording {
  const fail = (m: string): never => {
    throw new RecordingError(source, m);
  };
  if (bytes.length < HEADER_BYTES) fail(`${bytes.length} bytes is too short for a header`);
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const version = view.getUint32(4, true);
  if (version !== RECORDING_VERSION && version !== BINARY_BODY_VERSION) fail(`unsupported binary version ${version} (this page reads versions 1 and 2)`);
  const n = view.getUint32(8, true);
  const metaLength = view.getUint32(12, true);
  const metaPadded = Math.ceil(metaLength / 8) * 8;
  const base = HEADER_BYTES + metaPadded + 8 * n + 4 * n * 9 + 4 * n * 12 + n * 3;
  let j = 0, namesLength = 0;
  if (version === BINARY_BODY_VERSION) {
    if (bytes.length < base + 8) fail(`${bytes.length} bytes, but a header of ${n} frames and ${metaLength} meta bytes with body joints needs more than ${base + 8}`);
    j = view.getUint32(base, true);
    namesLength = view.getUint32(base + 4, true);
    if (j === 0 || j > 256) fail(`${j} body joints (1–256)`);
  }
  const expected = base + (version === BINARY_BODY_VERSION ? 8 + namesLength + n * j * 29 : 0);
  if (bytes.length !== expected) fail(`${bytes.length} bytes, but a header of ${n} frames and ${metaLength} meta bytes needs ${expected}`);
  let meta: unknown;
  try {
    meta = JSON.parse(new TextDecoder().decode(bytes.subarray(HEADER_BYTES, HEADER_BYTES + metaLength)));
  } catch {
    fail('meta is not valid JSON');
  }
  if (typeof meta !== 'object' || meta === null || Array.isArray(meta)) fail('meta must be a JSON object');
  const time = new Float64Array(n);
  const position = new Float64Array(n * 9);
  const rotation = new Float64Array(n * 12);
  let o = HEADER_BYTES + metaPadded;
  for (let i = 0; i < n; i++, o += 8) time[i] = view.getFloat64(o, true);
  for (let i = 0; i < n * 9; i++, o += 4) position[i] = view.getFloat32(o, true);
  for (let i = 0; i < n * 12; i++, o += 4) rotation[i] = view.getFloat32(o, true);
  const tracked = bytes.slice(o, o + n * 3);
  o += n * 3;
  let body: RecordingBody | undefined;
  if (j > 0) {
    let joints: unknown;
    try {
      joints = JSON.parse(new TextDecoder().decode(bytes.subarray(o + 8, o + 8 + namesLength)));
    } catch {
      fail('the body joint names are not valid JSON');
    }
    if (!Array.isArray(joints) || joints.length !== j || joints.some((x) => typeof x !== 'string')) fail(`the body joint names must be an array of ${j} names`);
    o += 8 + namesLength;
    const bp = new Float64Array(n * j * 3), br = new Float64Array(n * j * 4);
    for (let i = 0; i < n * j * 3; i++, o += 4) bp[i] = view.getFloat32(o, true);
    for (let i = 0; i < n * j * 4; i++, o += 4) br[i] = view.getFloat32(o, true);
    body = { joints: joints as string[], position: bp, rotation: br, tracked: bytes.slice(o, o + n * j) };
  }
  return { frames: n, time, position, rotation, tracked, meta: meta as RecordingMeta, body };
}

/**
 * Decodes and validates a recording from bytes (binary, by its magic, or UTF-8 JSON) or text.
 * `source` (a file name or URL) starts every error message.
 */
export function decodeRecording(data: Uint8Array | string, source = 'recording'): Recording {
  let r: Recording;
  if (typeof data !== 'string' && data.length >= 4 && new DataView(data.buffer, data.byteOffset, 4).getUint32(0, true) === MAGIC) {
    r = fromBinary(data, source);
  } else {
    r = fromJson(typeof data === 'string' ? data : new TextDecoder().decode(data), source);
  }
  validateRecording(r, source);
  return r;
}

// ------------------------------------------------------------------ recorder

/**
 * Appends samples into growing SoA buffers (capacity doubles, so appending is amortized O(1) and
 * allocates only on the rare growth).
 */
export class TrackerRecorder {
  private capacity: number;
  private count = 0;
  private time: Float64Array;
  private position: Float64Array;
  private rotation: Float64Array;
  private tracked: Uint8Array;
  private bodyPosition: Float64Array;
  private bodyRotation: Float64Array;
  private bodyTracked: Uint8Array;
  /** Whether any recorded frame had a tracked body joint (else the recording has no `body`). */
  private hadBody = false;

  /** `capacity`: frames preallocated (default one minute at 90 Hz). */
  constructor(capacity = 90 * 60) {
    this.capacity = Math.max(1, capacity);
    this.time = new Float64Array(this.capacity);
    this.position = new Float64Array(this.capacity * 9);
    this.rotation = new Float64Array(this.capacity * 12);
    this.tracked = new Uint8Array(this.capacity * 3);
    this.bodyPosition = new Float64Array(this.capacity * NUM_BODY_JOINTS * 3);
    this.bodyRotation = new Float64Array(this.capacity * NUM_BODY_JOINTS * 4);
    this.bodyTracked = new Uint8Array(this.capacity * NUM_BODY_JOINTS);
  }

  get frames(): number {
    return this.count;
  }

  clear(): void {
    this.count = 0;
    this.hadBody = false;
  }

  /** Appends a sample; a sample not later than the last one is skipped (time must increase). */
  add(sample: TrackerSample): void {
    if (this.count > 0 && !(sample.time > this.time[this.count - 1])) return;
    if (this.count === this.capacity) this.grow();
    const f = this.count++;
    this.time[f] = sample.time;
    this.position.set(sample.position, f * 9);
    this.rotation.set(sample.rotation, f * 12);
    this.tracked.set(sample.tracked, f * 3);
    this.bodyPosition.set(sample.bodyPosition, f * NUM_BODY_JOINTS * 3);
    this.bodyRotation.set(sample.bodyRotation, f * NUM_BODY_JOINTS * 4);
    this.bodyTracked.set(sample.bodyTracked, f * NUM_BODY_JOINTS);
    if (!this.hadBody) this.hadBody = sample.bodyTracked.includes(1);
  }

  /** A copy of what was recorded, times shifted to start at 0. Throws with no frames. */
  toRecording(meta: RecordingMeta = {}): Recording {
    if (this.count === 0) throw new RecordingError('recorder', 'nothing recorded');
    const n = this.count;
    const t0 = this.time[0];
    return {
      frames: n,
      time: this.time.slice(0, n).map((t) => t - t0),
      position: this.position.slice(0, n * 9),
      rotation: this.rotation.slice(0, n * 12),
      tracked: this.tracked.slice(0, n * 3),
      meta,
      body: this.hadBody
        ? {
            joints: [...BODY_JOINTS],
            position: this.bodyPosition.slice(0, n * NUM_BODY_JOINTS * 3),
            rotation: this.bodyRotation.slice(0, n * NUM_BODY_JOINTS * 4),
            tracked: this.bodyTracked.slice(0, n * NUM_BODY_JOINTS),
          }
        : undefined,
    };
  }

  private grow(): void {
    this.capacity *= 2;
    const grow = <T extends Float64Array | Uint8Array>(a: T, per: number, make: (n: number) => T): T => {
      const b = make(this.capacity * per);
      b.set(a);
      return b;
    };
    this.time = grow(this.time, 1, (n) => new Float64Array(n));
    this.position = grow(this.position, 9, (n) => new Float64Array(n));
    this.rotation = grow(this.rotation, 12, (n) => new Float64Array(n));
    this.tracked = grow(this.tracked, 3, (n) => new Uint8Array(n));
    this.bodyPosition = grow(this.bodyPosition, NUM_BODY_JOINTS * 3, (n) => new Float64Array(n));
    this.bodyRotation = grow(this.bodyRotation, NUM_BODY_JOINTS * 4, (n) => new Float64Array(n));
    this.bodyTracked = grow(this.bodyTracked, NUM_BODY_JOINTS, (n) => new Uint8Array(n));
  }
}

// ------------------------------------------------------------------ player

/** Samples a recording at any time: positions interpolated linearly, rotations by nlerp. */
export class RecordingPlayer {
  private cursor = 0;
  /** For each of `BODY_JOINTS`, its index among the recording's body joints (−1: not recorded). */
  private readonly bodyIndex = new Int32Array(NUM_BODY_JOINTS).fill(-1);

  constructor(readonly recording: Recording) {
    const names = recording.body?.joints ?? [];
    for (let j = 0; j < NUM_BODY_JOINTS; j++) this.bodyIndex[j] = names.indexOf(BODY_JOINTS[j]);
  }

  /** Seconds from the first to the last frame. */
  get duration(): number {
    const t = this.recording.time;
    return t[t.length - 1] - t[0];
  }

  /**
   * Writes the trackers and body joints at `time` (seconds from the recording's start, clamped
   * to it) into `out`; `out.time` is set to `time`. A tracker or joint counts as tracked only if
   * it is at both neighbouring frames. Sequential times are O(1); allocates nothing.
   */
  sampleAt(time: number, out: TrackerSample): void {
    const r = this.recording;
    const t = r.time;
    const at = t[0] + Math.min(Math.max(time, 0), this.duration);
    if (this.cursor >= r.frames - 1 || t[this.cursor] > at) this.cursor = 0;
    while (this.cursor < r.frames - 2 && t[this.cursor + 1] <= at) this.cursor++;
    const a = this.cursor;
    const b = Math.min(a + 1, r.frames - 1);
    const w = b === a ? 0 : Math.min(1, Math.max(0, (at - t[a]) / (t[b] - t[a])));
    out.time = time;
    for (let k = 0; k < NUM_TRACKERS; k++) {
      const ia = a * NUM_TRACKERS + k, ib = b * NUM_TRACKERS + k;
      out.tracked[k] = interpolatePose(r.position, r.rotation, r.tracked, ia, ib, w, out.position, out.rotation, k);
    }
    const body = r.body;
    out.bodyTracked.fill(0);
    if (!body) return;
    const count = body.joints.length;
    for (let j = 0; j < NUM_BODY_JOINTS; j++) {
      const k = this.bodyIndex[j];
      if (k < 0) continue;
      out.bodyTracked[j] = interpolatePose(body.position, body.rotation, body.tracked, a * count + k, b * count + k, w, out.bodyPosition, out.bodyRotation, j);
    }
  }
}

/**
 * Pose `ia` → `ib` of SoA arrays at `w` into slot `k` of `outPosition`/`outRotation`: the
 * position linearly, the rotation by nlerp on the near hemisphere. Returns the tracked flag (both
 * tracked).
 */
function interpolatePose(
  position: Float64Array, rotation: Float64Array, tracked: Uint8Array, ia: number, ib: number, w: number,
  outPosition: Float64Array, outRotation: Float64Array, k: number,
): number {
  for (let c = 0; c < 3; c++) outPosition[3 * k + c] = position[3 * ia + c] + (position[3 * ib + c] - position[3 * ia + c]) * w;
  let dot = 0;
  for (let c = 0; c < 4; c++) dot += rotation[4 * ia + c] * rotation[4 * ib + c];
  const sign = dot < 0 ? -1 : 1;
  let n = 0;
  for (let c = 0; c < 4; c++) {
    const v = rotation[4 * ia + c] + (sign * rotation[4 * ib + c] - rotation[4 * ia + c]) * w;
    outRotation[4 * k + c] = v;
    n += v * v;
  }
  n = Math.sqrt(n) || 1;
  for (let c = 0; c < 4; c++) outRotation[4 * k + c] /= n;
  return tracked[ia] & tracked[ib];
}

