/**
 * Drives the motion-matched character from the tracked user — the one place that knows how.
 *
 * The runtime's VR mode (THESIS_NOTES §9: it spring-smooths the head's ground velocity and the
 * body yaw, builds the trajectory query from them, and clamps the root within α of the head) is
 * `Crowd.setTracked(i, headX, headZ, velX, velZ, yaw)`. Until that wrapper exists this module
 * falls back, in order, to the raw binding's `set_tracked`, then to an equivalent stick input:
 * desired velocity = head velocity + (head − root) / `catchUp` (so the root is pulled back under
 * the head instead of drifting), strafing with the facing = body yaw.
 */
import { type Crowd } from '../core/crowd.ts';
import { createMoveInput } from '../input/input.ts';

type TrackedFn = (i: number, headX: number, headZ: number, velocityX: number, velocityZ: number, yaw: number) => void;

/** Walk speeds of the runtime's controller (docs/runtime.md), m/s. */
const WALK = { forward: 1.75, side: 1.5, backward: 1.25 };
const RUN = { forward: 4, side: 3, backward: 2.5 };

export class CharacterDriver {
  /** 'tracked' when the runtime's VR mode is used, 'input' for the stick-input stand-in. */
  readonly mode: 'tracked' | 'input';
  /** Stand-in only: seconds to close the head↔root gap. */
  catchUp = 0.4;
  /** Stand-in only: below this speed (m/s) the character stands. */
  standSpeed = 0.12;
  private readonly tracked: TrackedFn | null;
  private readonly input = createMoveInput();

  constructor(
    private readonly crowd: Crowd,
    private readonly index = 0,
  ) {
    const wrapped = (crowd as unknown as { setTracked?: TrackedFn }).setTracked;
    const raw = (crowd.binding as unknown as { set_tracked?: TrackedFn }).set_tracked;
    if (typeof wrapped === 'function') this.tracked = wrapped.bind(crowd);
    else if (typeof raw === 'function') this.tracked = raw.bind(crowd.binding);
    else this.tracked = null;
    this.mode = this.tracked ? 'tracked' : 'input';
  }

  /**
   * `headX, headZ`: the head centre on the floor; `velocityX, velocityZ`: its ground velocity
   * (m/s); `yaw`: body yaw (rad, 0 = +Z); `rootX, rootZ`: the character root now.
   */
  drive(headX: number, headZ: number, velocityX: number, velocityZ: number, yaw: number, rootX: number, rootZ: number): void {
    if (this.tracked) {
      this.tracked(this.index, headX, headZ, velocityX, velocityZ, yaw);
      return;
    }
    let vx = velocityX + (headX - rootX) / this.catchUp;
    let vz = velocityZ + (headZ - rootZ) / this.catchUp;
    const speed = Math.hypot(vx, vz);
    const input = this.input;
    input.faceX = Math.sin(yaw);
    input.faceZ = Math.cos(yaw);
    input.strafe = true;
    input.run = false;
    if (speed < this.standSpeed) {
      vx = 0;
      vz = 0;
    }
    // Into the facing frame (left = +X when facing +Z): local = R_y(−yaw)·v.
    const c = Math.cos(yaw), s = Math.sin(yaw);
    const lx = c * vx - s * vz;
    const lz = s * vx + c * vz;
    // The controller scales each local axis by its speed (controller.rs desired_velocity): invert.
    let sx = lx / WALK.side, sz = lz / (lz > 0 ? WALK.forward : WALK.backward);
    let m = Math.hypot(sx, sz);
    if (m > 1) {
      input.run = true;
      sx = lx / RUN.side;
      sz = lz / (lz > 0 ? RUN.forward : RUN.backward);
      m = Math.hypot(sx, sz);
      if (m > 1) {
        sx /= m;
        sz /= m;
      }
    }
    input.moveX = c * sx + s * sz;
    input.moveZ = -s * sx + c * sz;
    this.crowd.setInput(this.index, input);
  }
}
