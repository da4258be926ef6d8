/**
 * Keyboard control: WASD or arrows move relative to the camera, Shift runs, holding F strafes
 * (keeps the current facing), Q/E turn the facing while strafing. Listens on a target
 * (`attach(window)`); `press` is the whole state machine, so it is testable without a DOM.
 */
import type { CameraBasis, MoveInput } from './input.ts';

/** Facing turn rate for Q/E while strafing (rad/s). */
export const TURN_RATE = 2.0;

const MOVE_KEYS: Readonly<Record<string, readonly [number, number]>> = {
  KeyW: [0, 1],
  ArrowUp: [0, 1],
  KeyS: [0, -1],
  ArrowDown: [0, -1],
  KeyA: [-1, 0],
  ArrowLeft: [-1, 0],
  KeyD: [1, 0],
  ArrowRight: [1, 0],
};

export class KeyboardInput {
  private readonly down = new Set<string>();
  /** Facing yaw while strafing (radians, 0 = +Z), captured when strafing starts. */
  private facingYaw = 0;
  private wasStrafing = false;
  private detach: (() => void) | null = null;

  /** Listens to key events on `target` (e.g. `window`); call `dispose()` to stop. */
  attach(target: EventTarget): void {
    this.dispose();
    const onDown = (e: Event): void => this.press((e as KeyboardEvent).code, true);
    const onUp = (e: Event): void => this.press((e as KeyboardEvent).code, false);
    const onBlur = (): void => this.down.clear();
    target.addEventListener('keydown', onDown);
    target.addEventListener('keyup', onUp);
    target.addEventListener('blur', onBlur);
    this.detach = () => {
      target.removeEventListener('keydown', onDown);
      target.removeEventListener('keyup', onUp);
      target.removeEventListener('blur', onBlur);
    };
  }

  dispose(): void {
    this.detach?.();
    this.detach = null;
  }

  /** A key (`KeyboardEvent.code`) went down or up. */
  press(code: string, down: boolean): void {
    if (down) this.down.add(code);
    else this.down.delete(code);
  }

  /** Whether any of the keys this controller uses is held. */
  get active(): boolean {
    for (const code of this.down) if (code in MOVE_KEYS || code === 'KeyF' || code === 'KeyQ' || code === 'KeyE') return true;
    return false;
  }

  /**
   * Writes this frame's input. `currentYaw` is the character's facing (radians, 0 = +Z): it
   * becomes the kept facing when strafing starts.
   */
  read(camera: CameraBasis, currentYaw: number, dt: number, out: MoveInput): void {
    let x = 0;
    let y = 0;
    for (const code of this.down) {
      const m = MOVE_KEYS[code];
      if (m) {
        x += m[0];
        y += m[1];
      }
    }
    // Opposite keys cancel; diagonals are unit length like a stick pushed to the rim.
    x = Math.sign(x);
    y = Math.sign(y);
    const length = Math.hypot(x, y);
    camera.toWorld(length > 0 ? x / length : 0, length > 0 ? y / length : 0, out);
    out.run = this.down.has('ShiftLeft') || this.down.has('ShiftRight');
    out.strafe = this.down.has('KeyF');
    if (out.strafe && !this.wasStrafing) this.facingYaw = currentYaw;
    this.wasStrafing = out.strafe;
    if (out.strafe) {
      const turn = (this.down.has('KeyQ') ? 1 : 0) - (this.down.has('KeyE') ? 1 : 0);
      this.facingYaw += turn * TURN_RATE * dt;
    } else {
      this.facingYaw = currentYaw;
    }
    out.faceX = Math.sin(this.facingYaw);
    out.faceZ = Math.cos(this.facingYaw);
  }
}
