import * as THREE from 'three';
import { describe, expect, it } from 'vitest';
import { type HumanoidRole } from '../avatar/joint-maps.ts';
import { type TrackerPose } from './body-yaw.ts';
import { solveTwoBoneIK } from './two-bone-ik.ts';
import { UpperBody } from './upper-body.ts';
import { headingYaw } from '../yaw.ts';
import { seededRandom } from '../bench/queries.ts';

/** A T-posed humanoid upper body facing +Z (left = +X), bones with arbitrary rest rotations. */
function makeRig(twistRest = false) {
  const object = new THREE.Group();
  const bones: THREE.Bone[] = [];
  const roles = new Map<HumanoidRole, number>();
  const add = (role: HumanoidRole, parent: THREE.Object3D, x: number, y: number, z: number) => {
    const b = new THREE.Bone();
    b.name = role;
    b.position.set(x, y, z);
    parent.add(b);
    roles.set(role, bones.length);
    bones.push(b);
    return b;
  };
  const hips = add('hips', object, 0, 1.0, 0);
  const spine = add('spine', hips, 0, 0.1, 0);
  const chest = add('chest', spine, 0, 0.15, 0);
  const upperChest = add('upperChest', chest, 0, 0.15, 0);
  const neck = add('neck', upperChest, 0, 0.12, 0);
  add('head', neck, 0, 0.1, 0);
  for (const side of [1, -1]) {
    const p = side > 0 ? 'left' : 'right';
    const clavicle = add(`${p}Shoulder` as HumanoidRole, upperChest, side * 0.03, 0.08, 0);
    const upper = add(`${p}UpperArm` as HumanoidRole, clavicle, side * 0.15, 0, 0);
    const lower = add(`${p}LowerArm` as HumanoidRole, upper, side * 0.28, 0, 0);
    const hand = add(`${p}Hand` as HumanoidRole, lower, side * 0.25, 0, 0);
    if (twistRest) {
      // Rest rotations that are not identity must not matter (joint axes differ between rigs).
      for (const b of [clavicle, upper, lower, hand]) {
        const q = new THREE.Quaternion().setFromEuler(new THREE.Euler(0.3, -0.7, 1.1));
        b.quaternion.copy(q);
        b.position.applyQuaternion(b.parent === upperChest ? new THREE.Quaternion() : (b.parent as THREE.Bone).quaternion.clone().invert());
      }
    }
  }
  object.updateMatrixWorld(true);
  return { object, bones, roles, bone: (r: HumanoidRole) => bones[roles.get(r) as number] };
}

function pose(position: number[], rotation: number[]): TrackerPose {
  return { position, rotation, velocity: [0, 0, 0], angularVelocity: [0, 0, 0], status: 0 };
}
const world = (b: THREE.Object3D) => new THREE.Vector3().setFromMatrixPosition(b.matrixWorld);
/** Rotation of an HMD looking at `yaw` (0 = +Z), pitched down by `pitch`. */
function hmdRotation(yaw: number, pitch = 0): number[] {
  const q = new THREE.Quaternion().setFromEuler(new THREE.Euler(-pitch, yaw + Math.PI, 0, 'YXZ'));
  return [q.x, q.y, q.z, q.w];
}

describe('solveTwoBoneIK', () => {
  const chain = () => {
    const root = new THREE.Bone();
    const upper = new THREE.Bone();
    const lower = new THREE.Bone();
    const end = new THREE.Bone();
    root.add(upper);
    upper.add(lower);
    lower.add(end);
    upper.position.set(0.1, 1.4, 0);
    lower.position.set(0.3, 0, 0);
    end.position.set(0.25, 0, 0);
    root.updateMatrixWorld(true);
    return { root, upper, lower, end };
  };

  it('reaches targets within its reach to 1e-4 m, bending toward the pole', () => {
    const rng = seededRandom(7);
    for (let k = 0; k < 200; k++) {
      const { upper, lower, end } = chain();
      const dir = new THREE.Vector3(rng() - 0.5, rng() - 0.5, rng() - 0.5).normalize();
      const target = world(upper).addScaledVector(dir, 0.06 + 0.48 * rng());
      const pole = new THREE.Vector3(0, -1, -0.5);
      const error = solveTwoBoneIK(upper, lower, end, target, pole);
      expect(error).toBeLessThan(1e-4);
      expect(world(end).distanceTo(target)).toBeLessThan(1e-4);
      // Bone lengths are kept.
      expect(world(upper).distanceTo(world(lower))).toBeCloseTo(0.3, 6);
      expect(world(lower).distanceTo(world(end))).toBeCloseTo(0.25, 6);
      // The elbow is on the pole's side of the shoulder→target axis.
      const u = target.clone().sub(world(upper)).normalize();
      const n = pole.clone().addScaledVector(u, -pole.dot(u));
      if (n.length() > 0.1) expect(world(lower).sub(world(upper)).dot(n)).toBeGreaterThanOrEqual(-1e-6);
    }
  });

  it('stretches toward unreachable targets', () => {
    const { upper, lower, end } = chain();
    const target = new THREE.Vector3(0.1, 1.4 - 2, 0.5);
    const error = solveTwoBoneIK(upper, lower, end, target, new THREE.Vector3(0, 0, -1));
    const dir = target.clone().sub(world(upper)).normalize();
    expect(world(end).sub(world(upper)).normalize().dot(dir)).toBeCloseTo(1, 6);
    expect(world(end).distanceTo(world(upper))).toBeCloseTo(0.55, 6);
    expect(error).toBeCloseTo(target.distanceTo(world(upper)) - 0.55, 6);
  });

  it('never produces NaN: full extension, target at the shoulder, pole along the axis, zero-length bones', () => {
    const cases: [THREE.Vector3, THREE.Vector3][] = [
      [new THREE.Vector3(0.65, 1.4, 0), new THREE.Vector3(0, -1, 0)], // exactly full extension along the chain
      [new THREE.Vector3(0.1, 1.4, 0), new THREE.Vector3(0, -1, 0)], // at the shoulder
      [new THREE.Vector3(0.4, 1.4, 0), new THREE.Vector3(1, 0, 0)], // pole along the axis
      [new THREE.Vector3(0.4, 1.4, 0), new THREE.Vector3(0, 0, 0)], // zero pole
    ];
    for (const [target, pole] of cases) {
      const { upper, lower, end } = chain();
      solveTwoBoneIK(upper, lower, end, target, pole);
      for (const b of [upper, lower, end]) for (const v of b.matrixWorld.elements) expect(Number.isFinite(v)).toBe(true);
    }
    const { upper, lower, end } = chain();
    end.position.set(0, 0, 0);
    lower.updateMatrixWorld(true);
    solveTwoBoneIK(upper, lower, end, new THREE.Vector3(0.3, 1.2, 0.2), new THREE.Vector3(0, -1, 0));
    for (const v of end.matrixWorld.elements) expect(Number.isFinite(v)).toBe(true);
  });
});

describe('UpperBody', () => {
  for (const twistRest of [false, true]) {
    it(`puts the hands on the controllers within 1 cm and aligns the head with the HMD${twistRest ? ' (rotated rest frames)' : ''}`, () => {
      const rig = makeRig(twistRest);
      const body = new UpperBody(rig);
      const hmd = pose([0, 1.62, 0.05], hmdRotation(0.4, 0.3));
      // Controllers in front, rolled a little; all reachable.
      const qL = new THREE.Quaternion().setFromEuler(new THREE.Euler(-0.4, 0.2, 0.3));
      const qR = new THREE.Quaternion().setFromEuler(new THREE.Euler(-0.2, -0.5, -0.2));
      const left = pose([0.25, 1.2, 0.35], [qL.x, qL.y, qL.z, qL.w]);
      const right = pose([-0.2, 1.35, 0.3], [qR.x, qR.y, qR.z, qR.w]);
      body.apply(hmd, left, right, 0);
      expect(body.handError[0]).toBeLessThan(0.01);
      expect(body.handError[1]).toBeLessThan(0.01);
      expect(body.handError[0]).toBeLessThan(1e-4);
      // The grip point implied by the hand bone is the controller's: wrist + R_hand·(grip − wrist).
      const hand = rig.bone('leftHand');
      const handQ = new THREE.Quaternion();
      hand.matrixWorld.decompose(new THREE.Vector3(), handQ, new THREE.Vector3());
      // The hand's rotation relative to the controller is a constant (rest-derived).
      const relative = qL.clone().invert().multiply(handQ);
      body.apply(hmd, pose([0.2, 1.1, 0.3], [0, 0, 0, 1]), right, 0);
      hand.matrixWorld.decompose(new THREE.Vector3(), handQ, new THREE.Vector3());
      expect(handQ.angleTo(relative)).toBeLessThan(1e-6);
      // Head: its world rotation is the HMD's times a constant, so its heading follows the HMD.
      const headQ = new THREE.Quaternion();
      rig.bone('head').matrixWorld.decompose(new THREE.Vector3(), headQ, new THREE.Vector3());
      const h = hmd.rotation;
      const offset = new THREE.Quaternion(h[0], h[1], h[2], h[3]).invert().multiply(headQ);
      body.apply(pose([0, 1.6, 0], hmdRotation(-0.3)), left, right, 0);
      rig.bone('head').matrixWorld.decompose(new THREE.Vector3(), headQ, new THREE.Vector3());
      const h2 = hmdRotation(-0.3);
      expect(new THREE.Quaternion(h2[0], h2[1], h2[2], h2[3]).invert().multiply(headQ).angleTo(offset)).toBeLessThan(1e-6);
    });
  }

  it('in the rest pose, a controller held like the rest fist leaves the arm straight', () => {
    const rig = makeRig();
    const hand = world(rig.bone('leftHand'));
    const body = new UpperBody(rig);
    // The rest fist: rod forward (grip −Z = +Z), back of the left hand up (grip −X = +Y): grip = R_z(−π/2)·R_y(π)?
    // Derive it instead: move the controller to where UpperBody's rest grip is and compare.
    const gripX = new THREE.Vector3(0, -1, 0), gripZ = new THREE.Vector3(0, 0, -1);
    const gripY = new THREE.Vector3().crossVectors(gripZ, gripX);
    const q = new THREE.Quaternion().setFromRotationMatrix(new THREE.Matrix4().makeBasis(gripX, gripY, gripZ));
    const grip = hand.clone().add(new THREE.Vector3(body.options.gripForward, -body.options.gripPalm, 0));
    const restHmd = pose([0, 1.65, 0.05], hmdRotation(0));
    const right = pose([-0.73, 1.33, 0], [0, 0, 0, 1]);
    rig.object.updateMatrixWorld(true);
    body.apply(restHmd, pose([grip.x, grip.y, grip.z], [q.x, q.y, q.z, q.w]), right, 0);
    expect(world(rig.bone('leftHand')).distanceTo(hand)).toBeLessThan(1e-4);
    expect(body.handError[0]).toBeLessThan(1e-4);
  });

  it('twists the spine toward the head yaw and turns the clavicle toward far targets', () => {
    const rig = makeRig();
    const body = new UpperBody(rig);
    const hands = [pose([0.3, 1.1, 0.2], [0, 0, 0, 1]), pose([-0.3, 1.1, 0.2], [0, 0, 0, 1])] as const;
    body.apply(pose([0, 1.62, 0], hmdRotation(1.0)), hands[0], hands[1], 0);
    const chestQ = new THREE.Quaternion();
    rig.bone('upperChest').matrixWorld.decompose(new THREE.Vector3(), chestQ, new THREE.Vector3());
    const chestYaw = 2 * Math.atan2(chestQ.y, chestQ.w);
    // spine + chest + upperChest shares: 0.55 of the 1 rad difference.
    expect(chestYaw).toBeCloseTo(0.55, 4);
    const headQ = new THREE.Quaternion();
    rig.bone('head').matrixWorld.decompose(new THREE.Vector3(), headQ, new THREE.Vector3());
    const fwd = new THREE.Vector3(0, 0, 1).applyQuaternion(headQ);
    expect(Math.atan2(fwd.x, fwd.z)).toBeCloseTo(1.0, 4);
    expect(headingYaw(...(hmdRotation(1.0) as [number, number, number, number]))).toBeCloseTo(1.0, 6);

    // A target far up and out: the clavicle lifts (its child moves up) and the hand gets closer.
    const rig2 = makeRig();
    const body2 = new UpperBody(rig2, { clavicleMaxAngle: 0 });
    const far = pose([0.5, 2.3, 0.2], [0, 0, 0, 1]);
    const body3 = new UpperBody(makeRig());
    body2.apply(pose([0, 1.62, 0], hmdRotation(0)), far, hands[1], 0);
    body3.apply(pose([0, 1.62, 0], hmdRotation(0)), far, hands[1], 0);
    expect(body3.handError[0]).toBeLessThan(body2.handError[0] - 0.01);
    for (const v of body3.handPositions) expect(Number.isFinite(v)).toBe(true);
  });
});

describe('UpperBody stretch', () => {
  it('lengthens the forearm up to maxStretch for a target just out of reach, and restores it next frame', () => {
    const rig = makeRig();
    const body = new UpperBody(rig, { clavicleMaxAngle: 0 });
    const hmd = pose([0, 1.62, 0], [0, 1, 0, 0]);
    const right = pose([-0.3, 1.1, 0.2], [0, 0, 0, 1]);
    // Shoulder (upper arm) at (0.18, 1.48, 0), reach 0.53 m; the wrist 0.58 m straight out, the
    // controller held like the rest fist (rod forward, back of the hand up).
    const gripX = new THREE.Vector3(0, -1, 0), gripZ = new THREE.Vector3(0, 0, -1);
    const q = new THREE.Quaternion().setFromRotationMatrix(new THREE.Matrix4().makeBasis(gripX, new THREE.Vector3().crossVectors(gripZ, gripX), gripZ));
    const far = pose([0.18 + 0.58 + body.options.gripForward, 1.48 - body.options.gripPalm, 0], [q.x, q.y, q.z, q.w]);
    body.apply(hmd, far, right, 0);
    expect(body.handError[0]).toBeLessThan(0.01);
    const stretched = rig.bone('leftHand').position.length();
    expect(stretched).toBeGreaterThan(0.25);
    expect(stretched).toBeLessThanOrEqual(0.25 * 1.25 + 1e-9);
    body.apply(hmd, pose([0.3, 1.1, 0.25], [0, 0, 0, 1]), right, 0);
    expect(rig.bone('leftHand').position.length()).toBeCloseTo(0.25, 9);
    expect(body.handError[0]).toBeLessThan(1e-4);
    // Far beyond: stretched by at most maxStretch, the hand short of the target.
    body.apply(hmd, pose([2, 1.5, 0], [0, 0, 0, 1]), right, 0);
    expect(rig.bone('leftHand').position.length()).toBeCloseTo(0.25 * 1.25, 9);
    expect(body.handError[0]).toBeGreaterThan(0.5);
  });
});
