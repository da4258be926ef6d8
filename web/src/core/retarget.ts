/**
 * `Retargeter`: the runtime's retargeting of a character's world pose onto an avatar skeleton
 * (wraps `RawRetargeter`; the method is in wasm-core/src/runtime/retarget.rs). `apply` fills zero-copy
 * views of the avatar's local rotations and hips translation.
 */
import type { CharacterRuntime } from './character.ts';
import type { Database } from './database.ts';
import { RawRetargeter } from './raw.ts';
import { ROLE_NAMES, type RoleName } from './roles.ts';
import { ViewCache } from './view-cache.ts';
import { asError, freeRaw, wasmMemory } from './wasm.ts';

/** An avatar skeleton at rest (any joint order). */
export interface TargetSkeleton {
  /** Parent per joint, −1 for roots. */
  parents: ArrayLike<number>;
  /** Rest local rotations, T×4 (x, y, z, w). */
  restRotations: ArrayLike<number>;
  /** Rest local positions, T×3. */
  restPositions: ArrayLike<number>;
  roles: ReadonlyMap<RoleName, number>;
  /** World rotation of whatever carries the root joints (x, y, z, w). */
  rootParentRotation?: ArrayLike<number>;
  /** Direction-align limb bones (default true). */
  alignBones?: boolean;
}

export class Retargeter {
  readonly numJoints: number;
  /** The avatar's hips joint. */
  readonly targetHips: number;
  /** Avatar bone units per database metre. */
  readonly hipsScale: number;
  private raw: RawRetargeter | null;
  private readonly rotations: ViewCache<Float32Array>;
  private readonly hips = new ViewCache(Float32Array, 3);

  constructor(database: Database, target: TargetSkeleton) {
    const roles = Int32Array.from(ROLE_NAMES, (r) => target.roles.get(r) ?? -1);
    try {
      this.raw = new RawRetargeter(
        database.raw,
        Int32Array.from(target.parents),
        Float32Array.from(target.restRotations),
        Float32Array.from(target.restPositions),
        roles,
        Float32Array.from(target.rootParentRotation ?? [0, 0, 0, 1]),
        target.alignBones ?? true,
      );
    } catch (e) {
      throw asError(e);
    }
    this.numJoints = target.parents.length;
    this.targetHips = this.raw.target_hips();
    this.hipsScale = this.raw.hips_scale();
    this.rotations = new ViewCache(Float32Array, this.numJoints * 4);
  }

  private get live(): RawRetargeter {
    if (!this.raw) throw new Error('retargeter used after free()');
    return this.raw;
  }

  /**
   * Retargets `character`'s pose, the hips lifted `lift` avatar units (grounding). Throws when
   * the character plays a database with another skeleton than this retargeter was made for.
   */
  apply(character: CharacterRuntime, lift: number): void {
    try {
      this.live.apply(character.raw, lift);
    } catch (e) {
      throw asError(e);
    }
  }

  /** The avatar's local rotations after `apply` (T×4, zero-copy). */
  get localRotations(): Float32Array {
    return this.rotations.get(wasmMemory(), this.live.local_rotations_ptr());
  }

  /** The hips' local translation after `apply`. */
  get hipsPosition(): Float32Array {
    return this.hips.get(wasmMemory(), this.live.hips_position_ptr());
  }

  free(): void {
    if (this.raw) freeRaw(this.raw, 'rawretargeter');
    this.raw = null;
  }
}
