// T-pose retargeting (THESIS_NOTES §8): for each mapped joint, the target's world rotation is
//   q_t = q_s · q_s0⁻¹ · q_t0
// with q_s the source joint's world rotation now and q_s0, q_t0 the world rotations of the source
// and target joints in their T-poses; then back to target-local rotations through the target's
// parent world rotations. The root (hips) translation is scaled by the ratio of hip heights.
//
// Plain quaternion math on typed arrays (x, y, z, w): `apply()` allocates nothing.

import type { HumanoidRole } from './joint-maps.ts';

/** Rest (T-)pose data of the two skeletons, and how their joints map onto each other. */
export interface RetargeterOptions {
  /** Source parent indices (-1 for a root), length J. */
  sourceParents: ArrayLike<number>;
  /** Source world rotations in its T-pose, J×4. (For the .mmdb, BVH rest pose: all identity.) */
  sourceRestWorldRotations: ArrayLike<number>;
  /** Source world positions in its T-pose, J×3 (for the hips height and limb bone directions). */
  sourceRestWorldPositions: ArrayLike<number>;
  /** Target parent indices (-1 for a root), length T. */
  targetParents: ArrayLike<number>;
  /** Target local rotations in its T-pose, T×4 (e.g. glTF node rotations of the skin joints). */
  targetRestLocalRotations: ArrayLike<number>;
  /** Target local translations in its T-pose, T×3. */
  targetRestLocalPositions: ArrayLike<number>;
  /** Role → source joint index (`findRoles(sourceNames)`). */
  sourceRoles: ReadonlyMap<HumanoidRole, number>;
  /** Role → target joint index (`findRoles(targetNames)`). */
  targetRoles: ReadonlyMap<HumanoidRole, number>;
  /**
   * World rotation of whatever carries the target's root joints (e.g. a glTF "Armature" node),
   * x, y, z, w. Default identity.
   */
  targetRootParentRotation?: ArrayLike<number>;
  /**
   * Align limb bone directions (default true): rest poses differ beyond "T" — CMU's rest foot
   * points down 20–30° where a game avatar's is flat, arms may hang at different angles — and the
   * plain T-pose method carries that difference into every frame (toes up, feet off the floor).
   * With alignment, each limb bone of the target points where the source's bone points: the
   * source rest rotation is first swung so its bone lies along the target's rest bone.
   */
  alignBones?: boolean;
  /**
   * Height of the source's toe joints above its floor when a foot is planted (m; the database
   * summary's `toe_height_in_contact`). With it, heights map so that a planted source toe
   * puts the avatar's toe at its rest (standing) height: feet on the floor whatever the foot
   * geometry of the two skeletons.
   */
  sourceToeHeight?: number;
}

/**
 * Limb bones as (joint role, child role): their directions are aligned (`alignBones`). Not the
 * clavicles: anatomy differs there (CMU's clavicle bone rises ~20° to the shoulder, a game
 * avatar's is level), and copying its direction shrugs the avatar's shoulders.
 */
const LIMB_BONES: readonly (readonly [HumanoidRole, HumanoidRole])[] = [
  ['leftUpperArm', 'leftLowerArm'],
  ['leftLowerArm', 'leftHand'],
  ['rightUpperArm', 'rightLowerArm'],
  ['rightLowerArm', 'rightHand'],
  ['leftUpperLeg', 'leftLowerLeg'],
  ['leftLowerLeg', 'leftFoot'],
  ['leftFoot', 'leftToes'],
  ['rightUpperLeg', 'rightLowerLeg'],
  ['rightLowerLeg', 'rightFoot'],
  ['rightFoot', 'rightToes'],
];

// ---------------------------------------------------------------- quaternion helpers (x, y, z, w)

type Quats = Float32Array | Float64Array;

/** out[o] = a[ai] · b[bi] (Hamilton product). `out` may alias `a` or `b`. */
function quatMul(out: Quats, o: number, a: ArrayLike<number>, ai: number, b: ArrayLike<number>, bi: number): void {
  const ax = a[ai], ay = a[ai + 1], az = a[ai + 2], aw = a[ai + 3];
  const bx = b[bi], by = b[bi + 1], bz = b[bi + 2], bw = b[bi + 3];
  out[o] = aw * bx + ax * bw + ay * bz - az * by;
  out[o + 1] = aw * by - ax * bz + ay * bw + az * bx;
  out[o + 2] = aw * bz + ax * by - ay * bx + az * bw;
  out[o + 3] = aw * bw - ax * bx - ay * by - az * bz;
}

/** out[o] = conj(a[ai]) · b[bi] (= a⁻¹ · b for unit a). `out` may alias `a` or `b`. */
function quatInvMul(out: Quats, o: number, a: ArrayLike<number>, ai: number, b: ArrayLike<number>, bi: number): void {
  const ax = -a[ai], ay = -a[ai + 1], az = -a[ai + 2], aw = a[ai + 3];
  const bx = b[bi], by = b[bi + 1], bz = b[bi + 2], bw = b[bi + 3];
  out[o] = aw * bx + ax * bw + ay * bz - az * by;
  out[o + 1] = aw * by - ax * bz + ay * bw + az * bx;
  out[o + 2] = aw * bz + ax * by - ay * bx + az * bw;
  out[o + 3] = aw * bw - ax * bx - ay * by - az * bz;
}

/** Normalizes the quaternion at out[o] in place (identity if it is zero). */
function quatNormalize(out: Quats, o: number): void {
  const l = Math.hypot(out[o], out[o + 1], out[o + 2], out[o + 3]);
  if (l === 0) {
    out[o] = out[o + 1] = out[o + 2] = 0;
    out[o + 3] = 1;
    return;
  }
  out[o] /= l;
  out[o + 1] /= l;
  out[o + 2] /= l;
  out[o + 3] /= l;
}

/**
 * out[o] = the shortest rotation taking direction a to direction b (neither need be unit);
 * identity when either is zero, a half turn about some perpendicular axis when they oppose.
 */
function quatFromDirections(out: Quats, o: number, a: ArrayLike<number>, b: ArrayLike<number>): void {
  const la = Math.hypot(a[0], a[1], a[2]);
  const lb = Math.hypot(b[0], b[1], b[2]);
  out[o] = out[o + 1] = out[o + 2] = 0;
  out[o + 3] = 1;
  if (la === 0 || lb === 0) return;
  const ax = a[0] / la, ay = a[1] / la, az = a[2] / la;
  const bx = b[0] / lb, by = b[1] / lb, bz = b[2] / lb;
  const r = 1 + ax * bx + ay * by + az * bz;
  if (r < 1e-8) {
    // Opposite: any axis perpendicular to a.
    const useX = Math.abs(ax) < 0.9;
    out[o] = useX ? 0 : -az;
    out[o + 1] = useX ? az : 0;
    out[o + 2] = useX ? -ay : ax;
    out[o + 3] = 0;
  } else {
    out[o] = ay * bz - az * by;
    out[o + 1] = az * bx - ax * bz;
    out[o + 2] = ax * by - ay * bx;
    out[o + 3] = r;
  }
  quatNormalize(out, o);
}

/** Rotates vector v[vi] by the unit quaternion q[qi] into out[o]. */
function quatRotate(out: Quats, o: number, q: ArrayLike<number>, qi: number, v: ArrayLike<number>, vi: number): void {
  const qx = q[qi], qy = q[qi + 1], qz = q[qi + 2], qw = q[qi + 3];
  const vx = v[vi], vy = v[vi + 1], vz = v[vi + 2];
  // v' = v + 2w (q × v) + 2 q × (q × v)
  const tx = 2 * (qy * vz - qz * vy);
  const ty = 2 * (qz * vx - qx * vz);
  const tz = 2 * (qx * vy - qy * vx);
  out[o] = vx + qw * tx + (qy * tz - qz * ty);
  out[o + 1] = vy + qw * ty + (qz * tx - qx * tz);
  out[o + 2] = vz + qw * tz + (qx * ty - qy * tx);
}

/**
 * An order of joint indices in which every parent comes before its children (joint arrays from
 * glTF skins need not be sorted). Throws on a cycle or an out-of-range parent.
 */
export function parentFirstOrder(parents: ArrayLike<number>): Int32Array {
  const n = parents.length;
  const order = new Int32Array(n);
  const state = new Uint8Array(n); // 0 new, 1 visiting, 2 done
  let k = 0;
  const visit = (j: number): void => {
    if (state[j] === 2) return;
    if (state[j] === 1) throw new Error(`skeleton: parent cycle through joint ${j}`);
    state[j] = 1;
    const p = parents[j];
    if (p >= n) throw new Error(`skeleton: joint ${j} has parent ${p}, out of range (${n} joints)`);
    if (p >= 0) visit(p);
    state[j] = 2;
    order[k++] = j;
  };
  for (let j = 0; j < n; j++) visit(j);
  return order;
}

/**
 * Forward kinematics: world rotations (J×4) and positions (J×3) from local ones. Roots (parent
 * -1) take `rootRotation` (default identity) as their parent's rotation, at the origin.
 */
export function forwardKinematics(
  parents: ArrayLike<number>,
  localRotations: ArrayLike<number>,
  localPositions: ArrayLike<number>,
  outWorldRotations: Quats,
  outWorldPositions: Quats,
  rootRotation: ArrayLike<number> = IDENTITY,
  order: ArrayLike<number> = parentFirstOrder(parents),
): void {
  for (let k = 0; k < order.length; k++) {
    const j = order[k];
    const p = parents[j];
    if (p < 0) {
      quatMul(outWorldRotations, j * 4, rootRotation, 0, localRotations, j * 4);
      quatRotate(outWorldPositions, j * 3, rootRotation, 0, localPositions, j * 3);
    } else {
      quatMul(outWorldRotations, j * 4, outWorldRotations, p * 4, localRotations, j * 4);
      quatRotate(outWorldPositions, j * 3, outWorldRotations, p * 4, localPositions, j * 3);
      outWorldPositions[j * 3] += outWorldPositions[p * 3];
      outWorldPositions[j * 3 + 1] += outWorldPositions[p * 3 + 1];
      outWorldPositions[j * 3 + 2] += outWorldPositions[p * 3 + 2];
    }
  }
}

const IDENTITY = new Float64Array([0, 0, 0, 1]);

/** Height of joint `hips` above the lowest joint of the skeleton (Y up), from world positions. */
function hipsHeight(worldPositions: ArrayLike<number>, hips: number): number {
  let minY = Infinity;
  for (let j = 1; j < worldPositions.length; j += 3) minY = Math.min(minY, worldPositions[j]);
  return worldPositions[hips * 3 + 1] - minY;
}

/**
 * Hips height over the toes (average of both legs) of the target in its rest pose and of the
 * source standing with its leg bones along the target's rest bones; and the target's rest toe
 * height. `null` unless both skeletons map hips, upper/lower leg, foot and toes on both sides.
 */
function standingHeights(opts: RetargeterOptions, targetRest: ArrayLike<number>): { source: number; target: number; targetToeHeight: number } | null {
  const chains = [
    ['leftUpperLeg', 'leftLowerLeg', 'leftFoot', 'leftToes'],
    ['rightUpperLeg', 'rightLowerLeg', 'rightFoot', 'rightToes'],
  ] as const;
  const sp = opts.sourceRestWorldPositions;
  const y = (p: ArrayLike<number>, j: number) => p[j * 3 + 1];
  let source = 0, target = 0, toe = 0;
  for (const chain of chains) {
    const s = ['hips' as const, ...chain].map((r) => opts.sourceRoles.get(r));
    const t = ['hips' as const, ...chain].map((r) => opts.targetRoles.get(r));
    if (s.includes(undefined) || t.includes(undefined)) return null;
    const si = s as number[], ti = t as number[];
    // Hips → upper leg as the source has it; each leg bone's length along the target's direction.
    let drop = y(sp, si[0]) - y(sp, si[1]);
    for (let k = 1; k < 4; k++) {
      const len = Math.hypot(sp[si[k + 1] * 3] - sp[si[k] * 3], sp[si[k + 1] * 3 + 1] - sp[si[k] * 3 + 1], sp[si[k + 1] * 3 + 2] - sp[si[k] * 3 + 2]);
      const tx = targetRest[ti[k + 1] * 3] - targetRest[ti[k] * 3], ty = targetRest[ti[k + 1] * 3 + 1] - targetRest[ti[k] * 3 + 1], tz = targetRest[ti[k + 1] * 3 + 2] - targetRest[ti[k] * 3 + 2];
      const tl = Math.hypot(tx, ty, tz);
      drop -= tl > 0 ? (len * ty) / tl : 0;
    }
    source += drop / 2;
    target += (y(targetRest, ti[0]) - y(targetRest, ti[4])) / 2;
    toe += y(targetRest, ti[4]) / 2;
  }
  return source > 0 && target > 0 ? { source, target, targetToeHeight: toe } : null;
}

/**
 * Maps source poses onto a target skeleton by the T-pose method. Built once; `apply()` per frame
 * allocates nothing.
 *
 * Only roles present in both maps are retargeted; every other target joint keeps its rest local
 * rotation (so its world rotation follows its parent). The hips role must be in both maps.
 */
export class Retargeter {
  /** Number of target joints (T). */
  readonly numTargetJoints: number;
  /** Target joint index of the hips. */
  readonly targetHips: number;
  /** Source joint index of the hips. */
  readonly sourceHips: number;
  /** Target rest hips height / source rest hips height (each above its lowest joint). */
  readonly hipsScale: number;
  /** Target hips height above its lowest joint in the rest pose (m). */
  readonly targetHipsHeight: number;
  /** Source hips height above its lowest joint in the rest pose (m). */
  readonly sourceHipsHeight: number;
  /** Heights map as y_t = (y_s − sourceFloor)·hipsScale + targetFloor (see `sourceToeHeight`). */
  readonly sourceFloor: number = 0;
  readonly targetFloor: number = 0;

  private readonly parents: Int32Array;
  private readonly order: Int32Array;
  /** Source joint mapped to each target joint, or -1. */
  private readonly sourceOf: Int32Array;
  /** q_s0⁻¹ · q_t0 per mapped target joint (T×4; unused entries identity). */
  private readonly offsets: Float64Array;
  private readonly restLocal: Float64Array;
  private readonly rootParent: Float64Array;
  /** World rotation and position of the hips' parent (rest: ancestors of the hips are unmapped). */
  private readonly hipsParentRotation: Float64Array;
  private readonly hipsParentPosition: Float64Array;
  /** Scratch: target world rotations of the last `apply()`, T×4. */
  private readonly world: Float64Array;

  constructor(opts: RetargeterOptions) {
    const T = opts.targetParents.length;
    const J = opts.sourceParents.length;
    if (opts.targetRestLocalRotations.length !== T * 4) throw new Error(`retarget: target rest rotations: ${opts.targetRestLocalRotations.length} floats for ${T} joints`);
    if (opts.targetRestLocalPositions.length !== T * 3) throw new Error(`retarget: target rest positions: ${opts.targetRestLocalPositions.length} floats for ${T} joints`);
    if (opts.sourceRestWorldRotations.length !== J * 4) throw new Error(`retarget: source rest rotations: ${opts.sourceRestWorldRotations.length} floats for ${J} joints`);
    if (opts.sourceRestWorldPositions.length !== J * 3) throw new Error(`retarget: source rest positions: ${opts.sourceRestWorldPositions.length} floats for ${J} joints`);
    const sh = opts.sourceRoles.get('hips');
    const th = opts.targetRoles.get('hips');
    if (sh === undefined || th === undefined) throw new Error('retarget: the hips role must be mapped on both skeletons');

    this.numTargetJoints = T;
    this.parents = Int32Array.from(opts.targetParents);
    this.order = parentFirstOrder(this.parents);
    parentFirstOrder(opts.sourceParents); // validates the source hierarchy
    this.restLocal = Float64Array.from(opts.targetRestLocalRotations);
    for (let t = 0; t < T; t++) quatNormalize(this.restLocal, t * 4);
    this.rootParent = Float64Array.from(opts.targetRootParentRotation ?? IDENTITY);
    this.world = new Float64Array(T * 4);

    // Target rest world transforms.
    const restWorldRot = new Float64Array(T * 4);
    const restWorldPos = new Float64Array(T * 3);
    forwardKinematics(this.parents, this.restLocal, opts.targetRestLocalPositions, restWorldRot, restWorldPos, this.rootParent, this.order);

    this.sourceOf = new Int32Array(T).fill(-1);
    this.offsets = new Float64Array(T * 4);
    const srcRest = Float64Array.from(opts.sourceRestWorldRotations);
    if (opts.alignBones ?? true) {
      const sp = opts.sourceRestWorldPositions;
      const ds = new Float64Array(3);
      const dt = new Float64Array(3);
      const swing = new Float64Array(4);
      for (const [role, childRole] of LIMB_BONES) {
        const [s, sc, t, tc] = [opts.sourceRoles.get(role), opts.sourceRoles.get(childRole), opts.targetRoles.get(role), opts.targetRoles.get(childRole)];
        if (s === undefined || sc === undefined || t === undefined || tc === undefined) continue;
        for (let c = 0; c < 3; c++) {
          ds[c] = sp[sc * 3 + c] - sp[s * 3 + c];
          dt[c] = restWorldPos[tc * 3 + c] - restWorldPos[t * 3 + c];
        }
        // q_s0' = R(d_s → d_t) · q_s0: the source rotation at which its bone lies along the
        // target's rest bone, which then maps to the target's rest.
        quatFromDirections(swing, 0, ds, dt);
        quatNormalize(srcRest, s * 4);
        quatMul(srcRest, s * 4, swing, 0, srcRest, s * 4);
      }
    }
    for (const [role, t] of opts.targetRoles) {
      const s = opts.sourceRoles.get(role);
      if (s === undefined) continue;
      if (t < 0 || t >= T || s < 0 || s >= J) throw new Error(`retarget: role ${role} maps out of range (source ${s}, target ${t})`);
      this.sourceOf[t] = s;
      quatNormalize(srcRest, s * 4);
      quatInvMul(this.offsets, t * 4, srcRest, s * 4, restWorldRot, t * 4);
    }

    this.sourceHips = sh;
    this.targetHips = th;
    this.sourceHipsHeight = hipsHeight(opts.sourceRestWorldPositions, sh);
    this.targetHipsHeight = hipsHeight(restWorldPos, th);
    if (!(this.sourceHipsHeight > 0) || !(this.targetHipsHeight > 0)) {
      throw new Error(`retarget: hips heights must be positive (source ${this.sourceHipsHeight}, target ${this.targetHipsHeight})`);
    }
    this.hipsScale = this.targetHipsHeight / this.sourceHipsHeight;
    // Better: the hips' height over the toes with the source standing like the target (its leg
    // bones along the target's rest bones) — the rest foot's tilt no longer counts.
    const legs = standingHeights(opts, restWorldPos);
    if (legs && (opts.alignBones ?? true)) this.hipsScale = legs.target / legs.source;
    if (legs && opts.sourceToeHeight !== undefined) {
      if (!Number.isFinite(opts.sourceToeHeight)) throw new Error(`retarget: sourceToeHeight must be a number, got ${opts.sourceToeHeight}`);
      this.sourceFloor = opts.sourceToeHeight;
      this.targetFloor = legs.targetToeHeight;
    }

    const hp = this.parents[th];
    this.hipsParentRotation = new Float64Array(4);
    this.hipsParentPosition = new Float64Array(3);
    if (hp < 0) this.hipsParentRotation.set(this.rootParent);
    else {
      this.hipsParentRotation.set(restWorldRot.subarray(hp * 4, hp * 4 + 4));
      this.hipsParentPosition.set(restWorldPos.subarray(hp * 3, hp * 3 + 3));
    }
  }

  /**
   * Retargets one pose.
   *
   * - `sourceWorldRotations`: source world rotations now, J×4 (x, y, z, w), unit.
   * - `sourceHipsWorldPosition`: source hips world position (x, y, z), m.
   * - `outTargetLocalRotations`: receives the target local rotations, T×4.
   * - `outTargetHipsPosition`: receives the hips' LOCAL translation (in its parent joint's rest
   *   frame), ready to assign to the hips node; it equals the source hips position × `hipsScale`
   *   in the target's world.
   */
  apply(
    sourceWorldRotations: ArrayLike<number>,
    sourceHipsWorldPosition: ArrayLike<number>,
    outTargetLocalRotations: Float32Array | Float64Array,
    outTargetHipsPosition: Float32Array | Float64Array,
  ): void {
    const { parents, order, sourceOf, offsets, restLocal, world, rootParent } = this;
    for (let k = 0; k < order.length; k++) {
      const t = order[k];
      const p = parents[t];
      const pw = p < 0 ? rootParent : world;
      const pi = p < 0 ? 0 : p * 4;
      const s = sourceOf[t];
      const o = t * 4;
      if (s >= 0) {
        // q_t = q_s · (q_s0⁻¹ · q_t0), renormalized against drift; local = parent⁻¹ · q_t.
        quatMul(world, o, sourceWorldRotations, s * 4, offsets, o);
        quatNormalize(world, o);
        quatInvMul(_quatA, 0, pw, pi, world, o);
        outTargetLocalRotations[o] = _quatA[0];
        outTargetLocalRotations[o + 1] = _quatA[1];
        outTargetLocalRotations[o + 2] = _quatA[2];
        outTargetLocalRotations[o + 3] = _quatA[3];
      } else {
        outTargetLocalRotations[o] = restLocal[o];
        outTargetLocalRotations[o + 1] = restLocal[o + 1];
        outTargetLocalRotations[o + 2] = restLocal[o + 2];
        outTargetLocalRotations[o + 3] = restLocal[o + 3];
        quatMul(world, o, pw, pi, restLocal, o);
      }
    }
    const sc = this.hipsScale;
    const pp = this.hipsParentPosition;
    _v3A[0] = sourceHipsWorldPosition[0] * sc - pp[0];
    _v3A[1] = (sourceHipsWorldPosition[1] - this.sourceFloor) * sc + this.targetFloor - pp[1];
    _v3A[2] = sourceHipsWorldPosition[2] * sc - pp[2];
    // Into the parent's frame: rotate by the inverse (conjugate) rotation.
    const r = this.hipsParentRotation;
    _quatB[0] = -r[0];
    _quatB[1] = -r[1];
    _quatB[2] = -r[2];
    _quatB[3] = r[3];
    quatRotate(_v3B, 0, _quatB, 0, _v3A, 0);
    outTargetHipsPosition[0] = _v3B[0];
    outTargetHipsPosition[1] = _v3B[1];
    outTargetHipsPosition[2] = _v3B[2];
  }

  /** Target world rotations (T×4) computed by the last `apply()` (a live view; do not keep). */
  get targetWorldRotations(): Float64Array {
    return this.world;
  }
}

const _quatA = new Float64Array(4);
const _quatB = new Float64Array(4);
const _v3A = new Float64Array(3);
const _v3B = new Float64Array(3);
