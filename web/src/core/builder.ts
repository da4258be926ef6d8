/**
 * `DatabaseBuilder`: builds `.mmdb` bytes from BVH files in the page (wraps the WASM
 * `RawBuilder` and owns its lifetime).
 */
import { RawBuilder } from './raw.ts';
import { asError, freeRaw } from './wasm.ts';


export class DatabaseBuilder {
  private raw: RawBuilder | null;

  /** `config` is the same object as a `databases/*.json` build config; `{}` = defaults. */
  constructor(config: object = {}) {
    try {
      this.raw = new RawBuilder(JSON.stringify(config));
    } catch (e) {
      throw asError(e);
    }
  }

  private get r(): RawBuilder {
    if (!this.raw) throw new Error('DatabaseBuilder used after free()');
    return this.raw;
  }

  /** Parses one BVH file now; throws with a `file:line` message on a bad file. */
  addBvh(name: string, bytes: Uint8Array): void {
    try {
      this.r.add_bvh(name, bytes);
    } catch (e) {
      throw asError(e);
    }
  }

  /** Builds the database and returns its `.mmdb` bytes. */
  build(): Uint8Array {
    try {
      return this.r.build();
    } catch (e) {
      throw asError(e);
    }
  }

  /**
   * What the last successful build was estimated to need before it started (bytes of WASM
   * memory, database frames; a build over `limit` is refused with the estimate), or null.
   */
  footprint(): { bytes: number; frames: number; limit: number } | null {
    return JSON.parse(this.r.footprint_json()) as { bytes: number; frames: number; limit: number } | null;
  }

  /** Warnings collected while parsing and building. */
  warnings(): unknown[] {
    return JSON.parse(this.r.warnings_json()) as unknown[];
  }

  free(): void {
    if (this.raw) freeRaw(this.raw, 'rawbuilder');
    this.raw = null;
  }
}
