/**
 * The VR frame recipe (docs/method.md §9), the same for a live session and a replay: tracker
 * sample → tracker state (velocities, missing/frozen controllers) → body yaw → the character's
 * tracked drive (`Character.setTracked`: the runtime spring-smooths the head's ground velocity
 * and the body yaw into the trajectory query; the root is clamped within α of its target) and the
 * crouch (`Character.setCrouch`) → the character's update (runtime, world pose, retarget) →
 * upper body (spine twist, head, arm IK). Allocates nothing per frame; `lastUpdateMs` times it.
 *
 * Units: the room's metres everywhere — the character converts to its database (one place,
 * `Character.toDatabase`). Calibration scales the character (`object3d.scale`) so the avatar's
 * eyes are at the user's.
 *
 * Height (docs/vr.md): the head centre's drop below the reference height goes to the runtime
 * with the headset's pitch, which splits it (`Character.setCrouch`): looking ahead, the hips go
 * down by leg IK (feet planted); looking at the floor, the torso bends forward instead, as
 * bent-over people's do, and the root's target moves back under the hips. The head centre is
 * the point the head turns about,
 * `HMD_TO_HEAD_CENTRE` behind the headset along its view axis: the headset itself sits in front of
 * it, so looking down 35° lowers the headset by 0.10·sin 35° = 5.7 cm while the head centre stays
 * put — measuring the headset made looking down crouch the avatar. Before a calibration the
 * reference is the highest head-centre height seen since the last reset. Standing taller
 * (tip-toe) leaves the avatar standing.
 *
 * The root's target (docs/vr.md, "Where the root goes"): MMVR puts it under the head centre, but
 * people lean — the head sits 1–19 cm in front of the hips — so when the predictor says where the
 * hips are (`BodyYawPredictor.hips`: the orientation network's second output) the target moves
 * `HIPS_GAIN` (half) of the way there, at most `MAX_HIPS_OFFSET`; otherwise it is the head centre.
 *
 * Body tracking (docs/vr.md): when the headset tracks the body (`TrackerSample.bodyTracked`: the
 * hips and the hip joints' or the shoulders' line), the body yaw is the tracked hips' facing and
 * the root's target their floor point (`Character.setTracked(…, body = true)`: the runtime moves
 * and turns the shown hips onto them, the motion-matched legs keeping the feet), and α tightens
 * to `BODY_ALPHA`. The network still runs every frame, so when tracking is lost it takes over at
 * once from a warm state; the runtime blends the hips back to the animation's.
 */
import * as THREE from 'three';
import type { Character } from '../character/character.ts';
import type { RuntimeSettings } from '../core/character.ts';
import { facingYaw, headingYaw } from '../yaw.ts';
import type { BodyYawPredictor } from './body-yaw.ts';
import { HIPS, type TrackerSample } from './tracker-sample.ts';
import { TrackerState } from './trackers.ts';
import { UpperBody } from './upper-body.ts';
import vrSettings from '../../../settings/vr-settings.json' with { type: 'json' };

/**
 * HMD (eyes) → head centre, m backward along the headset's view axis (MMVR: HMD = head + 0.10 m
 * forward). The floor position uses its horizontal part along the heading.
 */
export const HMD_TO_HEAD_CENTRE = 0.1;

/**
 * The runtime settings of the VR mode (docs/runtime.md); α is set separately (`setAlpha`). One
 * file, `settings/vr-settings.json` at the repository root, read by this page and by the
 * native replay (`vr_replay.rs`):
 * - `clamping`; `adjustment_min_speed` 0.15 m/s: a standing avatar walks back under its user
 *   instead of staying up to α away;
 * - `clamp_angle` 0.35: turning on the spot, the root lags the predicted body yaw by ~20° at most;
 * - `beta_trajectory` 2: the trajectory comes from a real person, the pose part from the frame
 *   playing; trusting the trajectory twice as much keeps a dragged avatar from staying in
 *   standing frames while its user walks (replay bench, docs/vr.md: walk root distance 15 → 5 cm);
 * - `adjustment_position_halflife` 0.05 s, `adjustment_max_ratio` 4: the avatar follows its
 *   user twice as fast and may catch up at four times its own speed (Holden's 0.1 s and 0.5×
 *   suit a game character, whose player does not stand inside it). Feet the faster drag pulls
 *   out of their locks step back under the body (docs/method.md §7), so it costs little
 *   sliding: held-out replays, root distance 17.6 → 13.9 cm at 10.7 → 12.4 cm/s of skating
 *   (ratio 2); with the root aimed at the predicted hips, ratio 2 → 4 took the page's held-out
 *   root 12.3 → 11.0 cm and skating 8.3 → 7.0 cm/s (docs/vr.md, "Where the root goes").
 */
export const VR_SETTINGS: Readonly<RuntimeSettings> = vrSettings;

/** Default α (m): the avatar root stays within it of the head's floor projection. */
export const DEFAULT_ALPHA = 0.2;

/**
 * α while the body is tracked (m): the root stays within it of the tracked hips, and the runtime
 * moves the shown hips the rest of the way (at most 15 cm from the animation's).
 */
export const BODY_ALPHA = 0.1;

/**
 * The farthest (m) a predicted hips point may lie from the head centre on the floor: a person
 * bent over to touch the floor has the head ~0.5 m ahead of the hips; beyond that the prediction
 * is not believed and clipped to it.
 */
export const MAX_HIPS_OFFSET = 0.5;

/**
 * Smoothing of the predicted hips (half-life, s), in the body's frame: the network's guess moves
 * ~5 mm a frame on its own, and a root target that jitters drags the avatar about.
 */
export const HIPS_OFFSET_HALFLIFE = 0.2;

/**
 * The share of the predicted hips offset the root's target takes. On people the network never
 * saw its guess is half signal (upright walkers get a lean they do not have): held-out replays
 * root 13.2 cm at 0, 12.4 at 0.3, 12.2 at 0.5, 12.4 at 0.7, 13.0 at 1; leave-one-person-out the
 * target is 8.1 cm from the hips at 0.5, 8.6 at 1, 9.2 at 0 (docs/vr.md, "Where the root goes").
 */
export const HIPS_GAIN = 0.5;

/** Smoothing of the tracked hips' ground velocity (half-life, s): body tracking jitters a little every frame. */
const HIPS_VELOCITY_HALFLIFE = 0.05;

/** Body joints a facing is read from, in pairs left then right (`BODY_JOINTS` indices): the hip joints, else the shoulders. */
const FACING_PAIRS = [1, 2, 3, 4] as const;
const _h = new THREE.Vector3(), _l = new THREE.Vector3(), _r = new THREE.Vector3();

export class TrackedDrive {
  readonly trackers = new TrackerState();
  readonly upperBody: UpperBody | null;
  predictor: BodyYawPredictor;
  /** Head centre on the floor (x, z, room m) and body yaw of the last frame. */
  readonly headFloor = new Float64Array(2);
  /** The root's target on the floor (x, z, room m) of the last frame: the predicted hips, else the head centre. */
  readonly rootTarget = new Float64Array(2);
  yaw = 0;
  /** Milliseconds of the last `update`. */
  lastUpdateMs = 0;
  /** Standing eye (head joint) heights at scale 1: the database skeleton's and the avatar's, m. */
  readonly databaseEyeHeight: number;
  readonly avatarEyeHeight: number;
  /** The user's calibrated eye height (NaN before `calibrate`), and the reference used now. */
  calibratedEyeHeight = NaN;
  referenceEyeHeight = NaN;
  /** Hips drop (room m) and torso bend (rad) of the last frame; the head centre's height and the headset's pitch (rad) they came from. */
  hipsDrop = 0;
  torsoBend = 0;
  headCentreHeight = NaN;
  headsetPitch = 0;
  /** The avatar's hips height in its rest pose at scale 1, m (NaN without an avatar or hips). */
  readonly avatarHipsHeight: number;
  /** Whether the last frame drove from the tracked body; the tracked hips on the floor (x, z, room m), their ground velocity. */
  bodyTracked = false;
  readonly hipsFloor = new Float64Array(2);
  readonly hipsVelocity = new Float64Array(2);
  /** The network's (or heuristic's) yaw of the last frame, also while the body drives. */
  predictedYaw = 0;
  private hadHips = false;
  /** The predicted hips from the head centre in the body's frame (x left, z ahead), smoothed; NaN: none yet. */
  private readonly hipsLocal = new Float64Array([NaN, NaN]);
  /** Whether α was last set for a tracked body (`BODY_ALPHA`): it changes with the body only. */
  private alphaForBody = false;
  /** α in room metres. */
  private alpha = DEFAULT_ALPHA;

  constructor(
    readonly character: Character,
    predictor: BodyYawPredictor,
  ) {
    this.predictor = predictor;
    const avatar = character.avatar;
    // The upper body and the eye height are read off the rest pose (the next update poses again).
    avatar?.resetToRest();
    this.upperBody = avatar ? new UpperBody({ object: avatar.object, bones: avatar.bones, roles: avatar.roles }) : null;
    // The database skeleton's rest (a standing T-pose): its head joint's height, by the runtime's FK.
    const head = character.database.roles.get('head');
    const rest = character.database.restPositions();
    this.databaseEyeHeight = head === undefined ? 1.6 : rest[3 * head + 1] - Math.min(...rest.filter((_, i) => i % 3 === 1));
    const headBone = avatar?.bone('head');
    avatar?.object.updateMatrixWorld(true);
    this.avatarHipsHeight = avatar?.bone('hips')?.matrixWorld.elements[13] ?? NaN;
    if (headBone) {
      this.avatarEyeHeight = headBone.matrixWorld.elements[13];
    } else {
      this.avatarEyeHeight = this.databaseEyeHeight * character.worldScale;
    }
    character.settings = VR_SETTINGS;
    this.setAlpha(DEFAULT_ALPHA);
  }

  /** The character's scale (1 until calibrated). */
  get scale(): number {
    return this.character.object3d.scale.x;
  }

  /** α (room m): how far the avatar root may be from the head's floor projection. */
  setAlpha(alpha: number): void {
    this.alpha = alpha;
    this.alphaForBody = this.bodyTracked;
    this.character.setAlpha(this.bodyTracked ? Math.min(alpha, BODY_ALPHA) : alpha);
  }

  get clampDistance(): number {
    return this.alpha;
  }

  /**
   * The user stands straight: `eyeHeight` (the HMD's height, m) becomes the crouch reference and
   * the character is scaled so the avatar's eyes are at that height.
   */
  calibrate(eyeHeight: number): void {
    if (!(eyeHeight > 0.5 && eyeHeight < 2.6)) throw new RangeError(`calibrate: an eye height of ${eyeHeight} m is not a standing person's`);
    this.calibratedEyeHeight = eyeHeight;
    this.referenceEyeHeight = eyeHeight;
    const r = this.character.root;
    this.character.object3d.scale.setScalar(eyeHeight / this.avatarEyeHeight);
    this.character.object3d.updateMatrixWorld(true);
    this.character.teleport(r.x, r.z, r.yaw);
    this.setAlpha(this.alpha);
  }

  /** Switches the body-yaw predictor (it restarts from the HMD heading). */
  setPredictor(p: BodyYawPredictor): void {
    this.predictor = p;
    p.reset();
  }

  /** Forgets tracker and predictor history (session start, recentre). */
  reset(): void {
    this.trackers.reset();
    this.predictor.reset();
    this.referenceEyeHeight = this.calibratedEyeHeight;
    this.hadHips = false;
    this.hipsLocal.fill(NaN);
  }

  /**
   * The tracked body's facing (rad, 0 = +Z), from the first joint pair both tracked in `sample`:
   * forward = (left − right) × up, the builder's virtual-root rule; NaN without the hips or a
   * pair. Also moves `hipsFloor` and `hipsVelocity` on.
   */
  private bodyYaw(sample: TrackerSample, dt: number): number {
    const tracked = sample.bodyTracked, p = sample.bodyPosition;
    if (!tracked[HIPS]) {
      this.hadHips = false;
      return NaN;
    }
    const x = p[3 * HIPS], z = p[3 * HIPS + 2];
    if (this.hadHips && dt > 0) {
      const k = 1 - 2 ** (-dt / HIPS_VELOCITY_HALFLIFE);
      this.hipsVelocity[0] += ((x - this.hipsFloor[0]) / dt - this.hipsVelocity[0]) * k;
      this.hipsVelocity[1] += ((z - this.hipsFloor[1]) / dt - this.hipsVelocity[1]) * k;
    } else {
      this.hipsVelocity[0] = this.trackers.head.velocity[0];
      this.hipsVelocity[1] = this.trackers.head.velocity[2];
    }
    this.hipsFloor[0] = x;
    this.hipsFloor[1] = z;
    this.hadHips = true;
    for (let k = 0; k < FACING_PAIRS.length; k += 2) {
      const l = FACING_PAIRS[k], r = FACING_PAIRS[k + 1];
      if (!tracked[l] || !tracked[r]) continue;
      const lx = p[3 * l] - p[3 * r], lz = p[3 * l + 2] - p[3 * r + 2];
      if (lx * lx + lz * lz < 1e-6) continue;
      return facingYaw(lx, lz);
    }
    return NaN;
  }

  /**
   * The root's target (`rootTarget`): the head centre plus the predicted hips, smoothed in the
   * body's frame (turning carries it round at once) and at most `MAX_HIPS_OFFSET` long; the
   * head centre itself while the predictor does not say.
   */
  private aimRoot(dt: number): void {
    const hips = this.predictor.hips, local = this.hipsLocal;
    const hx = hips ? hips[0] : NaN, hz = hips ? hips[1] : NaN;
    const c = Math.cos(this.predictedYaw), s = Math.sin(this.predictedYaw);
    if (Number.isFinite(hx) && Number.isFinite(hz)) {
      // Into the body's frame (rotate_y by −yaw), then toward it at the half-life.
      const lx = c * hx - s * hz, lz = s * hx + c * hz;
      const fresh = Number.isNaN(local[0]);
      const k = 1 - 2 ** (-Math.max(dt, 0) / HIPS_OFFSET_HALFLIFE);
      local[0] = fresh ? lx : local[0] + (lx - local[0]) * k;
      local[1] = fresh ? lz : local[1] + (lz - local[1]) * k;
    } else local.fill(NaN);
    // Both parts are NaN together (none yet, or not known): the head centre itself.
    const g = Number.isNaN(local[0]) ? 0 : HIPS_GAIN;
    const x = g * (local[0] || 0), z = g * (local[1] || 0);
    const m = Math.min(1, MAX_HIPS_OFFSET / Math.max(Math.hypot(x, z), 1e-9));
    this.rootTarget[0] = this.headFloor[0] + m * (c * x + s * z);
    this.rootTarget[1] = this.headFloor[1] + m * (c * z - s * x);
  }

  /** Runs one frame. `dt` overrides the animation step (fixed-step tests); default the trackers' dt. */
  update(sample: TrackerSample, dt?: number): void {
    const t0 = performance.now();
    const tr = this.trackers;
    tr.update(sample);
    const step = dt ?? tr.dt;
    const head = tr.head;
    this.predictedYaw = this.predictor.update(head, tr.left, tr.right, step);
    const bodyYaw = this.bodyYaw(sample, step);
    this.bodyTracked = !Number.isNaN(bodyYaw);
    this.yaw = this.bodyTracked ? bodyYaw : this.predictedYaw;
    const q = head.rotation;
    const heading = headingYaw(q[0], q[1], q[2], q[3]);
    this.headFloor[0] = head.position[0] - HMD_TO_HEAD_CENTRE * Math.sin(heading);
    this.headFloor[1] = head.position[2] - HMD_TO_HEAD_CENTRE * Math.cos(heading);
    this.aimRoot(step);

    // Crouch: the head centre's drop (tip-toe: none) and the headset's pitch. The head centre is
    // HMD + R·(0, 0, d) (+Z is backward in the headset's frame); its height is the HMD's plus
    // d·(R·ẑ)_y = d·2(yz − wx), so pitching the head does not move it; the view axis is −R·ẑ,
    // so the pitch is asin(−2(yz − wx)).
    const up = 2 * (q[1] * q[2] - q[3] * q[0]);
    const eye = (this.headCentreHeight = head.position[1] + HMD_TO_HEAD_CENTRE * up);
    this.headsetPitch = Math.asin(Math.max(-1, Math.min(1, -up)));
    if (!(this.calibratedEyeHeight > 0) && tr.status[0] === 0 && !(eye <= this.referenceEyeHeight)) this.referenceEyeHeight = eye;
    const d = this.referenceEyeHeight > 0 ? this.referenceEyeHeight - eye : 0;

    const character = this.character;
    if (this.bodyTracked) {
      character.setTracked(this.hipsFloor[0], this.hipsFloor[1], this.hipsVelocity[0], this.hipsVelocity[1], this.yaw, true);
    } else {
      character.setTracked(this.rootTarget[0], this.rootTarget[1], head.velocity[0], head.velocity[2], this.yaw);
    }
    if (this.bodyTracked !== this.alphaForBody) this.setAlpha(this.alpha);
    character.setCrouch(d, this.headsetPitch);
    this.hipsDrop = character.drive.hipsDrop * character.metresPerDatabaseUnit;
    this.torsoBend = character.drive.bend;
    character.update(step);
    // The spine twists from the way the shown hips face: the tracked hips' while the body drives.
    this.upperBody?.apply(head, tr.left, tr.right, this.bodyTracked ? this.yaw : character.root.yaw);
    this.lastUpdateMs = performance.now() - t0;
  }

  /**
   * The shown hips on the floor and the way they face: (x, z, yaw) into `out` (room m, rad,
   * 0 = +Z; the facing from the hip joints, as the tracked body's) — the avatar's bones (world
   * matrices current: after `update`), else the character's pose.
   */
  shownHips(out: Float64Array | number[]): void {
    const avatar = this.character.avatar;
    const at = (role: 'hips' | 'left_upper_leg' | 'right_upper_leg', v: THREE.Vector3) => {
      const bone = avatar?.bone(role);
      if (bone) return v.setFromMatrixPosition(bone.matrixWorld);
      const j = this.character.database.roles.get(role);
      return j === undefined ? v.set(NaN, NaN, NaN) : this.character.jointPosition(j, v);
    };
    const h = at('hips', _h), l = at('left_upper_leg', _l), r = at('right_upper_leg', _r);
    out[0] = h.x;
    out[1] = h.z;
    out[2] = facingYaw(l.x - r.x, l.z - r.z);
  }

  dispose(): void {
    this.upperBody?.dispose();
  }
}
