// Memory over a page's life: characters made and disposed 1,000 times (what a page that mounts
// and unmounts <mm-avatar>, or a room where people come and go, does) leave the WASM memory and
// the JS heap where they were. WASM memory never shrinks, so "flat" is: no growth once the first
// cycles have sized it. (What one character holds, in bytes, is measured natively against a
// counting allocator: wasm-core/tests/crowd_cost.rs.)
import fs from 'node:fs';
import path from 'node:path';
import v8 from 'node:v8';
import vm from 'node:vm';
import { beforeAll, describe, expect, it } from 'vitest';
import { Character, Database, initWasmSync, liveObjects } from '../../web/src/index.ts';
import { wasmMemory } from '../../web/src/core/wasm.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
v8.setFlagsFromString('--expose-gc');
const gc = vm.runInNewContext('gc') as () => void;

let db: Database;
beforeAll(() => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
  db = Database.fromBytes(new Uint8Array(fs.readFileSync(path.join(ROOT, 'public/databases/locomotion.mmdb'))), 'locomotion.mmdb');
});

/** One character's life: made, walked a second (searches, transitions, foot locks), disposed. */
function cycle(): void {
  const c = new Character(db.retain(), null);
  c.setMove(0.3, 1);
  for (let k = 0; k < 60; k++) c.update(1 / 60);
  c.dispose();
}

const heap = () => {
  gc();
  gc();
  return process.memoryUsage().heapUsed;
};

describe('memory', () => {
  it('1,000 create / walk / dispose cycles leave the WASM memory and the JS heap flat', () => {
    const live = liveObjects();
    for (let k = 0; k < 100; k++) cycle();
    const wasm0 = wasmMemory().buffer.byteLength;
    const heap0 = heap();
    for (let k = 0; k < 900; k++) cycle();
    const wasm1 = wasmMemory().buffer.byteLength;
    const heap1 = heap();
    console.log(
      `after 100 → 1,000 cycles: WASM memory ${(wasm0 / 1e6).toFixed(2)} → ${(wasm1 / 1e6).toFixed(2)} MB; ` +
        `JS heap ${(heap0 / 1e6).toFixed(2)} → ${(heap1 / 1e6).toFixed(2)} MB (${((heap1 - heap0) / 900).toFixed(0)} B per cycle)`,
    );
    expect(wasm1).toBe(wasm0);
    // A leak of one small object per cycle would show: 900 cycles × 1 KB.
    expect(heap1 - heap0).toBeLessThan(900 * 1024);
    expect(liveObjects()).toEqual(live);
  });
});
