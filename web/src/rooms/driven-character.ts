/**
 * What shared rooms drive: the small interface the engine's `Character` (or an adapter around
 * it) satisfies, for the local avatar (`LocalAvatar`) and each remote one (`RemoteAvatar`).
 * Rooms never import the engine; the engine never needs the network.
 *
 * Determinism: given the same database, the same runtime settings for its drive mode and the
 * same calls with the same numbers in the same order, two characters compute the same motion.
 * The rooms code calls exactly `setDrive` then `update(dt)` per step, on both sides.
 */
import type { Drive } from '../core/drive.ts';
import type { RoomTrackerPose } from './protocol.ts';

export interface DrivenCharacter {
  /**
   * The drive value for the next `update` (database units; built from the wire's steps by
   * `step-drive.ts`, the same lines on sender and receiver), applied now: its path too when it is
   * not the object the character follows (a new one starts from its beginning). Throws on a path
   * the character cannot follow.
   */
  setDrive(drive: Readonly<Drive>): void;
  /** Advances the simulation by `dt` seconds (always `ticks / 7200`). */
  update(dt: number): void;
  /**
   * Places the character at a snapshot: database `frame` (−1: unknown, keep playing), root (x, z,
   * room m) and yaw (rad, 0 = +Z).
   */
  reset(frame: number, x: number, z: number, yaw: number): void;
  /**
   * Continues from a member's runtime state (`CharacterRuntime.saveState` bytes, sent when
   * someone joins), after `reset` and the path it follows (`setDrive`): from then on this copy
   * computes the sender's own floats. Throws with the reason on bytes the runtime refuses (nothing changes then).
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
