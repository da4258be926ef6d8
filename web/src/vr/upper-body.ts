/**
 * The VR upper body (docs/method.md §9), applied to a posed avatar after retargeting: the spine
 * twists from the animated root yaw toward the HMD's heading, the head takes the HMD's rotation,
 * and each arm reaches its controller by the runtime's two-bone IK (`TwoBoneIk`, the same
 * solver as the foot lock's legs) after a clavicle heuristic, the hand taking the controller's
 * rotation.
 *
 * Hands: the grip pose (WebXR: origin at the fist's centre, −Z toward the thumb along the held
 * rod, +X out of the back of the right hand / palm of the left) is related to the hand bone once,
 * from the avatar's rest pose: a fist in the rest (T- or A-) pose holds its rod pointing forward
 * with the back of the hand up. That gives, per hand, the wrist's offset in the grip frame and the
 * hand bone's rotation relative to the grip, so no bone-axis conventions of the avatar are assumed.
 *
 * Construct it before the avatar is first posed (its bones still in the rest pose). `apply`
 * allocates nothing.
 */
import * as THREE from 'three';
import { TwoBoneIk } from '../core/ik.ts';
import type { RoleName } from '../core/roles.ts';
import type { TrackerPose } from './body-yaw.ts';
import { headingYaw, wrapAngle } from '../yaw.ts';

/** What UpperBody needs of an avatar (avatar.ts `Avatar` is one). */
export interface UpperBodyRig {
  readonly object: THREE.Object3D;
  readonly bones: readonly THREE.Object3D[];
  readonly roles: ReadonlyMap<RoleName, number>;
}

export interface UpperBodyOptions {
  /** Share of the head↔root yaw difference taken by spine, chest, upperChest, neck (the head gets the rest). */
  spineWeights: readonly [number, number, number, number];
  /** Largest twist handed to the spine, rad: a head turned further turns alone. */
  maxTwist: number;
  /** The clavicle starts helping when the target is farther than this share of the arm's length. */
  clavicleReach: number;
  /** Most the clavicle turns toward a far target, rad. */
  clavicleMaxAngle: number;
  /** Wrist → fist centre along the hand (m at avatar scale 1) and toward the palm. */
  gripForward: number;
  gripPalm: number;
  /**
   * Elbow pole in the torso's frame: outward, downward, backward weights. No backward weight by
   * default: with 0.5 the elbows of a walk's hanging arms sat up to 20 cm behind the torso
   * (replay bench pose check: 77–365 arm-frames per recording → 0–39).
   */
  poleOut: number;
  poleDown: number;
  poleBack: number;
  /**
   * An elbow more than this (m) behind the torso's frontal plane, and further behind it than its
   * target, is bent the wrong way: the arm is solved again with its pole pointing forward.
   */
  elbowBehindLimit: number;
  /**
   * Most the forearm and hand may lengthen (share of their rest length) when a controller is out
   * of the arm's reach — the last resort that keeps hands on the controllers while the avatar's
   * shoulders lag the user's (walk sway, turning, a root up to α from the head).
   */
  maxStretch: number;
}

export const DEFAULT_UPPER_BODY_OPTIONS: Readonly<UpperBodyOptions> = {
  spineWeights: [0.15, 0.2, 0.2, 0.15],
  maxTwist: (100 * Math.PI) / 180,
  clavicleReach: 0.85,
  clavicleMaxAngle: (20 * Math.PI) / 180,
  gripForward: 0.085,
  gripPalm: 0.02,
  poleOut: 0.6,
  poleDown: 1,
  poleBack: 0,
  elbowBehindLimit: 0.04,
  maxStretch: 0.25,
};

interface Arm {
  /** +1 left, −1 right (left is +X when facing +Z). */
  side: number;
  clavicle: THREE.Object3D | null;
  upper: THREE.Object3D;
  lower: THREE.Object3D;
  hand: THREE.Object3D;
  /** Wrist (hand bone origin) in the grip frame, m at object scale 1. */
  wristInGrip: THREE.Vector3;
  /** Hand bone world rotation = grip rotation · handFromGrip. */
  handFromGrip: THREE.Quaternion;
  /** Rest local positions of the forearm and hand bones (restored before any stretch). */
  lowerRest: THREE.Vector3;
  handRest: THREE.Vector3;
}

const SPINE_ROLES = ['spine', 'chest', 'upper_chest', 'neck'] as const;
const UP = new THREE.Vector3(0, 1, 0);

const _q = new THREE.Quaternion();
const _q2 = new THREE.Quaternion();
const _identity = new THREE.Quaternion();
const _v = new THREE.Vector3();
const _target = new THREE.Vector3();
const _pole = new THREE.Vector3();
const _s = new THREE.Vector3();
const _a = new THREE.Vector3();
const _from = new THREE.Vector3();
const _to = new THREE.Vector3();
const _q3 = new THREE.Quaternion();
const _pos = new THREE.Vector3();
const _q2b = new THREE.Quaternion();
const _lowerWorld = new THREE.Quaternion();
const _p = new THREE.Vector3();
const _scale = new THREE.Vector3();
const _world = new THREE.Quaternion();
const _parent = new THREE.Quaternion();
const _shoulder = new THREE.Vector3();

/** Metres `v` is behind the frontal plane through `_shoulder` (a shoulder) facing (sin ψ, 0, cos ψ) = (sy, 0, cy). */
function behind(v: THREE.Vector3, sy: number, cy: number): number {
  return -((v.x - _shoulder.x) * sy + (v.z - _shoulder.z) * cy);
}

/** Pre-multiplies `bone`'s world rotation by `delta` (world frame), writing its local rotation. */
function rotateBoneWorld(bone: THREE.Object3D, delta: THREE.Quaternion): void {
  bone.matrixWorld.decompose(_p, _world, _scale);
  _world.premultiply(delta);
  setWorldQuaternion(bone, _world);
}

/** Sets `bone`'s local rotation so its world rotation is `world` (parent's matrixWorld current). */
function setWorldQuaternion(bone: THREE.Object3D, world: THREE.Quaternion): void {
  if (bone.parent) {
    bone.parent.matrixWorld.decompose(_p, _parent, _scale);
    bone.quaternion.copy(_parent.invert()).multiply(world);
  } else {
    bone.quaternion.copy(world);
  }
  bone.quaternion.normalize();
}

export class UpperBody {
  readonly options: UpperBodyOptions;
  /** Wrist ↔ controller-implied wrist distance (m) after the last `apply` (left, right). */
  readonly handError = new Float64Array(2);
  /** The hand bones' world positions after the last `apply` (left xyz, right xyz). */
  readonly handPositions = new Float64Array(6);
  /**
   * How far (m) each elbow, and each controller's wrist target, is behind the torso's frontal
   * plane through that arm's shoulder (normal the torso's forward) after the last `apply`
   * (left, right; negative: in front). An elbow well behind while its target is not is an arm
   * bent the wrong way (the pose check of docs/vr.md).
   */
  readonly elbowBehind = new Float64Array(2);
  readonly targetBehind = new Float64Array(2);
  private readonly object: THREE.Object3D;
  private readonly spine: { bone: THREE.Object3D; weight: number; torso: boolean }[] = [];
  private readonly head: THREE.Object3D | null;
  private readonly headFromHmd = new THREE.Quaternion();
  private readonly arms: Arm[] = [];
  private readonly ik = new TwoBoneIk();

  constructor(rig: UpperBodyRig, options: Partial<UpperBodyOptions> = {}) {
    this.options = { ...DEFAULT_UPPER_BODY_OPTIONS, ...options };
    this.object = rig.object;
    const bone = (role: RoleName): THREE.Object3D | null => {
      const i = rig.roles.get(role);
      return i === undefined ? null : rig.bones[i];
    };
    rig.object.updateMatrixWorld(true);
    // Rest transforms relative to the avatar object, so offsets do not depend on where it stands.
    const toObject = new THREE.Matrix4().copy(rig.object.matrixWorld).invert();
    const rest = (b: THREE.Object3D) => {
      const m = new THREE.Matrix4().multiplyMatrices(toObject, b.matrixWorld);
      const p = new THREE.Vector3();
      const q = new THREE.Quaternion();
      m.decompose(p, q, new THREE.Vector3());
      return { p, q };
    };

    SPINE_ROLES.forEach((role, k) => {
      const b = bone(role);
      if (b) this.spine.push({ bone: b, weight: this.options.spineWeights[k], torso: role !== 'neck' });
    });

    const leftUpper = bone('left_upper_arm');
    const rightUpper = bone('right_upper_arm');
    // Rest facing: left × up (facing +Z, left is +X); +Z if the arms are missing.
    const forward = new THREE.Vector3(0, 0, 1);
    if (leftUpper && rightUpper) {
      const lateral = rest(leftUpper).p.sub(rest(rightUpper).p);
      lateral.y = 0;
      if (lateral.lengthSq() > 1e-8) forward.crossVectors(lateral.normalize(), UP).normalize();
    }

    this.head = bone('head');
    if (this.head) {
      // A headset worn by the rest pose looks along `forward`: its −Z is forward, so R_y(yaw + π).
      const hmdRest = new THREE.Quaternion().setFromAxisAngle(UP, Math.atan2(forward.x, forward.z) + Math.PI);
      this.headFromHmd.copy(hmdRest.invert()).multiply(rest(this.head).q);
    }

    for (const [side, prefix] of [[1, 'left'], [-1, 'right']] as const) {
      const upper = bone(`${prefix}_upper_arm`);
      const lower = bone(`${prefix}_lower_arm`);
      const hand = bone(`${prefix}_hand`);
      if (!upper || !lower || !hand) continue;
      const lowerRest = rest(lower);
      const handRest = rest(hand);
      const along = handRest.p.clone().sub(lowerRest.p).normalize();
      // Back of the hand: up, orthogonal to the forearm (palm down in a T/A-pose).
      const back = UP.clone().addScaledVector(along, -UP.dot(along));
      if (back.lengthSq() < 1e-8) back.crossVectors(forward, along);
      back.normalize();
      const thumb = forward.clone().addScaledVector(along, -forward.dot(along)).addScaledVector(back, -forward.dot(back)).normalize();
      const x = back.clone().multiplyScalar(side > 0 ? -1 : 1);
      const z = thumb.clone().negate();
      const y = new THREE.Vector3().crossVectors(z, x);
      const gripRest = new THREE.Quaternion().setFromRotationMatrix(new THREE.Matrix4().makeBasis(x, y, z));
      const gripRestPosition = handRest.p.clone().addScaledVector(along, this.options.gripForward).addScaledVector(back, -this.options.gripPalm);
      const inverse = gripRest.clone().invert();
      this.arms.push({
        side,
        clavicle: bone(`${prefix}_shoulder`),
        upper,
        lower,
        hand,
        wristInGrip: handRest.p.clone().sub(gripRestPosition).applyQuaternion(inverse),
        handFromGrip: inverse.multiply(handRest.q),
        lowerRest: lower.position.clone(),
        handRest: hand.position.clone(),
      });
    }
  }

  /**
   * Applies the upper body. `rootYaw`: the animated root's yaw (rad, 0 = +Z); `left`/`right`:
   * the controller grip poses (world). The avatar's world matrices must be current (after
   * `avatar.pose`); they are current again afterwards.
   */
  apply(hmd: TrackerPose, left: TrackerPose, right: TrackerPose, rootYaw: number): void {
    const o = this.options;
    const h = hmd.rotation;
    const headYaw = headingYaw(h[0], h[1], h[2], h[3]);
    const twist = Math.min(o.maxTwist, Math.max(-o.maxTwist, wrapAngle(headYaw - rootYaw)));

    // Spine twist: each bone turns by its share about world Y. Every local is computed from the
    // untwisted parents (P⁻¹·R_y(θ)·P·L), which composes to the cumulative twist, so the world
    // matrices are updated once.
    let torsoTwist = 0;
    for (let k = 0; k < this.spine.length; k++) {
      const s = this.spine[k];
      rotateBoneWorld(s.bone, _q.setFromAxisAngle(UP, s.weight * twist));
      if (s.torso) torsoTwist += s.weight * twist;
    }
    if (this.spine.length) this.spine[0].bone.updateWorldMatrix(false, true);

    if (this.head) {
      _q.set(h[0], h[1], h[2], h[3]).multiply(this.headFromHmd);
      setWorldQuaternion(this.head, _q);
      this.head.updateWorldMatrix(false, true);
    }

    const objectScale = this.object.matrixWorld.getMaxScaleOnAxis();
    const torsoYaw = rootYaw + torsoTwist;
    const sy = Math.sin(torsoYaw), cy = Math.cos(torsoYaw);
    for (let k = 0; k < this.arms.length; k++) {
      const arm = this.arms[k];
      const tracker = arm.side > 0 ? left : right;
      const p = tracker.position, r = tracker.rotation;
      _q2.set(r[0], r[1], r[2], r[3]);
      _target.copy(arm.wristInGrip).multiplyScalar(objectScale).applyQuaternion(_q2);
      _target.x += p[0];
      _target.y += p[1];
      _target.z += p[2];
      arm.lower.position.copy(arm.lowerRest);
      arm.hand.position.copy(arm.handRest);
      arm.lower.updateWorldMatrix(false, true);
      if (arm.clavicle) this.reachWithClavicle(arm);
      // The frontal plane, facing (sin ψ, 0, cos ψ), through this arm's shoulder (where the clavicle
      // put it): an elbow straight below a shoulder that the twist or the clavicle moved back is not
      // bent backward, though it may sit behind the shoulders' midpoint (it did, up to 8 cm, in
      // random poses and in a VR replay).
      _shoulder.setFromMatrixPosition(arm.upper.matrixWorld);
      this.stretchToward(arm);
      // Torso frame: outward = side·R_y(ψ)·(1, 0, 0) = side·(cos ψ, 0, −sin ψ); backward = −(sin ψ, 0, cos ψ).
      _pole.set(arm.side * cy * o.poleOut - sy * o.poleBack, -o.poleDown, -arm.side * sy * o.poleOut - cy * o.poleBack);
      this.reach(arm);
      const j = arm.side > 0 ? 0 : 1;
      this.targetBehind[j] = behind(_target, sy, cy);
      this.elbowBehind[j] = behind(_v.setFromMatrixPosition(arm.lower.matrixWorld), sy, cy);
      const elbow = this.elbowBehind[j];
      const target = this.targetBehind[j];
      // A hand a few cm behind the plane is no reason for an elbow 20 cm behind it (a replay's
      // backward walk: the wrist 4.6 cm behind, the elbow 23 cm, not solved again while only a
      // target within the limit counted).
      if (elbow > o.elbowBehindLimit && !(elbow <= target)) {
        // Bend toward the torso's forward as seen across the shoulder–target axis u, plus a little
        // down (which decides when the target is straight ahead). An outward-and-down pole with
        // forward added can lie along u (a hand out, low and in front), and the solver then keeps
        // the bend it had: random poses left elbows up to 5.6 cm behind hands 18 cm in front.
        _pole.subVectors(_target, _shoulder).normalize();
        const fu = sy * _pole.x + cy * _pole.z;
        _pole.set(sy - fu * _pole.x, -fu * _pole.y - 0.5, cy - fu * _pole.z);
        this.reach(arm);
        this.elbowBehind[j] = behind(_v.setFromMatrixPosition(arm.lower.matrixWorld), sy, cy);
      }
      setWorldQuaternion(arm.hand, _q.copy(_q2).multiply(arm.handFromGrip));
      arm.hand.updateWorldMatrix(false, true);
      _pos.setFromMatrixPosition(arm.hand.matrixWorld);
      this.handError[j] = _pos.distanceTo(_target);
      this.handPositions[3 * j] = _pos.x;
      this.handPositions[3 * j + 1] = _pos.y;
      this.handPositions[3 * j + 2] = _pos.z;
    }
  }

  /**
   * The arm reaches `_target` bending toward `_pole`: the runtime's two-bone IK gives world
   * rotation deltas of the upper and lower arm, applied to the bones (the lower arm's delta
   * already includes the upper's).
   */
  private reach(arm: Arm): void {
    _a.setFromMatrixPosition(arm.upper.matrixWorld);
    _v.setFromMatrixPosition(arm.lower.matrixWorld);
    _pos.setFromMatrixPosition(arm.hand.matrixWorld);
    this.ik.solve(_a, _v, _pos, _target, _pole, 0, _q, _q2b);
    arm.lower.matrixWorld.decompose(_p, _lowerWorld, _scale);
    rotateBoneWorld(arm.upper, _q);
    arm.upper.updateWorldMatrix(false, true);
    setWorldQuaternion(arm.lower, _lowerWorld.premultiply(_q2b));
    arm.lower.updateWorldMatrix(false, true);
  }

  /** Frees the IK solver's WASM memory. */
  dispose(): void {
    this.ik.free();
  }

  /** Lengthens forearm and hand (up to `maxStretch`) when `_target` is beyond the arm's reach. */
  private stretchToward(arm: Arm): void {
    _a.setFromMatrixPosition(arm.upper.matrixWorld);
    _v.setFromMatrixPosition(arm.lower.matrixWorld);
    _pos.setFromMatrixPosition(arm.hand.matrixWorld);
    const l1 = _a.distanceTo(_v), l2 = _v.distanceTo(_pos);
    const d = _a.distanceTo(_target);
    // Only the forearm and hand lengthen: the elbow stays where the shoulder puts it.
    if (!(d > l1 + l2) || l2 < 1e-9) return;
    const k = Math.min(1 + this.options.maxStretch, (d - l1) / l2);
    arm.hand.position.multiplyScalar(k);
    arm.hand.updateWorldMatrix(false, true);
  }

  /** Turns the clavicle part of the way toward a target beyond `clavicleReach` of the arm. */
  private reachWithClavicle(arm: Arm): void {
    const o = this.options;
    const clavicle = arm.clavicle as THREE.Object3D;
    _s.setFromMatrixPosition(clavicle.matrixWorld);
    _a.setFromMatrixPosition(arm.upper.matrixWorld);
    const reach = _a.distanceTo(_v.setFromMatrixPosition(arm.lower.matrixWorld)) + _v.distanceTo(_pos.setFromMatrixPosition(arm.hand.matrixWorld));
    const excess = (_a.distanceTo(_target) - o.clavicleReach * reach) / Math.max(1e-6, (1 - o.clavicleReach) * reach);
    if (!(excess > 0)) return;
    _from.subVectors(_a, _s);
    _to.subVectors(_target, _s);
    if (_from.lengthSq() < 1e-12 || _to.lengthSq() < 1e-12) return;
    _q.setFromUnitVectors(_from.normalize(), _to.normalize());
    // A far target pulls the clavicle up to half the way, capped at clavicleMaxAngle.
    const angle = 2 * Math.acos(Math.min(1, Math.abs(_q.w)));
    if (angle < 1e-6) return;
    const wanted = Math.min(o.clavicleMaxAngle, angle * Math.min(1, excess) * 0.5);
    _q3.copy(_identity).slerp(_q, wanted / angle);
    rotateBoneWorld(clavicle, _q3);
    clavicle.updateWorldMatrix(false, true);
  }
}
