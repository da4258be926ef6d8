/**
 * Gamepad control (standard mapping): left stick moves relative to the camera, the right
 * stick pushed past half way sets the facing and strafes, the right trigger (or A) runs.
 */
import type { CameraBasis, MoveInput } from './input.ts';

/** The part of the Gamepad API this reads (so tests can pass plain objects). */
export interface GamepadLike {
  readonly axes: readonly number[];
  readonly buttons: readonly { readonly value: number; readonly pressed: boolean }[];
}

/** Sticks inside this radius read as centred (worn sticks drift). */
export const DEAD_ZONE = 0.2;
/** The right stick takes over the facing beyond this deflection. */
export const FACING_THRESHOLD = 0.5;

/** Radial dead zone, rescaled so output starts at 0 at the dead zone's edge; y up. */
function stick(x: number, y: number, out: { x: number; y: number }): void {
  const length = Math.hypot(x, y);
  if (length <= DEAD_ZONE) {
    out.x = 0;
    out.y = 0;
    return;
  }
  const scaled = Math.min(1, (length - DEAD_ZONE) / (1 - DEAD_ZONE));
  // Gamepad y axes point down; the game's point up.
  out.x = (x / length) * scaled;
  out.y = (-y / length) * scaled;
}

const _left = { x: 0, y: 0 };
const _right = { x: 0, y: 0 };

/** Writes `pad`'s input into `out`; returns false (and leaves `out` alone) without a pad. */
export function readGamepad(pad: GamepadLike | null | undefined, camera: CameraBasis, out: MoveInput): boolean {
  if (!pad || pad.axes.length < 4) return false;
  stick(pad.axes[0], pad.axes[1], _left);
  stick(pad.axes[2], pad.axes[3], _right);
  camera.toWorld(_left.x, _left.y, out);
  const trigger = pad.buttons[7]?.value ?? 0;
  out.run = trigger > 0.5 || (pad.buttons[0]?.pressed ?? false);
  out.strafe = Math.hypot(_right.x, _right.y) > FACING_THRESHOLD - DEAD_ZONE;
  if (out.strafe) {
    const x = camera.forwardX * _right.y + camera.rightX * _right.x;
    const z = camera.forwardZ * _right.y + camera.rightZ * _right.x;
    const length = Math.hypot(x, z);
    out.faceX = x / length;
    out.faceZ = z / length;
  }
  return true;
}
