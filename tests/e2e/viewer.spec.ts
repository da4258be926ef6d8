import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { expect, test, type ConsoleMessage, type Page } from '@playwright/test';

const ROOT = path.resolve(import.meta.dirname, '../..');
const MMDB = path.join(ROOT, 'wasm-core/target/opt/mmdb');
const DB = path.join(ROOT, 'public/databases/locomotion.mmdb');

function cliNumFrames(): number {
  const out = execFileSync(MMDB, ['inspect', DB, '--json'], { encoding: 'utf8' });
  return (JSON.parse(out) as { num_frames: number }).num_frames;
}

/** Collects console errors and uncaught page errors. */
function collectErrors(page: Page): string[] {
  const errors: string[] = [];
  page.on('console', (m: ConsoleMessage) => {
    if (m.type() === 'error') errors.push(`console: ${m.text()}`);
  });
  page.on('pageerror', (e) => errors.push(`pageerror: ${e.message}`));
  return errors;
}

const viewer = (page: Page) => page.evaluate(() => ({ ...window.__viewer }));

test('viewer plays the locomotion database', async ({ page }) => {
  const errors = collectErrors(page);
  await page.goto('/viewer.html');
  await page.waitForFunction(() => window.__viewer?.ready || window.__viewer?.error, null, { timeout: 30_000 });
  const state = await viewer(page);
  expect(state.error).toBeNull();
  expect(state.numFrames).toBe(cliNumFrames());
  expect(state.playing).toBe(true);
  expect(state.clipName).not.toBe('');
  await expect(page.locator('#error-box')).toBeHidden();

  // Plays: the frame advances over about a second.
  const f0 = state.frame;
  await page.waitForTimeout(1000);
  const f1 = (await viewer(page)).frame;
  expect(f1).not.toBe(f0);
  await expect(page.locator('#hud')).toContainText(`/ ${state.numFrames}`);

  // Pause, then the scrubber moves the frame.
  await page.locator('#play').click();
  await expect.poll(async () => (await viewer(page)).playing).toBe(false);
  const target = Math.floor(state.numFrames / 2);
  await page.locator('#scrubber').fill(String(target));
  await expect.poll(async () => (await viewer(page)).frame).toBe(target);
  await page.waitForTimeout(300);
  expect((await viewer(page)).frame).toBe(target); // stays paused

  // Back to the first frame for a stable screenshot.
  await page.locator('#scrubber').fill('0');
  await expect.poll(async () => (await viewer(page)).frame).toBe(0);
  await page.waitForTimeout(500); // let the follow camera settle
  fs.mkdirSync(path.join(ROOT, 'test-results'), { recursive: true });
  await page.screenshot({ path: path.join(ROOT, 'test-results/viewer.png') });

  expect(errors).toEqual([]);
});

test('a missing database shows an error in the page', async ({ page }) => {
  await page.goto('/viewer.html?db=databases/missing.mmdb');
  const box = page.locator('#error-box');
  await expect(box).toBeVisible();
  await expect(box).toContainText('missing.mmdb');
  const state = await viewer(page);
  expect(state.error).toContain('missing.mmdb');
  expect(state.ready).toBe(false);
});

test('a corrupt database shows the checksum error in the page', async ({ page }) => {
  const bytes = fs.readFileSync(DB);
  bytes[Math.floor(bytes.length / 2)] ^= 0xff;
  await page.route('**/databases/corrupt.mmdb', (route) =>
    route.fulfill({ status: 200, contentType: 'application/octet-stream', body: bytes }),
  );
  await page.goto('/viewer.html?db=databases/corrupt.mmdb');
  const box = page.locator('#error-box');
  await expect(box).toBeVisible();
  await expect(box).toContainText(/checksum/i);
  // The toolbar says what failed, with a Retry (the page loads again).
  await expect(page.locator('#hud')).toContainText(/corrupt\.mmdb: invalid \.mmdb: checksum mismatch/);
  await expect(page.locator('#hud button.retry')).toHaveText('Retry');
  expect((await viewer(page)).ready).toBe(false);
});
