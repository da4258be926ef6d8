/**
 * `RoomCharacter`: the engine's `Character` as a shared room drives it (`DrivenCharacter`), the
 * one adapter for both sides — the local member's `LocalAvatar` steps its own character through
 * it, and each `RemoteAvatar` replays its sender's steps through another. Both sides must run
 * the same code on the same numbers for the copies to compute the same motion: the drive values
 * (database units, from `step-drive.ts`) go to the character as they are, and positions convert
 * room metres with the member's `scale` (float32, as the wire carries it) — never through the
 * three.js transforms, whose matrix inverses would round differently on a receiver whose avatar
 * has another size.
 *
 * A remote member's character lives inside `display`: the drift correction's offset is that
 * group's transform (the avatar turned by `dyaw` about its root and moved by `dx, dz`), so the
 * simulation is never nudged. Its `object3d` is scaled so a database unit is drawn `scale` room
 * metres long whatever avatar the receiver shows.
 */
import * as THREE from 'three';
import type { Character } from '../character/character.ts';
import type { Drive } from '../core/drive.ts';
import type { DrivenCharacter } from './driven-character.ts';
import type { RoomTrackerPose } from './protocol.ts';

export class RoomCharacter implements DrivenCharacter {
  /** Holds a remote member's `character.object3d`; its transform is the display offset. Add it to the scene. */
  readonly display = new THREE.Group();
  /** A remote VR member's head and grips this frame (room space, before the display offset). */
  trackers: readonly RoomTrackerPose[] | null = null;
  private scale_ = 1;

  /**
   * `remote`: a copy of another member (drawn inside `display`, sized by the sender's scale);
   * otherwise the local member's own character, which stays where the page put it.
   */
  constructor(
    readonly character: Character,
    readonly remote: boolean,
  ) {
    if (remote) {
      this.display.name = 'mm-room-member';
      this.display.add(character.object3d);
      this.display.visible = false;
    }
  }

  /** Room metres per database unit. */
  get scale(): number {
    return this.scale_;
  }

  setScale(scale: number): void {
    if (!(scale > 0) || scale === this.scale_) return;
    this.scale_ = scale;
    if (this.remote) {
      this.character.object3d.scale.setScalar(scale / this.character.worldScale);
      this.character.object3d.updateMatrix();
    }
  }

  setDrive(drive: Readonly<Drive>): void {
    this.character.applyDrive(drive);
  }

  update(dt: number): void {
    this.character.advance(dt);
  }

  /**
   * A fresh runtime (same database and settings) placed at (x, z, yaw): every copy of a member
   * restarts this way from the same numbers — the sender when it joins, each receiver at the
   * sender's restart STATE — so from there on they compute the same motion (`frame` −1: a fresh
   * runtime searches from the placed root on its first update). A copy placed at a snapshot that
   * is not a restart (a late joiner, the sender moving) plays the sender's database `frame`,
   * moving as it moves, so it does not start from rest while its sender walks.
   */
  reset(frame: number, x: number, z: number, yaw: number): void {
    const s = this.scale_;
    this.character.restartAt(frame, x / s, z / s, yaw);
  }

  loadState(bytes: Uint8Array): void {
    this.character.loadState(bytes);
  }

  get rootX(): number {
    return this.character.databaseRoot[0] * this.scale_;
  }
  get rootZ(): number {
    return this.character.databaseRoot[2] * this.scale_;
  }
  get rootYaw(): number {
    return this.character.databaseRoot[3];
  }
  get frame(): number {
    return this.character.frame;
  }

  setDisplayOffset(dx: number, dz: number, dyaw: number): void {
    if (!this.remote) return;
    // Turn about the simulated root, then move: display = R(dyaw)·(p − root) + root + d.
    const x = this.rootX;
    const z = this.rootZ;
    const c = Math.cos(dyaw);
    const s = Math.sin(dyaw);
    this.display.rotation.set(0, dyaw, 0);
    this.display.position.set(x + dx - (x * c + z * s), 0, z + dz - (-x * s + z * c));
  }

  setTrackers(trackers: readonly RoomTrackerPose[]): void {
    this.trackers = trackers;
  }
}
