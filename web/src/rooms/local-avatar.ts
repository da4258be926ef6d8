/**
 * The local member's avatar in a room: drives the local `DrivenCharacter` and records every step
 * into the room's `InputStream` with the same quantized numbers, so receivers replaying the
 * stream compute the same motion. Call `setMove` / `setPath` / `setTracked` as the devices say,
 * then `update(dt)` once a frame instead of the character's own update.
 */
import type { MoveInput, TrackedInput } from '../core/character.ts';
import type { DrivenCharacter } from './driven-character.ts';
import type { InputStream } from './input-stream.ts';
import { createMoveStep, createTrackedStep, TICKS_PER_SECOND, type MoveStep, type TrackedStep, type RoomTrackerPose } from './protocol.ts';

export class LocalAvatar {
  private mode: 'move' | 'path' | 'tracked' = 'move';
  private readonly move: MoveStep = createMoveStep();
  private readonly tracked: TrackedStep = createTrackedStep();
  private scale = 1;
  private alpha = 0.2;

  constructor(
    readonly character: DrivenCharacter,
    readonly stream: InputStream,
  ) {}

  /** Desktop input for the next frame (leaves path mode). */
  setMove(input: Readonly<MoveInput>): void {
    const m = this.move;
    m.moveX = input.moveX;
    m.moveZ = input.moveZ;
    m.faceX = input.faceX;
    m.faceZ = input.faceZ;
    m.run = input.run;
    m.strafe = input.strafe;
    if (this.mode === 'path') this.character.setPath(null, 0);
    this.mode = 'move';
  }

  /**
   * Room metres per database unit of this member's character (desktop; VR passes it with every
   * `setTracked`): sent in STATE so receivers place and size their copy alike.
   */
  setScale(scale: number): void {
    const s = Math.fround(scale);
    if (s === this.scale) return;
    this.scale = s;
    this.stream.scale = s;
    this.character.setScale?.(s);
  }

  /** Follows a path (database units) from the next frame on. */
  setPath(points: Float32Array, speeds: Float32Array, looped: boolean): void {
    const bytes = this.stream.setPath(points, speeds, looped); // validates (throws on a bad path)
    void bytes;
    this.character.setPath({ points, speeds, looped }, 0);
    this.stream.queueState();
    this.mode = 'path';
  }

  /** VR: the tracked-mode input for the next frame (room metres), the avatar scale and α. */
  setTracked(step: Readonly<TrackedInput>, scale: number, alpha: number): void {
    Object.assign(this.tracked, step);
    // As the wire carries them (float32, whole cm), so both sides divide by the same numbers.
    this.scale = Math.fround(scale);
    this.alpha = Math.max(0, Math.min(255, Math.round(alpha * 100))) / 100;
    this.stream.scale = this.scale;
    this.stream.alpha = this.alpha;
    this.mode = 'tracked';
  }

  /** VR: the latest head and grip poses (sent with the next message, for display). */
  setTrackers(trackers: readonly RoomTrackerPose[]): void {
    this.stream.setTrackers(trackers);
  }

  /**
   * Advances the character by this frame's `dt` (s), quantized to ticks of 1/7200 s with the
   * remainder carried; returns the dt used (0 when the frame is too short for a tick).
   */
  update(dt: number): number {
    const ticks = this.stream.clock.ticksFor(dt);
    if (ticks === 0) return 0;
    const c = this.character;
    if (this.mode === 'tracked') {
      this.tracked.ticks = ticks;
      this.stream.recordTracked(this.tracked); // quantizes in place
      c.setTracked(this.tracked, this.scale, this.alpha);
    } else {
      this.move.ticks = ticks;
      this.move.path = this.mode === 'path';
      this.stream.recordMove(this.move);
      if (this.mode === 'move') c.setMove(this.move);
    }
    const step = ticks / TICKS_PER_SECOND;
    c.update(step);
    this.stream.report(c.rootX, c.rootZ, c.rootYaw, c.frame);
    return step;
  }
}
