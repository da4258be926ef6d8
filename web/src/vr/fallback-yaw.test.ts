import { describe, expect, it } from 'vitest';
import type { TrackerPose } from './body-yaw.ts';
import { HeadingYawPredictor } from './fallback-yaw.ts';

const deg = Math.PI / 180;

/** An HMD looking at `yaw` (0 = +Z), moving at `vx, vz`. */
function hmd(yaw: number, vx = 0, vz = 0): TrackerPose {
  const a = (yaw + Math.PI) / 2;
  return { position: [0, 1.6, 0], rotation: [0, Math.sin(a), 0, Math.cos(a)], velocity: [vx, 0, vz], angularVelocity: [0, 0, 0], status: 0 };
}
const hand: TrackerPose = { position: [0, 1, 0], rotation: [0, 0, 0, 1], velocity: [0, 0, 0], angularVelocity: [0, 0, 0], status: 0 };

function run(p: HeadingYawPredictor, pose: TrackerPose, seconds: number, dt = 1 / 90): number {
  let y = 0;
  for (let t = 0; t < seconds; t += dt) y = p.update(pose, hand, hand, dt);
  return y;
}

describe('HeadingYawPredictor', () => {
  it('starts at the head heading', () => {
    const p = new HeadingYawPredictor();
    expect(p.name).toBe('heuristic');
    expect(p.update(hmd(1), hand, hand, 1 / 90)).toBeCloseTo(1, 9);
  });

  it('keeps the body still while the head looks around inside the dead zone', () => {
    const p = new HeadingYawPredictor();
    run(p, hmd(0), 0.1);
    expect(run(p, hmd(20 * deg), 2)).toBeCloseTo(0, 9);
    expect(run(p, hmd(-24 * deg), 2)).toBeCloseTo(0, 9);
  });

  it('turns smoothly to bring the head back to the edge of the dead zone', () => {
    const p = new HeadingYawPredictor();
    run(p, hmd(0), 0.1);
    const early = run(p, hmd(90 * deg), 0.05);
    expect(early).toBeGreaterThan(0);
    expect(early).toBeLessThan(40 * deg); // not a snap
    expect(run(p, hmd(90 * deg), 3)).toBeCloseTo(65 * deg, 4);
  });

  it('turns across ±π the short way', () => {
    const p = new HeadingYawPredictor();
    run(p, hmd(170 * deg), 0.1);
    const y = run(p, hmd(-120 * deg), 3); // 70° further left, through 180°
    expect(Math.cos(y - 215 * deg)).toBeCloseTo(1, 6);
  });

  it('closes the dead zone while walking', () => {
    const p = new HeadingYawPredictor();
    run(p, hmd(0), 0.1);
    expect(run(p, hmd(20 * deg, 0.5, 1.2), 3)).toBeCloseTo(20 * deg, 4);
  });

  it('reset() restarts from the head heading', () => {
    const p = new HeadingYawPredictor();
    run(p, hmd(0), 0.5);
    p.reset();
    expect(p.update(hmd(2), hand, hand, 1 / 90)).toBeCloseTo(2, 9);
  });
});
