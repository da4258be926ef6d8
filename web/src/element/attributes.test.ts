import { describe, expect, it } from 'vitest';
import { checkStepsPerFrame, checkTimeStep, parseChoice, parseControls, parseUrl } from './attributes.ts';

const collect = () => {
  const warnings: string[] = [];
  return { warnings, warn: (m: string) => warnings.push(m) };
};

describe('<mm-avatar> attribute values', () => {
  it('controls: known words kept, a typo named with what is accepted, the default when unset', () => {
    const { warnings, warn } = collect();
    expect([...parseControls(null, warn)]).toEqual(['keyboard', 'gamepad']);
    expect([...parseControls('  path   keybaord ', warn)]).toEqual(['path']);
    expect(warnings).toEqual(['controls="  path   keybaord ": unknown control "keybaord" ignored (use keyboard, gamepad, path, none)']);
    expect([...parseControls('none', warn)]).toEqual(['none']);
    expect(warnings).toHaveLength(1);
  });

  it('choices fall back with a warning; long values are quoted short', () => {
    const { warnings, warn } = collect();
    expect(parseChoice('camera', 'fixed', ['follow', 'fixed'], 'follow', warn)).toBe('fixed');
    expect(parseChoice('camera', null, ['follow', 'fixed'], 'follow', warn)).toBe('follow');
    expect(parseChoice('camera', 'x'.repeat(10_000), ['follow', 'fixed'], 'follow', warn)).toBe('follow');
    expect(warnings).toHaveLength(1);
    expect(warnings[0].length).toBeLessThan(160);
    expect(warnings[0]).toMatch(/^camera="x{80}…" is not one of follow, fixed; using follow$/);
  });

  it('URLs: relative ones resolve against the page; garbage and unfetchable schemes are errors naming the attribute', () => {
    const base = 'https://example.org/app/page.html';
    expect(parseUrl('database', null, base)).toBeNull();
    expect(parseUrl('database', '   ', base)).toBeNull();
    expect(parseUrl('database', 'db/x.mmdb', base)).toBe('https://example.org/app/db/x.mmdb');
    expect(() => parseUrl('database', 'http://[oops', base)).toThrow('database="http://[oops" is not a URL');
    expect(() => parseUrl('avatar', 'javascript:alert(1)', base)).toThrow(/avatar="javascript:alert\(1\)": the element fetches http\(s\), blob: and data: URLs, not javascript:/);
    expect(() => parseUrl('avatar', 'file:///etc/passwd', base)).toThrow(/not file:/);
  });

  it('timeStep: (0, 1] or null; NaN, ∞, ≤ 0, > 1 and non-numbers refused, the previous value kept', () => {
    const { warnings, warn } = collect();
    expect(checkTimeStep(1 / 60, null, warn)).toBe(1 / 60);
    expect(checkTimeStep(null, 0.5, warn)).toBeNull();
    for (const bad of [NaN, Infinity, -1, 0, 2, '0.1']) expect(checkTimeStep(bad, 0.25, warn)).toBe(0.25);
    expect(warnings).toHaveLength(6);
    expect(warnings[0]).toBe('timeStep NaN refused: null (real time) or seconds per frame in (0, 1]');
  });

  it('stepsPerFrame: a whole number 1 to 16; fractions, 0, 17, NaN and non-numbers refused, the previous value kept', () => {
    const { warnings, warn } = collect();
    expect(checkStepsPerFrame(4, 1, warn)).toBe(4);
    expect(checkStepsPerFrame(16, 1, warn)).toBe(16);
    for (const bad of [0, 1.5, 17, NaN, -2, '4', null]) expect(checkStepsPerFrame(bad, 3, warn)).toBe(3);
    expect(warnings).toHaveLength(7);
    expect(warnings[0]).toBe('stepsPerFrame 0 refused: a whole number of updates per drawn frame, 1 to 16');
  });
});
