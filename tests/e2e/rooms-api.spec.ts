// The public room API in two browsers, a hostile member's flood, and a joiner whose page is
// blocked while its socket opens — on the room server vite runs on the page's origin.
//
// - Each demo page lists the other through `<mm-avatar>`'s `room.list()` (name, where its avatar
//   is drawn, which way it faces): after both stop, each page's view of the other is where the
//   other page's own character stands.
// - A raw WebSocket member floods 2,000 well-formed but absurd messages (thousands of km away,
//   5 km jumps, forged runtime states, huge frames): the server relays none, warns and closes it
//   (4007); each page's error box shows at most one line about it.
// - A page's main thread is blocked for 8 s right after it opens its room socket (a page busy
//   loading) while two people walk in the room (real engine and sessions in this process): it is
//   not dropped (the server's join timeout gives an open socket 30 s, however busy its page;
//   Chromium does not even read pings while the page is blocked), keeps its one socket, and shows
//   the two others within 2 s of resuming (the time is logged with the page's own steps).
import { expect, test, type Browser, type BrowserContext, type Page } from '@playwright/test';
import fs from 'node:fs';
import path from 'node:path';
import { WebSocket as NodeWebSocket } from 'ws';
import { sessionPerson } from '../../server/session-helpers.ts';
import { Database } from '../../web/src/core/database.ts';
import { initWasmSync } from '../../web/src/core/wasm.ts';
import { createMoveStep, createRoomId, CloseCode, encodeJoin, encodeMove, encodePath, encodeState, quantizeMoveStep, quantizeTrackedStep } from '../../web/src/rooms/protocol.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const contexts: BrowserContext[] = [];
test.afterEach(async () => {
  for (const c of contexts.splice(0)) await c.close().catch(() => undefined);
});

interface MemberView {
  id: number;
  name: string;
  shown: boolean;
  x: number;
  z: number;
  yaw: number;
}

async function open(browser: Browser, name: string, roomId: string, blockMs = 0): Promise<Page> {
  const context = await browser.newContext({ viewport: { width: 320, height: 240 } });
  contexts.push(context);
  const page = await context.newPage();
  await page.routeWebSocket((url) => !url.pathname.startsWith('/rooms/'), () => undefined);
  if (blockMs) {
    // The page's main thread is busy for blockMs right after it opens its room socket (counted,
    // so a reconnect — the server dropping it — would show).
    await page.addInitScript((ms) => {
      const Real = window.WebSocket;
      const w = window as unknown as { __roomSockets: number; __resumedAt: number; __seenAt: number; __steps: Record<string, number> };
      w.__roomSockets = 0;
      w.__resumedAt = 0;
      w.__seenAt = 0;
      w.__steps = {};
      const mark = (k: string) => (w.__steps[k] ??= Math.round(performance.now() - w.__resumedAt));
      // When the page first shows both others (timers are held while the page is blocked, like everything else).
      const watch = setInterval(() => {
        const room = (document.getElementById('avatar') as unknown as { room: any } | null)?.room;
        const l: { shown: boolean }[] = room?.list() ?? [];
        if (room?.memberId) mark('welcome');
        if (l.length === 2) mark('listed');
        if ([...(room?.members.values() ?? [])].filter((m: any) => m.remote).length === 2) mark('avatars loaded');
        if ([...(room?.members.values() ?? [])].filter((m: any) => m.remote?.ready).length === 2) mark('placed');
        if ((window as any).__mm?.updates > 0) mark('first frame');
        if (l.filter((m) => m.shown).length === 2) {
          w.__seenAt = performance.now();
          clearInterval(watch);
        }
      }, 10);
      (window as unknown as { WebSocket: unknown }).WebSocket = class extends Real {
        constructor(url: string | URL, protocols?: string | string[]) {
          super(url, protocols);
          if (!String(url).includes('/rooms/')) return;
          w.__roomSockets++;
          if (w.__roomSockets > 1) return;
          this.addEventListener('open', () => mark('socket open event'));
          this.addEventListener('message', () => mark('first server message'));
          const end = performance.now() + ms;
          while (performance.now() < end) {
            /* busy: no event, timer or frame runs */
          }
          w.__resumedAt = performance.now();
        }
      };
    }, blockMs);
  }
  await page.goto(`/?shadows=0&dt=0.05&room=${roomId}&name=${name}`);
  await page.waitForFunction(() => window.__mm?.ready || window.__mm?.error, null, { timeout: 120_000 });
  expect(await page.evaluate(() => window.__mm.error)).toBeNull();
  return page;
}

/** The other members as the page's public API lists them. */
const list = (page: Page): Promise<MemberView[]> => page.evaluate(() => (document.getElementById('avatar') as unknown as { room: { list(): MemberView[] } | null }).room?.list() ?? []);
/** Where the page's own character stands (the element's public `root`). */
const own = (page: Page) => page.evaluate(() => (document.getElementById('avatar') as unknown as { root: { x: number; z: number; yaw: number } }).root);
const errorLines = (page: Page) => page.evaluate(() => (document.getElementById('error-box')?.textContent ?? '').split('\n').filter(Boolean));

test('room API lists the others where they are in two browsers; a flood shows at most a line', async ({ browser, baseURL }) => {
  test.setTimeout(300_000);
  const roomId = createRoomId();
  const ada = await open(browser, 'Ada', roomId);
  const bo = await open(browser, 'Bo', roomId);
  for (const [page, other] of [
    [ada, 'Bo'],
    [bo, 'Ada'],
  ] as const) {
    await page.waitForFunction((name) => {
      const l = (document.getElementById('avatar') as unknown as { room: { list(): { name: string; shown: boolean }[] } | null }).room?.list() ?? [];
      return l.length === 1 && l[0].name === name && l[0].shown;
    }, other, { timeout: 120_000, polling: 200 });
  }
  // Both walk a little (through the element's API), then stand; each page's view of the other must be where the other stands.
  for (const [page, x, z] of [
    [ada, 0.6, 0.8],
    [bo, -1, 0],
  ] as const) await page.evaluate(([x, z]) => (document.getElementById('avatar') as unknown as { setMove(x: number, z: number): void }).setMove(x, z), [x, z]);
  const frames = async (page: Page, n: number) => {
    const u = await page.evaluate(() => window.__mm.updates);
    await page.waitForFunction((target) => window.__mm.updates >= target, u + n, { timeout: 120_000, polling: 100 });
  };
  await Promise.all([frames(ada, 40), frames(bo, 40)]);
  for (const page of [ada, bo]) await page.evaluate(() => (document.getElementById('avatar') as unknown as { setMove(x: number, z: number): void }).setMove(0, 0));
  await Promise.all([frames(ada, 60), frames(bo, 60)]);
  for (const [viewer, sender, name] of [
    [ada, bo, 'Bo'],
    [bo, ada, 'Ada'],
  ] as const) {
    // Let the viewer play out what is buffered (the jitter delay) before reading.
    await frames(viewer, 20);
    const [view] = await list(viewer);
    const root = await own(sender);
    // The copy shows the sender a jitter delay ago, and a standing character still sways (its
    // idle clip turns the root by tenths of a degree): compared with where the sender's own
    // character was at the closest of its last 3 s of steps (the page's trace of what it sent),
    // not with where it is when this test happens to read it (that read came 0.73° off once).
    const sent: number[][] = await sender.evaluate(() => {
      const room = (document.getElementById('avatar') as unknown as { room: { memberId: number; trace: { sent: number[][] } } }).room;
      return room.trace.sent.filter((r) => r[0] === room.memberId).slice(-60);
    });
    const angle = (a: number, b: number) => Math.abs(Math.atan2(Math.sin(a - b), Math.cos(a - b)));
    const [, , sx, sz, syaw] = sent.reduce((best, r) => (Math.hypot(r[2] - view.x, r[3] - view.z) + angle(r[4], view.yaw) < Math.hypot(best[2] - view.x, best[3] - view.z) + angle(best[4], view.yaw) ? r : best));
    const d = Math.hypot(view.x - sx, view.z - sz);
    const yaw = angle(view.yaw, syaw);
    const now = { d: Math.hypot(view.x - root.x, view.z - root.z), yaw: angle(view.yaw, root.yaw) };
    console.log(`room.list() of ${name}: (${view.x.toFixed(3)}, ${view.z.toFixed(3)}, ${view.yaw.toFixed(3)}); its own root then: ${(d * 1000).toFixed(2)} mm, ${((yaw * 180) / Math.PI).toFixed(3)}° (now (${root.x.toFixed(3)}, ${root.z.toFixed(3)}, ${root.yaw.toFixed(3)}): ${(now.d * 1000).toFixed(2)} mm, ${((now.yaw * 180) / Math.PI).toFixed(3)}°)`);
    expect(sent.length).toBeGreaterThan(20);
    expect(now.d).toBeLessThan(0.05); // standing: where it was a moment ago is where it is
    expect(view.name).toBe(name);
    expect(d).toBeLessThan(0.01);
    expect(yaw).toBeLessThan(0.01);
    expect(Math.hypot(root.x, root.z)).toBeGreaterThan(0.3); // it did walk
  }

  // A hostile member floods absurd but well-formed messages.
  const linesBefore = await Promise.all([ada, bo].map(errorLines));
  const origin = baseURL!;
  const ws = new NodeWebSocket(`${origin.replace(/^http/, 'ws')}/rooms/${roomId}`, { origin });
  await new Promise((resolve, reject) => (ws.once('open', resolve), ws.once('error', reject)));
  const closed = new Promise<number>((resolve) => ws.once('close', (code) => resolve(code)));
  const welcomed = new Promise((resolve) => ws.once('message', resolve));
  ws.send(encodeJoin({ name: 'Mallory', avatar: { kind: 'builtin', id: 0 }, database: 'locomotion', height: 0, mode: 'desktop', devices: { keyboard: true } }));
  await welcomed;
  const step = quantizeMoveStep({ ...createMoveStep(), ticks: 120, moveX: 0, moveZ: 1 });
  const tracked = quantizeTrackedStep({ ticks: 0, headX: 0, headZ: 0, velocityX: 0, velocityZ: 0, yaw: 0, body: false, hipsDrop: 0, bend: 0 });
  const forged = new Uint8Array(4716);
  const v = new DataView(forged.buffer);
  [0x53524d4d, 3, 32, 50_000, 27].forEach((x, i) => v.setUint32(4 * i, x, true));
  for (let o = 20; o < forged.length; o += 4) v.setFloat32(o, 1e30, true);
  const state = (seq: number, extra: object) => encodeState({ seq, time: seq * 50, frame: 1, rootX: 0, rootZ: 0, rootYaw: 0, drive: 'move', pathTime: 0, scale: 1, alpha: 0.2, move: step, tracked, ...extra });
  ws.send(state(1, { restart: true }));
  let sent = 1;
  for (let seq = 2; seq <= 2001 && ws.readyState === ws.OPEN; seq++) {
    const k = seq % 4;
    ws.send(
      k === 0
        ? encodeMove({ seq, time: seq * 50, rootX: 2_000_000, rootZ: 1_000_000, rootYaw: 0, steps: [step] })
        : k === 1
          ? encodePath({ seq, time: seq * 50, points: new Float32Array([90_000, 0, 90_001, 0]), speeds: new Float32Array([1]), looped: false })
          : k === 2
            ? state(seq, { frame: 16_000_000, runtime: forged })
            : encodeMove({ seq, time: seq * 50, rootX: (seq % 8) * 1000, rootZ: 0, rootYaw: 0, steps: [step] }),
    );
    sent++;
    if (seq % 20 === 0) await new Promise((r) => setTimeout(r, 5));
  }
  const code = await closed;
  console.log(`Mallory sent ${sent} messages before the server closed it with ${code}`);
  expect(code).toBe(CloseCode.contentRefused);
  await Promise.all([frames(ada, 10), frames(bo, 10)]);
  for (const [k, page] of [ada, bo].entries()) {
    const added = (await errorLines(page)).slice(linesBefore[k].length);
    console.log(`${k ? 'Bo' : 'Ada'}'s error box after the flood: ${added.length} new line(s)${added.length ? `: ${added.join(' | ')}` : ''}`);
    expect(added.length).toBeLessThanOrEqual(1);
    expect((await list(page)).map((m) => m.name)).not.toContain('Mallory');
  }
});

test('a joiner blocked 8 s right after opening its socket is not dropped and shows the others within 2 s of resuming', async ({ browser, baseURL }) => {
  test.setTimeout(180_000);
  // The others: two people walking on the real engine in this test's process, members of the
  // room on the page's server as any browser is (their pages are elsewhere: two more
  // software-rendered pages on these two cores would time their own frames, not the joiner).
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
  const db = Database.fromBytes(new Uint8Array(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.mmdb'))), 'locomotion.mmdb');
  const roomId = createRoomId();
  const origin = baseURL!;
  const server = { url: (id: string) => `${origin.replace(/^http/, 'ws')}/rooms/${id}`, origin };
  const others = [sessionPerson(db, server, roomId, 'desktop', 'Ada'), sessionPerson(db, server, roomId, 'desktop', 'Bo')];
  let clock = 0;
  const frames = setInterval(() => {
    clock += 1 / 30;
    others.forEach((p, k) => {
      p.character.setMove(Math.sin(clock * 0.5 + k), Math.cos(clock * 0.5 + k));
      p.character.update(1 / 30);
      p.session.update(1 / 30);
    });
  }, 1000 / 30);
  try {
    const cy = await open(browser, 'Cy', roomId, 8000);
    // It joins once its character plays the whole database (the first part's whole, loaded after
    // its first frame): the socket opens, and the block with it, a little after the page is ready.
    await cy.waitForFunction(() => (window as unknown as { __resumedAt: number }).__resumedAt > 0, null, { timeout: 60_000, polling: 100 });
    const t = await cy.evaluate(() => {
      const w = window as unknown as { __roomSockets: number; __resumedAt: number };
      return { sockets: w.__roomSockets, resumedAt: w.__resumedAt };
    });
    await cy.waitForFunction(() => (window as unknown as { __seenAt: number }).__seenAt > 0, null, { timeout: 60_000, polling: 100 }).catch(async (e) => {
      const state = await cy.evaluate(() => {
        const room = (document.getElementById('avatar') as unknown as { room: any }).room;
        return JSON.stringify({ status: room?.status, id: room?.memberId, list: room?.list(), members: [...(room?.members.values() ?? [])].map((m: any) => ({ id: m.id, ready: m.remote?.ready, shown: m.remote?.shown, exact: m.remote?.exact, stats: m.remote?.stats })), notes: [...(room?.notes.values() ?? [])], sockets: (window as any).__roomSockets, box: document.getElementById('error-box')?.textContent });
      });
      throw new Error(`${e}\nCy: ${state}`);
    });
    const seenAfter = (await cy.evaluate(() => (window as unknown as { __seenAt: number }).__seenAt)) - t.resumedAt;
    const sockets = await cy.evaluate(() => (window as unknown as { __roomSockets: number }).__roomSockets);
    const steps = await cy.evaluate(() => (window as unknown as { __steps: Record<string, number> }).__steps);
    const cyNotes = await cy.evaluate(() => [...((document.getElementById('avatar') as unknown as { room: { notes: Map<string, { text: string; count: number }> } | null }).room?.notes.values() ?? [])].map((n) => `${n.text} ×${n.count}`));
    if (cyNotes.length) console.log(`Cy's notes: ${cyNotes.join(' | ')}`);
    console.log(`Cy: blocked 8 s after opening its socket; ${sockets} room socket(s) in all; shows Ada and Bo ${seenAfter.toFixed(0)} ms after resuming (the page's own clock, checked every 10 ms; ms after resuming: ${JSON.stringify(steps)})`);
    expect(t.resumedAt).toBeGreaterThan(0);
    // One socket: the server's join and idle clocks wait for the page (30 s to JOIN; the idle
    // clock from when its WELCOME was read).
    expect(sockets).toBe(1);
    // Issue 26: within 2 s of resuming (0.7 s here; 1.8-1.9 s when the others are two more pages in
    // this browser, all three software-rendered on these two cores: each page then draws ~5 frames
    // a second, and every hop of the join — the open event, the others answering with their
    // runtime states, the joiner reading them — waits for a frame). After resuming the page JOINs
    // on its socket's open event, is welcomed with the server's snapshots (copies placed, not yet
    // shown) and shows each copy the moment its sender's runtime state arrives (exact from the
    // first frame drawn). What it no longer does then: download, parse and upload the avatar
    // again for the others, recompile the avatar's shaders, rebuild its debug views on the
    // welcome, wait a playout delay for the runtime states (the timeline above).
    expect(seenAfter).toBeLessThan(2_000);
    expect((await list(cy)).map((m) => m.name).sort()).toEqual(['Ada', 'Bo']);
    for (const p of others) expect(p.notes).toEqual([]);
  } finally {
    clearInterval(frames);
    for (const p of others) p.session.close();
    db.release();
  }
});
