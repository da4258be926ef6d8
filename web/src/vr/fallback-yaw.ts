/**
 * The HMD-forward dead-zone heuristic for the body yaw (docs/method.md §9's baseline, 14.5° mean
 * error against the network's 5.4°): the body keeps its yaw while the head looks around within
 * ±`deadZone`, and turns smoothly (half-life `halflife`) just far enough to bring the head back to
 * the edge of the dead zone when it looks further. While the head moves over the ground faster
 * than `walkSpeed` the dead zone closes (people look where they walk), so walking turns the body.
 */
import type { BodyYawPredictor, TrackerPose } from './body-yaw.ts';
import { headingYaw, wrapAngle } from '../yaw.ts';

export interface HeadingYawOptions {
  /** Half-width of the dead zone, rad (25°). */
  deadZone: number;
  /** Half-life of the turn toward the goal, s. */
  halflife: number;
  /** Head ground speed (m/s) at and above which the dead zone is fully closed. */
  walkSpeed: number;
}

export const DEFAULT_HEADING_YAW_OPTIONS: Readonly<HeadingYawOptions> = {
  deadZone: (25 * Math.PI) / 180,
  halflife: 0.15,
  walkSpeed: 0.6,
};

export class HeadingYawPredictor implements BodyYawPredictor {
  readonly name = 'heuristic';
  readonly options: HeadingYawOptions;
  private yaw = 0;
  private started = false;

  constructor(options: Partial<HeadingYawOptions> = {}) {
    this.options = { ...DEFAULT_HEADING_YAW_OPTIONS, ...options };
  }

  update(hmd: TrackerPose, _left: TrackerPose, _right: TrackerPose, dt: number): number {
    const q = hmd.rotation;
    const head = headingYaw(q[0], q[1], q[2], q[3]);
    if (!this.started) {
      this.started = true;
      this.yaw = head;
      return this.yaw;
    }
    const o = this.options;
    const speed = Math.hypot(hmd.velocity[0], hmd.velocity[2]);
    const zone = o.deadZone * Math.max(0, 1 - speed / o.walkSpeed);
    const offset = wrapAngle(head - this.yaw);
    const excess = Math.abs(offset) - zone;
    if (excess > 0 && dt > 0) {
      const step = Math.sign(offset) * excess * (1 - Math.pow(2, -dt / o.halflife));
      this.yaw = wrapAngle(this.yaw + step);
    }
    return this.yaw;
  }

  reset(): void {
    this.started = false;
  }
}
