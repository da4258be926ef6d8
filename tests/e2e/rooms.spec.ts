// Shared rooms, end to end: three browser contexts in one room — two desktop demo pages and the
// VR page under iwer — on the room server that vite runs on the page's own origin. Everyone sees
// the other two avatars; after 20 s of scripted walking, turning and side-stepping each remote
// avatar is where its sender's own character is; a closed context disappears from the others;
// a late joiner converges.
//
// Time: every page runs a fixed step (?dt=: one frame = 1/20 s of simulation on the desktop
// pages, 1/10 s on the VR page, whose stereo frames cost the most) because software WebGL draws
// a few frames a second, so simulated time runs slower than the wall clock — and differently on
// each page (as on real devices: a headset's frame rate is not a laptop's). The room stream is timed by each sender's wall clock and replayed
// at that pace, so nothing depends on the pages keeping up with each other. Positions are
// compared message by message: each sender records its character's root after every step
// (keyed by its stream time), each receiver the root it draws when that step has played.
import { expect, test, type Browser, type BrowserContext, type Page } from '@playwright/test';
import { createRoomId } from '../../web/src/rooms/protocol.ts';

const SCRIPT_SECONDS = Number(process.env.ROOMS_SCRIPT_SECONDS) || 20;
/**
 * Simulated seconds per frame (?dt=): 20 Hz steps keep 20 s of script within minutes at a few
 * frames a second; the VR page, the slowest to draw, steps 10 Hz.
 */
const STEP = { desktop: 0.05, vr: 0.1 };

type Row = [number, number, number, number, number];
interface Trace {
  id: number;
  sent: Row[];
  shown: Row[];
}

interface Person {
  page: Page;
  vr: boolean;
  name: string;
  errors: string[];
  /** Simulated seconds per frame. */
  step: number;
}

const hookName = (p: Person) => (p.vr ? '__vr' : '__mm');

// Contexts made here are not the test's own: closed after the test, or their pages keep drawing
// in software WebGL and starve the tests that follow (the VR e2e timed out behind them).
const contexts: BrowserContext[] = [];
test.afterEach(async () => {
  for (const c of contexts.splice(0)) await c.close().catch(() => undefined);
});

async function open(browser: Browser, vr: boolean, name: string, roomId: string): Promise<Person> {
  const context = await browser.newContext({ viewport: { width: 320, height: 240 } });
  contexts.push(context);
  const page = await context.newPage();
  const errors: string[] = [];
  page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
  page.on('pageerror', (e) => errors.push(e.message));
  // Vite's HMR socket stays open but silent (an edit elsewhere must not reload a slow run); the
  // room sockets (/rooms/<id>) are real.
  await page.routeWebSocket((url) => !url.pathname.startsWith('/rooms/'), () => undefined);
  const step = vr ? STEP.vr : STEP.desktop;
  const query = `dt=${step}&room=${roomId}&name=${name}`;
  // VR: the heuristic body yaw (the network would cost a second a frame here; rooms send whichever
  // yaw), no mirror (a third drawing of the scene: the VR page's frames pace this test).
  await page.goto(vr ? `/vr.html?emulate=1&devui=0&mirror=0&spectator=0&predictor=heuristic&${query}` : `/?shadows=0&${query}`);
  const p: Person = { page, vr, name, errors, step };
  await page.waitForFunction((h) => (window as any)[h]?.ready || (window as any)[h]?.error, hookName(p), { timeout: 120_000 });
  expect(await page.evaluate((h) => (window as any)[h].error, hookName(p))).toBeNull();
  if (vr) {
    // onnxruntime's start blocks the page for seconds: let it finish before anything is measured.
    await page.waitForFunction(() => window.__vr.networkLoaded || window.__vr.predictorFallback, null, { timeout: 120_000 });
    await page.locator('#enter-vr').click();
    await page.waitForFunction(() => window.__vr.inXR || window.__vr.error, null, { timeout: 60_000 });
  }
  return p;
}

/** Frames (`step` s of simulation each) the page has run. */
const frames = (p: Person) => p.page.evaluate((h) => (h === '__vr' ? window.__vr.frames : window.__mm.updates), hookName(p));

/** Names of the remote members the page shows (placed by the stream). */
const seen = (p: Person) =>
  p.page.evaluate((h) => {
    const s = (h === '__vr' ? (window as any).__vr.room?.session : (document.getElementById('avatar') as any)?.room);
    return s ? [...s.members.values()].filter((m: any) => m.remote?.ready).map((m: any) => m.join.name).sort() : [];
  }, hookName(p));

const trace = (p: Person): Promise<Trace> =>
  p.page.evaluate((h) => {
    const s = (h === '__vr' ? (window as any).__vr.room?.session : (document.getElementById('avatar') as any)?.room);
    return { id: s.client.memberId, sent: s.trace.sent, shown: s.trace.shown };
  }, hookName(p));

/**
 * Starts a scripted person (desktop: move input per frame through the element's API; VR: the
 * emulated headset and controllers per frame) for `seconds` of simulation from now.
 */
async function script(p: Person, seconds: number, variant: number): Promise<void> {
  if (!p.vr) {
    await p.page.evaluate(
      ([seconds, variant, step]) => {
        const el = document.getElementById('avatar') as unknown as { setMove(x: number, z: number, o?: { run?: boolean; face?: { x: number; z: number } }): void };
        const h = window.__mm;
        const start = h.updates;
        const sgn = variant ? -1 : 1;
        const tick = () => {
          const t = (h.updates - start) * step;
          if (t >= seconds) return el.setMove(0, 0);
          const u = t % 20;
          if (u < 4) el.setMove(0, sgn); // walk
          else if (u < 9) el.setMove(sgn * Math.sin((u - 4) * 0.9), sgn * Math.cos((u - 4) * 0.9)); // walk a curve: turning
          else if (u < 12) el.setMove(1, 0, { face: { x: 0, z: sgn } }); // side-step right
          else if (u < 14) el.setMove(-1, 0, { face: { x: 0, z: sgn } }); // side-step left
          else if (u < 16) el.setMove(-sgn, 0.3, { run: true }); // run
          else if (u < 17) el.setMove(0, 0); // stop
          else el.setMove(0, -sgn, { face: { x: 0, z: sgn } }); // step backwards
          requestAnimationFrame(tick);
        };
        tick();
      },
      [seconds, variant, p.step],
    );
    return;
  }
  await p.page.evaluate(([seconds, step]) => {
    type V = { set(x: number, y: number, z: number): void };
    type Q = { set(x: number, y: number, z: number, w: number): void };
    const device = window.__vr.emulator as { position: V; quaternion: Q; controllers: { left: { position: V; quaternion: Q }; right: { position: V; quaternion: Q } } };
    const s = (x: number) => (x <= 0 ? 0 : x >= 1 ? 1 : x * x * (3 - 2 * x));
    // The walker's state outlives one script: a second script goes on from where the first ended.
    const w = ((window as unknown as { __walker?: { x: number; z: number; yaw: number } }).__walker ??= { x: 0, z: 0, yaw: 0 });
    let start = -1;
    let lastT = 0;
    window.__vr.beforeFrame = (frame) => {
      let { x, z, yaw } = w;
      if (start < 0) start = frame;
      const t = Math.min(seconds, (frame - start) * step);
      const dt = t - lastT;
      lastT = t;
      const u = t % 20;
      // Walk forward (−Z at yaw 0) 4 s, turn in place 3 s, walk on 3 s, side-step right 3 s,
      // walk a curve 4 s, stand 3 s.
      const speed = u < 4 ? 1.0 : u >= 7 && u < 10 ? 1.0 : u >= 13 && u < 17 ? 0.8 : 0;
      if (u >= 4 && u < 7) yaw += dt * (Math.PI / 3) * s((u - 4) * 2) * s((7 - u) * 2);
      if (u >= 13 && u < 17) yaw += dt * 0.6;
      x += -Math.sin(yaw) * speed * dt;
      z += -Math.cos(yaw) * speed * dt;
      if (u >= 10 && u < 13) {
        x += Math.cos(yaw) * 0.4 * dt;
        z += -Math.sin(yaw) * 0.4 * dt;
      }
      Object.assign(w, { x, z, yaw });
      const y = 1.6 + (speed > 0 ? 0.015 * Math.sin(2 * Math.PI * 1.8 * t) : 0);
      const qy = Math.sin(yaw / 2), qw = Math.cos(yaw / 2);
      device.position.set(x, y, z);
      device.quaternion.set(0, qy, 0, qw);
      const c = Math.cos(yaw), sn = Math.sin(yaw);
      for (const [side, lx] of [['left', -0.22], ['right', 0.22]] as const) {
        const lz = -0.25;
        const ctrl = device.controllers[side];
        ctrl.position.set(x + c * lx + sn * lz, 1.0, z - sn * lx + c * lz);
        ctrl.quaternion.set(0, qy, 0, qw);
      }
    };
  }, [seconds, p.step]);
}

/** Waits until every page has run `count` more frames (they run at their own pace). */
async function runFrames(people: Person[], count: number, timeout: number): Promise<void> {
  const targets = await Promise.all(people.map(async (p) => (await frames(p)) + count));
  await Promise.all(
    people.map((p, k) =>
      p.page.waitForFunction(([h, n]) => (h === '__vr' ? window.__vr.frames : window.__mm.updates) >= (n as number), [hookName(p), targets[k]] as const, { timeout, polling: 500 }),
    ),
  );
}

interface PairStats {
  n: number;
  mean: number;
  max: number;
  yawMean: number;
  yawMax: number;
}

/** The receiver's drawn roots of `sender` against the sender's own, matched by sender stream time (from `fromTime` on). */
function compare(receiver: Trace, sender: Trace, fromTime = -Infinity, toTime = Infinity): PairStats {
  const sent = new Map(sender.sent.filter((r) => r[0] === sender.id).map((r) => [r[1], r]));
  const d: number[] = [];
  const yaw: number[] = [];
  for (const s of receiver.shown) {
    if (s[0] !== sender.id || s[1] < fromTime || s[1] > toTime) continue;
    const r = sent.get(s[1]);
    if (!r) continue;
    d.push(Math.hypot(s[2] - r[2], s[3] - r[3]));
    yaw.push(Math.abs(Math.atan2(Math.sin(s[4] - r[4]), Math.cos(s[4] - r[4]))) * (180 / Math.PI));
  }
  const mean = (v: number[]) => v.reduce((a, b) => a + b, 0) / Math.max(1, v.length);
  return { n: d.length, mean: mean(d), max: Math.max(0, ...d), yawMean: mean(yaw), yawMax: Math.max(0, ...yaw) };
}

const fmt = (s: PairStats) => `${s.n} messages: root mean ${(s.mean * 100).toFixed(2)} cm, max ${(s.max * 100).toFixed(2)} cm; yaw mean ${s.yawMean.toFixed(2)}°, max ${s.yawMax.toFixed(2)}°`;

test('three people in one room (two desktop, one VR under iwer): each sees the others where they are; leave; late join', async ({ browser }) => {
  test.setTimeout(40 * 60_000);
  const roomId = createRoomId();
  const people: Person[] = [];
  for (const [vr, name] of [[false, 'Ada'], [false, 'Bo'], [true, 'Vera']] as const) people.push(await open(browser, vr, name, roomId));
  const [ada, bo, vera] = people;

  // Everyone sees the other two (by their names), placed by the stream.
  for (const p of people) {
    const others = people.filter((q) => q !== p).map((q) => q.name).sort().join();
    await p.page.waitForFunction(
      ([h, others]) => [...((h === '__vr' ? (window as any).__vr.room?.session : (document.getElementById('avatar') as any)?.room)?.members.values() ?? [])].filter((m: any) => m.remote?.ready).map((m: any) => m.join.name).sort().join() === others,
      [hookName(p), others] as const,
      { timeout: 120_000, polling: 250 },
    );
  }
  for (const p of people) expect(await seen(p)).toEqual(people.filter((q) => q !== p).map((q) => q.name).sort());
  await expect(ada.page.locator('.mm-room-status')).toContainText(/Bo|Vera/);
  // Joined from a link: the room's link and QR code show on "Room link".
  await expect(ada.page.locator('.mm-room-qr')).toBeHidden();
  await ada.page.locator('.mm-room-share').click();
  await expect(ada.page.locator('.mm-room-qr')).toBeVisible();
  await expect(ada.page.locator('.mm-room-link')).toHaveAttribute('href', new RegExp(`room=${roomId}`));

  // Every copy computes its sender's own floats: copies of a newcomer from its restart, copies of
  // someone who was there before from the runtime state that person sent when the viewer came.
  for (const p of people) await p.page.waitForFunction((h) => [...(h === '__vr' ? (window as any).__vr.room?.session : (document.getElementById('avatar') as any)?.room).members.values()].every((m: any) => m.remote?.exact), hookName(p), { timeout: 120_000, polling: 250 });

  // The script: from each sender's stream time at its start.
  const startTimes = await Promise.all(people.map((p) => p.page.evaluate((h) => (h === '__vr' ? (window as any).__vr.room?.session : (document.getElementById('avatar') as any)?.room).client.stream.lastStepTime as number, hookName(p))));
  await Promise.all(people.map((p, k) => script(p, SCRIPT_SECONDS, k)));
  const t0 = Date.now();
  const done: number[] = [];
  await Promise.all(people.map((p, k) => runFrames([p], Math.ceil(SCRIPT_SECONDS / p.step) + 10, 30 * 60_000).then(() => (done[k] = Date.now() - t0))));
  const took = people.map((p, k) => `${p.name} ${(done[k] / 1000).toFixed(0)} s`).join(', ');
  console.log(`${SCRIPT_SECONDS} s of script took ${(Math.max(...done) / 1000).toFixed(0)} s of wall time (${took})`);
  await ada.page.waitForTimeout(1500); // the last messages play out
  await runFrames(people, 5, 120_000);

  const traces = await Promise.all(people.map(trace));
  let worst = { mean: 0, max: 0, yawMax: 0 };
  for (let r = 0; r < 3; r++) {
    for (let s = 0; s < 3; s++) {
      if (r === s) continue;
      const stats = compare(traces[r], traces[s], startTimes[s]);
      console.log(`${people[s].name} seen by ${people[r].name}: ${fmt(stats)}`);
      expect(stats.n, `${people[s].name} seen by ${people[r].name}`).toBeGreaterThan(SCRIPT_SECONDS * 5);
      worst = { mean: Math.max(worst.mean, stats.mean), max: Math.max(worst.max, stats.max), yawMax: Math.max(worst.yawMax, stats.yawMax) };
    }
  }
  console.log(`worst pair: root mean ${(worst.mean * 100).toFixed(2)} cm, max ${(worst.max * 100).toFixed(2)} cm, yaw max ${worst.yawMax.toFixed(2)}°`);
  // Soft: a miss still fails the test, after the leave and the late join have been measured too.
  expect.soft(worst.mean).toBeLessThan(0.1);
  expect.soft(worst.max).toBeLessThan(0.25);
  expect.soft(worst.yawMax).toBeLessThan(5);

  // Vera's copy on the desktop pages reaches for her replayed controllers (head and arms as on
  // her own page): each copy's wrists within 2 cm of where her grips put them.
  for (const p of [ada, bo]) {
    const errors = await p.page.evaluate(() => [...((document.getElementById('avatar') as any)?.room?.members.values() ?? [])].flatMap((m: any) => (m.upperBody ? [...m.upperBody.body.handError] : [])));
    console.log(`${p.name}'s copy of Vera: wrist ↔ controller ${errors.map((e) => `${(e * 100).toFixed(2)} cm`).join(', ')}`);
    expect.soft(errors.length, `${p.name} shows Vera's arms`).toBe(2);
    for (const e of errors) expect.soft(e).toBeLessThan(0.02);
  }

  // Bo closes the tab: Ada and Vera stop showing him within 2 s (each page notes the moment the
  // room told it, on the wall clock; polling a page that draws a frame a second would add its own delay).
  const boId = traces[1].id;
  for (const p of [ada, vera]) {
    await p.page.evaluate(([h, id]) => (h === '__vr' ? (window as any).__vr.room?.session : (document.getElementById('avatar') as any)?.room).client.on('memberLeft', (left: number) => left === id && ((window as any).__leftAt = performance.timeOrigin + performance.now())), [hookName(p), boId] as const);
  }
  const closedAt = Date.now();
  await bo.page.context().close();
  // Chromium takes a while to tear down a renderer busy with software WebGL: the context is
  // closed when close() returns, and the clock of "disappears within 2 s" starts there.
  const closeTook = Date.now() - closedAt;
  const goneAfter = await Promise.all(
    [ada, vera].map(async (p) => {
      await p.page.waitForFunction(([h, id]) => !(h === '__vr' ? (window as any).__vr.room?.session : (document.getElementById('avatar') as any)?.room).members.has(id), [hookName(p), boId] as const, { timeout: 15_000, polling: 20 });
      return (await p.page.evaluate(() => (window as any).__leftAt as number)) - closedAt;
    }),
  );
  console.log(
    `Bo left: context.close() took ${closeTook} ms; Ada told ${(goneAfter[0] - closeTook).toFixed(0)} ms after it returned, Vera ${(goneAfter[1] - closeTook).toFixed(0)} ms (${goneAfter[0].toFixed(0)} / ${goneAfter[1].toFixed(0)} ms after it was called)`,
  );
  for (const ms of goneAfter) expect.soft(ms - closeTook).toBeLessThan(2000);

  // A late joiner while Ada and Vera keep moving: placed by the snapshot, then by their runtime states.
  await Promise.all([ada, vera].map((p, k) => script(p, 30, k)));
  const cy = await open(browser, false, 'Cy', roomId);
  await cy.page.waitForFunction(() => [...((document.getElementById('avatar') as any)?.room?.members.values() ?? [])].filter((m: any) => m.remote?.ready).length === 2, null, { timeout: 120_000, polling: 100 });
  await runFrames([ada, vera, cy], 50, 10 * 60_000);
  const cyTrace = await trace(cy);
  for (const [sender, senderTrace] of [[ada, await trace(ada)], [vera, await trace(vera)]] as const) {
    const shown = cyTrace.shown.filter((s) => s[0] === senderTrace.id);
    const sent = senderTrace.sent.filter((r) => r[0] === senderTrace.id);
    const index = new Map(sent.map((r, k) => [r[1], k]));
    const errorAt = (s: Row) => {
      const r = sent[index.get(s[1])!];
      return { d: Math.hypot(s[2] - r[2], s[3] - r[3]), yaw: Math.abs(Math.atan2(Math.sin(s[4] - r[4]), Math.cos(s[4] - r[4]))) * (180 / Math.PI) };
    };
    const matched = shown.filter((s) => index.has(s[1]));
    expect(matched.length, `Cy's copy of ${sender.name}`).toBeGreaterThan(20);
    // Converged: from here on within 10 cm and 5°. Measured in the sender's simulated time (its
    // steps, `step` s each) from Cy's first drawn frame of it, and in wall time.
    // Root: within 10 cm from then on; root and yaw: also within 5°.
    const first = matched[0];
    const convergedAt = (ok: (s: Row) => boolean) => {
      let k = matched.length;
      while (k > 0 && ok(matched[k - 1])) k--;
      const at = matched[Math.min(k, matched.length - 1)];
      return { k, at, sim: (index.get(at[1])! - index.get(first[1])!) * sender.step, wall: (at[1] - first[1]) / 1000 };
    };
    const root = convergedAt((s) => errorAt(s).d < 0.1);
    const both = convergedAt((s) => errorAt(s).d < 0.1 && errorAt(s).yaw < 5);
    const all = compare(cyTrace, senderTrace, first[1]);
    console.log(
      `Cy joined late; ${sender.name}: first drawn ${(errorAt(first).d * 100).toFixed(1)} cm, ${errorAt(first).yaw.toFixed(1)}° off; root within 10 cm after ${root.sim.toFixed(2)} s of simulation (${root.wall.toFixed(1)} s of ${sender.name}'s wall clock), root and yaw within 10 cm and 5° after ${both.sim.toFixed(2)} s; whole time since: ${fmt(all)}`,
    );
    expect.soft(root.k, `Cy's copy of ${sender.name} ends converged`).toBeLessThan(matched.length);
    // Issue target: 1 s. Each sender answers a newcomer with its runtime state, so the copy is
    // the sender's floats from the first frame Cy draws of it (placing it playing the sender's
    // frame alone left its yaw up to 17° off in turns).
    expect.soft(root.sim, `Cy's copy of ${sender.name}: seconds until the root stays within 10 cm`).toBeLessThan(1);
    expect.soft(both.sim, `Cy's copy of ${sender.name}: seconds until root and yaw stay within 10 cm and 5°`).toBeLessThan(1);
    expect.soft(all.yawMean, `Cy's copy of ${sender.name}: mean yaw error`).toBeLessThan(5);
  }

  for (const p of [ada, vera, cy]) expect(p.errors, p.name).toEqual([]);
});
