import fs from 'node:fs';
import path from 'node:path';
import { expect, test, type Page } from '@playwright/test';
import type { PoseCheck } from '../../web/src/vr/replay-bench.ts';

// The VR page under the iwer emulator (a Quest 3 installed over Chromium's own navigator.xr with
// forceInstall), deterministic with ?dt=fixed: one frame = 1/60 s of tracker time. A skinned
// avatar plus a mirror in SwiftShader runs at a few frames per second, so scripts stay short.

const ROOT = path.resolve(import.meta.dirname, '../..');
const SHOTS = path.join(ROOT, 'test-results');

interface Frame {
  t: number;
  /** The root's target on the floor (the predicted hips, else the head centre): what α clamps to. */
  target: [number, number];
  hmdY: number;
  root: [number, number, number];
  rootYaw: number;
  handErrors: [number, number];
  status: [number, number, number];
  hips: number;
  toes: [number, number];
  runs: number;
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

async function waitFrames(page: Page, count: number, timeout = 90_000): Promise<void> {
  const start = await page.evaluate(() => window.__vr.frames);
  await page.waitForFunction((n) => window.__vr.frames >= n || window.__vr.error, start + count, { timeout, polling: 100 });
}

/**
 * The scripted user (seconds from the start, 60 frames per second of tracker time): stand 0.5 s;
 * walk 1.2 m along −Z (the headset's forward) in 1.8 s; side-step 0.5 m to the right (+X) in 1 s;
 * turn in place a full 360° over 2.5 s; crouch 0.5 m (eyes 1.6 → 1.1 m), hold; stand up. The
 * controllers ride in front of the hips, turning with the body.
 */
const SCRIPT = `
  (t) => {
    const s = (x) => (x <= 0 ? 0 : x >= 1 ? 1 : x * x * (3 - 2 * x));
    const ph = (a, len) => s((t - a) / len);
    const z = -1.2 * ph(0.5, 1.8);
    const x = 0.5 * ph(2.5, 1);
    const yaw = 2 * Math.PI * ph(3.7, 2.5);
    const crouch = ph(6.3, 0.8) - ph(7.6, 0.6);
    const y = 1.6 - 0.5 * crouch + (t > 0.5 && t < 2.3 ? 0.015 * Math.sin(2 * Math.PI * 1.8 * t) : 0);
    return { x, y, z, yaw };
  }`;
const SCRIPT_SECONDS = 8.3;

async function openVr(page: Page, query: string): Promise<string[]> {
  await page.setViewportSize({ width: 320, height: 200 });
  const errors = collectErrors(page);
  await muteHmr(page);
  await page.goto(`/vr.html?emulate=1&devui=0&dt=fixed${query}`);
  await page.waitForFunction(() => window.__vr?.ready || window.__vr?.error, null, { timeout: 60_000 });
  expect(await page.evaluate(() => window.__vr.error)).toBeNull();
  return errors;
}

/**
 * From the next frame on, moves the emulated headset and controllers along `SCRIPT` (60 frames a
 * second of tracker time), calibrates at 1.6 m once standing, and logs every frame's state in
 * the page (`window.__log`).
 */
async function startScript(page: Page): Promise<void> {
  await page.evaluate((script) => {
    type V = { set(x: number, y: number, z: number): void };
    type Q = { set(x: number, y: number, z: number, w: number): void };
    const device = window.__vr.emulator as { position: V; quaternion: Q; controllers: { left: { position: V; quaternion: Q }; right: { position: V; quaternion: Q } } };
    const motion = (0, eval)(script) as (t: number) => { x: number; y: number; z: number; yaw: number };
    const log: unknown[] = [];
    (window as unknown as { __log: unknown[] }).__log = log;
    let start = -1;
    window.__vr.beforeFrame = (frame) => {
      const h = window.__vr;
      if (start >= 0) {
        log.push({ t: (frame - 1 - start) / 60, target: [...h.target], hmdY: h.hmd[1], root: [...h.root], rootYaw: h.rootYaw, handErrors: [...h.handErrors], status: [...h.trackerStatus], hips: h.hipsHeight, toes: [...h.toeHeights], runs: h.predictorRuns });
      } else start = frame;
      const t = (frame - start) / 60;
      if (t === 0.25) h.calibrate(1.6);
      const m = motion(t);
      // Looking along −Z at yaw 0; turning by `yaw` about +Y (counter-clockwise seen from above).
      const qy = Math.sin(m.yaw / 2), qw = Math.cos(m.yaw / 2);
      device.position.set(m.x, m.y, m.z);
      device.quaternion.set(0, qy, 0, qw);
      const c = Math.cos(m.yaw), s = Math.sin(m.yaw);
      for (const [side, lateral] of [['left', -0.22], ['right', 0.22]] as const) {
        // Body frame: right = +X, forward = −Z at yaw 0; hands 0.25 m forward, at 1.0 m (0.3 m above the crouch's lowest).
        const lx = lateral, lz = -0.25;
        const ctrl = device.controllers[side];
        ctrl.position.set(m.x + c * lx + s * lz, Math.max(0.55, m.y - 0.6), m.z - s * lx + c * lz);
        ctrl.quaternion.set(0, qy, 0, qw);
      }
    };
  }, SCRIPT);
}

/** Enters VR through the button, as a person would. */
async function enterVr(page: Page): Promise<void> {
  await expect(page.locator('#enter-vr')).toHaveText('Enter VR');
  await page.locator('#enter-vr').click();
  await page.waitForFunction(() => window.__vr.inXR || window.__vr.error, null, { timeout: 30_000 });
  expect(await page.evaluate(() => window.__vr.mode)).toBe('xr');
}

// The scripted run draws the headset's two views only: the mirror (drawn again for every camera
// that sees it) and the spectator made each frame three times as long, and what they show is
// the next test's.
test('VR under iwer: enter VR; scripted walk, side-step, 360° turn and crouch; avatar within α, hands on the controllers, the network runs every frame', async ({ page }) => {
  test.setTimeout(360_000); // ~1 min alone; software WebGL under a loaded 2-core machine takes longer
  const errors = await openVr(page, '&mirror=0&spectator=0');

  // The network loads after the first frame (the heuristic drives meanwhile), then is the
  // predictor; the page says so.
  await page.waitForFunction(() => window.__vr.networkLoaded || window.__vr.predictorFallback, null, { timeout: 60_000 });
  expect(await page.evaluate(() => [window.__vr.networkLoaded, window.__vr.predictor])).toEqual([true, 'network']);
  await expect(page.locator('#predictor-status')).toHaveText('body yaw: network');

  await enterVr(page);
  // First person: the headset's cameras draw the headless copy, not the whole avatar.
  await waitFrames(page, 2);
  expect(await page.evaluate(() => window.__vr.headTrianglesHidden)).toBeGreaterThan(100);
  expect(await page.evaluate(() => window.__vr.views())).toMatchObject({ headsetWhole: false, headsetHeadless: true });

  await startScript(page);
  await waitFrames(page, Math.ceil(60 * SCRIPT_SECONDS) + 2, 300_000);
  const log = (await page.evaluate(() => (window as unknown as { __log: unknown[] }).__log)) as Frame[];
  if (process.env.VR_LOG) for (const f of log) console.log(JSON.stringify(f));
  const at = (t: number) => log.reduce((a, b) => (Math.abs(b.t - t) < Math.abs(a.t - t) ? b : a));
  const gap = (f: Frame) => Math.hypot(f.root[0] - f.target[0], f.root[2] - f.target[1]);
  const alpha = await page.evaluate(() => window.__vr.alpha);
  expect(alpha).toBe(0.2);

  // Walk forward: the root followed the head 1.2 m along −Z.
  expect(at(2.4).root[2]).toBeLessThan(-0.95);
  // Side-step right: +0.5 m in x.
  expect(at(3.6).root[0] - at(2.4).root[0]).toBeGreaterThan(0.3);
  // Turn in place: the root yaw went all the way round (unwrapped ≥ 300°) while the root stayed.
  let turned = 0;
  for (let k = 1; k < log.length; k++) {
    if (log[k].t < 3.6 || log[k].t > 6.3) continue;
    let d = log[k].rootYaw - log[k - 1].rootYaw;
    d -= 2 * Math.PI * Math.round(d / (2 * Math.PI));
    turned += d;
  }
  console.log(`turn in place: root yaw turned ${((turned * 180) / Math.PI).toFixed(0)}°`);
  expect(Math.abs(turned)).toBeGreaterThan((300 * Math.PI) / 180);
  // Within α of its target on every frame (the runtime's clamp): the predicted hips, else the head centre.
  const worstGap = Math.max(...log.map(gap));
  console.log(`root↔target gap: worst ${worstGap.toFixed(3)} m (α ${alpha})`);
  expect(worstGap).toBeLessThan(alpha + 0.005);

  // Crouch: the avatar's hips went down ~0.45 m (0.5 m minus the dead band), feet on the floor.
  // Standing: the hips' median over the turn in place (3.7–6.3 s, upright) — one frame of it is
  // a pivot step whose mocap dips the hips up to 12 cm (0.77–0.90 m with every network tried).
  const crouched = at(7.5);
  const upright = log.filter((f) => f.t >= 3.7 && f.t <= 6.3).map((f) => f.hips).sort((a, b) => a - b);
  const standing = { hips: upright[upright.length >> 1] };
  console.log(`hips ${standing.hips.toFixed(3)} (standing, median) → ${crouched.hips.toFixed(3)} m; toes crouched ${crouched.toes.map((v) => v.toFixed(3))} m; eyes ${crouched.hmdY.toFixed(2)} m`);
  expect(standing.hips - crouched.hips).toBeGreaterThan(0.35);
  expect(Math.max(...crouched.toes)).toBeLessThan(0.08);
  expect(Math.min(...crouched.toes)).toBeGreaterThan(-0.03);
  expect(at(8.25).hips).toBeGreaterThan(standing.hips - 0.08); // standing up again
  // Rising, the hips never sink below where the crouch held them (leaving the crouch data once
  // dropped them 26 cm for a frame: the whole IK drop on a pose still coming up out of it).
  const rising = Math.min(...log.filter((f) => f.t >= 7.6 && f.t <= 8.3).map((f) => f.hips));
  console.log(`standing up: hips lowest ${rising.toFixed(3)} m (crouched ${crouched.hips.toFixed(3)})`);
  expect(rising).toBeGreaterThan(crouched.hips - 0.02);

  // Hands within 1 cm of the controllers on every frame once the avatar faced the headset.
  const settled = log.filter((f) => f.t >= 0.6);
  expect(settled.every((f) => f.status[1] === 0 && f.status[2] === 0)).toBe(true);
  const worstHand = Math.max(...settled.flatMap((f) => f.handErrors));
  console.log(`worst hand error ${(worstHand * 1000).toFixed(3)} mm over ${settled.length} frames`);
  expect(worstHand).toBeLessThan(0.01);

  // The network ran once per frame (each run finishes before the next frame; none skipped).
  const runs = log[log.length - 1].runs - log[0].runs;
  const skipped = await page.evaluate(() => window.__vr.predictorSkipped);
  console.log(`network runs ${runs} over ${log.length - 1} frames, ${skipped} skipped`);
  expect(runs).toBeGreaterThanOrEqual(log.length - 2);
  expect(await page.evaluate(() => window.__vr.predictorFailures)).toBe(0);
  expect(errors).toEqual([]);
});

test('VR views: the headset draws the headless copy, the mirror and the spectator the whole avatar; the spectator shows only while presenting, the page camera after', async ({ page }) => {
  test.setTimeout(180_000);
  const errors = await openVr(page, '&mirror=128');

  // Outside a session the spectator canvas is not shown and does not cover the page (three.js's
  // inline display: block used to beat its `hidden`); it is made at the first session.
  expect(await page.evaluate(() => {
    const c = document.getElementById('spectator');
    const top = document.elementFromPoint(innerWidth - 20, innerHeight - 20);
    return [c ? getComputedStyle(c).display : 'none', c !== null && top === c];
  })).toEqual(['none', false]);

  await enterVr(page);
  // First person: the headset's cameras draw the headless copy, not the whole avatar; the
  // spectator (and the mirror, any camera but the headset's) the whole one.
  await waitFrames(page, 2);
  expect(await page.evaluate(() => window.__vr.headTrianglesHidden)).toBeGreaterThan(100);
  expect(await page.evaluate(() => window.__vr.views())).toMatchObject({ headsetWhole: false, headsetHeadless: true, spectatorWhole: true });

  // Standing and calibrated (the script's first half second): the mirror in front shows the avatar.
  await startScript(page);
  await waitFrames(page, 32);
  fs.mkdirSync(SHOTS, { recursive: true });
  await page.screenshot({ path: path.join(SHOTS, 'vr-first-person.png') });
  // While presenting, the page shows the spectator's third-person view (picture-in-picture),
  // with the head that first person hides; a larger page for a readable screenshot.
  await page.setViewportSize({ width: 960, height: 540 });
  await waitFrames(page, 3);
  await expect(page.locator('#spectator')).toBeVisible();
  await page.screenshot({ path: path.join(SHOTS, 'vr-in-vr-spectator.png') });

  // Leave VR: the desktop view is the spectator camera following the avatar.
  await page.evaluate(() => window.__vr.exitVR());
  await page.waitForFunction(() => !window.__vr.inXR, null, { timeout: 30_000 });
  await waitFrames(page, 3);
  expect((await page.evaluate(() => window.__vr.views())).pageWhole).toBe(true); // the page camera is third person again
  await page.screenshot({ path: path.join(SHOTS, 'vr-spectator.png') });
  expect(errors).toEqual([]);
});

test('with the model file missing the heuristic is used and the page says so; the switch compares them', async ({ page }) => {
  test.setTimeout(90_000);
  const errors = await openVr(page, '&model=missing.onnx&mirror=0');
  await page.waitForFunction(() => window.__vr.predictorFallback !== null, null, { timeout: 60_000 });
  const h = await page.evaluate(() => ({ loaded: window.__vr.networkLoaded, predictor: window.__vr.predictor, why: window.__vr.predictorFallback }));
  expect(h.loaded).toBe(false);
  expect(h.predictor).toBe('heuristic');
  expect(h.why).toContain('missing.onnx');
  await expect(page.locator('#predictor-status')).toHaveText(/fallback: heuristic/);
  await expect(page.locator('#predictor option[value="network"]')).toBeDisabled();
  await waitFrames(page, 5);
  expect(await page.evaluate(() => window.__vr.predictor)).toBe('heuristic');
  // The page's own warning is the only console message allowed.
  expect(errors).toEqual([]);
});

test('replay of a synthetic held-in recording with the benchmark: loose bounds', async ({ page }) => {
  test.setTimeout(120_000);
  await page.setViewportSize({ width: 480, height: 300 });
  const errors = collectErrors(page);
  await muteHmr(page);
  // dt=fixed: the live frames after the bench replay the walk at 1/60 s a frame; at wall-clock
  // dt (0.1 s frames on a loaded machine) the hands were 1–4 cm off after 30 frames half the time.
  await page.goto('/vr.html?replay=recordings/walk.json&bench=1&mirror=0&alpha=0.3&dt=fixed');
  await page.waitForFunction(() => window.__vr?.ready || window.__vr?.error, null, { timeout: 90_000 });
  expect(await page.evaluate(() => window.__vr.error)).toBeNull();
  const b = (await page.evaluate(() => window.__vr.bench))!;
  console.log(JSON.stringify({ root: b.rootDistance, yaw: b.yawError, skating: b.skatingCmPerS, ms: [b.median, b.p95, b.modelMedian] }));
  expect(b.predictor).toBe('network');
  expect(b.modelRuns).toBe(b.frames);
  expect(b.rootDistance!.mean).toBeLessThan(0.15);
  expect(b.targetGap.max).toBeLessThan(0.3 + 0.005);
  expect(b.yawError.network!.mean).toBeLessThan(10);
  expect(b.yawError.network!.mean).toBeLessThan(b.yawError.hmdForward!.mean);
  expect(b.median).toBeLessThan(5); // target ≤ 1 ms on a desktop; this machine is shared and slow
  await waitFrames(page, 30);
  expect(await page.evaluate(() => window.__vr.mode)).toBe('replay');
  expect(Math.max(...(await page.evaluate(() => window.__vr.handErrors)))).toBeLessThan(0.01);
  await page.screenshot({ path: path.join(SHOTS, 'vr-replay.png') });
  expect(errors).toEqual([]);
});

test('VR pose checks over every shipped recording and the scripted motion: the crouch leaves upright users standing and bent-over ones on their feet, no elbow bent behind the torso', async ({ page }) => {
  const names = [...(JSON.parse(fs.readFileSync(path.join(ROOT, 'public/recordings/index.json'), 'utf8')) as string[]).map((n) => `recordings/${n}`), 'scripted'];
  test.setTimeout(120_000 * names.length);
  await page.setViewportSize({ width: 320, height: 200 });
  const errors = collectErrors(page);
  await muteHmr(page);
  const rows: string[] = [];
  let upright = 0;
  let bent = 0;
  const checks: [string, PoseCheck][] = [];
  for (const name of names) {
    await page.goto(`/vr.html?replay=${name}&bench=1&mirror=0&spectator=0&alpha=0.3`);
    await page.waitForFunction(() => window.__vr?.ready || window.__vr?.error, null, { timeout: 110_000 });
    expect(await page.evaluate(() => window.__vr.error)).toBeNull();
    const p = (await page.evaluate(() => window.__vr.bench!.pose))!;
    rows.push(`${name}: upright ${p.uprightFrames}, hips low ${p.hipsLowFrames} (largest drop ${(100 * p.hipsDropMax).toFixed(1)} cm; hips/rest min ${p.hipsMinRatio.toFixed(3)}), bent over ${p.bentFrames}, kneeling ${p.bentKneelFrames} (largest drop ${(100 * p.bentDropMax).toFixed(1)} cm), elbows behind ${p.elbowBehindFrames} (worst ${(100 * p.elbowBehindMax).toFixed(1)} cm)`);
    upright += p.uprightFrames;
    bent += p.bentFrames;
    checks.push([name, p]);
  }
  console.log(rows.join('\n'));
  for (const [name, p] of checks) {
    expect(p.hipsLowFrames, name).toBe(0);
    expect(p.bentKneelFrames, name).toBe(0);
    expect(p.elbowBehindFrames, name).toBe(0);
  }
  expect(upright).toBeGreaterThan(1000);
  expect(bent).toBeGreaterThan(100); // moving-about (CMU 14 bending over laughing)
  expect(errors).toEqual([]);
});

test('device sets under iwer: two controllers, one, none, tracked hands and back, switched live while walking; the page names each, the avatar stays within α, no hand pops', async ({ page }) => {
  test.setTimeout(300_000);
  const errors = await openVr(page, '&mirror=0&spectator=0');
  await page.locator('#enter-vr').click();
  await page.waitForFunction(() => window.__vr.inXR || window.__vr.error, null, { timeout: 30_000 });
  // Each phase lasts 1.5 s of tracker time while the user walks along −Z at 0.4 m/s.
  const PHASES = ['headset + 2 controllers', 'headset + left controller', 'headset only', 'headset + hands', 'headset + 2 controllers'];
  await page.evaluate((phases) => {
    type V = { set(x: number, y: number, z: number): void };
    type Q = { set(x: number, y: number, z: number, w: number): void };
    type Input = { position: V; quaternion: Q; connected: boolean };
    const device = window.__vr.emulator as { position: V; quaternion: Q; primaryInputMode: 'controller' | 'hand'; controllers: Record<string, Input>; hands: Record<string, Input> };
    const log: unknown[] = [];
    (window as unknown as { __log: unknown[] }).__log = log;
    let start = -1;
    window.__vr.beforeFrame = (frame) => {
      const h = window.__vr;
      if (start >= 0) log.push({ t: (frame - 1 - start) / 60, set: h.deviceSet, model: h.predictor === 'network' ? h.yawModel : h.predictor, target: [...h.target], root: [...h.root], hands: [...h.hands] });
      else start = frame;
      const t = (frame - start) / 60;
      if (t === 0.25) h.calibrate(1.6);
      const phase = Math.min(phases.length - 1, Math.floor(t / 1.5));
      device.primaryInputMode = phase === 3 ? 'hand' : 'controller';
      device.controllers.left.connected = phase !== 2;
      device.controllers.right.connected = phase === 0 || phase === 4;
      const z = -0.4 * Math.max(0, t - 0.5);
      device.position.set(0, 1.6, z);
      device.quaternion.set(0, 0, 0, 1);
      for (const [side, x] of [['left', -0.22], ['right', 0.22]] as const) {
        for (const input of [device.controllers[side], device.hands[side]]) {
          input.position.set(x, 1.0, z - 0.25);
          input.quaternion.set(0, 0, 0, 1);
        }
      }
    };
  }, PHASES);
  await waitFrames(page, 60 * 1.5 * PHASES.length + 2, 250_000);
  const log = (await page.evaluate(() => (window as unknown as { __log: unknown[] }).__log)) as { t: number; set: string; model: string; target: number[]; root: number[]; hands: number[] }[];
  const alpha = await page.evaluate(() => window.__vr.alpha);
  PHASES.forEach((name, k) => {
    // The set is named from the first frames of its phase on (the tracker state sees a controller leave at once).
    const frames = log.filter((f) => f.t >= 1.5 * k + 0.1 && f.t < 1.5 * (k + 1));
    const named = frames.filter((f) => f.set === name).length / frames.length;
    // The body yaw is the mean of both models whatever the set (one controller or none changes
    // the inputs, not the mix), once the network has loaded and the recurrent model warmed up
    // (1.5 s: the first phase is the warm-up).
    const want = 'both';
    const networked = frames.filter((f) => f.model === 'both' || f.model === 'main');
    const right = k === 0 ? 1 : networked.filter((f) => f.model === want).length / Math.max(1, networked.length);
    console.log(`${name}: named on ${(100 * named).toFixed(0)} % of its frames; body yaw from the ${want} model on ${(100 * right).toFixed(0)} % of ${networked.length} networked frames`);
    expect(named, name).toBeGreaterThan(0.95);
    expect(right, `${name}: ${want} model`).toBeGreaterThan(0.95);
  });
  expect(log.filter((f) => f.t >= 1.5 && f.t < 4.5 && f.model === 'both').length, 'the network ran during the phases without two controllers').toBeGreaterThan(60);
  expect(await page.evaluate(() => window.__vr.predictorFailures)).toBe(0);
  const worstGap = Math.max(...log.map((f) => Math.hypot(f.root[0] - f.target[0], f.root[2] - f.target[1])));
  // Hands from the calibration on (it rescales the avatar at 0.25 s).
  let worstJump = 0, worstAt = 0;
  for (let i = 1; i < log.length; i++) {
    if (log[i - 1].t < 0.3) continue;
    for (const o of [0, 3]) {
      const jump = Math.hypot(log[i].hands[o] - log[i - 1].hands[o], log[i].hands[o + 1] - log[i - 1].hands[o + 1], log[i].hands[o + 2] - log[i - 1].hands[o + 2]);
      if (jump > worstJump) [worstJump, worstAt] = [jump, log[i].t];
    }
  }
  console.log(`device sets: root↔target worst ${worstGap.toFixed(3)} m (α ${alpha}); largest hand move in one frame ${(100 * worstJump).toFixed(1)} cm at ${worstAt.toFixed(2)} s`);
  expect(worstGap).toBeLessThan(alpha + 0.005);
  expect(worstJump).toBeLessThan(0.08); // a pop would move a hand by tens of centimetres in a frame
  await expect(page.locator('#devices')).toHaveText('headset + 2 controllers');
  expect(errors).toEqual([]);
});

/** One frame of the body-tracking run: the tracked hips given (x, z, facing) and the avatar's shown hips, the frame before. */
interface BodyFrame {
  t: number;
  tracked: [number, number, number];
  shown: [number, number, number];
  body: boolean;
  predictor: string;
}

test('body tracking under iwer: an emulated XRFrame.body driven from a held-out person\'s mocap; the avatar\'s hips follow the tracked ones within 3 cm and 3°; losing the body falls back to the network without a jump', async ({ page }) => {
  test.setTimeout(300_000);
  // The recording of CMU 14 stepping about (training/make_recordings.py): headset, controllers
  // and the body joints a body-tracking headset reports, from their mocap.
  const rec = JSON.parse(fs.readFileSync(path.join(ROOT, 'public/recordings/body-moving-about.json'), 'utf8'));
  expect(rec.body.joints[0]).toBe('hips');
  const errors = await openVr(page, '&mirror=0&spectator=0');
  await page.waitForFunction(() => window.__vr.networkLoaded || window.__vr.predictorFallback, null, { timeout: 60_000 });
  await page.evaluate(() => window.__vr.enterVR());
  await page.waitForFunction(() => window.__vr.inXR || window.__vr.error, null, { timeout: 30_000 });
  const LOST: [number, number] = [3, 4.5]; // seconds without a body (XRFrame.body null)
  const SECONDS = 6;
  await page.evaluate(({ rec, lost }) => {
    type V = { set(x: number, y: number, z: number): void };
    type Q = { set(x: number, y: number, z: number, w: number): void };
    const device = window.__vr.emulator as { position: V; quaternion: Q; controllers: Record<'left' | 'right', { position: V; quaternion: Q }> };
    const joints = rec.body.joints as string[];
    const J = joints.length;
    // The emulated body: XRFrame.body maps joint names to spaces; getPose of one gives its pose
    // this frame (the WebXR Body Tracking API), every other space goes to iwer's own getPose.
    const spaces = new Map(joints.map((name, j) => [name, { bodyJoint: j }]));
    const pose = { frame: 0 };
    let lostNow = false;
    const proto = (window as unknown as { XRFrame: { prototype: XRFrame } }).XRFrame.prototype;
    Object.defineProperty(proto, 'body', { configurable: true, get: () => (lostNow ? null : { get: (n: string) => spaces.get(n) }) });
    const getPose = proto.getPose;
    proto.getPose = function (this: XRFrame, space: XRSpace, base: XRSpace) {
      const j = (space as unknown as { bodyJoint?: number }).bodyJoint;
      if (j === undefined) return getPose.call(this, space, base);
      const k = pose.frame * J + j;
      const [p, q] = [rec.body.position, rec.body.rotation];
      return { emulatedPosition: false, transform: { position: { x: p[3 * k], y: p[3 * k + 1], z: p[3 * k + 2], w: 1 }, orientation: { x: q[4 * k], y: q[4 * k + 1], z: q[4 * k + 2], w: q[4 * k + 3] } } } as unknown as XRPose;
    };
    const log: unknown[] = [];
    (window as unknown as { __log: unknown[] }).__log = log;
    let start = -1;
    let given = [0, 0, 0];
    window.__vr.beforeFrame = (frame) => {
      const h = window.__vr;
      if (start >= 0) {
        log.push({ t: (frame - 1 - start) / 60, tracked: given, shown: [...h.shownHips], body: h.body, predictor: h.predictor });
      } else start = frame;
      const t = (frame - start) / 60;
      if (t === 0) h.calibrate(rec.meta.eyeHeight);
      // The recording's frame nearest this time (72 Hz recorded, 60 Hz replayed).
      const f = (pose.frame = Math.min(rec.frames - 1, Math.round(t * rec.meta.rate)));
      lostNow = t >= lost[0] && t < lost[1];
      const [p, q] = [rec.position, rec.rotation];
      device.position.set(p[9 * f], p[9 * f + 1], p[9 * f + 2]);
      device.quaternion.set(q[12 * f], q[12 * f + 1], q[12 * f + 2], q[12 * f + 3]);
      for (const [side, i] of [['left', 1], ['right', 2]] as const) {
        device.controllers[side].position.set(p[9 * f + 3 * i], p[9 * f + 3 * i + 1], p[9 * f + 3 * i + 2]);
        device.controllers[side].quaternion.set(q[12 * f + 4 * i], q[12 * f + 4 * i + 1], q[12 * f + 4 * i + 2], q[12 * f + 4 * i + 3]);
      }
      // What this frame gives: the hips on the floor and the hip joints' facing ((left − right) × up).
      const b = rec.body.position, k = f * J;
      const [lx, lz] = [b[3 * (k + 1)] - b[3 * (k + 2)], b[3 * (k + 1) + 2] - b[3 * (k + 2) + 2]];
      given = lostNow ? [NaN, NaN, NaN] : [b[3 * k], b[3 * k + 2], Math.atan2(-lz, lx)];
    };
  }, { rec, lost: LOST });
  await waitFrames(page, 60 * SECONDS + 2, 240_000);
  const log = (await page.evaluate(() => (window as unknown as { __log: unknown[] }).__log)) as BodyFrame[];
  const wrap = (a: number) => a - 2 * Math.PI * Math.round(a / (2 * Math.PI));
  const scored = log.filter((f) => f.body && f.t > 0.5 && !(f.t >= LOST[1] && f.t < LOST[1] + 0.5));
  const distance = scored.map((f) => Math.hypot(f.shown[0] - f.tracked[0], f.shown[1] - f.tracked[1]));
  const angle = scored.map((f) => (Math.abs(wrap(f.shown[2] - f.tracked[2])) * 180) / Math.PI);
  const mean = (a: number[]) => a.reduce((s, v) => s + v, 0) / a.length;
  const p95 = (a: number[]) => [...a].sort((x, y) => x - y)[Math.floor(0.95 * (a.length - 1))];
  let jump = 0;
  for (let k = 1; k < log.length; k++) {
    const [a, b] = [log[k - 1], log[k]];
    if (Math.abs(b.t - LOST[0]) < 0.5 || Math.abs(b.t - LOST[1]) < 0.5) jump = Math.max(jump, Math.hypot(b.shown[0] - a.shown[0], b.shown[1] - a.shown[1]));
  }
  console.log(`body tracking (iwer): avatar hips ${(100 * mean(distance)).toFixed(2)} cm mean / ${(100 * p95(distance)).toFixed(2)} cm p95 from the tracked hips, facing ${mean(angle).toFixed(2)}° mean / ${p95(angle).toFixed(2)}° p95 over ${scored.length} frames; largest hips move in a frame around the loss ${(100 * jump).toFixed(2)} cm`);
  expect(scored.length).toBeGreaterThan(200);
  expect(mean(distance)).toBeLessThan(0.03);
  expect(mean(angle)).toBeLessThan(3);
  expect(jump).toBeLessThan(0.05);
  // While lost the network drives (the page says so); tracked again, the body does.
  const during = log.filter((f) => f.t > LOST[0] + 0.05 && f.t < LOST[1] - 0.05);
  expect(during.every((f) => !f.body && f.predictor === 'network')).toBe(true);
  expect(log.filter((f) => f.t > 1 && f.t < LOST[0]).every((f) => f.body && f.predictor === 'network')).toBe(true);
  expect(log[log.length - 1].body).toBe(true);
  await expect(page.locator('#predictor-status')).toHaveText('body yaw: tracked hips');
  await page.setViewportSize({ width: 960, height: 540 });
  await page.evaluate(() => window.__vr.exitVR());
  await waitFrames(page, 3);
  await page.screenshot({ path: path.join(SHOTS, 'vr-body-tracking.png') });
  expect(errors).toEqual([]);
});
