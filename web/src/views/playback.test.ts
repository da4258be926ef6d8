import { describe, expect, it } from 'vitest';
import { Playback } from './playback.ts';

describe('Playback', () => {
  it('advances at the database frame rate and loops', () => {
    const p = new Playback(10, 30);
    expect(p.update(1 / 60)).toBe(false); // half a frame
    expect(p.update(1 / 60)).toBe(true);
    expect(p.frame).toBe(1);
    for (let i = 0; i < 8; i++) p.update(1 / 30 + 1e-6);
    expect(p.frame).toBe(9);
    p.update(1 / 30 + 1e-6);
    expect(p.frame).toBe(0);
  });

  it('does not advance while paused; seek clamps', () => {
    const p = new Playback(10, 30);
    p.toggle();
    expect(p.update(1)).toBe(false);
    expect(p.frame).toBe(0);
    p.seek(42);
    expect(p.frame).toBe(9);
    p.seek(-3);
    expect(p.frame).toBe(0);
    p.step(-1);
    expect(p.frame).toBe(9);
  });

  it('caps a long stall to a quarter second', () => {
    const p = new Playback(1000, 60);
    p.update(10);
    expect(p.frame).toBe(15);
  });
});
