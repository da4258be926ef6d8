// examples/embed.html as a web developer would serve it: the built dist/ on a plain static
// server (not vite) under a strict Content-Security-Policy. Both avatars load with no console
// error and no CSP violation; the focused keyboard one walks on W while the other keeps its
// path; walkTo arrives within α; removing an element frees its WASM memory.
import fs from 'node:fs';
import path from 'node:path';
import { expect, test } from '@playwright/test';
import { type StaticServer, serveStatic } from './static-server.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const DIST = path.join(ROOT, 'dist');
// No blob: anywhere: the avatar's textures decode from its bytes (embedded-images.ts), not
// fetched back from blob: URLs (connect-src). data: for the page's own empty favicon.
const CSP = "default-src 'self'; script-src 'self' 'wasm-unsafe-eval'; style-src 'self' 'unsafe-inline'; img-src 'self' data:";

let server: StaticServer;
test.beforeAll(async () => {
  expect(fs.existsSync(path.join(DIST, 'mm-avatar.js')), 'dist/ is built by `npm run build` (npm test builds it)').toBe(true);
  server = await serveStatic(DIST, { 'content-security-policy': CSP });
});
test.afterAll(async () => server?.close());

type Root = { x: number; y: number; z: number; yaw: number };

test('embed.html from dist/ under a strict CSP: two avatars, keyboard only where focused, walkTo, freeing', async ({ page }) => {
  test.setTimeout(300_000);
  await page.setViewportSize({ width: 900, height: 700 });
  const errors: string[] = [];
  page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
  page.on('pageerror', (e) => errors.push(e.message));
  // CSP violations are reported to the page as events: count them from the start.
  await page.addInitScript(() => {
    (window as unknown as { __csp: string[] }).__csp = [];
    document.addEventListener('securitypolicyviolation', (e) => (window as unknown as { __csp: string[] }).__csp.push(`${e.violatedDirective} ${e.blockedURI}`));
    // When each WebGL context is made (the lazy element's should follow the eager one's first frame).
    const made: number[] = ((window as unknown as { __webgl: number[] }).__webgl = []);
    const getContext = HTMLCanvasElement.prototype.getContext;
    HTMLCanvasElement.prototype.getContext = function (this: HTMLCanvasElement, ...args: unknown[]) {
      if (/webgl/.test(String(args[0]))) made.push(performance.now());
      return (getContext as (...a: unknown[]) => unknown).apply(this, args);
    } as typeof getContext;
  });
  await page.goto(`${server.url}/examples/embed.html`);
  // Both fire `load` (the lazy one is in view). Fixed time steps from then on: 1/60 s a frame.
  await page.waitForFunction(() => [...document.querySelectorAll('mm-avatar')].every((el) => (el as unknown as { character: unknown }).character), null, { timeout: 120_000 });
  await page.evaluate(() => {
    for (const el of document.querySelectorAll('mm-avatar')) (el as unknown as { timeStep: number }).timeStep = 1 / 60;
  });
  // The lazy element, though in view, started once the eager one had drawn: the first character
  // is not held back by the second's context, shaders and character (mm-avatar.ts, afterEager).
  const [webgl, firstFrame] = await page.evaluate(() => [(window as unknown as { __webgl: number[] }).__webgl, performance.getEntriesByName('mm:first-frame')[0].startTime] as const);
  console.log(`WebGL contexts made at ${webgl.map((t) => t.toFixed(0)).join(', ')} ms; first frame ${firstFrame.toFixed(0)} ms`);
  expect(webgl.filter((t) => t >= firstFrame).length, 'the lazy element\'s context, made after the first frame').toBe(1);
  // One avatar file, one parse: the second element shows a clone of the first one's avatar
  // (avatar/shared.ts; each parse marks mm:avatar-ready — two before).
  const parses = () => page.evaluate(() => performance.getEntriesByName('mm:avatar-ready').length);
  const avatars = await page.evaluate(() => {
    const a = (id: string) => (document.getElementById(id) as unknown as { character: { avatar: { object: { uuid: string } } | null } }).character.avatar;
    return [a('keys')?.object.uuid, a('walker')?.object.uuid];
  });
  expect(avatars.every(Boolean) && avatars[0] !== avatars[1], `two avatars: ${avatars}`).toBe(true);
  expect(await parses()).toBe(1);
  const root = (id: string) => page.evaluate((id) => (document.getElementById(id) as unknown as { root: Root }).root, id);
  const following = () => page.evaluate(() => (document.getElementById('walker') as unknown as { character: { followingPath: boolean } }).character.followingPath);
  expect(await following()).toBe(true);

  // Focus the keyboard avatar by clicking it, as a visitor would; hold W until it walked 1.5 m.
  await page.locator('#keys').click({ position: { x: 20, y: 20 } });
  const a = await root('keys');
  const w = await root('walker');
  await page.keyboard.down('KeyW');
  await page.waitForFunction(
    (a) => {
      const r = (document.getElementById('keys') as unknown as { root: Root }).root;
      return Math.hypot(r.x - a.x, r.z - a.z) > 1.6;
    },
    a,
    { timeout: 180_000, polling: 200 },
  );
  await page.keyboard.up('KeyW');
  const b = await root('keys');
  const forward = [Math.sin(b.yaw), Math.cos(b.yaw)];
  const along = (b.x - a.x) * forward[0] + (b.z - a.z) * forward[1];
  console.log(`keyboard avatar walked ${along.toFixed(2)} m along its facing`);
  expect(along).toBeGreaterThan(1.5);
  // The other one never saw the keys: still on its path (a key would have taken it off), moving.
  expect(await following()).toBe(true);
  const w2 = await root('walker');
  expect(Math.hypot(w2.x - w.x, w2.z - w.z)).toBeGreaterThan(0.3);

  // walkTo arrives within α (the runtime's clamp, in the element's metres).
  const target = { x: b.x + 1.5, z: b.z - 1.0 };
  await page.evaluate((t) => (document.getElementById('keys') as unknown as { walkTo(x: number, z: number): void }).walkTo(t.x, t.z), target);
  const alpha = await page.evaluate(() => {
    const c = (document.getElementById('keys') as unknown as { character: { settings: { clamp_distance: number }; metresPerDatabaseUnit: number } }).character;
    return c.settings.clamp_distance * c.metresPerDatabaseUnit;
  });
  await page.waitForFunction(
    ([t, alpha]) => {
      const r = (document.getElementById('keys') as unknown as { root: Root }).root;
      return Math.hypot(r.x - t.x, r.z - t.z) < alpha;
    },
    [target, alpha] as const,
    { timeout: 180_000, polling: 200 },
  );
  const c = await root('keys');
  console.log(`walkTo: ${Math.hypot(c.x - target.x, c.z - target.z).toFixed(3)} m from the target (α ${alpha.toFixed(3)} m)`);
  await page.screenshot({ path: path.join(ROOT, 'test-results', 'embed.png') });

  // Removing an element frees its character and, with the last one, the shared database.
  // The same module instance the page loaded (a module is evaluated once per URL).
  const live = () => page.evaluate(async (url) => ((await import(url)) as { liveObjects(): Record<string, number> }).liveObjects(), '/mm-avatar.js');
  const before = await live();
  expect(before.characters).toBe(2);
  expect(before.databases).toBe(1);
  await page.evaluate(() => document.getElementById('walker')!.remove());
  expect((await live()).characters).toBe(1);
  // The one left keeps its avatar and goes on (the shared geometry and textures stay).
  const updates = () => page.evaluate(() => (document.getElementById('keys') as unknown as { character: { runtime: { frame: number } } }).character.runtime.frame);
  const f0 = await updates();
  await page.waitForFunction((f0) => (document.getElementById('keys') as unknown as { character: { runtime: { frame: number } } }).character.runtime.frame !== f0, f0, { timeout: 60_000 });
  await page.evaluate(() => document.getElementById('keys')!.remove());
  const after = await live();
  expect(after.characters).toBe(0);
  expect(after.retargeters).toBe(0);
  expect(after.databases).toBe(0);
  // Re-adding works: the element loads again.
  await page.evaluate(() => document.querySelector('.pair figure')!.append(Object.assign(document.createElement('mm-avatar'), { id: 'again' })));
  await page.waitForFunction(() => (document.getElementById('again') as unknown as { character: unknown }).character, null, { timeout: 120_000 });
  expect((await live()).characters).toBe(1);
  // Nobody showed the model any more: it was let go and is loaded again, whole.
  expect(await page.evaluate(() => !!(document.getElementById('again') as unknown as { character: { avatar: unknown } }).character.avatar)).toBe(true);
  expect(await parses()).toBe(2);

  expect(await page.evaluate(() => (window as unknown as { __csp: string[] }).__csp)).toEqual([]);
  expect(errors).toEqual([]);
});

test('a timeStep and stepsPerFrame set before <mm-avatar> is defined are taken through the element (not left hiding its accessors)', async ({ page }) => {
  // Any same-origin page without the element: the server's 404.
  await page.goto(`${server.url}/nothing-here`);
  const result = await page.evaluate(async (url) => {
    const el = document.createElement('mm-avatar') as HTMLElement & { timeStep: number | null; stepsPerFrame: number; warnings: string[] };
    el.timeStep = 0.05; // before the element is defined: plain own properties
    el.stepsPerFrame = 3;
    document.body.append(el);
    await import(url);
    const own = Object.hasOwn(el, 'timeStep') || Object.hasOwn(el, 'stepsPerFrame');
    const kept = [el.timeStep, el.stepsPerFrame];
    el.timeStep = 5; // the accessors refuse these (> 1 s, not a whole number) and keep 0.05 and 3
    el.stepsPerFrame = 2.5;
    const after = [el.timeStep, el.stepsPerFrame];
    const warnings = [...el.warnings];
    el.remove();
    return { own, kept, after, warnings };
  }, '/mm-avatar.js');
  expect(result.own).toBe(false);
  expect(result.kept).toEqual([0.05, 3]);
  expect(result.after).toEqual([0.05, 3]);
  expect(result.warnings.join('\n')).toContain('timeStep 5 refused');
  expect(result.warnings.join('\n')).toContain('stepsPerFrame 2.5 refused');
});
