/**
 * Move controls for a character: keyboard (while its target has focus) and the first gamepad,
 * camera-relative. One instance per character; `read` writes one preallocated `MoveInput`.
 */
import { type MoveInput, createMoveInput } from '../core/drive.ts';
import { readGamepad } from './gamepad.ts';
import { CameraBasis } from './input.ts';
import { KeyboardInput } from './keyboard.ts';

/** The first connected gamepad, without allocating a closure per frame. */
function firstGamepad(): Gamepad | null {
  const pads = typeof navigator !== 'undefined' && navigator.getGamepads ? navigator.getGamepads() : [];
  for (const p of pads) if (p) return p;
  return null;
}

export class MoveControls {
  readonly keyboard = new KeyboardInput();
  readonly basis = new CameraBasis();
  readonly input: MoveInput = createMoveInput();
  keyboardEnabled = true;
  gamepadEnabled = true;
  /** A device asked for something last frame (so letting go stops the character once). */
  private active = false;

  /** Listens for keys on `target` (an element: only while it has focus; or `window`). */
  attach(target: EventTarget): void {
    this.keyboard.attach(target);
  }

  dispose(): void {
    this.keyboard.dispose();
  }

  /**
   * This frame's input, camera-relative (`lookX, lookZ`: the camera's look direction on the
   * floor), or null when no device asks for anything (a path or an API call keeps the
   * character). `yaw` is the character's facing, kept while strafing.
   */
  read(lookX: number, lookZ: number, yaw: number, dt: number): MoveInput | null {
    this.basis.setLook(lookX, lookZ);
    const input = this.input;
    let asking = false;
    if (this.keyboardEnabled && this.keyboard.active) {
      this.keyboard.read(this.basis, yaw, dt, input);
      asking = true;
    } else if (this.gamepadEnabled && readGamepad(firstGamepad(), this.basis, input)) {
      asking = input.moveX !== 0 || input.moveZ !== 0 || input.strafe;
    }
    if (asking) {
      this.active = true;
      return input;
    }
    if (!this.active) return null;
    // Let go: stop once, then leave the character to paths and API calls.
    this.active = false;
    input.moveX = input.moveZ = 0;
    input.strafe = false;
    input.run = false;
    return input;
  }
}
