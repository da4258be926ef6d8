/**
 * The builder's limits in WASM (issue 28): the 600-frame, `Frame Time: 1` take built at 1,000 fps
 * trapped the page builder at 3.7 GB ("RuntimeError: unreachable") and the trapped builder could
 * not be freed. Now it is refused with the estimate before anything is allocated; a build's
 * memory stays within its estimate; and an object a trap leaves behind is still freed. This file
 * has a WASM instance of its own (vitest isolates files), so memory growth is this file's.
 */
import fs from 'node:fs';
import path from 'node:path';
import { beforeAll, describe, expect, it } from 'vitest';
import { wasmMemory } from '../../web/src/core/wasm.ts';
import { CharacterRuntime, Database, DatabaseBuilder, createDrive, initWasmSync, liveObjects } from '../../web/src/index.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const CMU = path.resolve(ROOT, '../shared/mocap/cmu-asf/cmu_02_06.bvh');

/** The first `frames` frames of a real take with `Frame Time:` replaced (the file). */
function cut(frames: number, frameTime: string): Uint8Array {
  const text = fs.readFileSync(CMU, 'utf8');
  const [head, motion] = text.split('MOTION');
  const lines = motion.split('\n').filter((l) => l.trim() !== '').slice(3, 3 + frames);
  return new TextEncoder().encode(`${head}MOTION\nFrames: ${lines.length}\nFrame Time: ${frameTime}\n${lines.join("\n")}\n`);
}

beforeAll(() => {
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
});

describe('build limits in WASM', () => {
  it('refuses the 600-frame take at 1 fps built at 1,000 fps with the estimate, before allocating', () => {
    const before = wasmMemory().buffer.byteLength;
    const builder = new DatabaseBuilder({ fps: 1000, mirror: false });
    builder.addBvh('slow.bvh', cut(600, '1'));
    let error: unknown = null;
    try {
      builder.build();
    } catch (e) {
      error = e;
    }
    expect(error).toBeInstanceOf(Error);
    expect(error).not.toBeInstanceOf(WebAssembly.RuntimeError);
    expect((error as Error).message).toMatch(/the build would need about 3\.9 GB of memory \(599001 frames.*more than the 3\.2 GB a build may use/);
    expect(wasmMemory().buffer.byteLength - before).toBeLessThan(64 << 20);
    builder.free();
    expect(liveObjects().builders).toBe(0);
  });

  it('a build stays within its estimate, and what it builds loads and plays', () => {
    const builder = new DatabaseBuilder({ fps: 240, mirror: false });
    builder.addBvh('cmu_02_06.bvh', new Uint8Array(fs.readFileSync(CMU)));
    const before = wasmMemory().buffer.byteLength;
    const bytes = builder.build();
    const grown = wasmMemory().buffer.byteLength - before;
    const footprint = builder.footprint();
    builder.free();
    expect(footprint).not.toBeNull();
    console.log(`WASM build of ${footprint?.frames} frames: memory grew ${(grown / 1e6).toFixed(1)} MB, estimate ${((footprint?.bytes ?? 0) / 1e6).toFixed(1)} MB`);
    expect(grown).toBeLessThanOrEqual(footprint?.bytes ?? 0);
    const db = Database.fromBytes(bytes, 'cmu_02_06.mmdb');
    const runtime = new CharacterRuntime(db);
    const walk = createDrive();
    walk.moveZ = 1;
    runtime.setDrive(walk);
    for (let i = 0; i < 120; i++) runtime.update(1 / 60);
    expect(runtime.worldPositions.every(Number.isFinite)).toBe(true);
    runtime.free();
    db.release();
  });

  it('an object a trap leaves borrowed is still freed', () => {
    const builder = new DatabaseBuilder({ fps: 30, mirror: false });
    builder.addBvh('a.bvh', cut(300, '0.0083333'));
    expect(liveObjects().builders).toBe(1);
    // Take every page wasm32 has left…
    const memory = wasmMemory();
    for (let pages = 1 << 15; pages >= 1; pages >>= 1) {
      try {
        while (true) memory.grow(pages);
      } catch {
        // this step no longer fits: try a smaller one
      }
    }
    // …then fill what the allocator still holds: a file whose values do not fit is refused
    // ("out of memory", the parser's one big allocation is fallible), until some smaller
    // allocation inside a call fails: a trap, the builder left borrowed by that call.
    let trapped: unknown = null;
    let refused = 0;
    fill: for (const frames of [3000, 300, 30, 3]) {
      const bytes = cut(frames, '0.0083333');
      for (let i = 0; i < 100_000; i++) {
        try {
          builder.addBvh(`f${frames}_${i}.bvh`, bytes);
        } catch (e) {
          if (e instanceof WebAssembly.RuntimeError) {
            trapped = e;
            break fill;
          }
          expect((e as Error).message).toMatch(/out of memory: the motion's \d+ values/);
          refused++;
          continue fill;
        }
      }
    }
    if (!trapped) {
      try {
        builder.build();
      } catch (e) {
        trapped = e;
      }
    }
    expect(refused).toBeGreaterThan(0);
    expect(trapped).toBeInstanceOf(WebAssembly.RuntimeError);
    // wasm-bindgen's own free() would throw "attempted to take ownership of Rust value while it
    // was borrowed" and keep the builder's memory.
    builder.free();
    expect(liveObjects().builders).toBe(0);
    expect(() => builder.addBvh('c.bvh', cut(3, '0.0083333'))).toThrow(/DatabaseBuilder used after free\(\)/);
  });
});
