/**
 * One VR frame, the same for a live session and a replay (THESIS_NOTES §9): tracker sample →
 * tracker state (velocities, missing/frozen controllers) → body yaw → the runtime's tracked mode
 * (`Crowd.setTracked`: spring-smoothed head ground velocity and body yaw build the trajectory
 * query; the root is clamped within α of the head) and the crouch (`Crowd.setHipsDrop`) →
 * runtime update → forward kinematics → avatar pose by retargeting → upper body (spine twist,
 * head, arm IK). Allocates nothing per frame; `lastUpdateMs` times the whole thing.
 *
 * Units. The runtime works in database units, the trackers in the room's metres. One factor
 * `worldPerDb` maps one to the other: the avatar object is scaled by `avatarScale` (its eye
 * height = the user's calibrated eye height) and the retargeter maps source positions by its
 * `hipsScale`, so a database position p shows at `p · avatarScale · hipsScale` in the room;
 * tracker positions are divided by that before they reach the runtime, α too.
 *
 * Height (docs/vr.md): `calibrate(eyeHeight)` scales the avatar; crouching lowers the hips by
 * (calibrated eye height − HMD height) with leg IK in the runtime (feet planted). Before a
 * calibration the reference is the highest HMD height seen since the last reset, and the avatar
 * keeps its own size. Standing taller (tip-toe) leaves the avatar standing.
 */
import { type Avatar } from '../avatar/avatar.ts';
import { findRoles } from '../avatar/joint-maps.ts';
import { type Crowd } from '../core/crowd.ts';
import { forwardKinematics } from '../core/forward-kinematics.ts';
import { type BodyYawPredictor } from './body-yaw.ts';
import { type TrackerSample } from './tracker-sample.ts';
import { TrackerState } from './trackers.ts';
import { UpperBody } from './upper-body.ts';
import { bodyYaw, headingYaw } from './yaw.ts';

/** HMD (eyes) → head centre, m backward along the heading (MMVR: HMD = head + 0.10 m forward). */
export const HMD_TO_HEAD_CENTRE = 0.1;

/** The runtime settings of the VR mode (docs/runtime.md); α is set separately (`setAlpha`). */
export const VR_SETTINGS = {
  clamping: true,
  // A standing avatar walks back under its user instead of staying up to α away.
  adjustment_min_speed: 0.15,
  // Turning on the spot: the root may lag the predicted body yaw by at most ~20°.
  clamp_angle: 0.35,
  // The trajectory comes from a real person, the pose part from the frame playing: trusting the
  // trajectory twice as much keeps a dragged avatar from staying in standing frames while its
  // user walks (replay bench, docs/vr.md: walk root distance 15 → 5 cm).
  beta_trajectory: 2,
  // The avatar may catch up at its own speed (Holden's 0.5× is for a game character, whose
  // player does not stand inside it): replay bench, mean root distance 12.6 → 9.4 cm for ~3%
  // more skating.
  adjustment_max_ratio: 1.0,
} as const;

/**
 * Crouch dead band, m: the hips drop d − b once the eyes are d > 2b below the reference, easing in
 * quadratically (d²/4b) below that, so a walk's head bob (±2 cm) does not bob the hips twice.
 */
export const CROUCH_DEADBAND = 0.03;

/** Default α (m): the avatar root stays within it of the head's floor projection. */
export const DEFAULT_ALPHA = 0.2;

export class VrPipeline {
  readonly trackers = new TrackerState();
  readonly upperBody: UpperBody | null;
  predictor: BodyYawPredictor;
  /** Head centre on the floor (x, z, room m) and body yaw of the last frame. */
  readonly headFloor = new Float64Array(2);
  yaw = 0;
  /** The character root (room m: x, y, z) and its yaw after the last frame. */
  readonly root = new Float64Array(3);
  rootYaw = 0;
  /** Milliseconds of the last `update`, and the database skeleton's world pose (database units). */
  lastUpdateMs = 0;
  readonly world: Float32Array;
  readonly worldRotations: Float32Array;
  readonly toeHeights: [number, number] = [NaN, NaN];
  /** Room metres per database unit (see the header). */
  worldPerDb = 1;
  /** The avatar object's scale (1 until calibrated). */
  avatarScale = 1;
  /** The retargeter's horizontal map of source to avatar positions at avatar scale 1. */
  readonly hipsScale: number;
  /** Standing eye (head joint) heights at scale 1: the database skeleton's and the avatar's, m. */
  readonly databaseEyeHeight: number;
  readonly avatarEyeHeight: number;
  /** The user's calibrated eye height (NaN before `calibrate`), and the reference used now. */
  calibratedEyeHeight = NaN;
  referenceEyeHeight = NaN;
  /** Hips drop of the last frame: room m and database units. */
  hipsDrop = 0;
  hipsDropDb = 0;
  /** α in room metres. */
  private alpha = DEFAULT_ALPHA;

  /** Build before the avatar is first posed (UpperBody reads its rest pose). */
  constructor(
    readonly crowd: Crowd,
    readonly avatar: Avatar | null,
    predictor: BodyYawPredictor,
  ) {
    this.predictor = predictor;
    this.upperBody = avatar ? new UpperBody(avatar) : null;
    this.world = new Float32Array(crowd.numJoints * 3);
    this.worldRotations = new Float32Array(crowd.numJoints * 4);

    // The database skeleton's rest (a standing T-pose): its head joint's height.
    const rest = new Float32Array(crowd.numJoints * 4);
    for (let j = 0; j < crowd.numJoints; j++) rest[4 * j + 3] = 1;
    const restPositions = new Float32Array(crowd.positionsOf(0));
    restPositions[0] = 0;
    restPositions[1] = 0;
    restPositions[2] = 0;
    forwardKinematics(crowd.jointParents, restPositions, rest, this.world, this.worldRotations);
    const head = findRoles([...crowd.jointNames]).get('head');
    this.databaseEyeHeight = head === undefined ? 1.6 : this.world[3 * head + 1];

    if (avatar) {
      avatar.object.updateMatrixWorld(true);
      const h = avatar.roles.get('head');
      this.avatarEyeHeight = h === undefined ? this.databaseEyeHeight : avatar.bones[h].matrixWorld.elements[13];
      this.hipsScale = avatar.hipsScale;
    } else {
      this.avatarEyeHeight = this.databaseEyeHeight;
      this.hipsScale = 1;
    }
    this.worldPerDb = this.hipsScale;
    crowd.setSettings(VR_SETTINGS);
    this.setAlpha(DEFAULT_ALPHA);
  }

  /** α (room m): how far the avatar root may be from the head's floor projection. */
  setAlpha(alpha: number): void {
    this.alpha = alpha;
    this.crowd.setSettings({ clamp_distance: alpha / this.worldPerDb });
  }

  get clampDistance(): number {
    return this.alpha;
  }

  /**
   * The user stands straight: `eyeHeight` (the HMD's height, m) becomes the crouch reference and
   * the avatar is scaled so its eyes are at that height.
   */
  calibrate(eyeHeight: number): void {
    if (!(eyeHeight > 0.5 && eyeHeight < 2.6)) throw new RangeError(`calibrate: an eye height of ${eyeHeight} m is not a standing person's`);
    this.calibratedEyeHeight = eyeHeight;
    this.referenceEyeHeight = eyeHeight;
    this.avatarScale = eyeHeight / this.avatarEyeHeight;
    this.avatar?.object.scale.setScalar(this.avatarScale);
    this.avatar?.object.updateMatrixWorld(true);
    this.worldPerDb = this.avatarScale * this.hipsScale;
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
  }

  /** Runs one frame. `dt` overrides the animation step (fixed-step tests); default the trackers' dt. */
  update(sample: TrackerSample, dt?: number): void {
    const t0 = performance.now();
    const tr = this.trackers;
    tr.update(sample);
    const step = dt ?? tr.dt;
    const head = tr.head;
    this.yaw = this.predictor.update(head, tr.left, tr.right, step);
    const q = head.rotation;
    const heading = headingYaw(q[0], q[1], q[2], q[3]);
    this.headFloor[0] = head.position[0] - HMD_TO_HEAD_CENTRE * Math.sin(heading);
    this.headFloor[1] = head.position[2] - HMD_TO_HEAD_CENTRE * Math.cos(heading);

    // Crouch: the hips go down as far as the eyes did (tip-toe: no drop).
    const eye = head.position[1];
    if (!(this.calibratedEyeHeight > 0) && tr.status[0] === 0 && !(eye <= this.referenceEyeHeight)) this.referenceEyeHeight = eye;
    const d = this.referenceEyeHeight > 0 ? this.referenceEyeHeight - eye : 0;
    const b = CROUCH_DEADBAND;
    this.hipsDrop = d <= 0 ? 0 : d < 2 * b ? (d * d) / (4 * b) : d - b;
    const k = 1 / this.worldPerDb;
    this.hipsDropDb = this.hipsDrop * k;

    const crowd = this.crowd;
    crowd.setTracked(0, this.headFloor[0] * k, this.headFloor[1] * k, head.velocity[0] * k, head.velocity[2] * k, this.yaw);
    crowd.setHipsDrop(0, this.hipsDropDb);
    crowd.update(step);
    const rotations = crowd.rotationsOf(0);
    forwardKinematics(crowd.jointParents, crowd.positionsOf(0), rotations, this.world, this.worldRotations);
    this.root[0] = this.world[0] * this.worldPerDb;
    this.root[1] = this.world[1] * this.worldPerDb;
    this.root[2] = this.world[2] * this.worldPerDb;
    this.rootYaw = bodyYaw(rotations[0], rotations[1], rotations[2], rotations[3]);
    if (this.avatar && this.upperBody) {
      this.avatar.pose(this.world, this.worldRotations, crowd.contactsOf(0), step, this.toeHeights);
      this.upperBody.apply(head, tr.left, tr.right, this.rootYaw);
    }
    this.lastUpdateMs = performance.now() - t0;
  }
}
