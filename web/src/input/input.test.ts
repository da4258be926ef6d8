import { describe, expect, it } from 'vitest';
import { readGamepad, type GamepadLike } from './gamepad.ts';
import { CameraBasis, createMoveInput } from './input.ts';
import { KeyboardInput, TURN_RATE } from './keyboard.ts';

const pad = (axes: number[], trigger = 0): GamepadLike => ({
  axes,
  buttons: Array.from({ length: 16 }, (_, i) => ({ value: i === 7 ? trigger : 0, pressed: false })),
});

describe('keyboard', () => {
  it('moves relative to the camera, runs with Shift, cancels opposite keys', () => {
    const camera = new CameraBasis(); // three.js default: looking along −Z
    const keys = new KeyboardInput();
    const out = createMoveInput();
    keys.press('KeyW', true);
    keys.read(camera, 0, 1 / 60, out);
    expect([out.moveX, out.moveZ]).toEqual([0, -1]);
    keys.press('KeyD', true);
    keys.press('ShiftLeft', true);
    keys.read(camera, 0, 1 / 60, out);
    expect(out.moveX).toBeCloseTo(Math.SQRT1_2, 6);
    expect(out.moveZ).toBeCloseTo(-Math.SQRT1_2, 6);
    expect(out.run).toBe(true);
    keys.press('KeyA', true); // D + A cancel
    keys.read(camera, 0, 1 / 60, out);
    expect(out.moveX).toBeCloseTo(0, 6);
    // The camera turned to look along +X: W now walks +X.
    camera.setLook(1, 0);
    keys.press('KeyA', false);
    keys.press('KeyD', false);
    keys.read(camera, 0, 1 / 60, out);
    expect(out.moveX).toBeCloseTo(1, 6);
    expect(out.moveZ).toBeCloseTo(0, 6);
  });

  it('strafing keeps the facing it started with and Q/E turn it', () => {
    const camera = new CameraBasis();
    const keys = new KeyboardInput();
    const out = createMoveInput();
    keys.press('KeyF', true);
    keys.press('KeyA', true);
    keys.read(camera, 0.5, 1 / 60, out);
    expect(out.strafe).toBe(true);
    expect(Math.atan2(out.faceX, out.faceZ)).toBeCloseTo(0.5, 6);
    // The character's facing changes, the strafe facing does not.
    keys.read(camera, 1.2, 1 / 60, out);
    expect(Math.atan2(out.faceX, out.faceZ)).toBeCloseTo(0.5, 6);
    keys.press('KeyQ', true);
    for (let i = 0; i < 30; i++) keys.read(camera, 1.2, 1 / 60, out);
    expect(Math.atan2(out.faceX, out.faceZ)).toBeCloseTo(0.5 + 0.5 * TURN_RATE, 5);
    keys.press('KeyF', false);
    keys.read(camera, 1.2, 1 / 60, out);
    expect(out.strafe).toBe(false);
  });
});

describe('gamepad', () => {
  it('applies a radial dead zone and maps the left stick to the camera', () => {
    const camera = new CameraBasis();
    const out = createMoveInput();
    expect(readGamepad(pad([0.1, -0.1, 0, 0]), camera, out)).toBe(true);
    expect([out.moveX, out.moveZ]).toEqual([0, 0]);
    readGamepad(pad([0, -1, 0, 0], 0.9), camera, out); // stick up, trigger pulled
    expect(out.moveX).toBeCloseTo(0, 6);
    expect(out.moveZ).toBeCloseTo(-1, 6);
    expect(out.run).toBe(true);
    expect(out.strafe).toBe(false);
    readGamepad(pad([0.6, 0, 0, 0]), camera, out);
    expect(out.moveX).toBeCloseTo(0.5, 6); // (0.6 − 0.2) / 0.8
  });

  it('the right stick sets the facing and strafes', () => {
    const camera = new CameraBasis();
    const out = createMoveInput();
    readGamepad(pad([1, 0, 0, -1]), camera, out); // move right, face camera-forward
    expect(out.strafe).toBe(true);
    expect(out.faceX).toBeCloseTo(0, 6);
    expect(out.faceZ).toBeCloseTo(-1, 6);
    expect(readGamepad(null, camera, out)).toBe(false);
  });
});
