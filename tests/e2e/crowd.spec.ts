import fs from 'node:fs';
import path from 'node:path';
import { expect, test } from '@playwright/test';

const ROOT = path.resolve(import.meta.dirname, '../..');
test.use({ viewport: { width: 320, height: 240 } });

test('crowd: 200 characters on one database and one avatar walk, steer and update by distance', async ({ page }) => {
  test.setTimeout(180_000);
  const errors: string[] = [];
  page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
  page.on('pageerror', (e) => errors.push(e.message));
  // 0.1 s an update, three updates a drawn frame: 15 updates are 1.5 s of walking on a software
  // GPU that draws 200 skinned people in ~1.8 s (the vertices: the same at any page size).
  await page.goto('/crowd.html?n=200&dt=0.1&steps=3');
  await page.waitForFunction(() => window.__crowd?.ready || window.__crowd?.error, null, { timeout: 120_000 });
  await page.waitForFunction(() => window.__crowd.updates >= 16 || window.__crowd.error, null, { timeout: 120_000, polling: 250 });
  const h = await page.evaluate(() => window.__crowd);
  expect(h.error).toBeNull();
  expect(h.notFinite).toBe(0);
  const moved = h.start.map((_, i) => (i % 2 ? NaN : Math.hypot(h.positions[i] - h.start[i], h.positions[i + 1] - h.start[i + 1]))).filter((d) => !Number.isNaN(d)).sort((a, b) => a - b);
  console.log(`crowd: 200 characters, median ${moved[100].toFixed(2)} m walked in 1.5 s; updated by level ${h.levels.join(' / ')}; ${h.frame.drawCalls} draw calls; GPU holds ${JSON.stringify(h.memory)}; per character ${JSON.stringify(h.perCharacter)}`);
  expect(moved.length).toBe(200);
  expect(moved[100]).toBeGreaterThan(0.5); // they walk
  expect(moved[10]).toBeGreaterThan(0.1); // nearly all of them
  // Far ones update less often; one update moves each near one and some of the others.
  expect(h.levels[0]).toBeGreaterThan(0);
  expect(h.levels[1] + h.levels[2]).toBeGreaterThan(0);
  expect(h.levels[0] + h.levels[1] + h.levels[2]).toBeLessThan(200);
  // One avatar's resources for everyone: a handful of geometries and textures (and each person's
  // bone texture: one skeleton each, the eyes and eyebrows ride the head bone), three draws a person.
  expect(h.memory.geometries).toBeLessThan(12);
  expect(h.memory.textures).toBeLessThan(200 + 12);
  expect(h.frame.drawCalls).toBeLessThanOrEqual(3 * 200 + 2);
  for (const v of Object.values(h.perCharacter)) expect(v).toBeGreaterThan(0);
  fs.mkdirSync(path.join(ROOT, 'test-results'), { recursive: true });
  await page.screenshot({ path: path.join(ROOT, 'test-results/crowd.png') });
  expect(errors).toEqual([]);
});
