/**
 * A scripted user for replays, benchmarks and tests, no headset needed: stand, walk forward
 * 1.5 m (+Z) in 2 s, side-step 0.6 m to the right, turn in place 90° left, crouch and stand up
 * again, hands held in front of the hips with a little swing. `scriptedSample(t, out)` is
 * analytic, so any frame rate samples the same motion. Yaw 0 faces +Z (the HMD looks along its
 * −Z, so its rotation is R_y(yaw + π)).
 */
import { HEAD, LEFT, RIGHT, type TrackerSample } from './tracker-sample.ts';

/** Duration of the script, s. */
export const SCRIPT_DURATION = 11;

const smooth = (x: number) => (x <= 0 ? 0 : x >= 1 ? 1 : x * x * (3 - 2 * x));
const phase = (t: number, start: number, length: number) => smooth((t - start) / length);

/** Writes the scripted trackers at `t` seconds into `out` (all tracked; `out.time = t`). */
export function scriptedSample(t: number, out: TrackerSample, eyeHeight = 1.6): void {
  // 0–1 s stand; 1–3 s walk 1.5 m forward; 3.5–5 s side-step 0.6 m right (−X); 5.5–7 s turn 90°
  // left; 7.5–8.5 s crouch to 65 % eye height; 9–10 s stand up.
  const walk = 1.5 * phase(t, 1, 2);
  const side = -0.6 * phase(t, 3.5, 1.5);
  const yaw = (Math.PI / 2) * phase(t, 5.5, 1.5);
  const crouch = phase(t, 7.5, 1) - phase(t, 9, 1);
  const height = eyeHeight * (1 - 0.35 * crouch);
  const bob = 0.02 * Math.sin(2 * Math.PI * 1.8 * t) * (t > 1 && t < 3 ? 1 : 0);
  const hx = side, hz = walk, hy = height + bob;
  out.time = t;
  out.tracked.fill(0);
  const a = (yaw + Math.PI) / 2;
  // Slight nod down while crouching.
  const pitch = -0.3 * crouch;
  const cy = Math.cos(a), sy = Math.sin(a), cp = Math.cos(pitch / 2), sp = Math.sin(pitch / 2);
  // R_y(yaw + π) · R_x(pitch)
  out.set(HEAD, hx, hy, hz, cy * sp, sy * cp, -sy * sp, cy * cp);
  const s = Math.sin(yaw), c = Math.cos(yaw);
  const swing = 0.08 * Math.sin(2 * Math.PI * 0.9 * t) * (t > 1 && t < 3 ? 1 : 0);
  for (const [tracker, lateral, sw] of [[LEFT, 0.22, swing], [RIGHT, -0.22, -swing]] as const) {
    // Body frame (facing +Z, left = +X): hands 0.25 m forward, 0.55 of eye height up.
    const lx = lateral, lz = 0.25 + sw;
    const x = hx + c * lx + s * lz;
    const z = hz - s * lx + c * lz;
    const y = Math.max(0.3, hy * 0.62 - 0.1 * crouch);
    // Grip pointing forward and a little down: R_y(yaw) · R_x(0.5) (−Z_grip toward the thumb…).
    const half = yaw / 2, tilt = 0.25;
    out.set(tracker, x, y, z, Math.cos(half) * Math.sin(tilt), Math.sin(half) * Math.cos(tilt), -Math.sin(half) * Math.sin(tilt), Math.cos(half) * Math.cos(tilt));
  }
}
