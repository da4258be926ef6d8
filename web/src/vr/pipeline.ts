/**
 * One VR frame, the same for a live session and a replay (THESIS_NOTES §9): tracker sample →
 * tracker state (velocities, missing/frozen controllers) → body yaw → drive the character →
 * runtime update → forward kinematics → avatar pose by retargeting → upper body (spine twist,
 * head, arm IK). Allocates nothing per frame; `lastUpdateMs` times the whole thing.
 */
import { type Avatar } from '../avatar/avatar.ts';
import { type Crowd } from '../core/crowd.ts';
import { forwardKinematics } from '../core/forward-kinematics.ts';
import { type BodyYawPredictor } from './body-yaw.ts';
import { CharacterDriver } from './drive.ts';
import { type TrackerSample } from './tracker-sample.ts';
import { TrackerState } from './trackers.ts';
import { UpperBody } from './upper-body.ts';
import { bodyYaw, headingYaw } from './yaw.ts';

/** HMD (eyes) → head centre, m backward along the heading (MMVR: HMD = head + 0.10 m forward). */
export const HMD_TO_HEAD_CENTRE = 0.1;

export class VrPipeline {
  readonly trackers = new TrackerState();
  readonly driver: CharacterDriver;
  readonly upperBody: UpperBody | null;
  predictor: BodyYawPredictor;
  /** Head centre on the floor (x, z) and body yaw of the last frame. */
  readonly headFloor = new Float64Array(2);
  yaw = 0;
  /** The character root (world x, y, z) and its yaw after the last frame. */
  readonly root = new Float64Array(3);
  rootYaw = 0;
  /** Milliseconds of the last `update`, and the database skeleton's world pose. */
  lastUpdateMs = 0;
  readonly world: Float32Array;
  readonly worldRotations: Float32Array;
  readonly toeHeights: [number, number] = [NaN, NaN];

  /** Build before the avatar is first posed (UpperBody reads its rest pose). */
  constructor(
    readonly crowd: Crowd,
    readonly avatar: Avatar | null,
    predictor: BodyYawPredictor,
  ) {
    this.predictor = predictor;
    this.driver = new CharacterDriver(crowd, 0);
    this.upperBody = avatar ? new UpperBody(avatar) : null;
    this.world = new Float32Array(crowd.numJoints * 3);
    this.worldRotations = new Float32Array(crowd.numJoints * 4);
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

    const crowd = this.crowd;
    this.driver.drive(this.headFloor[0], this.headFloor[1], head.velocity[0], head.velocity[2], this.yaw, this.root[0], this.root[2]);
    crowd.update(step);
    const rotations = crowd.rotationsOf(0);
    forwardKinematics(crowd.jointParents, crowd.positionsOf(0), rotations, this.world, this.worldRotations);
    this.root[0] = this.world[0];
    this.root[1] = this.world[1];
    this.root[2] = this.world[2];
    this.rootYaw = bodyYaw(rotations[0], rotations[1], rotations[2], rotations[3]);
    if (this.avatar && this.upperBody) {
      this.avatar.pose(this.world, this.worldRotations, crowd.contactsOf(0), step, this.toeHeights);
      this.upperBody.apply(head, tr.left, tr.right, this.rootYaw);
    }
    this.lastUpdateMs = performance.now() - t0;
  }
}
