/**
 * `DatabaseBuilder`: builds `.mmdb` bytes in the page from motion files — BVH takes, glTF/GLB
 * animation clips and VRM Animation (`.vrma`) — the same build as `mmdb build` (wraps the WASM
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

  /**
   * Parses a glTF/GLB/VRMA file now: each of its animations becomes a take (`name#clip` when it
   * has several), the skeleton mapped by its VRM humanoid map when it has one, else by the
   * importer's rules (names, topology). Returns the takes' names; throws an Error naming the
   * file and what is wrong.
   */
  addGltf(name: string, bytes: Uint8Array): string[] {
    try {
      return JSON.parse(this.r.add_gltf(name, bytes)) as string[];
    } catch (e) {
      throw asError(e);
    }
  }

  /**
   * Adds a motion file by its kind: glTF (`.glb`, `.gltf`, `.vrma`, or bytes that start like
   * one) through `addGltf`, anything else as BVH. Returns the takes' names.
   */
  addFile(name: string, bytes: Uint8Array): string[] {
    if (isGltf(name, bytes)) return this.addGltf(name, bytes);
    this.addBvh(name, bytes);
    return [name];
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

/** glTF by name (`.glb`, `.gltf`, `.vrma`) or by content (`glTF` magic, JSON text) unless named `.bvh`. */
function isGltf(name: string, bytes: Uint8Array): boolean {
  const ext = name.toLowerCase().match(/\.([a-z0-9]+)$/)?.[1] ?? '';
  if (ext === 'glb' || ext === 'gltf' || ext === 'vrma') return true;
  if (ext === 'bvh') return false;
  const head = new TextDecoder().decode(bytes.subarray(0, 16)).replace(/^\uFEFF/, '').trimStart();
  return head.startsWith('glTF') || head.startsWith('{');
}
