/**
 * Times the three motion-matching searches (scalar, SIMD, AABB) of `SearchIndex` on one
 * database, the same way in Node and in the browser (the WASM module must be initialized).
 *
 * Per-search times: each query is run `reps` times back to back and its time is the batch time
 * over `reps`, with `reps` chosen so a batch lasts at least `minBatchMs` (browsers round
 * `performance.now()` to 5 µs when cross-origin isolated, 100 µs otherwise). All queries are
 * timed in `rounds` passes and each keeps its fastest pass: on a shared machine a batch is
 * sometimes preempted for milliseconds, and the same query is rarely hit twice. Median and p95
 * are over the queries, so p95 reflects the hard queries rather than the scheduler.
 */
import { Database } from '../core/database.ts';
import { SEARCH_METHODS as METHODS, SearchIndex } from '../core/search.ts';
import { type BenchQuery, realisticQueries } from './queries.ts';

export type MethodName = (typeof METHODS)[number];

export interface SearchBenchOptions {
  /** Number of distinct queries (default 400). */
  readonly queries?: number;
  readonly seed?: number;
  /** Shortest timed batch per query, ms (default 0.5). */
  readonly minBatchMs?: number;
  /** Timed passes over all queries; each query keeps its fastest (default 2). */
  readonly rounds?: number;
}

export interface MethodTiming {
  readonly method: MethodName;
  readonly median_ms: number;
  readonly p95_ms: number;
  readonly mean_ms: number;
  /** Repetitions per query in a timed batch. */
  readonly reps: number;
}

export interface SearchBenchResult {
  readonly database: string;
  readonly frames: number;
  readonly valid_frames: number;
  readonly features: number;
  /** `SearchIndex.backend()`: "simd128" in the SIMD build. */
  readonly backend: string;
  /** Building the index (transpose + boxes), median of 5 builds. */
  readonly index_build_ms: number;
  readonly queries: number;
  /** Queries where the methods did not return the same frame and cost (expected 0). */
  readonly mismatches: number;
  readonly methods: MethodTiming[];
}

/** Exclusion around the query's source frame, as the runtime does around the current frame. */
const EXCLUDE_RADIUS = 20;

function percentile(sorted: readonly number[], p: number): number {
  return sorted[Math.min(sorted.length - 1, Math.floor(p * (sorted.length - 1)))];
}

/** Benchmarks the searches on the `.mmdb` `bytes`; `name` labels the result. */
export function benchSearch(name: string, bytes: Uint8Array, options: SearchBenchOptions = {}): SearchBenchResult {
  const numQueries = options.queries ?? 400;
  const minBatchMs = options.minBatchMs ?? 0.5;
  const db = Database.fromBytes(bytes, name);
  let index: SearchIndex | null = null;
  try {
    const buildTimes: number[] = [];
    for (let i = 0; i < 5; i++) {
      const t = performance.now();
      const built = new SearchIndex(db);
      buildTimes.push(performance.now() - t);
      index?.free();
      index = built;
    }
    const ix = index as SearchIndex;
    const numFrames = ix.numFrames;
    const numDims = ix.numFeatures;
    // Copied out (`realisticQueries` slices): views over WASM memory die when it grows.
    const queries = realisticQueries(db.featureMatrix, db.features, (f) => ix.isValid(f), numQueries, options.seed ?? 1);
    let validFrames = 0;
    for (let f = 0; f < numFrames; f++) validFrames += ix.isValid(f) ? 1 : 0;

    // Nothing allocates in WASM from here on, so this view stays valid.
    const query = ix.query;
    const run = (method: number, q: BenchQuery): number => {
      query.set(q.values);
      return ix.search(method, 1, 1, q.source - EXCLUDE_RADIUS, q.source + EXCLUDE_RADIUS + 1, Infinity);
    };

    let mismatches = 0;
    for (const q of queries) {
      const found = METHODS.map((_, m) => [run(m, q), ix.lastCost]);
      if (found.some(([f, c]) => f !== found[0][0] || c !== found[0][1])) mismatches++;
    }

    const methods = METHODS.map((method, m): MethodTiming => {
      // Calibrate: mean time per search over the first queries, for at least 20 ms.
      let calls = 0;
      const start = performance.now();
      while (performance.now() - start < 20 || calls < 20) run(m, queries[calls++ % queries.length]);
      const meanGuess = (performance.now() - start) / calls;
      const reps = Math.max(1, Math.min(1000, Math.ceil(minBatchMs / meanGuess)));
      const times = queries.map(() => Infinity);
      for (let round = 0; round < (options.rounds ?? 2); round++) {
        queries.forEach((q, i) => {
          query.set(q.values);
          const from = q.source - EXCLUDE_RADIUS;
          const to = q.source + EXCLUDE_RADIUS + 1;
          const t = performance.now();
          for (let r = 0; r < reps; r++) ix.search(m, 1, 1, from, to, Infinity);
          times[i] = Math.min(times[i], (performance.now() - t) / reps);
        });
      }
      const sorted = [...times].sort((a, b) => a - b);
      return {
        method,
        median_ms: sorted[Math.floor(sorted.length / 2)],
        p95_ms: percentile(sorted, 0.95),
        mean_ms: times.reduce((a, b) => a + b, 0) / times.length,
        reps,
      };
    });

    return {
      database: name,
      frames: numFrames,
      valid_frames: validFrames,
      features: numDims,
      backend: SearchIndex.backend(),
      index_build_ms: [...buildTimes].sort((a, b) => a - b)[2],
      queries: queries.length,
      mismatches,
      methods,
    };
  } finally {
    index?.free();
    db.release();
  }
}
