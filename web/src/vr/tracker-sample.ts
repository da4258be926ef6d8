/**
 * One frame of raw tracker data — HMD and both controllers' grip poses in the `local-floor`
 * reference space (docs/method.md §9), and the body joints where the headset tracks the body
 * (WebXR Body Tracking) — as structure-of-arrays, and the sampling of a WebXR frame into it. The same sample is what a recording stores (recording.ts) and what a replay feeds
 * back, so the live and replayed pipelines start from identical data.
 */

import { mulQuat } from '../quat.ts';

/** Tracker indices into every SoA array of the VR modules. */
export const HEAD = 0;
export const LEFT = 1;
export const RIGHT = 2;
export const NUM_TRACKERS = 3;

/**
 * The body joints kept from WebXR body tracking (`XRFrame.body`, its joint names), the order of
 * every body array: the hips (where the root goes) and the two lines a body's facing is read
 * from — the hip joints' (the database builder's virtual-root rule) and, for devices that track
 * only the upper body, the shoulders'.
 */
export const BODY_JOINTS = ['hips', 'left-upper-leg', 'right-upper-leg', 'left-arm-upper', 'right-arm-upper'] as const;
export const NUM_BODY_JOINTS = BODY_JOINTS.length;
export const HIPS = 0;

/** `XRFrame.body` (WebXR Body Tracking): joint name → joint space. Not in the WebXR typings yet. */
interface XRBodyLike {
  get(joint: string): XRSpace | undefined;
}

export class TrackerSample {
  /** Seconds (the XR animation-frame timestamp / 1000). */
  time = 0;
  /** 3×3: x, y, z per tracker, m. */
  readonly position = new Float64Array(NUM_TRACKERS * 3);
  /** 3×4: x, y, z, w per tracker (unit quaternions). */
  readonly rotation = new Float64Array(NUM_TRACKERS * 4);
  /** 1 when the device reported a (non-emulated) pose for the tracker this frame. */
  readonly tracked = new Uint8Array(NUM_TRACKERS);
  /** 1 when that pose is a tracked hand's rather than a controller's (live only; recordings do not keep it). */
  readonly hand = new Uint8Array(NUM_TRACKERS);
  /** Body joints (`BODY_JOINTS` order): positions (m), rotations (x, y, z, w), 1 when tracked this frame. */
  readonly bodyPosition = new Float64Array(NUM_BODY_JOINTS * 3);
  readonly bodyRotation = new Float64Array(NUM_BODY_JOINTS * 4);
  readonly bodyTracked = new Uint8Array(NUM_BODY_JOINTS);

  constructor() {
    for (let t = 0; t < NUM_TRACKERS; t++) this.rotation[4 * t + 3] = 1;
    for (let j = 0; j < NUM_BODY_JOINTS; j++) this.bodyRotation[4 * j + 3] = 1;
  }

  /** Sets one tracker's pose and marks it tracked. */
  set(t: number, px: number, py: number, pz: number, qx: number, qy: number, qz: number, qw: number): void {
    this.position[3 * t] = px;
    this.position[3 * t + 1] = py;
    this.position[3 * t + 2] = pz;
    this.rotation[4 * t] = qx;
    this.rotation[4 * t + 1] = qy;
    this.rotation[4 * t + 2] = qz;
    this.rotation[4 * t + 3] = qw;
    this.tracked[t] = 1;
  }

  copyFrom(other: TrackerSample): void {
    this.time = other.time;
    this.position.set(other.position);
    this.rotation.set(other.rotation);
    this.tracked.set(other.tracked);
    this.hand.set(other.hand);
    this.bodyPosition.set(other.bodyPosition);
    this.bodyRotation.set(other.bodyRotation);
    this.bodyTracked.set(other.bodyTracked);
  }
}

/**
 * Reads the viewer (HMD) pose and the left/right grip poses of `frame` in `space` into `out`
 * (`time` in seconds). A tracker with no pose this frame, or only an emulated position (a
 * controller that lost tracking keeps its orientation but guesses its position), keeps its
 * previous values and is marked untracked; trackers.ts decides what to show instead.
 * `acceptEmulated`: take emulated positions as tracked — an emulator (iwer) flags every pose so.
 *
 * Hand tracking: a hand input source is read through its grip space like a controller (Quest
 * Browser gives hands one); a hand without one gets a grip-like pose from its joints
 * (`gripFromHand`). `hand` flags which trackers are hands.
 *
 * Body tracking: where the frame has a body (`XRFrame.body`, the session granted the optional
 * `body-tracking` feature), each of `BODY_JOINTS` is read by `getPose` and flagged in
 * `bodyTracked`; a joint the device does not track this frame keeps its previous values.
 *
 * WebXR itself allocates the XRPose objects it returns; nothing else is allocated here.
 */
export function sampleXRFrame(frame: XRFrame, space: XRReferenceSpace, time: number, out: TrackerSample, acceptEmulated = false): void {
  out.time = time;
  out.tracked.fill(0);
  out.hand.fill(0);
  const viewer = frame.getViewerPose(space);
  if (viewer && (acceptEmulated || !viewer.emulatedPosition)) writePose(out, HEAD, viewer.transform);
  const sources = frame.session.inputSources;
  for (let i = 0; i < sources.length; i++) {
    const source = sources[i];
    const t = source.handedness === 'left' ? LEFT : source.handedness === 'right' ? RIGHT : -1;
    if (t < 0) continue;
    if (source.gripSpace) {
      const pose = frame.getPose(source.gripSpace, space);
      if (pose && (acceptEmulated || !pose.emulatedPosition)) writePose(out, t, pose.transform);
    } else if (source.hand && frame.getJointPose) {
      const wrist = source.hand.get('wrist');
      const knuckle = source.hand.get('middle-finger-phalanx-proximal');
      const w = wrist && frame.getJointPose(wrist, space);
      const k = knuckle && frame.getJointPose(knuckle, space);
      if (w && k) {
        const a = w.transform.position, b = k.transform.position, q = w.transform.orientation;
        gripFromHand(source.handedness === 'left', a.x, a.y, a.z, q.x, q.y, q.z, q.w, b.x, b.y, b.z, out, t);
      }
    }
    if (out.tracked[t] && source.hand) out.hand[t] = 1;
  }
  out.bodyTracked.fill(0);
  const body = (frame as XRFrame & { body?: XRBodyLike | null }).body;
  if (!body) return;
  for (let j = 0; j < NUM_BODY_JOINTS; j++) {
    const joint = body.get(BODY_JOINTS[j]);
    const pose = joint && frame.getPose(joint, space);
    if (!pose || (!acceptEmulated && pose.emulatedPosition)) continue;
    const p = pose.transform.position, q = pose.transform.orientation;
    out.bodyPosition[3 * j] = p.x;
    out.bodyPosition[3 * j + 1] = p.y;
    out.bodyPosition[3 * j + 2] = p.z;
    out.bodyRotation[4 * j] = q.x;
    out.bodyRotation[4 * j + 1] = q.y;
    out.bodyRotation[4 * j + 2] = q.z;
    out.bodyRotation[4 * j + 3] = q.w;
    out.bodyTracked[j] = 1;
  }
}

/** The components of the grip-from-wrist rotations, all ±½ (120° turns about (1, ±1, ±1)/√3). */
const G = 0.5;
const _q = new Float64Array(4);

/**
 * A controller-grip-like pose from a tracked hand's joints: the position halfway from the wrist
 * to the middle finger's knuckle (the palm's centre, where a held rod would pass), the
 * orientation the wrist joint's turned into the grip convention. WebXR hand joints look along
 * −Z toward the fingertips with +Y out of the back of the hand; a grip looks along −Z toward
 * the thumb with +X out of the back of the right hand (the palm of the left). So for the right
 * hand grip (X, Y, Z) = joint (Y, Z, X) — a rotation by 120° about (1, 1, 1) — and for the left
 * grip (X, Y, Z) = joint (−Y, Z, −X).
 */
export function gripFromHand(left: boolean, wx: number, wy: number, wz: number, qx: number, qy: number, qz: number, qw: number, kx: number, ky: number, kz: number, out: TrackerSample, t: number): void {
  // Right: q·g with g = (½, ½, ½, ½). Left: q·g' where g' maps grip axes to (−Y, Z, −X): g' = (½, −½, −½, ½).
  mulQuat(_q, 0, qx, qy, qz, qw, G, left ? -G : G, left ? -G : G, G);
  out.set(t, (wx + kx) / 2, (wy + ky) / 2, (wz + kz) / 2, _q[0], _q[1], _q[2], _q[3]);
}

function writePose(out: TrackerSample, t: number, transform: XRRigidTransform): void {
  const p = transform.position;
  const q = transform.orientation;
  out.set(t, p.x, p.y, p.z, q.x, q.y, q.z, q.w);
}
