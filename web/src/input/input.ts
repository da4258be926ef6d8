/**
 * What a player asks the character for this frame, on the ground plane in world space — the
 * `Input` of the Rust controller (`RawCrowd.set_input`). Devices write into one preallocated
 * `MoveInput` each frame (no allocation per frame).
 */
export interface MoveInput {
  /** Desired move direction (x, z); length 0–1 is the stick magnitude. */
  moveX: number;
  moveZ: number;
  /** Desired facing (x, z), unit length; used while strafing. */
  faceX: number;
  faceZ: number;
  run: boolean;
  /** Keep facing (faceX, faceZ) while moving in any direction (side-steps, backwards). */
  strafe: boolean;
}

export function createMoveInput(): MoveInput {
  return { moveX: 0, moveZ: 0, faceX: 0, faceZ: 1, run: false, strafe: false };
}

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
