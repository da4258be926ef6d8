/**
 * The server judges what a message says, not only its form: a message that every receiver
 * would refuse (docs/rooms.md, "Remote data is untrusted") is dropped here instead of being
 * relayed to the room, and counted against its sender — warned at the first, disconnected
 * (close 4007) when the count outruns a slow allowance. A well-behaved member never trips it.
 *
 * Checked (the same limits the receivers apply, or the physical ones they rely on):
 * - **bounds**: roots, tracked heads and path points (× the sender's scale) within ±`worldLimit`
 *   m (`RemoteAvatar`'s 10 km);
 * - **speed**: between two messages the root moves at most `maxSpeed` m/s over the simulated
 *   time of the steps in between (the rate limits tie that to real time), with `jumpSlack` m
 *   of allowance, so a sender cannot make its avatar fly across the room;
 * - **frames**: a STATE's frame below the database's frame count (from the member's runtime
 *   state header);
 * - **runtime states**: the header (magic `MMRS`, version, joints, frames and features as in
 *   the member's first one), a whole number of 4-byte words, each a finite value within ±10⁶
 *   (what the runtime's reader refuses), and the same length as the member's earlier ones.
 */
import { RUNTIME_STATE_VERSION, stepSeconds, type StreamMessage } from '../web/src/rooms/protocol.ts';
import { TokenBucket } from './rate-limit.ts';

export interface ContentLimits {
  /** |x|, |z| in room metres beyond this are refused (receivers refuse them too). Default 10 000. */
  worldLimit: number;
  /** Root speed (m/s) over the simulated time of a message's steps. Default 20 (the fastest path speed the protocol takes). */
  maxSpeed: number;
  /** A one-off jump allowance (m) on top of the speed; a STATE (no steps) may be this far from the last root. Default 5. */
  jumpSlack: number;
  /** Refused messages a sender may have before it is disconnected, and how fast the count drains (per s). Default 10, 0.2. */
  strikeBurst: number;
  strikesPerSecond: number;
}

export const DEFAULT_CONTENT_LIMITS: ContentLimits = { worldLimit: 10_000, maxSpeed: 20, jumpSlack: 5, strikeBurst: 10, strikesPerSecond: 0.2 };

/** Why a message was refused (one word: stats and logs count by it). */
export type ContentCause = 'bounds' | 'speed' | 'frame' | 'runtime' | 'restart';

const MAGIC = 0x53524d4d; // "MMRS" little-endian
const HEADER_BYTES = 20;
const MAX_STATE_VALUE = 1e6;

/** One member's content record: where its root was, what its runtime states look like. */
export class ContentJudge {
  private lastX = NaN;
  private lastZ = NaN;
  private scale = 1;
  private messages = 0;
  /** Jump allowance left (m). */
  private slack: number;
  /** Runtime state header words (joints, frames, features) and length, from the first one that passed. */
  private joints = -1;
  private frames = -1;
  private features = -1;
  private stateLength = -1;
  readonly strikes: TokenBucket;
  refused = 0;

  constructor(
    private readonly l: ContentLimits,
    nowMs: number,
  ) {
    this.slack = l.jumpSlack;
    this.strikes = new TokenBucket(l.strikesPerSecond, l.strikeBurst, nowMs);
  }

  /**
   * The member sent a new profile (a JOIN again: a new style, a new height): its runtime restarts
   * with it, so its next message may be a restart STATE, as its first was.
   */
  profileChanged(): void {
    this.messages = 0;
  }

  /** Null if `m` may be relayed, else the cause and a reason naming the value. Updates the record either way. */
  judge(m: StreamMessage): { cause: ContentCause; reason: string } | null {
    const first = this.messages++ === 0;
    const w = this.l.worldLimit;
    const out = (v: number) => !(Math.abs(v) <= w);
    if (m.type === 'path') {
      for (let i = 0; i < m.points.length; i++) if (out(m.points[i] * this.scale)) return { cause: 'bounds', reason: `path point ${i >> 1} at ${m.points[i]} is beyond ±${w} m` };
      return null;
    }
    if (out(m.rootX) || out(m.rootZ)) return { cause: 'bounds', reason: `root (${m.rootX}, ${m.rootZ}) is beyond ±${w} m` };
    if (m.type === 'tracked') {
      for (const s of m.steps) if (out(s.headX) || out(s.headZ)) return { cause: 'bounds', reason: `tracked head (${s.headX}, ${s.headZ}) is beyond ±${w} m` };
    }
    if (m.type === 'state') {
      // A restart places the member anew: only its first message may be one (RoomClient sends it right after WELCOME).
      if (m.restart && !first) return { cause: 'restart', reason: 'a restart STATE after the first message' };
      if (m.runtime) {
        const bad = this.runtime(m.runtime);
        if (bad) return { cause: 'runtime', reason: bad };
      }
      if (this.frames > 0 && m.frame >= this.frames) return { cause: 'frame', reason: `frame ${m.frame} is beyond the database's ${this.frames} frames` };
    }
    if (m.type === 'tracked' || m.type === 'state') this.scale = m.scale;
    // Speed: the distance from the last root, against the simulated time of this message's steps.
    const x = m.rootX;
    const z = m.rootZ;
    if (first || (m.type === 'state' && m.restart) || !Number.isFinite(this.lastX)) {
      this.lastX = x;
      this.lastZ = z;
      return null;
    }
    const d = Math.hypot(x - this.lastX, z - this.lastZ);
    if (m.type === 'state') {
      // A STATE takes no steps: it reports the root after the last one (or a few not sent yet).
      return d > this.l.jumpSlack ? { cause: 'speed', reason: `STATE root ${d.toFixed(2)} m from the last root (at most ${this.l.jumpSlack} m)` } : null;
    }
    const allowed = this.l.maxSpeed * stepSeconds(m);
    if (d > allowed) {
      const over = d - allowed;
      if (over > this.slack) {
        // The new place becomes the reference: a one-off jump costs one refusal, not a stream of them.
        this.lastX = x;
        this.lastZ = z;
        return { cause: 'speed', reason: `root moved ${d.toFixed(2)} m in ${(stepSeconds(m) * 1000).toFixed(0)} ms of steps (at most ${this.l.maxSpeed} m/s)` };
      }
      this.slack -= over;
    } else this.slack = Math.min(this.l.jumpSlack, this.slack + (allowed - d));
    this.lastX = x;
    this.lastZ = z;
    return null;
  }

  /** The runtime state's structure; null if it parses. */
  private runtime(b: Uint8Array): string | null {
    if (b.length < HEADER_BYTES || b.length % 4 !== 0) return `runtime state of ${b.length} bytes (a header of ${HEADER_BYTES} and whole 4-byte words)`;
    const v = new DataView(b.buffer, b.byteOffset, b.byteLength);
    if (v.getUint32(0, true) !== MAGIC) return 'runtime state magic is not MMRS';
    if (v.getUint32(4, true) !== RUNTIME_STATE_VERSION) return `runtime state version ${v.getUint32(4, true)} (expected ${RUNTIME_STATE_VERSION})`;
    const joints = v.getUint32(8, true);
    const frames = v.getUint32(12, true);
    const features = v.getUint32(16, true);
    if (joints < 1 || joints > 1024 || frames < 1 || frames >= 1 << 24 || features < 1 || features > 4096) return `runtime state header: ${joints} joints, ${frames} frames, ${features} features`;
    if (this.joints >= 0 && (joints !== this.joints || frames !== this.frames || features !== this.features || b.length !== this.stateLength)) {
      return `runtime state for ${joints} joints, ${frames} frames, ${features} features, ${b.length} bytes: the member's earlier ones were ${this.joints}, ${this.frames}, ${this.features}, ${this.stateLength}`;
    }
    for (let o = HEADER_BYTES; o < b.length; o += 4) {
      const f = v.getFloat32(o, true);
      if (!(Math.abs(f) <= MAX_STATE_VALUE)) return `runtime state value ${f} at byte ${o}`;
    }
    this.joints = joints;
    this.frames = frames;
    this.features = features;
    this.stateLength = b.length;
    return null;
  }
}
