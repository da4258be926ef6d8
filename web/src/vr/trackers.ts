/**
 * Tracker state for the VR avatar (docs/method.md §9): the HMD and both controller grips each frame,
 * with linear and angular velocities differentiated over the *real* frame dt (Quest Browser runs
 * at 72/90/120 Hz; MMVR's fixed 90 fps assumption is wrong elsewhere) and lightly smoothed.
 *
 * Robustness, because a body must be shown whatever the devices do:
 * - dt spikes: a frame longer than `maxDt` (a dropped frame, a hitch) is differentiated over its
 *   real duration, so velocities stay bounded averages; after more than `resetAfter` (tab hidden,
 *   headset taken off) the differentiator restarts from zero. `dt` (what the animation should
 *   advance) is clamped to `maxDt`. Speeds are capped (`maxSpeed`, `maxAngularSpeed`) against
 *   tracking glitches.
 * - a controller that is missing (not tracked: asleep, hand tracking off, out of view) or frozen
 *   (bit-for-bit the same pose for `frozenTime` of head motion: a controller gone to sleep may
 *   keep reporting its last pose) blends, over `fallbackHalflife`, to a hanging pose at the side relative
 *   to the HMD's heading, and back when it returns; `status` flags it.
 * - a missing HMD pose holds the last one.
 * - garbage (WebXR poses can be garbage for a frame): a pose with a non-finite number, a position
 *   beyond ±1e5 m or a rotation that is not a quaternion counts as missing for that frame, a
 *   non-finite time as no time passing; each is counted in `rejected`. Rotations are normalized.
 *
 * Everything is preallocated SoA (indices HEAD, LEFT, RIGHT); `update` allocates nothing.
 */
import { HEAD, LEFT, NUM_TRACKERS, RIGHT, type TrackerSample } from './tracker-sample.ts';
import { headingYaw } from '../yaw.ts';
import { mulQuat } from '../quat.ts';

/** Tracker status values (`TrackerState.status`). */
export const TRACKED = 0;
export const MISSING = 1;
export const FROZEN = 2;

export interface TrackerOptions {
  /** Half-life of the velocity smoothing, s. Light: the runtime springs smooth again. */
  velocityHalflife: number;
  /** Frames longer than this (s) are spikes; `dt` is clamped to it. */
  maxDt: number;
  /** After a gap longer than this (s) velocities restart from zero. */
  resetAfter: number;
  /** Cap on tracker speed, m/s. */
  maxSpeed: number;
  /** Cap on angular speed, rad/s. */
  maxAngularSpeed: number;
  /** A controller whose pose did not change at all for this long (s) while the head moved is frozen. */
  frozenTime: number;
  /** Half-life of the blend to and from the hanging pose, s. */
  fallbackHalflife: number;
  /** Hanging hand: sideways from the head centre line (m), height as a fraction of head height, forward (m). */
  hangSide: number;
  hangHeight: number;
  hangForward: number;
}

export const DEFAULT_TRACKER_OPTIONS: Readonly<TrackerOptions> = {
  velocityHalflife: 0.03,
  maxDt: 0.1,
  resetAfter: 0.5,
  maxSpeed: 10,
  maxAngularSpeed: 40,
  frozenTime: 0.5,
  fallbackHalflife: 0.12,
  hangSide: 0.2,
  hangHeight: 0.5,
  hangForward: 0.05,
};

/** One tracker's slice of the SoA state (views, no copies). */
export class TrackerView {
  readonly position: Float64Array;
  readonly rotation: Float64Array;
  readonly velocity: Float64Array;
  readonly angularVelocity: Float64Array;

  constructor(
    private readonly state: TrackerState,
    readonly index: number,
  ) {
    this.position = state.position.subarray(3 * index, 3 * index + 3);
    this.rotation = state.rotation.subarray(4 * index, 4 * index + 4);
    this.velocity = state.velocity.subarray(3 * index, 3 * index + 3);
    this.angularVelocity = state.angularVelocity.subarray(3 * index, 3 * index + 3);
  }

  /** TRACKED, MISSING or FROZEN. */
  get status(): number {
    return this.state.status[this.index];
  }
}

export class TrackerState {
  readonly options: TrackerOptions;
  /** Output poses (world = local-floor space): what the avatar should follow. */
  readonly position = new Float64Array(NUM_TRACKERS * 3);
  readonly rotation = new Float64Array(NUM_TRACKERS * 4);
  /** World-space linear (m/s) and angular (rad/s, axis × rate) velocities of the output poses. */
  readonly velocity = new Float64Array(NUM_TRACKERS * 3);
  readonly angularVelocity = new Float64Array(NUM_TRACKERS * 3);
  readonly status = new Uint8Array(NUM_TRACKERS).fill(MISSING);
  readonly head: TrackerView;
  readonly left: TrackerView;
  readonly right: TrackerView;
  /** What the animation should advance this frame, s (the real dt clamped to `maxDt`). */
  dt = 0;
  /** The real time since the previous sample, s. */
  rawDt = 0;
  /** Samples consumed since construction or `reset()`. */
  frames = 0;
  /** Tracker poses and times refused as garbage since construction (see the class comment). */
  rejected = 0;

  // Last device pose per tracker, how long it has not changed, and the fallback blend (0 = device).
  private readonly devicePosition = new Float64Array(NUM_TRACKERS * 3);
  private readonly deviceRotation = new Float64Array(NUM_TRACKERS * 4);
  private readonly unchangedFor = new Float64Array(NUM_TRACKERS);
  private readonly fallbackWeight = new Float64Array(NUM_TRACKERS);
  private readonly hasDevicePose = new Uint8Array(NUM_TRACKERS);
  private readonly previousPosition = new Float64Array(NUM_TRACKERS * 3);
  private readonly previousRotation = new Float64Array(NUM_TRACKERS * 4);
  // Hand ↔ controller: which one tracks each tracker, and the decaying offset (position, rotation)
  // from the new device's pose to where the old one left the hand, so a switch does not pop.
  private readonly kind = new Uint8Array(NUM_TRACKERS);
  private readonly switched = new Uint8Array(NUM_TRACKERS);
  private readonly switchPosition = new Float64Array(NUM_TRACKERS * 3);
  private readonly switchRotation = new Float64Array(NUM_TRACKERS * 4);
  private lastTime = 0;

  constructor(options: Partial<TrackerOptions> = {}) {
    this.options = { ...DEFAULT_TRACKER_OPTIONS, ...options };
    this.head = new TrackerView(this, HEAD);
    this.left = new TrackerView(this, LEFT);
    this.right = new TrackerView(this, RIGHT);
    this.reset();
  }

  /** Forgets all history (session start, reference-space reset / recentre). */
  reset(): void {
    this.frames = 0;
    this.dt = 0;
    this.rawDt = 0;
    this.velocity.fill(0);
    this.angularVelocity.fill(0);
    this.unchangedFor.fill(0);
    this.hasDevicePose.fill(0);
    this.status.fill(MISSING);
    this.fallbackWeight.fill(1);
    this.position.fill(0);
    this.rotation.fill(0);
    this.devicePosition.fill(0);
    this.deviceRotation.fill(0);
    this.kind.fill(0);
    this.switchPosition.fill(0);
    this.switchRotation.fill(0);
    for (let t = 0; t < NUM_TRACKERS; t++) {
      this.rotation[4 * t + 3] = 1;
      this.deviceRotation[4 * t + 3] = 1;
      this.switchRotation[4 * t + 3] = 1;
    }
    // A standing head until the first HMD pose, so the hanging hands have somewhere to hang.
    this.position[3 * HEAD + 1] = 1.6;
    this.devicePosition[3 * HEAD + 1] = 1.6;
  }

  /** Consumes one sample. */
  update(sample: TrackerSample): void {
    const o = this.options;
    const first = this.frames === 0;
    const timeOk = Number.isFinite(sample.time);
    if (!timeOk) this.rejected++;
    const rawDt = first || !timeOk ? 0 : sample.time - this.lastTime;
    if (timeOk) this.lastTime = sample.time;
    this.rawDt = rawDt;
    this.dt = Math.min(Math.max(rawDt, 0), o.maxDt);
    const differentiate = !first && rawDt > 0 && rawDt <= o.resetAfter;
    this.previousPosition.set(this.position);
    this.previousRotation.set(this.rotation);

    // Device poses and status. A controller only counts as frozen while the head moves: an
    // emulator (or a paused replay) holds every pose bit-for-bit at once, a real HMD never does.
    const headMoved = usable(sample, HEAD) && !(this.hasDevicePose[HEAD] === 1 && samePose(sample, HEAD, this.devicePosition, this.deviceRotation));
    for (let t = 0; t < NUM_TRACKERS; t++) {
      if (sample.tracked[t] && !usable(sample, t)) this.rejected++;
      if (!usable(sample, t)) {
        this.status[t] = MISSING;
        this.unchangedFor[t] = 0;
        continue;
      }
      const same = this.hasDevicePose[t] === 1 && samePose(sample, t, this.devicePosition, this.deviceRotation);
      if (!same) this.unchangedFor[t] = 0;
      else if (headMoved) this.unchangedFor[t] += Math.max(rawDt, 0);
      this.switched[t] = !first && this.hasDevicePose[t] === 1 && sample.hand[t] !== this.kind[t] ? 1 : 0;
      this.kind[t] = sample.hand[t];
      copyPose(sample.position, sample.rotation, t, this.devicePosition, this.deviceRotation);
      this.hasDevicePose[t] = 1;
      // The head is never called frozen: a still head is a person standing still.
      this.status[t] = t !== HEAD && this.unchangedFor[t] >= o.frozenTime ? FROZEN : TRACKED;
    }

    // Head: the device pose, or the last one held.
    copyPose(this.devicePosition, this.deviceRotation, HEAD, this.position, this.rotation);

    // Hands: blend between the device pose and the hanging pose.
    const h = this.rotation;
    const yaw = headingYaw(h[4 * HEAD], h[4 * HEAD + 1], h[4 * HEAD + 2], h[4 * HEAD + 3]);
    const blend = first ? 1 : 1 - Math.pow(2, -this.dt / o.fallbackHalflife);
    for (let t = LEFT; t <= RIGHT; t++) {
      const goal = this.status[t] === TRACKED ? 0 : 1;
      this.fallbackWeight[t] += (goal - this.fallbackWeight[t]) * blend;
      if (first || !this.hasDevicePose[t]) this.fallbackWeight[t] = goal;
      this.writeHand(t, yaw, this.fallbackWeight[t]);
      this.smoothSwitch(t, first ? 0 : this.dt);
    }

    for (let t = 0; t < NUM_TRACKERS; t++) this.differentiate(t, differentiate ? rawDt : 0);
    this.frames++;
  }

  private writeHand(t: number, yaw: number, w: number): void {
    const o = this.options;
    const hx = this.position[3 * HEAD], hy = this.position[3 * HEAD + 1], hz = this.position[3 * HEAD + 2];
    const s = Math.sin(yaw), c = Math.cos(yaw);
    // Body frame (facing +Z): left is +X. R_y(yaw)·(x, 0, z) = (c·x + s·z, 0, −s·x + c·z).
    const side = t === LEFT ? o.hangSide : -o.hangSide;
    const fx = hx + c * side + s * o.hangForward;
    const fy = hy * o.hangHeight;
    const fz = hz - s * side + c * o.hangForward;
    // A hanging hand's grip frame is the body frame turned half a turn about Y (thumb forward
    // = −Z_grip, back of the hand outward, +Y_grip up the forearm): R_y(yaw + π).
    const half = (yaw + Math.PI) / 2;
    const fqy = Math.sin(half), fqw = Math.cos(half);
    const dp = this.devicePosition, dr = this.deviceRotation;
    const p = this.position, r = this.rotation;
    p[3 * t] = dp[3 * t] + (fx - dp[3 * t]) * w;
    p[3 * t + 1] = dp[3 * t + 1] + (fy - dp[3 * t + 1]) * w;
    p[3 * t + 2] = dp[3 * t + 2] + (fz - dp[3 * t + 2]) * w;
    // nlerp toward (0, fqy, 0, fqw) on the shorter arc.
    const ax = dr[4 * t], ay = dr[4 * t + 1], az = dr[4 * t + 2], aw = dr[4 * t + 3];
    const sign = ay * fqy + aw * fqw < 0 ? -1 : 1;
    let x = ax + (0 - ax) * w;
    let y = ay + (sign * fqy - ay) * w;
    let z = az + (0 - az) * w;
    let qw = aw + (sign * fqw - aw) * w;
    const n = Math.hypot(x, y, z, qw) || 1;
    x /= n; y /= n; z /= n; qw /= n;
    r[4 * t] = x;
    r[4 * t + 1] = y;
    r[4 * t + 2] = z;
    r[4 * t + 3] = qw;
  }

  /**
   * A hand put down for a controller (or back): the two devices' grips are not at the same place,
   * so the output keeps the previous pose plus an offset that decays with `fallbackHalflife`
   * (the same as a controller coming back), instead of jumping by the difference.
   */
  private smoothSwitch(t: number, dt: number): void {
    const p = this.position, r = this.rotation, sp = this.switchPosition, sr = this.switchRotation;
    const i = 3 * t, j = 4 * t;
    if (this.switched[t]) {
      this.switched[t] = 0;
      for (let k = 0; k < 3; k++) sp[i + k] = this.previousPosition[i + k] - p[i + k];
      // Offset rotation = previous · current⁻¹ (unit quaternions: the inverse is the conjugate).
      const pr = this.previousRotation;
      mulQuat(sr, j, pr[j], pr[j + 1], pr[j + 2], pr[j + 3], -r[j], -r[j + 1], -r[j + 2], r[j + 3]);
    }
    if (sp[i] === 0 && sp[i + 1] === 0 && sp[i + 2] === 0 && sr[j + 3] === 1) return;
    for (let k = 0; k < 3; k++) p[i + k] += sp[i + k];
    // Rotation: offset · current, renormalized.
    mulQuat(r, j, sr[j], sr[j + 1], sr[j + 2], sr[j + 3], r[j], r[j + 1], r[j + 2], r[j + 3]);
    const n = Math.hypot(r[j], r[j + 1], r[j + 2], r[j + 3]) || 1;
    for (let k = 0; k < 4; k++) r[j + k] /= n;
    // Decay toward no offset; below 0.1 mm and ~0.01° it is gone.
    const keep = Math.pow(2, -dt / this.options.fallbackHalflife);
    for (let k = 0; k < 3; k++) sp[i + k] *= keep;
    const sign = sr[j + 3] < 0 ? -1 : 1;
    const x = sr[j] * keep, y = sr[j + 1] * keep, z = sr[j + 2] * keep, w = sign * (1 - keep) + sr[j + 3] * keep;
    const m = Math.hypot(x, y, z, w) || 1;
    sr[j] = x / m;
    sr[j + 1] = y / m;
    sr[j + 2] = z / m;
    sr[j + 3] = w / m;
    if (Math.hypot(sp[i], sp[i + 1], sp[i + 2]) < 1e-4 && Math.abs(sr[j + 3]) > 1 - 1e-8) {
      sp.fill(0, i, i + 3);
      sr.fill(0, j, j + 3);
      sr[j + 3] = 1;
    }
  }

  /** Velocity and angular velocity of tracker `t` over `dt` (0: restart from rest). */
  private differentiate(t: number, dt: number): void {
    const o = this.options;
    const v = this.velocity, av = this.angularVelocity;
    if (dt <= 0) {
      v.fill(0, 3 * t, 3 * t + 3);
      av.fill(0, 3 * t, 3 * t + 3);
      return;
    }
    const a = 1 - Math.pow(2, -dt / o.velocityHalflife);
    const p = this.position, q = this.previousPosition;
    let vx = (p[3 * t] - q[3 * t]) / dt;
    let vy = (p[3 * t + 1] - q[3 * t + 1]) / dt;
    let vz = (p[3 * t + 2] - q[3 * t + 2]) / dt;
    const speed = Math.hypot(vx, vy, vz);
    if (speed > o.maxSpeed) {
      const k = o.maxSpeed / speed;
      vx *= k; vy *= k; vz *= k;
    }
    v[3 * t] += (vx - v[3 * t]) * a;
    v[3 * t + 1] += (vy - v[3 * t + 1]) * a;
    v[3 * t + 2] += (vz - v[3 * t + 2]) * a;

    // Δq = q·q_prev⁻¹ (world frame); ω = axis · angle / dt on the shorter arc.
    const r = this.rotation, s = this.previousRotation;
    const bx = r[4 * t], by = r[4 * t + 1], bz = r[4 * t + 2], bw = r[4 * t + 3];
    const cx = -s[4 * t], cy = -s[4 * t + 1], cz = -s[4 * t + 2], cw = s[4 * t + 3];
    let dx = bw * cx + bx * cw + by * cz - bz * cy;
    let dy = bw * cy - bx * cz + by * cw + bz * cx;
    let dz = bw * cz + bx * cy - by * cx + bz * cw;
    let dw = bw * cw - bx * cx - by * cy - bz * cz;
    if (dw < 0) {
      dx = -dx; dy = -dy; dz = -dz; dw = -dw;
    }
    const sinHalf = Math.hypot(dx, dy, dz);
    let wx = 0, wy = 0, wz = 0;
    if (sinHalf > 1e-12) {
      let rate = (2 * Math.atan2(sinHalf, dw)) / dt;
      rate = Math.min(rate, o.maxAngularSpeed);
      wx = (dx / sinHalf) * rate;
      wy = (dy / sinHalf) * rate;
      wz = (dz / sinHalf) * rate;
    }
    av[3 * t] += (wx - av[3 * t]) * a;
    av[3 * t + 1] += (wy - av[3 * t + 1]) * a;
    av[3 * t + 2] += (wz - av[3 * t + 2]) * a;
  }
}

/** Farther than this from the reference space's origin (m) a tracker pose is garbage. */
const MAX_COORDINATE = 1e5;

/** Whether tracker `t` of `sample` is tracked and its pose is numbers that make a pose. */
function usable(sample: TrackerSample, t: number): boolean {
  if (!sample.tracked[t]) return false;
  const p = sample.position, r = sample.rotation;
  for (let k = 3 * t; k < 3 * t + 3; k++) if (!(Math.abs(p[k]) <= MAX_COORDINATE)) return false;
  const n = Math.hypot(r[4 * t], r[4 * t + 1], r[4 * t + 2], r[4 * t + 3]);
  return Number.isFinite(n) && n > 1e-6;
}

/** Length of tracker `t`'s rotation in `r` (usable samples only: finite and not 0). */
function rotationLength(r: Float64Array, t: number): number {
  return Math.hypot(r[4 * t], r[4 * t + 1], r[4 * t + 2], r[4 * t + 3]);
}

function samePose(sample: TrackerSample, t: number, position: Float64Array, rotation: Float64Array): boolean {
  const eps = 1e-7;
  const n = rotationLength(sample.rotation, t);
  for (let k = 0; k < 3; k++) if (Math.abs(sample.position[3 * t + k] - position[3 * t + k]) > eps) return false;
  for (let k = 0; k < 4; k++) if (Math.abs(sample.rotation[4 * t + k] / n - rotation[4 * t + k]) > eps) return false;
  return true;
}

/** Copies tracker `t`'s pose, its rotation normalized. */
function copyPose(fromP: Float64Array, fromR: Float64Array, t: number, toP: Float64Array, toR: Float64Array): void {
  const n = rotationLength(fromR, t);
  toP[3 * t] = fromP[3 * t];
  toP[3 * t + 1] = fromP[3 * t + 1];
  toP[3 * t + 2] = fromP[3 * t + 2];
  toR[4 * t] = fromR[4 * t] / n;
  toR[4 * t + 1] = fromR[4 * t + 1] / n;
  toR[4 * t + 2] = fromR[4 * t + 2] / n;
  toR[4 * t + 3] = fromR[4 * t + 3] / n;
}
