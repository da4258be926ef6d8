/**
 * Drift correction for a re-synthesized remote avatar: a display offset (x, z, yaw) added to the
 * local simulation's root so the avatar shows where its sender says it is, blended in by a
 * critically damped spring (Holden's `simple_spring_damper_exact`, parametrized by half-life)
 * with its per-step change clamped to `maxSpeed · dt` (and `maxAngularSpeed · dt`): it never
 * pops. The simulation itself is never moved, so replaying the sender's steps stays exact; the
 * offset only covers what replay could not reproduce (a late join, a lost message, different
 * settings).
 *
 *   displayed root = simulated root + (offsetX, offsetZ); displayed yaw = simulated yaw + offsetYaw
 *   (the body turned by offsetYaw about its root).
 */
import { wrapAngle } from '../yaw.ts';

export interface DriftCorrectorOptions {
  /** Half-life of the spring, s: the offset covers half the error in about this time. Default 0.25. */
  halflife?: number;
  /** Largest correction speed, m/s. Default 1.5. */
  maxSpeed?: number;
  /** Largest correction turn rate, rad/s. Default 2. */
  maxAngularSpeed?: number;
}

const LN2 = Math.LN2;

/** One critically damped spring step toward `goal`; returns the new value, velocity in `v[i]`. */
function springStep(x: number, v: Float64Array, i: number, goal: number, halflife: number, dt: number): number {
  const y = (4 * LN2) / halflife / 2;
  const j0 = x - goal;
  const j1 = v[i] + j0 * y;
  const e = Math.exp(-y * dt);
  v[i] = e * (v[i] - j1 * y * dt);
  return e * (j0 + j1 * dt) + goal;
}

export class DriftCorrector {
  readonly options: Required<DriftCorrectorOptions>;
  offsetX = 0;
  offsetZ = 0;
  offsetYaw = 0;
  /** What the offset moves to: reported − simulated at the last measurement. */
  targetX = 0;
  targetZ = 0;
  targetYaw = 0;
  /** Measurements taken and rejected (non-finite). */
  measurements = 0;
  rejected = 0;
  private readonly velocity = new Float64Array(3);

  constructor(options: DriftCorrectorOptions = {}) {
    this.options = { halflife: options.halflife ?? 0.25, maxSpeed: options.maxSpeed ?? 1.5, maxAngularSpeed: options.maxAngularSpeed ?? 2 };
  }

  /**
   * The sender's reported root against the local re-synthesized root at the same step (after
   * replaying the message's last step). Non-finite values are ignored.
   */
  measure(simX: number, simZ: number, simYaw: number, reportedX: number, reportedZ: number, reportedYaw: number): boolean {
    const dx = reportedX - simX;
    const dz = reportedZ - simZ;
    const dyaw = wrapAngle(reportedYaw - simYaw);
    if (!Number.isFinite(dx) || !Number.isFinite(dz) || !Number.isFinite(dyaw)) {
      this.rejected++;
      return false;
    }
    this.targetX = dx;
    this.targetZ = dz;
    // Keep the target yaw on the same turn as the current offset (no 2π spin).
    this.targetYaw = this.offsetYaw + wrapAngle(dyaw - this.offsetYaw);
    this.measurements++;
    return true;
  }

  /**
   * The simulation jumped by (dx, dz, dyaw) (a reset to a snapshot): shift the offset the other
   * way so the displayed avatar does not move this frame; the spring then blends it out.
   */
  rebase(dx: number, dz: number, dyaw: number): void {
    if (!Number.isFinite(dx + dz + dyaw)) return;
    this.offsetX -= dx;
    this.offsetZ -= dz;
    this.offsetYaw -= dyaw;
    this.targetX -= dx;
    this.targetZ -= dz;
    this.targetYaw -= dyaw;
  }

  /** Advances the offset by `dt` seconds toward the target. */
  update(dt: number): void {
    if (!(dt > 0) || !Number.isFinite(dt)) return;
    const o = this.options;
    const v = this.velocity;
    const x = springStep(this.offsetX, v, 0, this.targetX, o.halflife, dt);
    const z = springStep(this.offsetZ, v, 1, this.targetZ, o.halflife, dt);
    const yaw = springStep(this.offsetYaw, v, 2, this.targetYaw, o.halflife, dt);
    let dx = x - this.offsetX;
    let dz = z - this.offsetZ;
    const step = Math.hypot(dx, dz);
    const maxStep = o.maxSpeed * dt;
    if (step > maxStep) {
      dx *= maxStep / step;
      dz *= maxStep / step;
      v[0] = dx / dt;
      v[1] = dz / dt;
    }
    let dyaw = yaw - this.offsetYaw;
    const maxTurn = o.maxAngularSpeed * dt;
    if (Math.abs(dyaw) > maxTurn) {
      dyaw = Math.sign(dyaw) * maxTurn;
      v[2] = dyaw / dt;
    }
    this.offsetX += dx;
    this.offsetZ += dz;
    this.offsetYaw += dyaw;
    // Keep the yaw offset and its target in (−π, π] together.
    if (Math.abs(this.offsetYaw) > Math.PI) {
      const wrapped = wrapAngle(this.offsetYaw);
      this.targetYaw += wrapped - this.offsetYaw;
      this.offsetYaw = wrapped;
    }
  }

  /** Distance (m) between the displayed and the reported root at the last measurement. */
  get error(): number {
    return Math.hypot(this.targetX - this.offsetX, this.targetZ - this.offsetZ);
  }

  reset(): void {
    this.offsetX = this.offsetZ = this.offsetYaw = 0;
    this.targetX = this.targetZ = this.targetYaw = 0;
    this.velocity.fill(0);
  }
}
