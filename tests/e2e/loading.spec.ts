// Loading and failure states as a visitor sees them (issue "Load fast and fail clearly"): an
// offline database (message + Retry that then loads), a stalled download named after 5 s, a
// missing avatar (the skeleton walks, with a note), a mistyped ?db= (vite's HTML fallback, and
// the production server's 404), the database list from the generated index, and the second
// visit working offline from the caches (production server: dist/ as `npm start` serves it).
// Each test saves the screenshot of what the user sees to test-results/load-*.png.
import fs from 'node:fs';
import path from 'node:path';
import { expect, test, type Page } from '@playwright/test';
import { type SiteServer, startSiteServer } from '../../server/serve.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const SHOTS = path.join(ROOT, 'test-results');
const shot = (page: Page, name: string) => page.screenshot({ path: path.join(SHOTS, `load-${name}.png`) });
const status = (page: Page) => page.locator('mm-avatar .status');

test.beforeAll(() => fs.mkdirSync(SHOTS, { recursive: true }));

test('offline database: the element names the URL and offers Retry, which then loads', async ({ page }) => {
  test.setTimeout(120_000);
  const db = '**/databases/locomotion*.mmdb*'; // the first part, then the whole it falls back to
  await page.route(db, (route) => route.abort('internetdisconnected'));
  await page.goto('/');
  await expect(status(page)).toHaveClass(/error/);
  await expect(status(page)).toContainText(/could not fetch the database http:\/\/127\.0\.0\.1:\d+\/databases\/locomotion\.mmdb.*offline, or the server is down/);
  const retry = page.locator('mm-avatar .status button');
  await expect(retry).toHaveText('Retry');
  await shot(page, 'offline-db');
  await page.unroute(db);
  await retry.click();
  await page.waitForFunction(() => window.__mm?.ready, null, { timeout: 90_000 });
  await expect(status(page)).toBeHidden();
});

test('stalled database: after 5 s the element says what it is waiting for', async ({ page }) => {
  test.setTimeout(60_000);
  await page.route('**/databases/locomotion.first.mmdb*', () => undefined); // never answered
  await page.goto('/');
  await expect(status(page)).toContainText('Loading', { timeout: 10_000 });
  const t0 = Date.now();
  await expect(status(page)).toContainText(/Still waiting for the database \/databases\/locomotion\.first\.mmdb: nothing received for 5 s/, { timeout: 15_000 });
  const waited = Date.now() - t0;
  console.log(`stall reported after ${waited} ms of the page's loading status`);
  await expect(status(page)).toHaveClass(/stalled/);
  await shot(page, 'stalled-db');
});

test('missing avatar: the skeleton walks and a note names the URL (demo and VR page)', async ({ page }) => {
  test.setTimeout(120_000);
  await page.goto('/?avatar=avatars/missing.glb');
  await page.waitForFunction(() => window.__mm?.ready, null, { timeout: 90_000 });
  await expect(status(page)).toContainText(/Avatar unavailable, showing the skeleton: could not load the avatar http:\/\/127\.0\.0\.1:\d+\/avatars\/missing\.glb/);
  expect(await page.evaluate(() => window.__mm.avatar)).toBe('');
  await expect(page.locator('#error-box')).toContainText('avatars/missing.glb');
  await shot(page, 'missing-avatar');

  await page.setViewportSize({ width: 640, height: 400 });
  await page.goto('/vr.html?avatar=avatars/missing.glb&mirror=0');
  await page.waitForFunction(() => window.__vr?.ready || window.__vr?.error, null, { timeout: 90_000 });
  expect(await page.evaluate(() => window.__vr.error)).toBeNull();
  await expect(page.locator('#error-box')).toContainText(/Avatar unavailable, showing the skeleton: .*avatars\/missing\.glb/);
  await shot(page, 'missing-avatar-vr');
});

test('first frames compile only what they draw: shader programs linked before the first frame, demo and VR page', async ({ page }) => {
  // Each program is ~10 ms (unlit) to ~40 ms (the avatar's) of a software GPU's first frame.
  // Before: the demo's overlays took 8 unlit programs (now 4, overlay-materials.ts), the VR
  // page's mirror 4 more (now from the second frame on, mirror.ts).
  await page.addInitScript(() => {
    const w = window as unknown as { __links: number };
    w.__links = 0;
    for (const C of [WebGL2RenderingContext, WebGLRenderingContext]) {
      const link = C.prototype.linkProgram;
      C.prototype.linkProgram = function (this: WebGLRenderingContext, program: WebGLProgram) {
        if (performance.getEntriesByName('mm:first-frame').length === 0) w.__links++;
        return link.call(this, program);
      };
    }
  });
  for (const [url, most] of [['/', 7], ['/vr.html', 4]] as const) {
    await page.goto(url);
    await page.waitForFunction(() => performance.getEntriesByName('mm:first-frame').length > 0, null, { timeout: 120_000 });
    const links = await page.evaluate(() => (window as unknown as { __links: number }).__links);
    console.log(`${url}: ${links} shader programs linked before the first frame (at most ${most})`);
    expect(links).toBeLessThanOrEqual(most);
  }
});

test('VR page: the heuristic drives from the first frame until the network has loaded; iwer only with ?emulate=1', async ({ page }) => {
  test.setTimeout(120_000);
  const requested: string[] = [];
  page.on('request', (r) => requested.push(r.url()));
  let release: () => void = () => {};
  const held = new Promise<void>((r) => (release = r));
  await page.route('**/models/orientation.onnx*', async (route) => (await held, route.continue()));
  await page.setViewportSize({ width: 640, height: 400 });
  await page.goto('/vr.html?mirror=0&dt=fixed');
  await page.waitForFunction(() => window.__vr?.ready || window.__vr?.error, null, { timeout: 90_000 });
  const f0 = await page.evaluate(() => window.__vr.frames);
  await page.waitForFunction((f) => window.__vr.frames > f + 5, f0, { timeout: 60_000 });
  expect(await page.evaluate(() => [window.__vr.predictor, window.__vr.networkLoaded])).toEqual(['heuristic', false]);
  await expect(page.locator('#predictor-status')).toHaveText('body yaw: heuristic (loading the network…)');
  await shot(page, 'vr-heuristic-first');
  release();
  await expect(page.locator('#predictor-status')).toHaveText('body yaw: network', { timeout: 60_000 });
  const runs = await page.evaluate(() => window.__vr.predictorRuns);
  await page.waitForFunction((r) => window.__vr.predictorRuns > r + 5, runs, { timeout: 60_000 });
  expect(requested.filter((u) => /iwer|devui/.test(u))).toEqual([]);
});

test('a mistyped ?db= (the dev server answers with its HTML page) names the URL; Retry is offered', async ({ page }) => {
  await page.goto('/?db=databases/locomotoin.mmdb');
  await expect(status(page)).toContainText(/could not load the database http:\/\/127\.0\.0\.1:\d+\/databases\/locomotoin\.mmdb: not found \(the server answered with an HTML page\)/, { timeout: 30_000 });
  await expect(page.locator('mm-avatar .status button')).toHaveText('Retry');
  await shot(page, 'wrong-db');
});

test('the database list offers exactly the databases the generated index lists, each served', async ({ page, request }) => {
  test.setTimeout(90_000);
  const index = (await (await request.get('/databases/index.json')).json()) as { databases: { name: string; file: string; bytes: number }[] };
  expect(index.databases.length).toBeGreaterThan(0);
  for (const d of index.databases) {
    const head = await request.head(`/databases/${d.file}`);
    expect(head.status(), d.file).toBe(200);
    expect(Number(head.headers()['content-length']), d.file).toBe(d.bytes);
  }
  await page.goto('/');
  await page.waitForFunction(() => window.__mm?.ready, null, { timeout: 90_000 });
  const select = page.locator('.lil-gui select').first();
  await expect.poll(async () => (await select.locator('option').allTextContents()).sort()).toEqual(index.databases.map((d) => d.name).sort());
});

test('attribute typos in a page: a non-URL database is named in the element, unknown values warned about, the character still walks', async ({ page }) => {
  test.setTimeout(120_000);
  await page.goto('/');
  await page.waitForFunction(() => window.__mm?.ready, null, { timeout: 90_000 });
  const result = await page.evaluate(async () => {
    const bad = document.createElement('mm-avatar') as HTMLElement & { warnings: string[] };
    bad.setAttribute('database', 'http://[oops');
    bad.style.cssText = 'width:200px;height:150px;position:fixed;left:0;top:0';
    document.body.append(bad);
    const odd = document.createElement('mm-avatar') as HTMLElement & { warnings: string[]; timeStep: number | null };
    odd.setAttribute('avatar', 'none');
    odd.setAttribute('controls', 'keybaord path');
    odd.setAttribute('camera', 'orbit');
    odd.style.cssText = 'width:200px;height:150px;position:fixed;right:0;top:0';
    document.body.append(odd);
    odd.timeStep = NaN;
    await new Promise((r) => setTimeout(r, 500));
    return { status: bad.shadowRoot?.querySelector('.status')?.textContent ?? '', warnings: odd.warnings, timeStep: odd.timeStep };
  });
  expect(result.status).toContain('database="http://[oops" is not a URL');
  expect(result.warnings.join('\n')).toContain('unknown control "keybaord" ignored');
  expect(result.warnings.join('\n')).toContain('camera="orbit" is not one of follow, fixed; using follow');
  expect(result.warnings.join('\n')).toContain('timeStep NaN refused');
  expect(result.timeStep).toBeNull();
  const u0 = await page.evaluate(() => window.__mm.updates);
  await page.waitForFunction((u) => window.__mm.updates > u + 5, u0, { timeout: 30_000 });
});

test.describe('production server (dist/)', () => {
  let server: SiteServer;
  test.beforeAll(async () => {
    expect(fs.existsSync(path.join(ROOT, 'dist', 'sw.js')), 'dist/ is built by `npm run build` (npm test builds it)').toBe(true);
    server = await startSiteServer({ root: path.join(ROOT, 'dist'), port: 0, host: '127.0.0.1' });
  });
  test.afterAll(async () => server?.close());

  test('a wrong ?db= is a 404 naming the URL', async ({ page }) => {
    await page.goto(`${server.url}/?db=databases/nope.mmdb`);
    await expect(status(page)).toContainText(/could not load the database http:\/\/127\.0\.0\.1:\d+\/databases\/nope\.mmdb: HTTP 404/, { timeout: 30_000 });
    await shot(page, 'wrong-db-production');
  });

  test('the second visit works offline: pages from the service worker, assets from Cache Storage', async ({ page, context }) => {
    test.setTimeout(180_000);
    const errors: string[] = [];
    page.on('pageerror', (e) => errors.push(e.message));
    await page.goto(`${server.url}/`);
    await page.waitForFunction(() => window.__mm?.ready, null, { timeout: 120_000 });
    // The first visit leaves: an active service worker with the shell (the page and every
    // script and style it loaded), the library's assets.
    const missing = () =>
      page.evaluate(async () => {
        const reg = await navigator.serviceWorker.getRegistration();
        const cached = new Set<string>();
        for (const k of await caches.keys()) for (const r of await (await caches.open(k)).keys()) cached.add(r.url.split('?')[0]);
        const loaded = performance.getEntriesByType('resource').map((e) => e.name.split('?')[0]).filter((u) => u.startsWith(location.origin) && /\.(js|css)$/.test(u));
        const need = [location.origin + '/', ...loaded, ...['mmcore_bg.wasm', 'databases/locomotion.first.mmdb', 'databases/locomotion.mmdb', 'avatars/ubc_male.glb'].map((f) => `${location.origin}/${f}`)];
        return [...(reg?.active ? [] : ['an active service worker']), ...need.filter((u) => !cached.has(u))];
      });
    await expect.poll(missing, { timeout: 60_000, intervals: [500] }).toEqual([]);
    await context.setOffline(true);
    // What the offline visit asked for and did not get: printed when the page does not come up.
    const failed: string[] = [];
    const consoleLines: string[] = [];
    page.on('requestfailed', (r) => failed.push(`${r.url()} (${r.failure()?.errorText}, sw: ${r.serviceWorker() ? 'yes' : 'no'})`));
    page.on('response', (r) => !r.ok() && failed.push(`${r.url()}: HTTP ${r.status()}`));
    page.on('console', (m) => consoleLines.push(`${m.type()}: ${m.text()}`));
    await page.reload();
    try {
      await page.waitForFunction(() => window.__mm?.ready, null, { timeout: 60_000 });
    } catch (e) {
      console.log(`offline reload did not become ready.\nfailed requests:\n  ${failed.join('\n  ')}\nconsole:\n  ${consoleLines.join('\n  ')}\nstatus: ${await status(page).textContent().catch(() => '?')}`);
      throw e;
    }
    const u0 = await page.evaluate(() => window.__mm.updates);
    await page.waitForFunction((u) => window.__mm.updates > u + 10, u0, { timeout: 60_000 });
    expect(await page.evaluate(() => navigator.onLine)).toBe(false);
    expect(await page.evaluate(() => window.__mm.avatar)).toBe('ubc_male.glb');
    await expect(status(page)).toBeHidden();
    await shot(page, 'offline-second-visit');
    await context.setOffline(false);
    expect(errors).toEqual([]);
    // A repeat visit takes each preloaded asset through its preload (the service worker answers
    // it from the cache), not from the cache beside it: none left unused, which Chromium warns
    // about some seconds after the load event (three warnings a repeat visit before).
    await page.close();
    const warnings: string[] = [];
    const again = await context.newPage();
    again.on('console', (m) => m.type() === 'warning' && warnings.push(m.text()));
    await again.goto(`${server.url}/`);
    await again.waitForFunction(() => window.__mm?.ready, null, { timeout: 60_000 });
    // The worker's static routes: the browser read the scripts, styles and versioned assets from
    // Cache Storage without running the fetch handler (web/sw/sw.js).
    const sources = await again.evaluate(() =>
      performance
        .getEntriesByType('resource')
        .filter((e) => e.name.startsWith(location.origin) && (/\/assets\/[^?]+\.(js|css)$/.test(e.name) || /\?v=/.test(e.name)))
        .map((e) => `${e.name.replace(location.origin, '')}: ${(e as PerformanceResourceTiming & { workerFinalSourceType?: string }).workerFinalSourceType}`),
    );
    expect(sources.length).toBeGreaterThan(5);
    expect(sources.filter((s) => !s.endsWith(': cache'))).toEqual([]);
    // The page itself too: from the worker's shell, no round trip to the network.
    const pageSource = await again.evaluate(() => (performance.getEntriesByType('navigation')[0] as PerformanceNavigationTiming & { workerFinalSourceType?: string }).workerFinalSourceType);
    expect(pageSource).toBe('cache');
    const loadEnd = await again.evaluate(() => (performance.getEntriesByType('navigation')[0] as PerformanceNavigationTiming).loadEventEnd);
    await again.waitForFunction((end) => performance.now() > end + 6000, loadEnd, { timeout: 30_000 });
    await again.close();
    expect(warnings.filter((w) => /preload/i.test(w))).toEqual([]);
  });
});
