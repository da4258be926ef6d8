/**
 * Analytic two-bone IK on three.js bones (THESIS_NOTES §9, upper body): rotates `upper` and
 * `lower` so that `end`'s origin reaches `target`, the middle joint bending toward `pole`.
 *
 * By the law of cosines the middle joint is placed at angle α from the root→target axis u, in
 * the plane spanned by u and the pole direction; the upper bone is then turned by the minimal
 * rotation onto that joint and the lower bone onto the target, so the animated twist of each
 * bone is kept. Out of reach the chain straightens and points at the target (the end stops at
 * full extension); a target at the root or zero-length bones leave the chain as it was. No NaN
 * for any input; nothing is allocated.
 *
 * Preconditions: the three bones' `matrixWorld` are current, and their ancestors carry at most
 * uniform scale (local rotations are recovered as parent⁻¹ · world).
 */
import * as THREE from 'three';

const _a = new THREE.Vector3();
const _b = new THREE.Vector3();
const _c = new THREE.Vector3();
const _u = new THREE.Vector3();
const _n = new THREE.Vector3();
const _goal = new THREE.Vector3();
const _from = new THREE.Vector3();
const _to = new THREE.Vector3();
const _scale = new THREE.Vector3();
const _p = new THREE.Vector3();
const _delta = new THREE.Quaternion();
const _world = new THREE.Quaternion();
const _parent = new THREE.Quaternion();

const EPS = 1e-9;

/**
 * Solves the chain; returns the distance from `end` to `target` afterwards (0 when reachable,
 * the shortfall when not).
 */
export function solveTwoBoneIK(upper: THREE.Object3D, lower: THREE.Object3D, end: THREE.Object3D, target: THREE.Vector3, pole: THREE.Vector3): number {
  _a.setFromMatrixPosition(upper.matrixWorld);
  _b.setFromMatrixPosition(lower.matrixWorld);
  _c.setFromMatrixPosition(end.matrixWorld);
  const l1 = _a.distanceTo(_b);
  const l2 = _b.distanceTo(_c);
  if (l1 < EPS || l2 < EPS) return _c.distanceTo(target);

  _u.subVectors(target, _a);
  let d = _u.length();
  if (d < EPS) return _c.distanceTo(target);
  _u.divideScalar(d);
  // Reachable distances lie in [|l1 − l2|, l1 + l2].
  d = Math.min(Math.max(d, Math.abs(l1 - l2)), l1 + l2);

  // Bend direction: the pole orthogonal to u, else the current bend, else any perpendicular.
  _n.copy(pole).addScaledVector(_u, -pole.dot(_u));
  if (_n.lengthSq() < 1e-12) {
    _n.subVectors(_b, _a);
    _n.addScaledVector(_u, -_n.dot(_u));
  }
  if (_n.lengthSq() < 1e-12) {
    _n.set(Math.abs(_u.x) < 0.9 ? 1 : 0, Math.abs(_u.x) < 0.9 ? 0 : 1, 0);
    _n.addScaledVector(_u, -_n.dot(_u));
  }
  _n.normalize();

  const cosAlpha = Math.min(1, Math.max(-1, (l1 * l1 + d * d - l2 * l2) / (2 * l1 * d)));
  const sinAlpha = Math.sqrt(Math.max(0, 1 - cosAlpha * cosAlpha));
  // Middle joint goal, then turn the upper bone onto it.
  _goal.copy(_a).addScaledVector(_u, l1 * cosAlpha).addScaledVector(_n, l1 * sinAlpha);
  _from.subVectors(_b, _a).divideScalar(l1);
  _to.subVectors(_goal, _a).divideScalar(l1);
  rotateBoneWorld(upper, _delta.setFromUnitVectors(_from, _to));
  upper.updateWorldMatrix(false, true);

  // The end goal is on the axis at the (clamped) distance: the target itself when reachable.
  _b.setFromMatrixPosition(lower.matrixWorld);
  _c.setFromMatrixPosition(end.matrixWorld);
  _goal.copy(_a).addScaledVector(_u, d);
  _from.subVectors(_c, _b).normalize();
  _to.subVectors(_goal, _b).normalize();
  rotateBoneWorld(lower, _delta.setFromUnitVectors(_from, _to));
  lower.updateWorldMatrix(false, true);
  return _c.setFromMatrixPosition(end.matrixWorld).distanceTo(target);
}

/** Pre-multiplies `bone`'s world rotation by `delta` (world frame), writing its local rotation. */
export function rotateBoneWorld(bone: THREE.Object3D, delta: THREE.Quaternion): void {
  bone.matrixWorld.decompose(_p, _world, _scale);
  _world.premultiply(delta);
  setWorldQuaternion(bone, _world);
}

/** Sets `bone`'s local rotation so its world rotation is `world` (parent's matrixWorld current). */
export function setWorldQuaternion(bone: THREE.Object3D, world: THREE.Quaternion): void {
  if (bone.parent) {
    bone.parent.matrixWorld.decompose(_p, _parent, _scale);
    bone.quaternion.copy(_parent.invert()).multiply(world);
  } else {
    bone.quaternion.copy(world);
  }
  bone.quaternion.normalize();
}
