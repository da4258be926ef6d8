import fs from 'node:fs';
import path from 'node:path';
import { expect, test, type Page } from '@playwright/test';
import { bvhToGltf, readBvh } from '../unit/gltf-fixtures.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const hook = (page: Page) =>
  page.evaluate(() => {
    const { screenOf: _, toeErrors: __, ...h } = window.__mm;
    return { ...h, root: [...h.root], steps: [...h.steps], path: { points: [...h.path.points], following: h.path.following } };
  });

/**
 * Loads the demo and waits for it: fixed 1/60 s updates, `steps` per drawn frame (software WebGL
 * draws a few dozen frames a second; what the tests check is read per update), no shadows.
 * Keys are pressed and released between frames, so the more updates a frame runs, the more a
 * hold overruns: the keyboard test keeps 2 (at 4 its strafe turned 8–10° instead of 3–4°,
 * the gaps between holds being a few updates longer).
 */
async function open(page: Page, query = '', steps = 2): Promise<string[]> {
  const errors: string[] = [];
  page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
  page.on('pageerror', (e) => errors.push(e.message));
  await page.goto(`/?dt=fixed&steps=${steps}&shadows=0${query}`);
  await page.waitForFunction(() => window.__mm?.ready || window.__mm?.error, null, { timeout: 60_000 });
  expect((await hook(page)).error).toBeNull();
  return errors;
}

/** Drops files (name → text or base64 bytes) on the page as a user would. */
async function drop(page: Page, files: { name: string; text?: string; base64?: string }[]): Promise<void> {
  await page.evaluate((files) => {
    const transfer = new DataTransfer();
    for (const f of files) {
      const bytes = f.base64 !== undefined ? Uint8Array.from(atob(f.base64), (c) => c.charCodeAt(0)) : new TextEncoder().encode(f.text ?? '');
      transfer.items.add(new File([bytes], f.name));
    }
    document.body.dispatchEvent(new DragEvent('drop', { dataTransfer: transfer, bubbles: true, cancelable: true }));
  }, files);
}

/** Waits until the runtime has run `n` updates in all (fixed dt: 60 updates = 1 s). */
const untilUpdate = (page: Page, n: number) => page.waitForFunction((n) => window.__mm.updates >= n, n, { timeout: 60_000, polling: 50 });

/** Holds `keys` for `frames` runtime updates. */
async function hold(page: Page, keys: string[], frames: number): Promise<void> {
  const start = (await hook(page)).updates;
  for (const k of keys) await page.keyboard.down(k);
  await untilUpdate(page, start + frames);
  for (const k of keys) await page.keyboard.up(k);
}

/** Signed smallest difference of two angles. */
const angleDiff = (a: number, b: number) => Math.atan2(Math.sin(a - b), Math.cos(a - b));

test('the character walks, turns and strafes under the keyboard', async ({ page }) => {
  // ~330 frames of a skinned avatar in software WebGL (SwiftShader): ~1 min alone on 2 cores.
  test.setTimeout(240_000);
  const errors = await open(page);
  await expect(page.getByText('Motion matching')).toBeVisible(); // the settings panel
  await page.locator('#viewport canvas').click(); // focus

  // W for 2 s: > 1.5 m along the facing, both feet stepping.
  const a = await hook(page);
  // Toe heights are measured while walking, after the first half second (starting from idle).
  await page.keyboard.down('KeyW');
  await untilUpdate(page, a.updates + 30);
  await page.evaluate(() => (window.__mm.toeErrors.length = 0));
  await untilUpdate(page, a.updates + 120);
  const b = await hook(page);
  // Half a second more for the toe heights: starting from standing (the first view is idle), 2 s
  // gave 59 planted foot-frames, one short of the sample this check wants.
  await untilUpdate(page, a.updates + 150);
  await page.keyboard.up('KeyW');
  const forward = [Math.sin(b.yaw), Math.cos(b.yaw)];
  const along = (b.root[0] - a.root[0]) * forward[0] + (b.root[2] - a.root[2]) * forward[1];
  expect(along).toBeGreaterThan(1.5);
  // The sun's ±3 m shadow box went along (Stage.follow): it stayed at the start, shadows lost 3 m out.
  const sun = await page.evaluate(() => {
    const stage = (document.querySelector('mm-avatar') as unknown as { stage: { sun: { target: { position: { x: number; z: number } } } } }).stage;
    return Math.hypot(stage.sun.target.position.x - window.__mm.root[0], stage.sun.target.position.z - window.__mm.root[2]);
  });
  expect(sun).toBeLessThan(0.5);
  expect(b.steps[0] - a.steps[0]).toBeGreaterThan(0);
  expect(b.steps[1] - a.steps[1]).toBeGreaterThan(0);
  // The avatar's feet are on the floor while in contact (and not stepping back under the body,
  // docs/method.md §7): toe height within 3 cm of standing.
  const toeErrors = await page.evaluate(() => window.__mm.toeErrors.map(Math.abs).sort((x, y) => x - y));
  expect(toeErrors.length).toBeGreaterThan(60);
  const p90 = toeErrors[Math.floor(toeErrors.length * 0.9)];
  console.log(`avatar toe height in contact: median ${(toeErrors[toeErrors.length >> 1] * 100).toFixed(1)} cm, p90 ${(p90 * 100).toFixed(1)} cm (${toeErrors.length} foot-frames)`);
  expect(p90).toBeLessThan(0.03);

  // A (camera-left) for 1.5 s: the facing turns by more than 60°.
  await hold(page, ['KeyA'], 90);
  const c = await hook(page);
  expect(Math.abs(angleDiff(c.yaw, b.yaw))).toBeGreaterThan((60 * Math.PI) / 180);

  // Strafe (F) moving right for 2 s: the facing stays within 10°, the root goes sideways
  // (across the facing more than along it) and both feet step: side-steps, not a turned walk.
  /** Root displacement from `p` to `q` along and across `p`'s facing (m). */
  const moved = (p: typeof c, q: typeof c) => {
    const [dx, dz] = [q.root[0] - p.root[0], q.root[2] - p.root[2]];
    return { along: dx * Math.sin(p.yaw) + dz * Math.cos(p.yaw), across: Math.abs(dx * Math.cos(p.yaw) - dz * Math.sin(p.yaw)) };
  };
  // Controls are camera-relative: W for 1 s faces the character along the camera first, so
  // camera-right (D) is its right and camera-back (S) its back.
  await hold(page, ['KeyW'], 60);
  const c1 = await hook(page);
  await hold(page, ['KeyF', 'KeyD'], 120);
  const d = await hook(page);
  const side = moved(c1, d);
  console.log(`strafe right 2 s: ${side.across.toFixed(2)} m across the facing, ${side.along.toFixed(2)} m along; steps ${d.steps[0] - c1.steps[0]} / ${d.steps[1] - c1.steps[1]}; facing turned ${((angleDiff(d.yaw, c1.yaw) * 180) / Math.PI).toFixed(1)}°`);
  expect(Math.abs(angleDiff(d.yaw, c1.yaw))).toBeLessThan((10 * Math.PI) / 180);
  expect(side.across).toBeGreaterThan(0.5);
  expect(side.across).toBeGreaterThan(2 * Math.abs(side.along));
  expect(Math.min(d.steps[0] - c1.steps[0], d.steps[1] - c1.steps[1])).toBeGreaterThan(0);

  // Backward: S with the facing held (F) for 2 s: the root goes back, the facing stays, both feet step.
  await hold(page, ['KeyF', 'KeyS'], 120);
  const e = await hook(page);
  const back = moved(d, e);
  console.log(`backward 2 s: ${(-back.along).toFixed(2)} m back, ${back.across.toFixed(2)} m across; steps ${e.steps[0] - d.steps[0]} / ${e.steps[1] - d.steps[1]}; facing turned ${((angleDiff(e.yaw, d.yaw) * 180) / Math.PI).toFixed(1)}°`);
  expect(Math.abs(angleDiff(e.yaw, d.yaw))).toBeLessThan((15 * Math.PI) / 180);
  expect(-back.along).toBeGreaterThan(0.5);
  expect(-back.along).toBeGreaterThan(2 * back.across);
  expect(Math.min(e.steps[0] - d.steps[0], e.steps[1] - d.steps[1])).toBeGreaterThan(0);

  // It started on the database's first part and moved to the whole after its first frame.
  const marks = await page.evaluate(() => ['mm:first-frame', 'mm:whole-database'].map((m) => performance.getEntriesByName(m)[0]?.startTime ?? NaN));
  const whole = await hook(page);
  console.log(`first frame ${marks[0].toFixed(0)} ms, whole database (${whole.databaseFrames} frames) in use ${marks[1].toFixed(0)} ms`);
  expect(marks[1]).toBeGreaterThan(marks[0]);
  expect(whole.database).toBe('locomotion');
  expect(whole.databaseFrames).toBeGreaterThan(20_000);

  fs.mkdirSync(path.join(ROOT, 'test-results'), { recursive: true });
  await page.screenshot({ path: path.join(ROOT, 'test-results/demo.png') });
  expect(errors).toEqual([]);
});

/**
 * From now on the page keeps the root (x, z) after every update in `window.__roots` and, once
 * it is past `far` m from here, the largest hips ↔ root distance in `window.__worstHips`
 * (the demo's own per-update hook runs first). Returns the update count at the start.
 */
async function recordRoots(page: Page, far = Infinity): Promise<number> {
  return page.evaluate((far) => {
    const el = document.getElementById('avatar') as unknown as { afterUpdate: ((dt: number) => void) | null };
    const w = window as unknown as { __roots: number[]; __worstHips: number };
    const previous = el.afterUpdate;
    const [x0, z0] = [window.__mm.root[0], window.__mm.root[2]];
    [w.__roots, w.__worstHips] = [[], 0];
    el.afterUpdate = (dt) => {
      previous?.(dt);
      const [x, z, hips] = [window.__mm.root[0], window.__mm.root[2], window.__mm.hips];
      w.__roots.push(x, z);
      if (Math.hypot(x - x0, z - z0) > far) w.__worstHips = Math.max(w.__worstHips, Math.hypot(hips[0] - x, hips[1] - z));
    };
    return window.__mm.updates;
  }, far);
}

/** Shortest distance from (x, z) to the closed polyline `points` (x, z pairs). */
function distanceToLoop(x: number, z: number, points: number[]): number {
  let best = Infinity;
  const n = points.length / 2;
  for (let i = 0; i < n; i++) {
    const [ax, az, bx, bz] = [points[2 * i], points[2 * i + 1], points[(2 * i + 2) % (2 * n)], points[(2 * i + 3) % (2 * n)]];
    const [dx, dz] = [bx - ax, bz - az];
    const t = Math.max(0, Math.min(1, ((x - ax) * dx + (z - az) * dz) / (dx * dx + dz * dz)));
    best = Math.min(best, Math.hypot(ax + t * dx - x, az + t * dz - z));
  }
  return best;
}

// Clicks on the floor between the panel and the toolbar: the full 1280×720 (the others run at the
// config's 640×360).
test.describe('at 1280×720', () => {
  test.use({ viewport: { width: 1280, height: 720 } });
  test('path mode: clicked keypoints make a 4 m square the character follows within α', async ({ page }) => {
    test.setTimeout(240_000);
    const errors = await open(page, '&avatar=none', 4);
    // Zoom out so the whole square is on screen, and open the path folder's edit switch.
    await page.mouse.move(640, 360);
    for (let i = 0; i < 6; i++) await page.mouse.wheel(0, 400);
    await page.waitForTimeout(500);
    await page.getByText('Path mode', { exact: true }).click(); // open the folder
    await page.getByText('edit (click the floor)').click();
    // The path starts where the character stands (the origin); click the other three corners.
    for (const [x, z] of [[-4, 0], [-4, -4], [0, -4]]) {
      const p = await page.evaluate(([x, z]) => window.__mm.screenOf(x, z), [x, z]);
      expect(p.x).toBeGreaterThan(0);
      expect(p.x).toBeLessThan(1000); // left of the panel
      expect(p.y).toBeGreaterThan(0);
      expect(p.y).toBeLessThan(670); // above the toolbar
      await page.mouse.click(p.x, p.y);
    }
    const h = await hook(page);
    expect(h.path.points.length).toBe(8);
    await page.screenshot({ path: path.join(ROOT, 'test-results/demo-path.png') }); // its dots and segments
    const square = h.path.points;
    // Each corner within a few cm of where it was meant to be (the start is wherever the idle
    // character stands, near the origin).
    expect(Math.hypot(square[2] + 4, square[3])).toBeLessThan(0.05);
    await page.getByText('follow the path').click();
    expect((await hook(page)).path.following).toBe(true);
    const alpha = 0.15; // the default clamp_distance (docs/runtime.md)
    // 16 m at 1.4 m/s: ~11.5 s, the root recorded after every update.
    const start = await recordRoots(page);
    await page.waitForFunction((n) => window.__mm.updates >= n, start + 12 * 60, { timeout: 120_000, polling: 100 });
    const roots = await page.evaluate(() => (window as unknown as { __roots: number[] }).__roots);
    const distances: number[] = [];
    const corners = new Set<number>();
    for (let i = 0; i < roots.length; i += 2) {
      distances.push(distanceToLoop(roots[i], roots[i + 1], square));
      for (let c = 0; c < 4; c++) if (Math.hypot(roots[i] - square[2 * c], roots[i + 1] - square[2 * c + 1]) < 0.5) corners.add(c);
    }
    const max = Math.max(...distances);
    console.log(`path square: max distance to the path ${max.toFixed(3)} m over ${distances.length} samples`);
    expect(max).toBeLessThanOrEqual(alpha + 1e-3);
    expect(corners.size).toBe(4); // went all the way round
    expect(errors).toEqual([]);
  });
});

test('dropping BVH files builds a database the character walks on; a broken one is reported', async ({ page }) => {
  test.setTimeout(240_000);
  const errors = await open(page);
  const bvh = fs.readFileSync(path.join(ROOT, '../shared/mocap/cmu-asf/cmu_16_15.bvh'), 'utf8');
  await drop(page, [{ name: 'cmu_16_15.bvh', text: bvh }]);
  await page.waitForFunction(() => window.__mm.databaseLoads === 2 || window.__mm.fileError, null, { timeout: 60_000 });
  let h = await hook(page);
  expect(h.fileError).toBeNull();
  expect(h.database).toBe('cmu_16_15.bvh');
  expect(h.databaseFrames).toBeGreaterThan(300); // the take and its mirror at 60 fps
  expect(h.avatar).toBe('ubc_male.glb'); // the avatar was bound to the new skeleton
  await page.locator('#viewport canvas').click();
  const a = await hook(page);
  await hold(page, ['KeyW'], 90);
  const b = await hook(page);
  expect(Math.hypot(b.root[0] - a.root[0], b.root[2] - a.root[2])).toBeGreaterThan(1.0);

  // A broken file: the importer's message (file and line) in the page; the database stays.
  await drop(page, [{ name: 'broken.bvh', text: 'HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n' }]);
  await page.waitForFunction(() => window.__mm.fileError !== null, null, { timeout: 30_000 });
  h = await hook(page);
  expect(h.fileError).toMatch(/broken\.bvh:\d+/);
  await expect(page.locator('#error-box')).toContainText('broken.bvh');
  expect(h.databaseLoads).toBe(2);
  expect(h.database).toBe('cmu_16_15.bvh');
  await hold(page, ['KeyW'], 60);
  const c = await hook(page);
  expect(Math.hypot(c.root[0] - b.root[0], c.root[2] - b.root[2])).toBeGreaterThan(0.5);

  // An avatar swap: the same GLB dropped binds again; a broken one is reported and the old stays.
  const glb = fs.readFileSync(path.join(ROOT, 'public/avatars/ubc_male.glb')).toString('base64');
  await drop(page, [{ name: 'dropped.glb', base64: glb }]);
  await page.waitForFunction(() => window.__mm.avatar === 'dropped.glb', null, { timeout: 60_000 });
  await drop(page, [{ name: 'junk.vrm', text: 'not a model' }]);
  await page.waitForFunction(() => /junk\.vrm/.test(window.__mm.fileError ?? ''), null, { timeout: 30_000 });
  expect((await hook(page)).avatar).toBe('dropped.glb');
  // A VRM whose bones have meaningless names: only its humanoid mapping can bind it.
  await drop(page, [{ name: 'renamed.vrm', base64: vrmFromGlb(fs.readFileSync(path.join(ROOT, 'public/avatars/ubc_male.glb'))).toString('base64') }]);
  await page.waitForFunction(() => window.__mm.avatar === 'renamed.vrm' || /renamed/.test(window.__mm.fileError ?? ''), null, { timeout: 60_000 });
  expect((await hook(page)).avatar).toBe('renamed.vrm');
  // Its feet on the floor while walking: measured after the first half second, as the keyboard
  // test does — the start from standing on a one-take database swung the median of 40 updates
  // from 1.1 to 3.7 cm between runs (how long the character had stood depends on the load's wall time).
  const start = (await hook(page)).updates;
  await page.keyboard.down('KeyW');
  await untilUpdate(page, start + 30);
  await page.evaluate(() => (window.__mm.toeErrors.length = 0));
  await untilUpdate(page, start + 120);
  await page.keyboard.up('KeyW');
  const vrmToes = await page.evaluate(() => window.__mm.toeErrors.map(Math.abs).sort((x, y) => x - y));
  const cm = (q: number) => (vrmToes[Math.floor(vrmToes.length * q)] * 100).toFixed(1);
  console.log(`renamed VRM: toe height in contact median ${cm(0.5)} cm, p90 ${cm(0.9)} cm (${vrmToes.length} foot-frames)`);
  expect(vrmToes.length).toBeGreaterThan(40);
  expect(vrmToes[vrmToes.length >> 1]).toBeLessThan(0.03);
  await page.screenshot({ path: path.join(ROOT, 'test-results/demo-dropped.png') });
  expect(errors).toEqual([]);
});

test('dropping a GLB with animation clips or a .vrma builds a database the character walks on; broken ones are reported', async ({ page }) => {
  test.setTimeout(240_000);
  const errors = await open(page);
  // Made here from a ../shared BVH take with @gltf-transform (tests/unit/gltf-fixtures.ts).
  const take = readBvh(path.join(ROOT, '../shared/mocap/cmu-asf/cmu_16_15.bvh'));
  const half = Math.floor(take.times.length / 2);
  const glb = Buffer.from(await bvhToGltf(take, { clips: [['First', 0, half], ['Second', half, take.times.length]], dcc: true }));
  const vrma = Buffer.from(await bvhToGltf(take, { clips: [['Walk', 0, take.times.length]], vrma: true }));
  let loads = (await hook(page)).databaseLoads;
  for (const [name, bytes] of [['clips.glb', glb], ['walk.vrma', vrma]] as const) {
    await drop(page, [{ name, base64: bytes.toString('base64') }]);
    await page.waitForFunction((n) => window.__mm.databaseLoads > n || window.__mm.fileError, loads, { timeout: 60_000 });
    const h = await hook(page);
    expect(h.fileError, name).toBeNull();
    expect(h.database).toBe(name);
    expect(h.databaseFrames).toBeGreaterThan(300); // the clips and their mirrors at 60 fps
    expect(h.avatar).toBe('ubc_male.glb'); // a motion file is not taken for an avatar
    loads = h.databaseLoads;
    await page.locator('#viewport canvas').click();
    await hold(page, ['KeyW'], 90);
    const walked = await hook(page);
    console.log(`${name}: walked ${Math.hypot(walked.root[0] - h.root[0], walked.root[2] - h.root[2]).toFixed(2)} m in 1.5 s`);
    expect(Math.hypot(walked.root[0] - h.root[0], walked.root[2] - h.root[2])).toBeGreaterThan(1.0);
  }
  // Broken: a GLB cut in its binary chunk and a .vrma that is not glTF; the message names the
  // file and the fault, the database stays.
  const cut = 20 + glb.readUInt32LE(12) + 1000;
  await drop(page, [{ name: 'cut.glb', base64: glb.subarray(0, cut).toString('base64') }]);
  await page.waitForFunction(() => /cut\.glb/.test(window.__mm.fileError ?? ''), null, { timeout: 30_000 });
  expect((await hook(page)).fileError).toMatch(new RegExp(`cut\\.glb: truncated GLB: its header says \\d+ bytes, the file has ${cut}`));
  await drop(page, [{ name: 'junk.vrma', text: 'not motion' }]);
  await page.waitForFunction(() => /junk\.vrma/.test(window.__mm.fileError ?? ''), null, { timeout: 30_000 });
  expect((await hook(page)).fileError).toMatch(/junk\.vrma: not a glTF file/);
  expect((await hook(page)).database).toBe('walk.vrma');
  expect(errors).toEqual([]);
});

/**
 * A VRM 1.0 made from a GLB for the test (nothing committed): the `VRMC_vrm` extension maps
 * humanoid bones to nodes, and every node is renamed `n<i>` so that name conventions cannot help.
 */
function vrmFromGlb(glb: Buffer): Buffer {
  const jsonLength = glb.readUInt32LE(12);
  const json = JSON.parse(glb.subarray(20, 20 + jsonLength).toString('utf8'));
  const rest = glb.subarray(20 + jsonLength); // the BIN chunk, header included
  const byName = new Map<string, number>(json.nodes.map((n: { name?: string }, i: number) => [n.name, i]));
  const bones: Record<string, string> = {
    hips: 'pelvis', spine: 'spine_01', chest: 'spine_02', upperChest: 'spine_03', neck: 'neck_01', head: 'Head',
  };
  for (const [side, s] of [['left', 'l'], ['right', 'r']]) {
    Object.assign(bones, {
      [`${side}Shoulder`]: `clavicle_${s}`, [`${side}UpperArm`]: `upperarm_${s}`, [`${side}LowerArm`]: `lowerarm_${s}`, [`${side}Hand`]: `hand_${s}`,
      [`${side}UpperLeg`]: `thigh_${s}`, [`${side}LowerLeg`]: `calf_${s}`, [`${side}Foot`]: `foot_${s}`, [`${side}Toes`]: `ball_${s}`,
    });
  }
  const humanBones = Object.fromEntries(Object.entries(bones).map(([role, name]) => [role, { node: byName.get(name) }]));
  json.nodes.forEach((n: { name?: string }, i: number) => (n.name = `n${i}`));
  json.extensionsUsed = [...(json.extensionsUsed ?? []), 'VRMC_vrm'];
  json.extensions = { ...(json.extensions ?? {}), VRMC_vrm: { specVersion: '1.0', meta: { name: 'test', authors: ['test'], licenseUrl: 'https://vrm.dev/licenses/1.0/' }, humanoid: { humanBones } } };
  let text = Buffer.from(JSON.stringify(json), 'utf8');
  text = Buffer.concat([text, Buffer.alloc((4 - (text.length % 4)) % 4, 0x20)]);
  const header = Buffer.alloc(20);
  header.writeUInt32LE(0x46546c67, 0);
  header.writeUInt32LE(2, 4);
  header.writeUInt32LE(20 + text.length + rest.length, 8);
  header.writeUInt32LE(text.length, 12);
  header.writeUInt32LE(0x4e4f534a, 16);
  return Buffer.concat([header, text, rest]);
}

test('one position space: after running 50 m the avatar’s hips are over the character root and the foot-lock rings under its feet', async ({ page }) => {
  test.setTimeout(300_000);
  await page.setViewportSize({ width: 480, height: 320 }); // software rendering: a small page is fast
  const errors = await open(page, '', 4);
  await page.locator('#viewport canvas').click({ position: { x: 30, y: 150 } }); // left of the panel
  // Run forward (Shift+W) until 50 m from the start; the avatar is drawn where the runtime is
  // (the hips checked after every update past 45 m).
  const a = await hook(page);
  await recordRoots(page, 45);
  await page.keyboard.down('ShiftLeft');
  await page.keyboard.down('KeyW');
  await page.waitForFunction(([x, z]) => Math.hypot(window.__mm.root[0] - x, window.__mm.root[2] - z) > 50, [a.root[0], a.root[2]], { timeout: 240_000, polling: 100 });
  const worstHips = await page.evaluate(() => (window as unknown as { __worstHips: number }).__worstHips);
  await page.keyboard.up('KeyW');
  await page.keyboard.up('ShiftLeft');
  // Standing again: both feet planted and locked; the rings are where the avatar's toes are.
  const stop = (await hook(page)).updates;
  await page.waitForFunction((n) => window.__mm.updates > n + 120 && window.__mm.lockRings.every(Number.isFinite), stop, { timeout: 120_000, polling: 100 });
  const h = await hook(page);
  const hips = Math.hypot(h.hips[0] - h.root[0], h.hips[1] - h.root[2]);
  const rings = [0, 1].map((k) => Math.hypot(h.lockRings[2 * k] - h.toes[2 * k], h.lockRings[2 * k + 1] - h.toes[2 * k + 1]));
  console.log(`after ${Math.hypot(h.root[0] - a.root[0], h.root[2] - a.root[2]).toFixed(1)} m: hips ↔ root ${(hips * 100).toFixed(1)} cm standing, worst ${(worstHips * 100).toFixed(1)} cm running past 45 m; lock rings ↔ avatar toes ${rings.map((d) => (d * 100).toFixed(1)).join(' / ')} cm`);
  expect(hips).toBeLessThan(0.05);
  expect(worstHips).toBeLessThan(0.1);
  for (const d of rings) expect(d).toBeLessThan(0.08);
  await page.screenshot({ path: path.join(ROOT, 'test-results/demo-50m.png') });
  expect(errors).toEqual([]);
});

test('a manual joint-map override reaches the avatar; a wrong one is reported, the skeleton stays', async ({ page }) => {
  test.setTimeout(120_000);
  // `Head` is what the table finds anyway: the override path binds as usual.
  let errors = await open(page, `&roles=${encodeURIComponent(JSON.stringify({ head: 'Head' }))}`);
  expect((await hook(page)).avatar).toBe('ubc_male.glb');
  expect(errors).toEqual([]);
  const page2 = await page.context().newPage();
  errors = await open(page2, `&roles=${encodeURIComponent(JSON.stringify({ head: 'no_such_bone' }))}`);
  const h = await hook(page2);
  expect(h.fileError).toMatch(/no_such_bone/);
  expect(h.avatar).toBe('');
  expect(h.updates).toBeGreaterThan(0); // the skeleton plays on
  expect(errors).toEqual([]);
});
