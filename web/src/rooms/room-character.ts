/**
 * `RoomCharacter`: the engine's `Character` as a shared room drives it (`DrivenCharacter`), the
 * one adapter for both sides — the local member's `LocalAvatar` steps its own character through
 * it, and each `RemoteAvatar` replays its sender's steps through another. Both sides must run
 * the same code on the same numbers for the copies to compute the same motion, so this talks to
 * the runtime directly in database units, converting room metres with the member's `scale`
 * (float32, as the wire carries it) — never through the three.js transforms, whose matrix
 * inverses would round differently on a receiver whose avatar has another size.
 *
 * A remote member's character lives inside `display`: the drift correction's offset is that
 * group's transform (the avatar turned by `dyaw` about its root and moved by `dx, dz`), so the
 * simulation is never nudged. Its `object3d` is scaled so a database unit is drawn `scale` room
 * metres long whatever avatar the receiver shows.
 */
import * as THREE from 'three';
import type { Character } from '../character/character.ts';
import type { DrivenCharacter, PathInput } from './driven-character.ts';
import type { MoveStep, RoomTrackerPose, TrackedStep } from './protocol.ts';

export class RoomCharacter implements DrivenCharacter {
  /** Holds a remote member's `character.object3d`; its transform is the display offset. Add it to the scene. */
  readonly display = new THREE.Group();
  /** A remote VR member's head and grips this frame (room space, before the display offset). */
  trackers: readonly RoomTrackerPose[] | null = null;
  private scale_ = 1;
  /** The clamp distance last given to the runtime (database units; NaN: none yet). */
  private clamp = NaN;

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

  setMove(step: Readonly<MoveStep>): void {
    this.character.runtime.setInput(step);
  }

  /** `time` is not used: the runtime starts a path at its beginning (a late joiner's copy then loads how far along the sender is: `loadState`). */
  setPath(path: PathInput | null, _time: number): void {
    if (path) this.character.runtime.setPath(path.points, path.speeds, path.looped);
    else this.character.runtime.clearPath();
  }

  setTracked(step: Readonly<TrackedStep>, scale: number, alpha: number): void {
    this.setScale(scale);
    const s = this.scale_;
    const runtime = this.character.runtime;
    runtime.setTracked(step.headX / s, step.headZ / s, step.velocityX / s, step.velocityZ / s, step.yaw);
    runtime.setHipsDrop(step.hipsDrop / s);
    runtime.setTorsoBend(step.bend);
    const clamp = alpha / s;
    if (clamp !== this.clamp) {
      this.clamp = clamp; // settings go through JSON: only when α or the scale changed
      runtime.setSettings({ clamp_distance: clamp });
    }
  }

  update(dt: number): void {
    this.character.runtime.update(dt);
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
    this.character.restartRuntime();
    this.clamp = NaN;
    const s = this.scale_;
    if (frame >= 0) this.character.runtime.teleportPlaying(frame, x / s, z / s, yaw);
    else this.character.runtime.teleport(x / s, z / s, yaw);
  }

  loadState(bytes: Uint8Array): void {
    this.character.runtime.loadState(bytes);
  }

  get rootX(): number {
    return this.character.runtime.root[0] * this.scale_;
  }
  get rootZ(): number {
    return this.character.runtime.root[2] * this.scale_;
  }
  get rootYaw(): number {
    return this.character.runtime.root[3];
  }
  get frame(): number {
    return this.character.runtime.frame;
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
