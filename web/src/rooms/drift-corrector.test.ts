import { describe, expect, it } from 'vitest';
import { DriftCorrector } from './drift-corrector.ts';
import { wrapAngle } from '../yaw.ts';

const DT = 1 / 60;

function run(c: DriftCorrector, seconds: number) {
  let maxStep = 0;
  let maxTurn = 0;
  let maxAccel = 0;
  let prevStep = 0;
  const trace: number[] = [];
  for (let t = 0; t < seconds; t += DT) {
    const x = c.offsetX;
    const z = c.offsetZ;
    const yaw = c.offsetYaw;
    c.update(DT);
    const step = Math.hypot(c.offsetX - x, c.offsetZ - z);
    maxStep = Math.max(maxStep, step);
    maxAccel = Math.max(maxAccel, Math.abs(step - prevStep));
    prevStep = step;
    maxTurn = Math.max(maxTurn, Math.abs(c.offsetYaw - yaw));
    trace.push(Math.hypot(c.targetX - c.offsetX, c.targetZ - c.offsetZ));
  }
  return { maxStep, maxTurn, maxAccel, trace };
}

describe('DriftCorrector', () => {
  it('never jumps: a 3 m error is covered at ≤ maxSpeed, then converges to < 1 mm', () => {
    const c = new DriftCorrector({ maxSpeed: 1.5, halflife: 0.25 });
    c.measure(0, 0, 0, 3, 0, 0);
    const r = run(c, 4);
    expect(r.maxStep).toBeLessThanOrEqual(1.5 * DT + 1e-12);
    expect(r.maxStep).toBeGreaterThan(1.5 * DT * 0.99); // it does use the speed it has
    expect(r.trace[Math.round(1 / DT)]).toBeGreaterThan(1); // still catching up after 1 s
    expect(r.trace.at(-1)).toBeLessThan(0.001);
    expect(c.offsetX).toBeCloseTo(3, 3);
  });

  it('small errors: critically damped (analytic decay), no overshoot', () => {
    const c = new DriftCorrector({ halflife: 0.25 });
    c.measure(1, 1, 0, 1.05, 1, 0); // 5 cm
    const r = run(c, 1.5);
    const atHalflife = r.trace[Math.round(0.25 / DT) - 1];
    // A critically damped spring from rest leaves (1 + y t) e^(−y t) of the error, y = 2 ln 2 / halflife:
    // at t = halflife that is (1 + 2 ln 2) / 4 = 0.597.
    expect(atHalflife / 0.05).toBeCloseTo((1 + 2 * Math.LN2) / 4, 2);
    expect(r.trace.at(-1)!).toBeLessThan(0.0005);
    expect(c.offsetX).toBeLessThanOrEqual(0.05 + 1e-9); // never beyond the target
    expect(r.maxStep).toBeLessThan(0.05 * 0.05); // smooth: < 2.5 mm a frame
  });

  it('yaw takes the short way across ±π and turns at ≤ maxAngularSpeed', () => {
    const c = new DriftCorrector({ maxAngularSpeed: 2 });
    c.measure(0, 0, 3.1, 0, 0, -3.1); // 0.083 rad, not −6.2
    expect(c.targetYaw).toBeCloseTo(2 * Math.PI - 6.2, 9);
    const r = run(c, 2);
    expect(r.maxTurn).toBeLessThanOrEqual(2 * DT + 1e-12);
    expect(wrapAngle(3.1 + c.offsetYaw - -3.1)).toBeCloseTo(0, 4);
    const big = new DriftCorrector({ maxAngularSpeed: 2 });
    big.measure(0, 0, 0, 0, 0, 3);
    const rb = run(big, 3);
    expect(rb.maxTurn).toBeLessThanOrEqual(2 * DT + 1e-12);
    expect(big.offsetYaw).toBeCloseTo(3, 3);
  });

  it('follows a moving error smoothly (a reported root that keeps drifting)', () => {
    const c = new DriftCorrector();
    let maxStep = 0;
    // The error grows 0.2 m/s for 3 s (measurements at 20 Hz), then stays.
    for (let f = 0; f < 6 * 60; f++) {
      const t = f * DT;
      if (f % 3 === 0) c.measure(0, 0, 0, Math.min(t, 3) * 0.2, 0, 0);
      const x = c.offsetX;
      c.update(DT);
      maxStep = Math.max(maxStep, Math.abs(c.offsetX - x));
    }
    expect(maxStep).toBeLessThan(0.2 * DT * 1.6);
    expect(c.offsetX).toBeCloseTo(0.6, 3);
  });

  it('rebase keeps the display still when the simulation jumps; non-finite measurements are ignored', () => {
    const c = new DriftCorrector();
    c.measure(0, 0, 0, 1, 0, 0);
    run(c, 0.3);
    const shown = 10 + c.offsetX; // simulation at 10
    c.rebase(-2, 0, 0); // the simulation jumped to 8
    expect(8 + c.offsetX).toBeCloseTo(shown, 12);
    expect(c.measure(0, 0, 0, NaN, 0, 0)).toBe(false);
    expect(c.measure(0, Infinity, 0, 0, 0, 0)).toBe(false);
    expect(c.rejected).toBe(2);
    expect(Number.isFinite(c.targetX)).toBe(true);
  });
});
