/**
 * `SearchIndex`: the motion-matching search on its own (wraps `RawSearchIndex`), for
 * benchmarks and tools. The query is written into a zero-copy view, then searched.
 */
import type { Database } from './database.ts';
import { RawSearchIndex } from './raw.ts';
import { ViewCache } from './view-cache.ts';
import { asError, freeRaw, wasmMemory } from './wasm.ts';

/** 0 scalar, 1 SIMD, 2 AABB: all return the same frame and cost. */
export const SEARCH_METHODS = ['scalar', 'simd', 'aabb'] as const;

export class SearchIndex {
  readonly numFrames: number;
  readonly numFeatures: number;
  private raw: RawSearchIndex | null;
  private readonly queryView: ViewCache<Float32Array>;

  constructor(database: Database) {
    try {
      this.raw = RawSearchIndex.from_database(database.raw);
    } catch (e) {
      throw asError(e);
    }
    this.numFrames = this.raw.num_frames();
    this.numFeatures = this.raw.num_features();
    this.queryView = new ViewCache(Float32Array, this.numFeatures);
  }

  /** The lane backend compiled into the module: `simd128` or `scalar`. */
  static backend(): string {
    return RawSearchIndex.backend();
  }

  private get live(): RawSearchIndex {
    if (!this.raw) throw new Error('search index used after free()');
    return this.raw;
  }

  /** The normalized query (write it before `search` / `cost`). */
  get query(): Float32Array {
    return this.queryView.get(wasmMemory(), this.live.query_ptr());
  }

  isValid(frame: number): boolean {
    return this.live.is_valid(frame);
  }

  /** Best frame strictly under `bar` (Infinity: overall), frames [excludeFrom, excludeTo) skipped; -1 if none. */
  search(method: number, betaPose: number, betaTrajectory: number, excludeFrom: number, excludeTo: number, bar = Infinity): number {
    return this.live.search(method, betaPose, betaTrajectory, excludeFrom, excludeTo, bar);
  }

  /** Cost of the frame the last search found (NaN if none). */
  get lastCost(): number {
    return this.live.last_cost();
  }

  cost(frame: number, betaPose: number, betaTrajectory: number): number {
    return this.live.cost(frame, betaPose, betaTrajectory);
  }

  free(): void {
    if (this.raw) freeRaw(this.raw, 'rawsearchindex');
    this.raw = null;
  }
}
