import { describe, expect, it } from 'vitest';
import { HEAD, LEFT, RIGHT, TrackerSample } from './tracker-sample.ts';
import { FROZEN, MISSING, TRACKED, TrackerState } from './trackers.ts';
import { headingYaw } from '../yaw.ts';

/** A head walking along +Z at `speed`, hands in front at waist height; yaw 0 = looking along +Z. */
function walk(sample: TrackerSample, time: number, speed: number): void {
  sample.time = time;
  sample.tracked.fill(0);
  const z = speed * time;
  // Looking along +Z: R_y(π) (the viewer looks along its −Z).
  sample.set(HEAD, 0, 1.6, z, 0, 1, 0, 0);
  sample.set(LEFT, 0.25, 1.0, z + 0.3, 0, 0, 0, 1);
  sample.set(RIGHT, -0.25, 1.0, z + 0.3, 0, 0, 0, 1);
}

describe('TrackerState', () => {
  it('differentiates velocity over the real dt at 72, 90 and 120 Hz', () => {
    for (const hz of [72, 90, 120]) {
      const s = new TrackerSample();
      const state = new TrackerState();
      for (let k = 0; k < hz; k++) {
        walk(s, k / hz, 1.3);
        state.update(s);
      }
      expect(state.head.velocity[2]).toBeCloseTo(1.3, 6);
      expect(state.left.velocity[2]).toBeCloseTo(1.3, 6);
      expect(Math.abs(state.head.velocity[0])).toBeLessThan(1e-9);
      expect(state.dt).toBeCloseTo(1 / hz, 9);
      expect(state.status[HEAD]).toBe(TRACKED);
    }
  });

  it('measures angular velocity about the turning axis', () => {
    const s = new TrackerSample();
    const state = new TrackerState();
    const rate = 2; // rad/s about +Y
    for (let k = 0; k < 90; k++) {
      const t = k / 90;
      walk(s, t, 0);
      const a = (Math.PI + rate * t) / 2;
      s.set(HEAD, 0, 1.6, 0, 0, Math.sin(a), 0, Math.cos(a));
      state.update(s);
    }
    expect(state.head.angularVelocity[1]).toBeCloseTo(rate, 5);
    expect(Math.hypot(state.head.angularVelocity[0], state.head.angularVelocity[2])).toBeLessThan(1e-9);
  });

  it('keeps velocities bounded across dt spikes and restarts after a long gap', () => {
    const s = new TrackerSample();
    const state = new TrackerState();
    let t = 0;
    for (let k = 0; k < 60; k++, t += 1 / 60) {
      walk(s, t, 1);
      state.update(s);
    }
    // A 200 ms hitch: the displacement over it is a 1 m/s average, not 12 m/s.
    t += 0.2;
    walk(s, t, 1);
    state.update(s);
    expect(state.head.velocity[2]).toBeGreaterThan(0.9);
    expect(state.head.velocity[2]).toBeLessThan(1.1);
    expect(state.dt).toBe(0.1);
    // Tab hidden for 5 s while the head "moved" 5 m: velocities restart from zero.
    t += 5;
    walk(s, t, 1);
    state.update(s);
    expect(state.head.velocity[2]).toBe(0);
    // A tracking glitch (teleport by 3 m in one frame) is capped.
    t += 1 / 60;
    s.position[3 * HEAD + 2] += 3;
    state.update(s);
    expect(Math.hypot(...state.head.velocity)).toBeLessThanOrEqual(state.options.maxSpeed + 1e-9);
    // Repeated or backward timestamps do not divide by zero.
    state.update(s);
    expect(Number.isFinite(state.head.velocity[2])).toBe(true);
    expect(state.dt).toBe(0);
  });

  it('hangs a missing controller at the side of the head and flags it', () => {
    const s = new TrackerSample();
    const state = new TrackerState();
    for (let k = 0; k < 120; k++) {
      walk(s, k / 60, 0);
      s.position[3 * HEAD + 1] += 1e-4 * Math.sin(k); // worn and held devices always jitter
      s.position[3 * LEFT + 1] += 1e-4 * Math.sin(k);
      if (k >= 30) s.tracked[RIGHT] = 0;
      state.update(s);
      // Never a jump: the hand moves smoothly from its last pose to the hanging pose.
      expect(Math.hypot(...state.right.velocity)).toBeLessThan(4);
    }
    expect(state.right.status).toBe(MISSING);
    expect(state.left.status).toBe(TRACKED);
    // Looking along +Z the body's right is −X; hands hang at half the head height.
    expect(state.right.position[0]).toBeCloseTo(-state.options.hangSide, 3);
    expect(state.right.position[1]).toBeCloseTo(0.8, 3);
    expect(state.right.position[2]).toBeCloseTo(state.options.hangForward, 3);
    // It comes back when tracked again.
    for (let k = 120; k < 180; k++) {
      walk(s, k / 60, 0);
      state.update(s);
    }
    expect(state.right.status).toBe(TRACKED);
    expect(state.right.position[0]).toBeCloseTo(-0.25, 2);
    expect(state.right.position[2]).toBeCloseTo(0.3, 2);
  });

  it('blends from a controller to a tracked hand (and back) whose grip is elsewhere, without a jump', () => {
    const s = new TrackerSample();
    const state = new TrackerState();
    let worst = 0;
    const at = (k: number, hand: boolean) => {
      walk(s, k / 60, 0.5);
      s.hand[LEFT] = hand ? 1 : 0;
      // The hand's grip-like pose sits 12 cm from where the controller's grip was, turned 40°.
      if (hand) s.set(LEFT, 0.25 + 0.12, 1.0, 0.5 * (k / 60) + 0.3, 0, Math.sin(0.35), 0, Math.cos(0.35));
      const before = [...state.left.position];
      state.update(s);
      if (k > 0) worst = Math.max(worst, Math.hypot(state.left.position[0] - before[0], state.left.position[1] - before[1], state.left.position[2] - before[2]));
    };
    for (let k = 0; k < 60; k++) at(k, false);
    for (let k = 60; k < 180; k++) at(k, true);
    expect(state.left.status).toBe(TRACKED);
    expect(state.left.position[0]).toBeCloseTo(0.37, 3); // on the hand after 2 s
    expect(Math.abs(state.left.rotation[1])).toBeCloseTo(Math.sin(0.35), 3);
    for (let k = 180; k < 300; k++) at(k, false);
    expect(state.left.position[0]).toBeCloseTo(0.25, 3);
    // Walking moves it 0.8 cm a frame; the 12 cm switch is spread over ~0.1 s half-lives.
    expect(worst).toBeLessThan(0.03);
  });

  it('hangs controllers relative to the head heading, for a controller never seen too', () => {
    const s = new TrackerSample();
    const state = new TrackerState();
    s.time = 0;
    // Head looking along +X: R_y(π/2 + π).
    const a = (Math.PI / 2 + Math.PI) / 2;
    s.set(HEAD, 1, 1.7, 2, 0, Math.sin(a), 0, Math.cos(a));
    state.update(s);
    expect(state.status[LEFT]).toBe(MISSING);
    // Facing +X, the body's left is −Z.
    expect(state.left.position[0]).toBeCloseTo(1 + state.options.hangForward, 6);
    expect(state.left.position[2]).toBeCloseTo(2 - state.options.hangSide, 6);
    const r = state.left.rotation;
    expect(headingYaw(r[0], r[1], r[2], r[3])).toBeCloseTo(Math.PI / 2, 6);
  });

  it('flags a controller frozen while the head moves, not when everything is still', () => {
    const s = new TrackerSample();
    const state = new TrackerState();
    for (let k = 0; k < 60; k++) {
      walk(s, k / 60, 0); // head and hands bit-for-bit still: an emulator, not a sleeping controller
      state.update(s);
    }
    expect(state.status).toEqual(new Uint8Array([TRACKED, TRACKED, TRACKED]));
    for (let k = 60; k < 120; k++) {
      walk(s, k / 60, 0);
      s.position[3 * HEAD + 1] += 1e-4 * Math.sin(k);
      s.position[3 * LEFT] += 0.001 * Math.sin(k); // a held controller jitters
      state.update(s);
    }
    expect(state.left.status).toBe(TRACKED);
    expect(state.right.status).toBe(FROZEN);
    expect(state.head.status).toBe(TRACKED);
  });

  it('reset() forgets history', () => {
    const s = new TrackerSample();
    const state = new TrackerState();
    walk(s, 0, 1);
    state.update(s);
    walk(s, 0.1, 1);
    state.update(s);
    state.reset();
    expect(state.frames).toBe(0);
    walk(s, 10, 1);
    state.update(s);
    expect(state.head.velocity[2]).toBe(0);
    expect(state.head.position[2]).toBe(10);
  });

  it('treats a garbage pose (NaN, ±Inf, far away, a zero quaternion) or a NaN time as a missing frame, never as a pose', () => {
    const finite = (state: TrackerState) =>
      [state.position, state.rotation, state.velocity, state.angularVelocity].every((a) => a.every(Number.isFinite));
    const garbage: Array<(s: TrackerSample) => void> = [
      (s) => (s.position[3 * HEAD] = NaN),
      (s) => (s.position[3 * LEFT + 1] = Infinity),
      (s) => (s.position[3 * RIGHT + 2] = -1e300),
      (s) => s.rotation.fill(NaN, 4 * HEAD, 4 * HEAD + 4),
      (s) => s.rotation.fill(0, 4 * LEFT, 4 * LEFT + 4),
      (s) => (s.time = NaN),
    ];
    for (const [k, spoil] of garbage.entries()) {
      const s = new TrackerSample();
      const state = new TrackerState();
      for (let f = 0; f < 90; f++) {
        walk(s, f / 90, 1.2);
        if (f === 45) spoil(s);
        state.update(s);
        expect(finite(state), `case ${k}, frame ${f}`).toBe(true);
        if (f === 45) expect(state.rejected, `case ${k}`).toBe(1);
      }
      // Walking on: the head speed is the walk's again.
      expect(state.head.velocity[2], `case ${k}`).toBeCloseTo(1.2, 3);
      expect(state.status[HEAD]).toBe(TRACKED);
    }
  });

  it('normalizes rotations a device reports unnormalized', () => {
    const s = new TrackerSample();
    const state = new TrackerState();
    walk(s, 0, 0);
    s.set(HEAD, 0, 1.6, 0, 0, 3, 0, 0);
    state.update(s);
    expect(Math.hypot(...state.head.rotation)).toBeCloseTo(1, 12);
    expect(state.head.rotation[1]).toBeCloseTo(1, 12);
  });
});
