import fs from 'node:fs';
import path from 'node:path';
import { expect, test, type Page } from '@playwright/test';

// The VR page under the iwer emulator (a Quest 3 installed over Chromium's own navigator.xr with
// forceInstall), deterministic with ?dt=fixed: one frame = 1/60 s of tracker time. A skinned
// avatar plus a mirror in SwiftShader runs at a few frames per second, so scripts stay short.

const ROOT = path.resolve(import.meta.dirname, '../..');
const SHOTS = path.join(ROOT, 'test-results');

interface Frame {
  frame: number;
  head: [number, number];
  root: [number, number, number];
  handErrors: [number, number];
  status: [number, number, number];
}

/**
 * Keeps vite's HMR socket open but silent (a mock that never forwards to the server), so an edit
 * elsewhere in the repository cannot reload the page in the middle of a slow software-rendered run.
 */
async function muteHmr(page: Page): Promise<void> {
  await page.routeWebSocket(/.*/, () => undefined);
}

function collectErrors(page: Page): string[] {
  const errors: string[] = [];
  page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
  page.on('pageerror', (e) => errors.push(e.message));
  return errors;
}

async function waitFrames(page: Page, count: number): Promise<void> {
  const start = await page.evaluate(() => window.__vr.frames);
  await page.waitForFunction((n) => window.__vr.frames >= n || window.__vr.error, start + count, { timeout: 90_000, polling: 100 });
}

test('VR under iwer: enter VR, walk forward 1.5 m, avatar follows with hands on the controllers', async ({ page }) => {
  test.setTimeout(150_000);
  await page.setViewportSize({ width: 640, height: 400 });
  const errors = collectErrors(page);
  await muteHmr(page);
  await page.goto('/vr.html?emulate=1&devui=0&dt=fixed');
  await page.waitForFunction(() => window.__vr?.ready || window.__vr?.error, null, { timeout: 60_000 });
  expect(await page.evaluate(() => window.__vr.error)).toBeNull();

  // No model in this build: the heuristic is used and the page says so.
  expect(await page.evaluate(() => window.__vr.predictor)).toBe('heuristic');
  await expect(page.locator('#predictor-status')).toHaveText(/fallback: heuristic/);

  // Enter VR through the button, as a person would.
  await expect(page.locator('#enter-vr')).toHaveText('Enter VR');
  await page.locator('#enter-vr').click();
  await page.waitForFunction(() => window.__vr.inXR || window.__vr.error, null, { timeout: 30_000 });
  expect(await page.evaluate(() => window.__vr.mode)).toBe('xr');

  // Script the emulated headset and controllers per frame: stand 0.5 s, walk 1.5 m along −Z
  // (the headset's forward) in 2 s with a slight bob, stand 1 s. Controllers ride along in
  // front of the hips. Every frame's state is logged in the page.
  await page.evaluate(() => {
    type V = { set(x: number, y: number, z: number): void };
    type Q = { set(x: number, y: number, z: number, w: number): void };
    const device = window.__vr.emulator as { position: V; quaternion: Q; controllers: { left: { position: V; quaternion: Q }; right: { position: V; quaternion: Q } } };
    const log: unknown[] = [];
    (window as unknown as { __log: unknown[] }).__log = log;
    let start = -1;
    window.__vr.beforeFrame = (frame) => {
      if (start < 0) start = frame;
      const t = (frame - start) / 60;
      const x = Math.min(1, Math.max(0, (t - 0.5) / 2));
      const z = -1.5 * x * x * (3 - 2 * x);
      const bob = t > 0.5 && t < 2.5 ? 0.015 * Math.sin(2 * Math.PI * 1.8 * t) : 0;
      device.position.set(0, 1.6 + bob, z);
      device.quaternion.set(0, 0, 0, 1); // looking along −Z
      device.controllers.left.position.set(-0.22, 1.0, z - 0.25);
      device.controllers.right.position.set(0.22, 1.0, z - 0.25);
      device.controllers.left.quaternion.set(0, 0, 0, 1);
      device.controllers.right.quaternion.set(0, 0, 0, 1);
      const h = window.__vr;
      log.push({ frame: t, head: [...h.head], root: [...h.root], handErrors: [...h.handErrors], status: [...h.trackerStatus] });
    };
  });
  await waitFrames(page, 60 * 3.5);
  const log = (await page.evaluate(() => (window as unknown as { __log: unknown[] }).__log)) as Frame[];
  const end = log[log.length - 1];
  if (process.env.VR_LOG) for (const f of log) console.log(JSON.stringify(f));

  // The head moved ~1.5 m forward; the avatar root followed it.
  expect(end.head[1]).toBeLessThan(-1.35); // the head centre is 0.1 m behind the eyes
  expect(end.root[2]).toBeLessThan(-1.2);
  const gap = (f: Frame) => Math.hypot(f.root[0] - f.head[0], f.root[2] - f.head[1]);
  const alpha = 0.2; // the page's default clamp
  const drive = await page.evaluate(() => window.__vr.drive);
  console.log(`drive: ${drive}; root↔head gap: end ${gap(end).toFixed(3)} m, worst ${Math.max(...log.map(gap)).toFixed(3)} m`);
  if (drive === 'tracked') {
    // The runtime's VR mode clamps the root within α of the head's floor position, every frame.
    for (const f of log) expect(gap(f)).toBeLessThan(alpha + 0.005);
  } else {
    // The stick-input stand-in only pulls the root back: within α once the user stands still.
    expect(gap(end)).toBeLessThan(alpha + 0.02);
  }

  // Hands within 1 cm of the controllers on every tracked frame once the avatar has turned to
  // the headset (it starts facing +Z, the emulated headset looks along −Z: a turn in place).
  const settled = log.filter((f) => f.frame >= 0.6);
  expect(settled.every((f) => f.status[1] === 0 && f.status[2] === 0)).toBe(true);
  const worstHand = Math.max(...settled.flatMap((f) => f.handErrors));
  console.log(`worst hand error ${(worstHand * 1000).toFixed(3)} mm over ${settled.length} frames`);
  expect(worstHand).toBeLessThan(0.01);

  fs.mkdirSync(SHOTS, { recursive: true });
  await page.screenshot({ path: path.join(SHOTS, 'vr-first-person.png') });

  // Leave VR: the desktop view is the spectator camera following the avatar.
  await page.evaluate(() => window.__vr.exitVR());
  await page.waitForFunction(() => !window.__vr.inXR, null, { timeout: 30_000 });
  await waitFrames(page, 3);
  await page.screenshot({ path: path.join(SHOTS, 'vr-spectator.png') });
  expect(errors).toEqual([]);
});

test('replay of a scripted session on the desktop page, with the VR update benchmark', async ({ page }) => {
  test.setTimeout(120_000);
  await page.setViewportSize({ width: 640, height: 400 });
  const errors = collectErrors(page);
  await muteHmr(page);
  await page.goto('/vr.html?replay=scripted&bench=1&dt=fixed&mirror=0');
  await page.waitForFunction(() => window.__vr?.ready || window.__vr?.error, null, { timeout: 90_000 });
  expect(await page.evaluate(() => window.__vr.error)).toBeNull();
  const bench = await page.evaluate(() => window.__vr.bench);
  expect(bench).not.toBeNull();
  console.log(`VR update over the replay (${bench?.frames} frames at 72 Hz): median ${bench?.median.toFixed(3)} ms, p95 ${bench?.p95.toFixed(3)} ms, mean ${bench?.mean.toFixed(3)} ms`);
  expect(bench?.frames).toBeGreaterThan(700);
  expect(bench?.median).toBeLessThan(5); // the target is ≤ 1 ms on a desktop; this machine is shared and slow
  await waitFrames(page, 90); // 1.5 s of replay: standing, then starting to walk
  const h = await page.evaluate(() => ({ mode: window.__vr.mode, hand: [...window.__vr.handErrors] }));
  expect(h.mode).toBe('replay');
  expect(Math.max(...h.hand)).toBeLessThan(0.01);
  await page.screenshot({ path: path.join(SHOTS, 'vr-replay.png') });
  expect(errors).toEqual([]);
});
