/**
 * What shared rooms drive: the small interface the engine's `Character` (or an adapter around
 * it) satisfies, for the local avatar (`LocalAvatar`) and each remote one (`RemoteAvatar`).
 * Rooms never import the engine; the engine never needs the network.
 *
 * Determinism: given the same database, the same runtime settings for its drive mode and the
 * same calls with the same numbers in the same order, two characters compute the same motion.
 * The rooms code calls exactly `set*` then `update(dt)` per step, on both sides.
 */
import type { MoveStep, TrackedStep, RoomTrackerPose } from './protocol.ts';

export interface PathInput {
  /** Keypoints (x, z interleaved) in database units. */
  points: Float32Array;
  /** m/s per segment (count − 1, or count when looped). */
  speeds: Float32Array;
  looped: boolean;
}

export interface DrivenCharacter {
  /** Desktop input for the next `update` (stick direction, facing, run, strafe), world space. */
  setMove(step: Readonly<MoveStep>): void;
  /**
   * Follow `path` from `time` seconds into it (0: its start), or `null` to return to move input.
   * A runtime that cannot start mid-path may start at its beginning (drift correction covers it).
   */
  setPath(path: PathInput | null, time: number): void;
  /**
   * VR: the tracked-mode input for the next `update`, in room metres (head floor position, ground
   * velocity, body yaw, hips drop); `scale` = room metres per database unit, `alpha` = clamp
   * distance (m). The adapter divides by `scale` itself (the same code on sender and receiver).
   */
  setTracked(step: Readonly<TrackedStep>, scale: number, alpha: number): void;
  /** Advances the simulation by `dt` seconds (always `ticks / 7200`). */
  update(dt: number): void;
  /**
   * Places the character at a snapshot: database `frame` (−1: unknown, keep playing), root (x, z,
   * room m) and yaw (rad, 0 = +Z).
   */
  reset(frame: number, x: number, z: number, yaw: number): void;
  /**
   * Continues from a member's runtime state (`CharacterRuntime.saveState` bytes, sent when
   * someone joins), after `reset` and `setPath`: from then on this copy computes the sender's
   * own floats. Throws with the reason on bytes the runtime refuses (nothing changes then).
   */
  loadState?(bytes: Uint8Array): void;
  /** The simulated root after the last update (room m, rad) and the database frame playing. */
  readonly rootX: number;
  readonly rootZ: number;
  readonly rootYaw: number;
  readonly frame: number;
  /**
   * Display-only drift correction: show the avatar moved by (dx, dz) and turned by `dyaw` about
   * its root. Never changes the simulation. Called every frame for remote avatars.
   */
  setDisplayOffset(dx: number, dz: number, dyaw: number): void;
  /**
   * Room metres per database unit of the member this character stands for (optional): the
   * sender's own, from its STATE and TRACKED messages. Positions (`reset`, `rootX`/`rootZ`) are
   * converted with it and the avatar drawn at that size.
   */
  setScale?(scale: number): void;
  /** VR display (optional): head and grips (head, left, right) at this frame, room space. */
  setTrackers?(trackers: readonly RoomTrackerPose[]): void;
}
