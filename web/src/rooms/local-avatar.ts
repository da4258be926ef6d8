/**
 * The local member's avatar in a room: drives the local `DrivenCharacter` and records every step
 * into the room's `InputStream` with the same quantized numbers, so receivers replaying the
 * stream compute the same motion. Call `setMove` / `setPath` / `setTracked` as the devices say,
 * then `update(dt)` once a frame instead of the character's own update.
 */
import { copyMoveInput, createDrive, type DrivePath, type MoveInput, type TrackedInput } from '../core/drive.ts';
import type { DrivenCharacter } from './driven-character.ts';
import type { InputStream } from './input-stream.ts';
import { createMoveStep, createTrackedStep, TICKS_PER_SECOND, type MoveStep, type TrackedStep, type RoomTrackerPose } from './protocol.ts';
import { driveFromMove, driveFromPath, driveFromTracked } from './step-drive.ts';

export class LocalAvatar {
  /** The drive value the character is given (database units), made from the steps as sent; its mode is the one mode here. */
  private readonly drive = createDrive();
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
    copyMoveInput(input, this.move);
    this.drive.mode = 'move';
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

  /** Follows a path (database units) from the next frame on. Throws on a bad path (nothing sent). */
  setPath(points: Float32Array, speeds: Float32Array, looped: boolean): void {
    this.stream.setPath(points, speeds, looped); // validates (throws on a bad path)
    const path: DrivePath = { points, speeds, looped };
    this.character.setDrive(driveFromPath(path, this.drive));
    this.stream.queueState();
  }

  /** VR: the tracked-mode input for the next frame (room metres), the avatar scale and α. */
  setTracked(step: Readonly<TrackedInput>, scale: number, alpha: number): void {
    Object.assign(this.tracked, step);
    // As the wire carries them (float32, whole cm), so both sides divide by the same numbers.
    this.setScale(scale);
    this.alpha = Math.max(0, Math.min(255, Math.round(alpha * 100))) / 100;
    this.stream.alpha = this.alpha;
    this.drive.mode = 'tracked';
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
    const d = this.drive;
    if (d.mode === 'tracked') {
      this.tracked.ticks = ticks;
      this.stream.recordTracked(this.tracked); // quantizes in place
      c.setDrive(driveFromTracked(this.tracked, this.scale, this.alpha, d));
    } else {
      this.move.ticks = ticks;
      this.move.path = d.mode === 'path';
      this.stream.recordMove(this.move); // quantizes in place
      if (d.mode === 'move') c.setDrive(driveFromMove(this.move, d));
    }
    const step = ticks / TICKS_PER_SECOND;
    c.update(step);
    this.stream.report(c.rootX, c.rootZ, c.rootYaw, c.frame);
    return step;
  }
}
