/**
 * One remote member's avatar: its relayed stream goes through a `JitterBuffer`; each frame the
 * steps whose sender time has come are replayed on the local `DrivenCharacter` with the
 * sender's own dt and inputs (so the motion is the sender's, re-synthesized), and after each
 * message's last step the sender's reported root feeds a `DriftCorrector` whose display offset
 * hides whatever replay did not reproduce. VR trackers are interpolated at the playout time.
 *
 * Remote data is untrusted: messages are already validated by the protocol decoder; here
 * positions beyond `worldLimit` are refused with a note and never reach the character.
 */
import { DriftCorrector, type DriftCorrectorOptions } from './drift-corrector.ts';
import { createDrive, type DrivePath } from '../core/drive.ts';
import type { DrivenCharacter } from './driven-character.ts';
import { JitterBuffer, type JitterBufferOptions, type PushResult } from './jitter-buffer.ts';
import { RUNTIME_STATE_INTERVAL_MS } from './room-client.ts';
import { driveFromMove, driveFromPath, driveFromTracked } from './step-drive.ts';
import {
  angleToI16,
  fromMm,
  i16ToAngle,
  toMm,
  stepSeconds,
  TICKS_PER_SECOND,
  type MoveMessage,
  type PathMessage,
  type StateMessage,
  type StreamMessage,
  type TrackedMessage,
  type RoomTrackerPose,
} from './protocol.ts';

export interface RemoteAvatarOptions {
  jitter?: JitterBufferOptions;
  drift?: DriftCorrectorOptions;
  /** Steps replayed per `update` at most (a long stall catches up over several frames). Default 32. */
  maxStepsPerUpdate?: number;
  /** Lost time longer than this (s) is not simulated (the drift correction covers it). Default 2. */
  maxGapSeconds?: number;
  /** |x|, |z| beyond this (m) are refused. Default 10 000. */
  worldLimit?: number;
  /** Called with a reason whenever remote data is refused or patched over. */
  onNote?: (note: string) => void;
  /**
   * Called when a message's last step has played, with its sender time (ms): the character is
   * where the sender's report in that message says (up to the drift correction's offset).
   */
  onPlayed?: (senderTimeMs: number) => void;
}

export interface RemoteAvatarStats {
  stepsApplied: number;
  /** Messages known lost (a later one arrived first and the time came). */
  lostMessages: number;
  /** Lost time played with the last input as it passed (s), and all at once after a snapshot (s). */
  extrapolatedSeconds: number;
  /** Times the playout buffer overflowed (no frames played it) and the avatar started over. */
  resyncs: number;
  gapSeconds: number;
  refused: number;
  underflows: number;
}

/**
 * How long (sender time after the snapshot, ms) a copy placed by the server's snapshot stays
 * unseen waiting for the sender's runtime state. The server asks every member for it when someone
 * joins; a member answers at once, but with its runtime state only once `RUNTIME_STATE_INTERVAL_MS`
 * has passed since its last one (another join just before) — the STATE it sends at once then
 * carries no runtime, and a copy shown from it is close, not exact (the rooms e2e measured up to
 * 1.2 cm). A sender that never sends one (no `runtimeState` option) is shown after this.
 */
export const RUNTIME_WAIT_MS = 2 * RUNTIME_STATE_INTERVAL_MS + 500;

function poseCopy(): RoomTrackerPose {
  return { tracked: false, fromHand: false, position: [0, 0, 0], rotation: [0, 0, 0, 1] };
}

export class RemoteAvatar {
  readonly buffer: JitterBuffer<StreamMessage>;
  readonly drift: DriftCorrector;
  readonly stats: RemoteAvatarStats = { stepsApplied: 0, lostMessages: 0, extrapolatedSeconds: 0, resyncs: 0, gapSeconds: 0, refused: 0, underflows: 0 };
  /** True once placed by a state (snapshot or in-stream) or a first message. */
  ready = false;
  /**
   * The copy computes the sender's own floats: placed by the sender's runtime state (or a
   * restart), every step since replayed and no lost time guessed. Drift is exactly 0 then.
   */
  exact = false;
  /**
   * Placed by the server's cached snapshot (up to a STATE interval old) and not yet by a STATE
   * from the stream: the sender answers a newcomer with a fresh STATE at once, which re-places
   * the copy (no blend: it is not shown yet). See `shown`.
   */
  private provisional = false;
  /** Sender time (ms) of the snapshot that made the copy provisional. */
  private provisionalSince = NaN;
  /** The trackers shown this frame (VR members). */
  readonly trackers: [RoomTrackerPose, RoomTrackerPose, RoomTrackerPose] = [poseCopy(), poseCopy(), poseCopy()];
  private readonly o: Required<Omit<RemoteAvatarOptions, 'jitter' | 'drift' | 'onNote' | 'onPlayed'>>;
  private readonly onPlayed: ((senderTimeMs: number) => void) | undefined;
  private readonly note: (n: string) => void;
  private current: MoveMessage | TrackedMessage | null = null;
  private stepIndex = 0;
  private stepEnd = 0;
  /** Sender time at the end of the last applied step. */
  private lastEnd = NaN;
  private path: DrivePath | null = null;
  /** The drive value the copy is given (database units; from the steps, by the sender's own lines); its mode is the one mode here. */
  private readonly drive = createDrive();
  private scale = 1;
  private alpha = 0.2;
  private readonly trackerA: RoomTrackerPose[] = [poseCopy(), poseCopy(), poseCopy()];
  private readonly trackerB: RoomTrackerPose[] = [poseCopy(), poseCopy(), poseCopy()];
  private trackerTimeA = NaN;
  private trackerTimeB = NaN;
  /** Lost time played in the current gap (ms), reset when a message plays. */
  private gapMs = 0;
  /** Messages were declared lost and their time is being played with the last input. */
  private inGap = false;

  constructor(
    readonly character: DrivenCharacter,
    options: RemoteAvatarOptions = {},
  ) {
    this.buffer = new JitterBuffer(options.jitter);
    this.drift = new DriftCorrector(options.drift);
    this.o = { maxStepsPerUpdate: options.maxStepsPerUpdate ?? 32, maxGapSeconds: options.maxGapSeconds ?? 2, worldLimit: options.worldLimit ?? 10_000 };
    this.note = options.onNote ?? (() => {});
    this.onPlayed = options.onPlayed;
  }

  private refuse(reason: string): PushResult {
    this.stats.refused++;
    this.note(reason);
    return 'invalid';
  }

  private inWorld(...values: number[]): boolean {
    for (const v of values) if (!(Math.abs(v) <= this.o.worldLimit)) return false;
    return true;
  }

  /** A relayed stream message arrived at local time `nowMs`. */
  receive(m: StreamMessage, nowMs: number): PushResult {
    if (m.type === 'move' || m.type === 'tracked' || m.type === 'state') {
      if (!this.inWorld(m.rootX, m.rootZ)) return this.refuse(`root (${m.rootX}, ${m.rootZ}) is beyond ±${this.o.worldLimit} m`);
    }
    if (m.type === 'tracked') {
      for (const s of m.steps) if (!this.inWorld(s.headX, s.headZ)) return this.refuse('tracked head beyond the world limit');
    }
    if (m.type === 'path') {
      for (const p of m.points) if (!this.inWorld(p * (this.scale || 1))) return this.refuse('path point beyond the world limit');
    }
    const result = this.buffer.push(m.seq, m.time, nowMs, m, stepSeconds(m) * 1000);
    if (result === 'overflow') {
      // Nobody has been playing this avatar (a hidden page gets no frames): forget the backlog
      // and start over from this message; the avatar snaps to the sender once frames resume.
      this.note(`playout buffer full (${this.buffer.size} messages not played): starting over at seq ${m.seq}`);
      this.stats.resyncs++;
      this.buffer.skipTo(m.seq - 1);
      this.current = null;
      this.inGap = false;
      this.ready = false;
      this.exact = false;
      return this.buffer.push(m.seq, m.time, nowMs, m, stepSeconds(m) * 1000);
    }
    // The state a copy placed by the snapshot waits for (it is not shown until then): played the
    // moment it is here, not a playout delay later. The copy is its sender's floats from it on
    // either way; only when it is first drawn changes.
    if (result === 'ok' && this.provisional && m.type === 'state' && (m.runtime || m.restart)) this.buffer.playFrom(m.seq, nowMs);
    return result;
  }

  /** The late-join snapshot the server cached (state and path may be null). */
  applySnapshot(state: StateMessage | null, path: PathMessage | null): void {
    if (path && this.inWorld(...path.points)) this.path = { points: path.points, speeds: path.speeds, looped: path.looped };
    if (!state) return;
    if (!this.inWorld(state.rootX, state.rootZ)) {
      this.refuse('snapshot root beyond the world limit');
      return;
    }
    this.resetTo(state);
    this.provisional = true;
    this.provisionalSince = state.time;
    this.buffer.skipTo(Math.max(state.seq, path?.seq ?? 0));
  }

  /** Measures the drift with the local root quantized as the sender's report is (1 mm, int16 yaw). */
  private measure(x: number, z: number, yaw: number): void {
    const c = this.character;
    this.drift.measure(fromMm(toMm(c.rootX)), fromMm(toMm(c.rootZ)), i16ToAngle(angleToI16(c.rootYaw)), x, z, yaw);
  }

  /** Whether to draw the avatar: placed by the stream (a snapshot alone is too old to show). */
  get shown(): boolean {
    return this.ready && !this.provisional;
  }

  /** Sender time (ms) at the end of the last step played (NaN before the first). */
  get playedTime(): number {
    return this.lastEnd;
  }

  /** Part of a message's steps is played (its sender time is not reached yet). */
  get midMessage(): boolean {
    return this.current !== null;
  }

  private setScale(scale: number): void {
    if (scale === this.scale) return;
    this.scale = scale;
    this.character.setScale?.(scale);
  }

  private resetTo(s: StateMessage): void {
    const c = this.character;
    this.setScale(s.scale);
    const [x0, z0, yaw0] = [c.rootX, c.rootZ, c.rootYaw];
    this.alpha = s.alpha;
    // A restart is recomputed from the same numbers as the sender's (a fresh runtime, frame −1);
    // any other snapshot places the copy playing the sender's frame.
    c.reset(s.restart ? -1 : s.frame, s.rootX, s.rootZ, s.rootYaw);
    // The path first: the runtime state below continues along it.
    if (s.drive === 'path' && this.path) c.setDrive(driveFromPath(this.path, this.drive));
    else if (s.drive === 'path') this.note('snapshot follows a path it did not include');
    // The sender's whole runtime state (sent when someone joins): from here on the copy is the
    // sender's floats. Refused bytes leave the copy placed playing the sender's frame.
    let loaded = false;
    if (s.runtime && c.loadState) {
      try {
        c.loadState(s.runtime);
        loaded = true;
      } catch (e) {
        this.note(`runtime state refused: ${e instanceof Error ? e.message : String(e)}`);
      }
    }
    this.exact = s.restart === true || loaded;
    // The sender's last step's value, for the lost time (`stepLastInput`). A restarted sender gave
    // its fresh runtime nothing yet: it gives it its next step's value, as this copy does when
    // that step plays — handing this one over now would start the tracked mode from another
    // sample (another velocity) than the sender's, and the copy would drift by millimetres.
    if (s.drive === 'tracked') driveFromTracked(s.tracked, this.scale, this.alpha, this.drive);
    else if (s.drive === 'move') driveFromMove(s.move, this.drive);
    if (s.drive !== 'path' && (!s.restart || loaded)) c.setDrive(this.drive);
    if (this.ready) this.drift.rebase(c.rootX - x0, c.rootZ - z0, c.rootYaw - yaw0);
    else this.drift.reset();
    this.measure(s.rootX, s.rootZ, s.rootYaw);
    this.lastEnd = s.time;
    this.current = null;
    this.inGap = false;
    this.ready = true;
  }

  /**
   * Once a frame: replays every step due at local time `nowMs`, then advances the display
   * correction by `dt` (s) and hands it, and the trackers, to the character.
   */
  update(nowMs: number, dt: number): void {
    const playout = this.buffer.playoutTime(nowMs);
    let budget = this.o.maxStepsPerUpdate;
    while (budget > 0) {
      if (!this.current) {
        const r = this.buffer.pop(nowMs);
        if (!r) {
          if (this.ready && Number.isFinite(playout) && playout > this.lastEnd + 1.5) {
            const head = this.buffer.peekSeq();
            if (head > this.buffer.releasedSeq + 1) {
              // A later message is here but the one for this time is not: it is lost (the
              // stream is ordered). Play the lost time with the last input as it passes.
              const lost = head - this.buffer.releasedSeq - 1;
              this.note(`${lost} message(s) lost before seq ${head}`);
              this.stats.lostMessages += lost;
              this.buffer.skipTo(head - 1);
              this.inGap = true;
            }
            // Only lost time is guessed: a sender that paused (a hidden tab) or stalled took no
            // steps then, so its receivers take none either.
            if (this.inGap) this.extrapolate(Math.min(playout, this.buffer.nextStart()));
            else if (this.buffer.size === 0) this.stats.underflows++;
          }
          break;
        }
        const m = r.item;
        const start = r.time - r.span;
        if (r.missingBefore > 0) {
          this.note(`${r.missingBefore} message(s) lost before seq ${r.seq}`);
          this.exact = false;
        }
        // Messages lost (or never sent to us: before a snapshot) and not yet played as they passed.
        if (r.missingBefore > 0 && !this.inGap && this.ready && Number.isFinite(this.lastEnd) && start > this.lastEnd + 1.5) {
          this.fillGap((start - this.lastEnd) / 1000);
        }
        this.inGap = false;
        if (m.type === 'state') {
          // The sender restarted its runtime: restarting the copy at the same numbers makes it the sender's floats.
          if (this.provisional) {
            if (!m.runtime && !m.restart && m.time - this.provisionalSince < RUNTIME_WAIT_MS) {
              // Placed by it but not shown: the sender's runtime state is on its way.
              this.resetTo(m);
              continue;
            }
            this.provisional = false;
            this.ready = false; // placed afresh, not blended from where nobody saw it
          }
          if (!this.ready || m.restart || m.runtime) this.resetTo(m);
          else {
            this.setScale(m.scale);
            this.measure(m.rootX, m.rootZ, m.rootYaw);
            this.alpha = m.alpha;
            this.lastEnd = m.time;
          }
          continue;
        }
        if (m.type === 'path') {
          this.path = { points: m.points, speeds: m.speeds, looped: m.looped };
          this.character.setDrive(driveFromPath(this.path, this.drive));
          this.lastEnd = m.time;
          continue;
        }
        if (!this.ready) {
          // No state yet: start where the sender says it is.
          this.character.reset(-1, m.rootX, m.rootZ, m.rootYaw);
          this.drift.reset();
          this.ready = true;
          this.exact = false;
        }
        if (m.type === 'tracked') {
          this.setScale(m.scale);
          this.alpha = m.alpha;
          this.pushTrackers(m);
        }
        this.current = m;
        this.stepIndex = 0;
        this.stepEnd = start;
        this.gapMs = 0;
      }
      const m = this.current;
      const step = m.steps[this.stepIndex];
      const end = this.stepEnd + (step.ticks * 1000) / TICKS_PER_SECOND;
      if (end > playout) break;
      this.applyStep(m, this.stepIndex);
      budget--;
      this.stepEnd = end;
      this.lastEnd = end;
      this.stepIndex++;
      if (this.stepIndex === m.steps.length) {
        this.measure(m.rootX, m.rootZ, m.rootYaw);
        this.lastEnd = m.time;
        this.current = null;
        this.onPlayed?.(m.time);
      }
    }
    this.drift.update(dt);
    this.character.setDisplayOffset(this.drift.offsetX, this.drift.offsetZ, this.drift.offsetYaw);
    if (Number.isFinite(this.trackerTimeB)) this.interpolateTrackers(playout);
  }

  private applyStep(m: MoveMessage | TrackedMessage, i: number): void {
    const c = this.character;
    const d = this.drive;
    if (m.type === 'move') {
      const s = m.steps[i];
      if (s.path && this.path) {
        if (d.mode !== 'path') {
          this.note('path step without a running path');
          c.setDrive(driveFromPath(this.path, d));
        }
      } else c.setDrive(driveFromMove(s, d));
      c.update(s.ticks / TICKS_PER_SECOND);
    } else {
      const s = m.steps[i];
      c.setDrive(driveFromTracked(s, m.scale, m.alpha, d));
      c.update(s.ticks / TICKS_PER_SECOND);
    }
    this.stats.stepsApplied++;
  }

  /** Steps the character `ticks` with the last input (lost time: a guess the drift correction fixes). */
  private stepLastInput(ticks: number): void {
    const c = this.character;
    if (this.drive.mode !== 'path') c.setDrive(this.drive);
    c.update(ticks / TICKS_PER_SECOND);
  }

  /** Plays lost time up to sender time `until` (one step per frame, so the motion stays smooth). */
  private extrapolate(until: number): void {
    const ms = Math.min(until - this.lastEnd, this.o.maxGapSeconds * 1000 - this.gapMs);
    const ticks = Math.min(Math.floor((ms * TICKS_PER_SECOND) / 1000), TICKS_PER_SECOND / 10);
    if (ticks >= 1) {
      this.exact = false;
      this.stepLastInput(ticks);
      this.gapMs += (ticks * 1000) / TICKS_PER_SECOND;
      this.stats.extrapolatedSeconds += ticks / TICKS_PER_SECOND;
    }
    this.lastEnd = until;
  }

  /**
   * Lost time discovered at once (e.g. after a snapshot): simulated now with the last input
   * (steps ≤ 1/30 s, up to `maxGapSeconds`); the display is rebased so it does not jump and
   * blends to the sender's report instead.
   */
  private fillGap(seconds: number): void {
    const total = Math.min(seconds, this.o.maxGapSeconds);
    this.stats.gapSeconds += total;
    this.exact = false;
    const c = this.character;
    const [x0, z0, yaw0] = [c.rootX, c.rootZ, c.rootYaw];
    let left = Math.round(total * TICKS_PER_SECOND);
    while (left > 0) {
      const ticks = Math.min(left, TICKS_PER_SECOND / 30);
      this.stepLastInput(ticks);
      left -= ticks;
    }
    this.drift.rebase(c.rootX - x0, c.rootZ - z0, c.rootYaw - yaw0);
  }

  private pushTrackers(m: TrackedMessage): void {
    // B becomes A; the new sample is B (at the message's time).
    for (let i = 0; i < 3; i++) copyPose(this.trackerA[i], Number.isFinite(this.trackerTimeB) ? this.trackerB[i] : m.trackers[i]);
    this.trackerTimeA = Number.isFinite(this.trackerTimeB) ? this.trackerTimeB : m.time;
    for (let i = 0; i < 3; i++) copyPose(this.trackerB[i], m.trackers[i]);
    this.trackerTimeB = m.time;
  }

  private interpolateTrackers(playout: number): void {
    const span = this.trackerTimeB - this.trackerTimeA;
    const t = span > 0 ? Math.max(0, Math.min(1, (playout - this.trackerTimeA) / span)) : 1;
    for (let i = 0; i < 3; i++) {
      const a = this.trackerA[i];
      const b = this.trackerB[i];
      const d = this.trackers[i];
      d.tracked = b.tracked;
      d.fromHand = b.fromHand;
      for (let k = 0; k < 3; k++) d.position[k] = a.position[k] + (b.position[k] - a.position[k]) * t;
      // nlerp on the shorter arc.
      const dot = a.rotation[0] * b.rotation[0] + a.rotation[1] * b.rotation[1] + a.rotation[2] * b.rotation[2] + a.rotation[3] * b.rotation[3];
      const sb = dot < 0 ? -1 : 1;
      let n = 0;
      for (let k = 0; k < 4; k++) {
        d.rotation[k] = a.rotation[k] * (1 - t) + sb * b.rotation[k] * t;
        n += d.rotation[k] * d.rotation[k];
      }
      n = Math.sqrt(n) || 1;
      for (let k = 0; k < 4; k++) d.rotation[k] /= n;
    }
    this.character.setTrackers?.(this.trackers);
  }
}

function copyPose(d: RoomTrackerPose, s: RoomTrackerPose): void {
  d.tracked = s.tracked;
  d.fromHand = s.fromHand;
  for (let k = 0; k < 3; k++) d.position[k] = s.position[k];
  for (let k = 0; k < 4; k++) d.rotation[k] = s.rotation[k];
}
