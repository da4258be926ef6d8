import { createMoveInput, type MoveInput } from '../core/drive.ts';

export { createMoveInput, type MoveInput };

/**
 * The ground directions of a camera: where "forward" (W, stick up) and "right" point in the
 * world when the camera looks along `lookX, lookZ` (any length; a straight-down camera keeps
 * the previous basis). three.js cameras look along −Z, so the default is forward = (0, −1).
 */
export class CameraBasis {
  forwardX = 0;
  forwardZ = -1;

  /** Sets the basis from the camera's world look direction (`camera.getWorldDirection`). */
  setLook(lookX: number, lookZ: number): void {
    const length = Math.hypot(lookX, lookZ);
    if (length < 1e-6) return;
    this.forwardX = lookX / length;
    this.forwardZ = lookZ / length;
  }

  /** Right of forward on the ground: forward × up. */
  get rightX(): number {
    return -this.forwardZ;
  }
  get rightZ(): number {
    return this.forwardX;
  }

  /** Writes the world direction of a screen-space stick (x right, y up) into `out`. */
  toWorld(stickX: number, stickY: number, out: MoveInput): void {
    out.moveX = this.forwardX * stickY + this.rightX * stickX;
    out.moveZ = this.forwardZ * stickY + this.rightZ * stickX;
  }
}
