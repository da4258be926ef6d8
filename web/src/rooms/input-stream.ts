/**
 * The sending side of a member's stream: records each simulation step the local character takes
 * (quantized: the caller must drive its own character with the values `recordMove` /
 * `recordTracked` leave in the step), batches them into MOVE / TRACKED messages at the send
 * rate, keeps PATH messages in step order, and produces STATE messages (periodic, on request).
 *
 * Time: a message's `time` is the sender's wall clock (ms since this stream started) at its last
 * step; a STATE's, when it was queued. Steps inside a message are timed back from it by their
 * ticks. A wall clock (not the sum of the ticks) keeps the receivers' clock mapping steady when
 * the sender stalls or its tab is hidden: it simply sends no steps for a while.
 */
import {
  createMoveStep,
  createTrackedStep,
  encodeMove,
  encodePath,
  encodeState,
  encodeTracked,
  MAX_DT_TICKS,
  MAX_STEPS,
  quantizeMoveStep,
  quantizeTrackedStep,
  TICKS_PER_SECOND,
  type DriveMode,
  type MoveStep,
  type TrackedStep,
  type RoomTrackerPose,
} from './protocol.ts';

/**
 * Seconds → whole ticks, carrying the rounding remainder so the simulated clock never drifts
 * from the real one (a 60 Hz display gives 120 ticks a frame on average whatever its jitter).
 */
export class TickClock {
  private remainder = 0;
  /** Ticks for a frame of `dt` seconds: 0 (no step) up to MAX_DT_TICKS (longer frames are cut). */
  ticksFor(dt: number): number {
    if (!(dt > 0) || !Number.isFinite(dt)) return 0;
    const exact = dt * TICKS_PER_SECOND + this.remainder;
    const ticks = Math.min(MAX_DT_TICKS, Math.floor(exact + 0.5));
    this.remainder = Math.max(-0.5, Math.min(0.5, exact - ticks));
    return ticks;
  }
  reset(): void {
    this.remainder = 0;
  }
}

export interface StreamReport {
  rootX: number;
  rootZ: number;
  rootYaw: number;
  frame: number;
}

function identityTracker(): RoomTrackerPose {
  return { tracked: false, fromHand: false, position: [0, 0, 0], rotation: [0, 0, 0, 1] };
}

export class InputStream {
  /** Last sequence number used (messages start at 1). */
  seq = 0;
  /** Simulation clock, ticks (steps recorded since the stream started). */
  simTicks = 0;
  readonly clock = new TickClock();
  /** Room metres per database unit and α (m) of tracked mode. */
  scale = 1;
  alpha = 0.2;
  drive: DriveMode = 'move';
  /** Seconds since the current path started. */
  pathTime = 0;
  readonly root: StreamReport = { rootX: 0, rootZ: 0, rootYaw: 0, frame: 0 };
  readonly lastMove: MoveStep = createMoveStep();
  readonly lastTracked: TrackedStep = createTrackedStep();
  readonly trackers: [RoomTrackerPose, RoomTrackerPose, RoomTrackerPose] = [identityTracker(), identityTracker(), identityTracker()];
  private path: { points: Float32Array; speeds: Float32Array; looped: boolean } | null = null;
  private moveSteps: MoveStep[] = [];
  private trackedSteps: TrackedStep[] = [];
  private queue: Uint8Array[] = [];
  private readonly now: () => number;
  private startMs: number;
  /** Wall time (ms since start) of the last recorded step, and the last time put in a message. */
  private lastStepMs = 0;
  private lastSentTime = 0;

  /** `now`: the wall clock in ms (default `performance.now`; tests pass a simulated one). */
  constructor(now: () => number = () => performance.now()) {
    this.now = now;
    this.startMs = now();
  }

  /** Wall time (ms since the stream started) of the last recorded step: the `time` of the message that will carry it. */
  get lastStepTime(): number {
    return this.lastStepMs;
  }

  private wallMs(): number {
    return Math.max(0, Math.round(this.now() - this.startMs));
  }

  /** A message time: never earlier than the last one sent (u32 ms). */
  private stamp(ms: number): number {
    this.lastSentTime = Math.max(this.lastSentTime, ms);
    return this.lastSentTime >>> 0;
  }

  /**
   * Records a desktop step (`step.ticks` set by the caller, e.g. from `clock.ticksFor(dt)`);
   * quantizes `step` in place: drive the local character with its values and `ticks / 7200` s.
   */
  recordMove(step: MoveStep): MoveStep {
    quantizeMoveStep(step);
    if (step.ticks < 1) return step;
    if (this.trackedSteps.length) this.batch();
    if (this.drive === 'path' && !step.path) this.drive = 'move';
    if (this.drive === 'path') this.pathTime += step.ticks / TICKS_PER_SECOND;
    if (this.drive === 'tracked') this.drive = 'move';
    this.moveSteps.push({ ...step });
    Object.assign(this.lastMove, step);
    this.simTicks += step.ticks;
    this.lastStepMs = this.wallMs();
    if (this.moveSteps.length === MAX_STEPS) this.batch();
    return step;
  }

  /** Records a VR step; quantizes `step` in place (drive the local runtime with its values). */
  recordTracked(step: TrackedStep): TrackedStep {
    quantizeTrackedStep(step);
    if (step.ticks < 1) return step;
    if (this.moveSteps.length) this.batch();
    this.drive = 'tracked';
    this.trackedSteps.push({ ...step });
    Object.assign(this.lastTracked, step);
    this.simTicks += step.ticks;
    this.lastStepMs = this.wallMs();
    if (this.trackedSteps.length === MAX_STEPS) this.batch();
    return step;
  }

  /** The latest tracker sample (head, left, right) for the next TRACKED message. */
  setTrackers(t: readonly RoomTrackerPose[]): void {
    for (let i = 0; i < 3; i++) {
      const d = this.trackers[i];
      const s = t[i];
      d.tracked = s.tracked;
      d.fromHand = s.fromHand;
      for (let c = 0; c < 3; c++) d.position[c] = s.position[c];
      for (let c = 0; c < 4; c++) d.rotation[c] = s.rotation[c];
    }
  }

  /** The character's root and frame after the last step (reported with every message). */
  report(rootX: number, rootZ: number, rootYaw: number, frame: number): void {
    this.root.rootX = rootX;
    this.root.rootZ = rootZ;
    this.root.rootYaw = rootYaw;
    this.root.frame = frame;
  }

  /** Starts following a path from the next step on (the PATH message follows earlier steps). */
  setPath(points: Float32Array, speeds: Float32Array, looped: boolean): Uint8Array {
    this.batch();
    const bytes = encodePath({ seq: this.seq + 1, time: this.stamp(this.wallMs()), points, speeds, looped });
    this.seq++;
    this.queue.push(bytes);
    this.drive = 'path';
    this.pathTime = 0;
    this.path = { points, speeds, looped };
    return bytes;
  }

  /**
   * A new connection (new member id): sequence and clock start over, unsent steps are dropped;
   * the root, inputs and drive are kept, and the path being followed is queued again (the
   * caller queues a STATE next, which carries how far along it is).
   */
  restart(): void {
    this.seq = 0;
    this.simTicks = 0;
    this.startMs = this.now();
    this.lastStepMs = 0;
    this.lastSentTime = 0;
    this.clock.reset();
    this.moveSteps = [];
    this.trackedSteps = [];
    this.queue = [];
    if (this.drive === 'path' && this.path) {
      this.seq++;
      this.queue.push(encodePath({ seq: this.seq, time: this.stamp(0), ...this.path }));
    }
  }

  /** Everything to send now: queued messages and a message with the steps since the last flush. */
  flush(): Uint8Array[] {
    this.batch();
    const out = this.queue;
    this.queue = [];
    return out;
  }

  /**
   * Queues a STATE message (after the steps so far): sent by the next `flush()`. `runtime`: the
   * character's runtime state after the last recorded step (`CharacterRuntime.saveState`).
   */
  queueState(restart = false, runtime: Uint8Array | null = null): void {
    this.batch();
    this.seq++;
    this.queue.push(this.encodeState(restart, runtime));
  }

  private encodeState(restart: boolean, runtime: Uint8Array | null): Uint8Array {
    return encodeState({
      restart,
      runtime,
      seq: this.seq,
      time: this.stamp(this.wallMs()),
      frame: this.root.frame,
      rootX: this.root.rootX,
      rootZ: this.root.rootZ,
      rootYaw: this.root.rootYaw,
      drive: this.drive,
      pathTime: this.pathTime,
      scale: this.scale,
      alpha: this.alpha,
      move: this.lastMove,
      tracked: this.lastTracked,
    });
  }

  private batch(): void {
    if (this.moveSteps.length) {
      this.seq++;
      this.queue.push(encodeMove({ seq: this.seq, time: this.stamp(this.lastStepMs), ...this.root, steps: this.moveSteps }));
      this.moveSteps = [];
    }
    if (this.trackedSteps.length) {
      this.seq++;
      this.queue.push(
        encodeTracked({ seq: this.seq, time: this.stamp(this.lastStepMs), ...this.root, scale: this.scale, alpha: this.alpha, trackers: this.trackers, steps: this.trackedSteps }),
      );
      this.trackedSteps = [];
    }
  }
}
