// The benchmark's pinned recipes (scripts/bench-recipes.mjs): every take they name is in
// ../shared, the recipes the bench relies on exist, and none reads a whole folder (a glob would
// grow with ../shared and make today's numbers incomparable with tomorrow's).
import fs from 'node:fs';
import { describe, expect, it } from 'vitest';
// @ts-expect-error a plain .mjs script without types
import { PARSE_RECIPE, recipes, RUNTIME_RECIPE } from '../../scripts/bench-recipes.mjs';

type Recipe = { name: string; file: string; description: string; clips: string[] };

describe('pinned benchmark recipes', () => {
  const all = recipes() as Recipe[];

  it('has the recipes the bench runs on, each described', () => {
    const names = all.map((r) => r.name);
    expect(names).toContain(RUNTIME_RECIPE);
    expect(names).toContain(PARSE_RECIPE);
    for (const r of all) expect(r.description.length, r.name).toBeGreaterThan(20);
  });

  it('names each take one by one (no globs), and every take is there', () => {
    for (const r of all) {
      const config = JSON.parse(fs.readFileSync(r.file, 'utf8')) as { clips: { file: string }[] };
      for (const c of config.clips) expect(c.file, r.name).not.toMatch(/[*?[]/);
      for (const f of r.clips) expect(fs.existsSync(f), f).toBe(true);
    }
  });
});
