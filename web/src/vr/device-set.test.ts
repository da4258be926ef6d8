import { describe, expect, it } from 'vitest';
import { deviceSetName } from './device-set.ts';
import { FROZEN, MISSING, TRACKED } from './trackers.ts';

describe('deviceSetName', () => {
  it('names every set', () => {
    const name = (l: number, r: number, hl = 0, hr = 0) => deviceSetName([TRACKED, l, r], [0, hl, hr]);
    expect(name(MISSING, MISSING)).toBe('headset only');
    expect(name(TRACKED, TRACKED)).toBe('headset + 2 controllers');
    expect(name(TRACKED, TRACKED, 1, 1)).toBe('headset + hands');
    expect(name(MISSING, TRACKED)).toBe('headset + right controller');
    expect(name(TRACKED, FROZEN)).toBe('headset + left controller'); // asleep: its arm hangs
    expect(name(TRACKED, TRACKED, 1, 0)).toBe('headset + left hand + right controller');
    expect(name(TRACKED, MISSING, 1, 0)).toBe('headset + left hand');
  });
});
