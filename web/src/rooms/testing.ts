/**
 * A small deterministic stand-in for the engine's character (tests and the load test): springs
 * toward the requested velocity and facing, follows paths, and in tracked mode stays within α
 * of the head. Same calls with the same numbers → the same floats, like the real runtime.
 */
import type { Drive, DrivePath } from '../core/drive.ts';
import type { DrivenCharacter } from './driven-character.ts';
import { wrapAngle } from '../yaw.ts';
import { createMoveStep, createTrackedStep, type MoveStep, type TrackedStep, type RoomTrackerPose } from './protocol.ts';

export class TestCharacter implements DrivenCharacter {
  rootX = 0;
  rootZ = 0;
  rootYaw = 0;
  frame = 0;
  velocityX = 0;
  velocityZ = 0;
  mode: 'move' | 'path' | 'tracked' = 'move';
  readonly move: MoveStep = createMoveStep();
  readonly tracked: TrackedStep = createTrackedStep();
  path: DrivePath | null = null;
  pathTime = 0;
  scale = 1;
  alpha = 0.2;
  offsetX = 0;
  offsetZ = 0;
  offsetYaw = 0;
  updates = 0;
  simulatedSeconds = 0;
  trackers: readonly RoomTrackerPose[] | null = null;

  /** Takes the drive value (database units) back in room metres (× `scale`), as the old adapter did. */
  setDrive(d: Readonly<Drive>): void {
    this.mode = d.mode;
    if (d.mode === 'move') Object.assign(this.move, { moveX: d.moveX, moveZ: d.moveZ, faceX: d.faceX, faceZ: d.faceZ, run: d.run, strafe: d.strafe });
    else if (d.mode === 'path') {
      if (d.path !== this.path) this.pathTime = 0;
      this.path = d.path;
    } else {
      const s = this.scale;
      Object.assign(this.tracked, { headX: d.headX * s, headZ: d.headZ * s, velocityX: d.velocityX * s, velocityZ: d.velocityZ * s, yaw: d.yaw, hipsDrop: d.hipsDrop * s, bend: d.bend });
      this.alpha = d.clampDistance * s;
    }
    if (d.mode !== 'path') this.path = null;
  }
  setScale(scale: number): void {
    this.scale = scale;
  }
  update(dt: number): void {
    let tx = 0;
    let tz = 0;
    if (this.mode === 'move') {
      const speed = this.move.run ? 3.5 : 1.4;
      tx = this.move.moveX * speed;
      tz = this.move.moveZ * speed;
    } else if (this.mode === 'path' && this.path) {
      const p = this.path.points;
      const n = p.length / 2;
      const k = Math.floor(this.pathTime / 2) % n;
      const dx = p[2 * k] - this.rootX;
      const dz = p[2 * k + 1] - this.rootZ;
      const d = Math.hypot(dx, dz);
      const speed = this.path.speeds[Math.min(k, this.path.speeds.length - 1)];
      if (d > 1e-6) {
        tx = (dx / d) * speed;
        tz = (dz / d) * speed;
      }
      this.pathTime += dt;
    } else if (this.mode === 'tracked') {
      tx = this.tracked.velocityX;
      tz = this.tracked.velocityZ;
    }
    const k = 1 - Math.exp(-10 * dt);
    this.velocityX += (tx - this.velocityX) * k;
    this.velocityZ += (tz - this.velocityZ) * k;
    this.rootX += this.velocityX * dt;
    this.rootZ += this.velocityZ * dt;
    if (this.mode === 'tracked') {
      // Stay within α of the head.
      const dx = this.rootX - this.tracked.headX;
      const dz = this.rootZ - this.tracked.headZ;
      const d = Math.hypot(dx, dz);
      if (d > this.alpha) {
        this.rootX = this.tracked.headX + (dx / d) * this.alpha;
        this.rootZ = this.tracked.headZ + (dz / d) * this.alpha;
      }
    }
    let goal = this.rootYaw;
    if (this.mode === 'tracked') goal = this.tracked.yaw;
    else if (this.mode === 'move' && this.move.strafe) goal = Math.atan2(this.move.faceX, this.move.faceZ);
    else if (Math.hypot(this.velocityX, this.velocityZ) > 0.1) goal = Math.atan2(this.velocityX, this.velocityZ);
    this.rootYaw = wrapAngle(this.rootYaw + wrapAngle(goal - this.rootYaw) * k);
    this.frame = (this.frame + 1) % 100_000;
    this.updates++;
    this.simulatedSeconds += dt;
  }
  reset(frame: number, x: number, z: number, yaw: number): void {
    if (frame >= 0) this.frame = frame;
    this.rootX = x;
    this.rootZ = z;
    this.rootYaw = yaw;
    this.velocityX = 0;
    this.velocityZ = 0;
  }
  setDisplayOffset(dx: number, dz: number, dyaw: number): void {
    this.offsetX = dx;
    this.offsetZ = dz;
    this.offsetYaw = dyaw;
  }
  setTrackers(trackers: readonly RoomTrackerPose[]): void {
    this.trackers = trackers;
  }
  get displayX(): number {
    return this.rootX + this.offsetX;
  }
  get displayZ(): number {
    return this.rootZ + this.offsetZ;
  }
}
