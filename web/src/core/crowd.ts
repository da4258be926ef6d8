/**
 * `Crowd`: many characters on one database updated in one call (wraps `RawCrowd`): what the
 * "characters per 4 ms" benchmark measures.
 */
import { type MoveInput } from './character.ts';
import { type Database } from './database.ts';
import { RawCrowd } from './raw.ts';
import { ViewCache } from './view-cache.ts';
import { asError, wasmMemory } from './wasm.ts';

export class Crowd {
  readonly count: number;
  private raw: RawCrowd | null;
  private readonly positions: ViewCache<Float32Array>[];

  constructor(
    private readonly database: Database,
    count: number,
  ) {
    try {
      this.raw = new RawCrowd(database.raw, count);
    } catch (e) {
      throw asError(e);
    }
    database.retain();
    this.count = count;
    this.positions = Array.from({ length: count }, () => new ViewCache(Float32Array, database.numJoints * 3));
  }

  private get live(): RawCrowd {
    if (!this.raw) throw new Error('crowd used after free()');
    return this.raw;
  }

  setInput(i: number, input: MoveInput): void {
    this.live.set_input(i, input.moveX, input.moveZ, input.faceX, input.faceZ, input.run, input.strafe);
  }

  update(dt: number): void {
    this.live.update(dt);
  }

  /** World joint positions of character `i` (J×3, zero-copy). */
  worldPositions(i: number): Float32Array {
    return this.positions[i].get(wasmMemory(), this.live.world_positions_ptr(i));
  }

  free(): void {
    if (!this.raw) return;
    this.raw.free();
    this.raw = null;
    this.database.release();
  }
}
