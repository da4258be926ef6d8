import fs from 'node:fs';
import path from 'node:path';
import { afterAll, beforeAll, describe, expect, it } from 'vitest';
import { seededRandom } from '../../web/src/bench/queries.ts';
import type { FeatureGroupInfo } from '../../web/src/core/database.ts';
import { RawDatabase, RawSearchIndex } from '../../web/src/core/raw.ts';
import { initWasmSync, wasmMemory } from '../../web/src/core/wasm.ts';

const ROOT = path.resolve(import.meta.dirname, '../..');
const WASM_PATH = path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm');
const DB_PATH = path.join(ROOT, 'public/databases/locomotion.mmdb');
const SCALAR = 0;
const SIMD = 1;
const AABB = 2;

let db: RawDatabase;
let index: RawSearchIndex;
let numFrames: number;
let numDims: number;
/** Row-major normalized features, copied out of WASM memory. */
let features: Float32Array;
let trajectoryDims: boolean[];
let tagRanges: Map<string, [number, number][]>;

beforeAll(() => {
  initWasmSync(fs.readFileSync(WASM_PATH));
  db = new RawDatabase(fs.readFileSync(DB_PATH));
  index = RawSearchIndex.from_database(db);
  numFrames = index.num_frames();
  numDims = index.num_features();
  features = new Float32Array(wasmMemory().buffer, db.features_ptr(), numFrames * numDims).slice();
  const inspect = JSON.parse(db.inspect_json()) as Record<string, unknown>;
  trajectoryDims = new Array<boolean>(numDims).fill(false);
  for (const g of inspect['features'] as FeatureGroupInfo[]) trajectoryDims.fill(g.trajectory, g.dims[0], g.dims[1]);
  tagRanges = new Map((inspect['tags'] as { name: string; ranges: [number, number][] }[]).map((t) => [t.name, t.ranges]));
});

afterAll(() => {
  index?.free();
  db?.free();
});

/** The query buffer in WASM memory (re-viewed each time: views die when memory grows). */
function queryView(): Float32Array {
  return new Float32Array(wasmMemory().buffer, index.query_ptr(), numDims);
}

interface Found {
  frame: number;
  cost: number;
}

function search(method: number, betaPose: number, betaTrajectory: number, from: number, to: number, bar: number): Found {
  const frame = index.search(method, betaPose, betaTrajectory, from, to, bar);
  return { frame, cost: index.last_cost() };
}

/**
 * The scalar reference in JS with f32 rounding at every step (Math.fround), in the order of
 * `search::brute_force`: best valid, non-excluded, unmasked frame with cost < bar, earliest on
 * a tie. Bit-exact with the WASM searches.
 */
function referenceSearch(q: Float32Array, betaPose: number, betaTrajectory: number, from: number, to: number, bar: number, mask: Uint8Array | null): Found {
  const f32 = Math.fround;
  const weights = trajectoryDims.map((t) => f32(t ? betaTrajectory : betaPose));
  let best: Found = { frame: -1, cost: NaN };
  let bestCost = bar;
  for (let frame = 0; frame < numFrames; frame++) {
    if (!index.is_valid(frame) || (frame >= from && frame < to) || (mask && !mask[frame])) continue;
    let cost = 0;
    const row = frame * numDims;
    for (let d = 0; d < numDims; d++) {
      const diff = f32(q[d] - features[row + d]);
      cost = f32(cost + f32(f32(weights[d] * diff) * diff));
    }
    if (cost < bestCost) {
      bestCost = cost;
      best = { frame, cost };
    }
  }
  return best;
}

/** Seeded random queries: a database row plus noise (sometimes far away), random β's and windows. */
function* randomQueries(count: number, seed: number) {
  const random = seededRandom(seed);
  const normal = () => (random() + random() + random() + random() - 2) * Math.sqrt(3);
  for (let i = 0; i < count; i++) {
    const source = Math.floor(random() * numFrames);
    const q = new Float32Array(numDims);
    const far = random() < 0.1;
    const noise = [0, 0.05, 0.3, 1][Math.floor(random() * 4)];
    for (let d = 0; d < numDims; d++) q[d] = far ? (random() * 2 - 1) * 20 : features[source * numDims + d] + noise * normal();
    const beta = () => (random() < 0.1 ? 0 : Math.fround(random() * 3));
    const windowed = random() < 0.8;
    yield {
      q,
      source,
      betaPose: beta(),
      betaTrajectory: beta(),
      from: windowed ? source - 20 : 0,
      to: windowed ? source + 21 : 0,
      useBar: random() < 0.3,
    };
  }
}

describe('RawSearchIndex (real WASM in Node)', () => {
  it('is the SIMD build', () => {
    expect(RawSearchIndex.backend()).toBe('simd128');
  });

  it('scalar, SIMD and AABB agree on 2,000 random queries', () => {
    let found = 0;
    let none = 0;
    for (const { q, source, betaPose, betaTrajectory, from, to, useBar } of randomQueries(2000, 42)) {
      queryView().set(q);
      // The runtime's bar: the cost of the frame playing now.
      const bar = useBar ? index.cost(source, betaPose, betaTrajectory) : Infinity;
      const results = [SCALAR, SIMD, AABB].map((m) => search(m, betaPose, betaTrajectory, from, to, bar));
      // Exactly equal: every method computes each cost with the same f32 steps.
      expect(results[1]).toEqual(results[0]);
      expect(results[2]).toEqual(results[0]);
      if (results[0].frame >= 0) {
        found++;
        expect(results[0].cost).toBeLessThan(bar);
        expect(index.is_valid(results[0].frame)).toBe(true);
        expect(results[0].frame >= from && results[0].frame < to).toBe(false);
      } else {
        none++;
        expect(results[0].cost).toBeNaN();
      }
    }
    expect(found).toBeGreaterThan(1000);
    expect(none).toBeGreaterThan(0);
  });

  it('equals a bit-exact JS brute force (150 queries, tag masks included)', () => {
    const tags = [...tagRanges.keys()];
    let i = 0;
    for (const { q, betaPose, betaTrajectory, from, to } of randomQueries(150, 7)) {
      const tag = i++ % 3 === 0 ? tags[i % tags.length] : null;
      let mask: Uint8Array | null = null;
      if (tag) {
        mask = new Uint8Array(numFrames);
        for (const [s, e] of tagRanges.get(tag)!) mask.fill(1, s, e);
        expect(index.use_tag(tag)).toBe(true);
      } else {
        index.clear_tag();
      }
      queryView().set(q);
      const expected = referenceSearch(q, betaPose, betaTrajectory, from, to, Infinity, mask);
      expect(search(AABB, betaPose, betaTrajectory, from, to, Infinity)).toEqual(expected);
      expect(search(SIMD, betaPose, betaTrajectory, from, to, Infinity)).toEqual(expected);
    }
    index.clear_tag();
  });

  it('treats the bar strictly and reports nothing found as -1 / NaN', () => {
    const source = 1000;
    queryView().set(features.subarray(source * numDims, (source + 1) * numDims));
    const best = search(AABB, 1, 1, source - 20, source + 21, Infinity);
    expect(best.frame).toBeGreaterThanOrEqual(0);
    expect(index.cost(best.frame, 1, 1)).toBe(best.cost);
    for (const m of [SCALAR, SIMD, AABB]) {
      expect(search(m, 1, 1, source - 20, source + 21, best.cost)).toEqual({ frame: -1, cost: NaN });
      // Without the exclusion the frame itself matches exactly (cost 0).
      expect(search(m, 1, 1, 0, 0, Infinity)).toEqual({ frame: source, cost: 0 });
      expect(search(m, 1, 1, 0, numFrames, Infinity).frame).toBe(-1);
    }
    expect(index.cost(numFrames, 1, 1)).toBeNaN();
    expect(() => index.search(3, 1, 1, 0, 0, Infinity)).toThrow(/search method 3/);
  });

  it('restricts to a tag and lifts the restriction', () => {
    const walk = tagRanges.get('walk');
    expect(walk).toBeDefined();
    const runFrame = tagRanges.get('run')![0][0] + 50;
    queryView().set(features.subarray(runFrame * numDims, (runFrame + 1) * numDims));
    expect(index.use_tag('walk')).toBe(true);
    const found = search(AABB, 1, 1, 0, 0, Infinity).frame;
    expect(walk!.some(([s, e]) => found >= s && found < e)).toBe(true);
    expect(index.use_tag('no such tag')).toBe(false);
    expect(search(AABB, 1, 1, 0, 0, Infinity).frame).toBe(runFrame);
    index.clear_tag();
  });

  it('builds from .mmdb bytes as from a loaded database', () => {
    const fromBytes = new RawSearchIndex(fs.readFileSync(DB_PATH));
    try {
      expect(fromBytes.num_frames()).toBe(numFrames);
      const source = 777;
      const row = features.subarray(source * numDims, (source + 1) * numDims);
      new Float32Array(wasmMemory().buffer, fromBytes.query_ptr(), numDims).set(row);
      queryView().set(row);
      const a = fromBytes.search(AABB, 1, 2, source - 20, source + 21, Infinity);
      expect(a).toBe(index.search(AABB, 1, 2, source - 20, source + 21, Infinity));
      expect(fromBytes.last_cost()).toBe(index.last_cost());
    } finally {
      fromBytes.free();
    }
  });
});

/** Section payloads of a WASM binary by section id (LEB128 sizes, per the spec's binary format). */
function wasmSections(bytes: Uint8Array): { id: number; start: number; end: number }[] {
  const sections = [];
  let at = 8; // magic + version
  while (at < bytes.length) {
    const id = bytes[at++];
    let size = 0;
    for (let shift = 0; ; shift += 7) {
      const b = bytes[at++];
      size += (b & 0x7f) * 2 ** shift;
      if (b < 0x80) break;
    }
    sections.push({ id, start: at, end: at + size });
    at += size;
  }
  return sections;
}

describe('the .wasm module', () => {
  it('contains SIMD128 instructions in its code section', () => {
    const bytes = new Uint8Array(fs.readFileSync(WASM_PATH));
    const code = wasmSections(bytes).find((s) => s.id === 10);
    expect(code).toBeDefined();
    // A byte scan, not a disassembly: count the encodings of f32x4.add/sub/mul (0xFD prefix,
    // then opcode 228/229/230 as LEB128). A scalar build has no reason to contain them many
    // times, while the search kernels use each per feature dimension.
    const counts = { add: 0, sub: 0, mul: 0 };
    for (let i = code!.start; i + 2 < code!.end; i++) {
      if (bytes[i] !== 0xfd || bytes[i + 2] !== 0x01) continue;
      if (bytes[i + 1] === 0xe4) counts.add++;
      else if (bytes[i + 1] === 0xe5) counts.sub++;
      else if (bytes[i + 1] === 0xe6) counts.mul++;
    }
    expect(counts.mul).toBeGreaterThanOrEqual(4);
    expect(counts.sub).toBeGreaterThanOrEqual(4);
    expect(counts.add).toBeGreaterThanOrEqual(4);
  });
});
