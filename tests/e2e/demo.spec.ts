import fs from 'node:fs';
import path from 'node:path';
import { expect, test, type Page } from '@playwright/test';

const ROOT = path.resolve(import.meta.dirname, '../..');
const hook = (page: Page) => page.evaluate(() => ({ ...window.__mm, root: [...window.__mm.root], steps: [...window.__mm.steps] }));

/** Holds `keys` for `frames` runtime updates (fixed dt: 60 updates = 1 s). */
async function hold(page: Page, keys: string[], frames: number): Promise<void> {
  const start = (await hook(page)).updates;
  for (const k of keys) await page.keyboard.down(k);
  await page.waitForFunction((n) => window.__mm.updates >= n, start + frames, { timeout: 60_000, polling: 50 });
  for (const k of keys) await page.keyboard.up(k);
}

/** Signed smallest difference of two angles. */
const angleDiff = (a: number, b: number) => Math.atan2(Math.sin(a - b), Math.cos(a - b));

test('the character walks, turns and strafes under the keyboard', async ({ page }) => {
  // ~330 frames of a skinned avatar in software WebGL (SwiftShader): ~1 min alone on 2 cores.
  test.setTimeout(240_000);
  const errors: string[] = [];
  page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
  page.on('pageerror', (e) => errors.push(e.message));
  await page.goto('/demo.html?dt=fixed');
  await page.waitForFunction(() => window.__mm?.ready || window.__mm?.error, null, { timeout: 30_000 });
  expect((await hook(page)).error).toBeNull();
  await expect(page.getByText('Motion matching')).toBeVisible(); // the settings panel
  await page.locator('#viewport canvas').click(); // focus

  // W for 2 s: > 1.5 m along the facing, both feet stepping.
  const a = await hook(page);
  await hold(page, ['KeyW'], 120);
  const b = await hook(page);
  const forward = [Math.sin(b.yaw), Math.cos(b.yaw)];
  const along = (b.root[0] - a.root[0]) * forward[0] + (b.root[2] - a.root[2]) * forward[1];
  expect(along).toBeGreaterThan(1.5);
  expect(b.steps[0] - a.steps[0]).toBeGreaterThan(0);
  expect(b.steps[1] - a.steps[1]).toBeGreaterThan(0);

  // A (camera-left) for 1.5 s: the facing turns by more than 60°.
  await hold(page, ['KeyA'], 90);
  const c = await hook(page);
  expect(Math.abs(angleDiff(c.yaw, b.yaw))).toBeGreaterThan((60 * Math.PI) / 180);

  // Strafe (F) moving right for 2 s: the facing stays within 10°.
  await hold(page, ['KeyF', 'KeyD'], 120);
  const d = await hook(page);
  expect(Math.abs(angleDiff(d.yaw, c.yaw))).toBeLessThan((10 * Math.PI) / 180);
  expect(Math.hypot(d.root[0] - c.root[0], d.root[2] - c.root[2])).toBeGreaterThan(0.5);

  fs.mkdirSync(path.join(ROOT, 'test-results'), { recursive: true });
  await page.screenshot({ path: path.join(ROOT, 'test-results/demo.png') });
  expect(errors).toEqual([]);
});
