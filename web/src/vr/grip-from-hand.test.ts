import * as THREE from 'three';
import { describe, expect, it } from 'vitest';
import { LEFT, RIGHT, TrackerSample, gripFromHand } from './tracker-sample.ts';

/** The grip's axes in the world after `gripFromHand` with the wrist joint turned by `q`. */
function gripAxes(left: boolean, q: THREE.Quaternion) {
  const s = new TrackerSample();
  const t = left ? LEFT : RIGHT;
  gripFromHand(left, 0, 1, 0, q.x, q.y, q.z, q.w, 0, 1, -0.1, s, t);
  const r = new THREE.Quaternion(...s.rotation.subarray(4 * t, 4 * t + 4));
  return {
    position: new THREE.Vector3(...s.position.subarray(3 * t, 3 * t + 3)),
    x: new THREE.Vector3(1, 0, 0).applyQuaternion(r),
    z: new THREE.Vector3(0, 0, 1).applyQuaternion(r),
    unit: Math.hypot(r.x, r.y, r.z, r.w),
  };
}

const close = (a: THREE.Vector3, b: [number, number, number]) => expect(a.distanceTo(new THREE.Vector3(...b))).toBeLessThan(1e-9);

describe('gripFromHand (WebXR hand joints → a controller-grip-like pose)', () => {
  // Palm down, fingers forward (joint −Z = world −Z, joint +Y = back of the hand = up).
  it('right hand: +X out of the back of the hand, −Z toward the thumb (left)', () => {
    const g = gripAxes(false, new THREE.Quaternion());
    close(g.x, [0, 1, 0]);
    close(g.z, [1, 0, 0]); // −Z_grip = −X world: the right thumb, palm down
    close(g.position, [0, 1, -0.05]); // the palm's centre
    expect(g.unit).toBeCloseTo(1, 12);
  });

  it('left hand: +X out of the palm, −Z toward the thumb (right)', () => {
    const g = gripAxes(true, new THREE.Quaternion());
    close(g.x, [0, -1, 0]);
    close(g.z, [-1, 0, 0]);
  });

  it('turns with the wrist', () => {
    const yaw = new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(0, 1, 0), Math.PI / 2); // fingers toward −X
    const g = gripAxes(false, yaw);
    close(g.x, [0, 1, 0]);
    close(g.z, [0, 0, -1]); // the thumb toward +Z: −Z_grip = +Z world
  });
});
