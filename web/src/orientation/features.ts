/**
 * The 54 inputs of the body-orientation network from raw WebXR tracker poses — the browser twin
 * of `training/orientation/features.py` (the contract is `docs/orientation-model.md`).
 *
 * Frames: WebXR `local-floor` space as three.js uses it (Y up, metres, quaternions x, y, z, w).
 * The headset pose is the viewer pose (looks down its local −Z); the controllers are their
 * `gripSpace` poses. Everything is re-expressed in the frame of the HMD's yaw ("R_H"), so the
 * network sees the same numbers wherever the user faces in the room (docs/method.md §9).
 *
 * Per frame nothing is allocated: the input lives in one preallocated Float32Array, the headset's
 * last second in a preallocated ring.
 */

import { headingYaw as hmdYaw } from '../yaw.ts';

export const NUM_TRACKERS = 3;
export const NUM_INPUTS = 54;
/** The thesis's inputs (trackers and the previous slot): a model from before the context takes these. */
export const LEGACY_INPUTS = 42;
/** Start of the previous-orientation slot (6 floats) in the input. */
export const PREV_OFFSET = 36;
/** Start of the context: the controllers relative to the headset, then the headset's windowed velocities. */
export const CONTEXT_OFFSET = 42;
/** The windows (s) of the headset's mean velocity, inputs 48..53 (longest last). */
export const CONTEXT_WINDOWS: readonly number[] = [0.25, 0.5, 1.0];
/** Frames the ring keeps: the longest window at up to 1,000 Hz (beyond that the window is shorter). */
const HISTORY = 1024;
/** A frame gap longer than this (s) is a discontinuity (paused session): velocities are zero. */
export const MAX_DT = 0.25;

/** Writes the 6D of a pure yaw φ — (cos φ, 0, −sin φ, 0, 1, 0) — into `out` at `offset`. */
export function writeYaw6d(out: Float32Array, offset: number, phi: number): void {
  out[offset] = Math.cos(phi);
  out[offset + 1] = 0;
  out[offset + 2] = -Math.sin(phi);
  out[offset + 3] = 0;
  out[offset + 4] = 1;
  out[offset + 5] = 0;
}

/**
 * Builds the network input frame by frame.
 *
 * Layout of `input` (see docs/orientation-model.md): for tracker k = HMD, left, right, at 12k:
 * rotation 6D (columns 0 and 1 of R_H⁻¹·R), velocity R_H⁻¹·Δp/dt (m/s), angular velocity
 * R_H⁻¹·rotvec(q·q_prev⁻¹)/dt (rad/s); then at 36 the previous body orientation's 6D, which the
 * caller sets with {@link setPrevious} (after `reset()` it is "HMD forward", φ = 0); then at 42
 * each controller relative to the headset, R_H⁻¹·(p_k − p_hmd) (m), and at 48 the headset's
 * mean velocity over the last 0.25, 0.5 and 1 s, (x, z) of R_H⁻¹·(p − p_j)/(t − t_j) (m/s), j
 * the oldest frame since the last reset or gap with t_j ≥ t − window (t: the dts summed).
 */
export class OrientationFeatures {
  /** The 54 network inputs (reused every frame). */
  readonly input = new Float32Array(NUM_INPUTS);
  /** HMD yaw of the last update, radians. */
  hmdYaw = 0;
  private readonly prevPos = new Float64Array(NUM_TRACKERS * 3);
  private readonly prevQuat = new Float64Array(NUM_TRACKERS * 4);
  private hasPrev = false;
  /** Seconds since the reset (the dts summed in order, as `features.py` sums them). */
  private time = 0;
  /** The headset's floor positions (x, z) since the restart, at most the longest window back: a ring. */
  private readonly ringTime = new Float64Array(HISTORY);
  private readonly ringPos = new Float64Array(HISTORY * 2);
  private ringStart = 0;
  private ringCount = 0;

  constructor() {
    this.reset();
  }

  /** Forgets the previous poses: the next update has zero velocities; previous slot = HMD forward. */
  reset(): void {
    this.hasPrev = false;
    this.time = 0;
    this.ringCount = 0;
    this.input.fill(0);
    writeYaw6d(this.input, PREV_OFFSET, 0);
  }

  /**
   * Updates inputs 0..35 and 42..53 from this frame's poses.
   * @param positions 9 numbers: HMD, left grip, right grip positions (x, y, z), metres.
   * @param quaternions 12 numbers: the same trackers' orientations (x, y, z, w), any length > 0.
   * @param dt seconds since the previous update (the real frame time: 1/72, 1/90, 1/120 s…).
   * @returns `input` (the previous-orientation slot untouched).
   * @throws RangeError for non-finite poses, zero quaternions or a non-positive dt.
   */
  update(positions: ArrayLike<number>, quaternions: ArrayLike<number>, dt: number): Float32Array {
    if (positions.length < 9 || quaternions.length < 12) {
      throw new RangeError(`OrientationFeatures.update: need 9 positions and 12 quaternion numbers, got ${positions.length} and ${quaternions.length}`);
    }
    for (let i = 0; i < 9; i++) {
      if (!Number.isFinite(positions[i])) throw new RangeError(`OrientationFeatures.update: position ${i} is ${positions[i]}`);
    }
    for (let i = 0; i < 12; i++) {
      if (!Number.isFinite(quaternions[i])) throw new RangeError(`OrientationFeatures.update: quaternion number ${i} is ${quaternions[i]}`);
    }
    if (this.hasPrev && !(dt > 0 && Number.isFinite(dt))) {
      throw new RangeError(`OrientationFeatures.update: dt must be positive and finite seconds, got ${dt}`);
    }
    const moving = this.hasPrev && dt <= MAX_DT;

    // The HMD's yaw frame of this frame; R_H⁻¹ v = (c·vx − s·vz, vy, s·vx + c·vz).
    let hx = quaternions[0], hy = quaternions[1], hz = quaternions[2], hw = quaternions[3];
    const hn = Math.hypot(hx, hy, hz, hw);
    if (!(hn > 1e-6)) throw new RangeError('OrientationFeatures.update: HMD quaternion has zero length');
    hx /= hn; hy /= hn; hz /= hn; hw /= hn;
    const yaw = hmdYaw(hx, hy, hz, hw);
    const c = Math.cos(yaw);
    const s = Math.sin(yaw);
    const input = this.input;

    for (let k = 0; k < NUM_TRACKERS; k++) {
      let x = quaternions[4 * k], y = quaternions[4 * k + 1], z = quaternions[4 * k + 2], w = quaternions[4 * k + 3];
      const n = Math.hypot(x, y, z, w);
      if (!(n > 1e-6)) throw new RangeError(`OrientationFeatures.update: quaternion of tracker ${k} has zero length`);
      x /= n; y /= n; z /= n; w /= n;
      const o = 12 * k;
      // Columns 0 and 1 of the rotation matrix, then into the HMD-yaw frame.
      const c0x = 1 - 2 * (y * y + z * z), c0y = 2 * (x * y + z * w), c0z = 2 * (x * z - y * w);
      const c1x = 2 * (x * y - z * w), c1y = 1 - 2 * (x * x + z * z), c1z = 2 * (y * z + x * w);
      input[o] = c * c0x - s * c0z;
      input[o + 1] = c0y;
      input[o + 2] = s * c0x + c * c0z;
      input[o + 3] = c * c1x - s * c1z;
      input[o + 4] = c1y;
      input[o + 5] = s * c1x + c * c1z;

      const px = positions[3 * k], py = positions[3 * k + 1], pz = positions[3 * k + 2];
      if (moving) {
        const vx = (px - this.prevPos[3 * k]) / dt;
        const vy = (py - this.prevPos[3 * k + 1]) / dt;
        const vz = (pz - this.prevPos[3 * k + 2]) / dt;
        input[o + 6] = c * vx - s * vz;
        input[o + 7] = vy;
        input[o + 8] = s * vx + c * vz;
        // Δq = q · q_prev⁻¹ (world-frame rotation over the frame), shorter way round.
        const ax = -this.prevQuat[4 * k], ay = -this.prevQuat[4 * k + 1], az = -this.prevQuat[4 * k + 2], aw = this.prevQuat[4 * k + 3];
        let dx = w * ax + x * aw + y * az - z * ay;
        let dy = w * ay - x * az + y * aw + z * ax;
        let dz = w * az + x * ay - y * ax + z * aw;
        let dw = w * aw - x * ax - y * ay - z * az;
        if (dw < 0) { dx = -dx; dy = -dy; dz = -dz; dw = -dw; }
        const dn = Math.hypot(dx, dy, dz);
        // rotvec = axis·angle; angle/|xyz| → 2/w for tiny rotations.
        const scale = (dn > 1e-12 ? (2 * Math.atan2(dn, dw)) / dn : 2 / Math.max(dw, 1e-12)) / dt;
        const wx = dx * scale, wy = dy * scale, wz = dz * scale;
        input[o + 9] = c * wx - s * wz;
        input[o + 10] = wy;
        input[o + 11] = s * wx + c * wz;
      } else {
        input.fill(0, o + 6, o + 12);
      }
      this.prevPos[3 * k] = px;
      this.prevPos[3 * k + 1] = py;
      this.prevPos[3 * k + 2] = pz;
      this.prevQuat[4 * k] = x;
      this.prevQuat[4 * k + 1] = y;
      this.prevQuat[4 * k + 2] = z;
      this.prevQuat[4 * k + 3] = w;
    }
    this.updateContext(positions, dt, moving, c, s);
    this.hasPrev = true;
    this.hmdYaw = yaw;
    return input;
  }

  /** Inputs 42..53: where the hands are from the head, where the head has been going. */
  private updateContext(positions: ArrayLike<number>, dt: number, moving: boolean, c: number, s: number): void {
    const input = this.input;
    const hx = positions[0], hy = positions[1], hz = positions[2];
    for (let k = 1; k < NUM_TRACKERS; k++) {
      const dx = positions[3 * k] - hx, dy = positions[3 * k + 1] - hy, dz = positions[3 * k + 2] - hz;
      const o = CONTEXT_OFFSET + 3 * (k - 1);
      input[o] = c * dx - s * dz;
      input[o + 1] = dy;
      input[o + 2] = s * dx + c * dz;
    }
    if (this.hasPrev) this.time += dt;
    const now = this.time;
    if (!moving) this.ringCount = 0; // a reset or a gap: the windows start again here
    // Push this frame (overwriting the oldest when the ring is full), then drop what no window
    // will reach again (t only grows).
    if (this.ringCount === HISTORY) {
      this.ringStart = (this.ringStart + 1) % HISTORY;
      this.ringCount--;
    }
    const at = (this.ringStart + this.ringCount) % HISTORY;
    this.ringTime[at] = now;
    this.ringPos[2 * at] = hx;
    this.ringPos[2 * at + 1] = hz;
    this.ringCount++;
    const oldest = now - CONTEXT_WINDOWS[CONTEXT_WINDOWS.length - 1];
    while (this.ringTime[this.ringStart] < oldest) {
      this.ringStart = (this.ringStart + 1) % HISTORY;
      this.ringCount--;
    }
    for (let w = 0; w < CONTEXT_WINDOWS.length; w++) {
      const from = now - CONTEXT_WINDOWS[w];
      let i = 0;
      while (this.ringTime[(this.ringStart + i) % HISTORY] < from) i++;
      const j = (this.ringStart + i) % HISTORY;
      const span = now - this.ringTime[j];
      const o = CONTEXT_OFFSET + 6 + 2 * w;
      if (span > 0) {
        const vx = (hx - this.ringPos[2 * j]) / span, vz = (hz - this.ringPos[2 * j + 1]) / span;
        input[o] = c * vx - s * vz;
        input[o + 1] = s * vx + c * vz;
      } else {
        input[o] = 0;
        input[o + 1] = 0;
      }
    }
  }

  /** Sets the previous-orientation slot to the body yaw φ relative to this frame's HMD yaw. */
  setPrevious(relativeYaw: number): void {
    writeYaw6d(this.input, PREV_OFFSET, relativeYaw);
  }
}
