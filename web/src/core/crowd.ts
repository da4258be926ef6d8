/**
 * `Crowd`: many characters on one database updated in one call (wraps `RawCrowd`): what the
 * "characters per 4 ms" benchmark measures. Its size is bounded by cost: `Crowd.maxCharacters`
 * (every character searches the database at its first update; docs/robustness.md).
 */
import type { MoveInput } from './drive.ts';
import type { Database } from './database.ts';
import { RawCrowd } from './raw.ts';
import { ViewCache } from './view-cache.ts';
import { asError, freeRaw, wasmMemory } from './wasm.ts';

export class Crowd {
  readonly count: number;
  private raw: RawCrowd | null;
  private readonly positions: ViewCache<Float32Array>[];

  /**
   * `count` characters on `database` (retained until `free()`). Throws on a count that is not a
   * whole number from 1 to `Crowd.maxCharacters(database)`.
   */
  constructor(
    private readonly database: Database,
    count: number,
  ) {
    if (!Number.isSafeInteger(count) || count < 1) throw new RangeError(`crowd: the character count must be a whole number ≥ 1, got ${String(count)}`);
    try {
      this.raw = new RawCrowd(database.raw, count);
    } catch (e) {
      throw asError(e);
    }
    database.retain();
    this.count = count;
    this.positions = Array.from({ length: count }, () => new ViewCache(Float32Array, database.numJoints * 3));
  }

  /**
   * The most characters a crowd on `database` may hold: the feature values one update compares
   * when every character searches (its first) stay within ~1 s of search, and the characters
   * within 256 MB (docs/robustness.md, "Limits").
   */
  static maxCharacters(database: Database): number {
    return RawCrowd.max_characters(database.raw);
  }

  private get live(): RawCrowd {
    if (!this.raw) throw new Error('crowd used after free()');
    return this.raw;
  }

  private check(i: number): void {
    if (!Number.isInteger(i) || i < 0 || i >= this.count) throw new RangeError(`crowd: no character ${String(i)} (the crowd has ${this.count}: 0 to ${this.count - 1})`);
  }

  setInput(i: number, input: MoveInput): void {
    this.check(i);
    this.live.set_input(i, input.moveX, input.moveZ, input.faceX, input.faceZ, input.run, input.strafe);
  }

  update(dt: number): void {
    this.live.update(dt);
  }

  /** World joint positions of character `i` (J×3, zero-copy). Throws when there is no character `i`. */
  worldPositions(i: number): Float32Array {
    this.check(i);
    return this.positions[i].get(wasmMemory(), this.live.world_positions_ptr(i));
  }

  free(): void {
    if (!this.raw) return;
    freeRaw(this.raw, 'rawcrowd');
    this.raw = null;
    this.database.release();
  }
}
