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
  private readonly carrier = new ViewCache(Float32Array, 16);
  private readonly world: ViewCache<Float32Array>;
  private skinViews: ViewCache<Float32Array>[] = [];

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
    this.world = new ViewCache(Float32Array, this.numJoints * 16);
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

  /**
   * From now on `skin` computes the bones' world matrices and the skins' matrices in the core
   * (wasm-core/src/runtime/skinning.rs) instead of three.js: `parents`, `restPositions` as
   * given to the constructor; per skin (a three.js `Skeleton`), its bones (indices into the
   * avatar's) and `boneInverses` (16 column-major floats each). Throws on inconsistent input.
   */
  enableSkinning(target: Pick<TargetSkeleton, 'parents' | 'restPositions'>, skins: readonly { bones: ArrayLike<number>; inverseBinds: ArrayLike<number> }[]): void {
    try {
      this.live.enable_skinning(
        Int32Array.from(target.parents),
        Float32Array.from(target.restPositions),
        Uint32Array.from(skins, (k) => k.bones.length),
        Uint32Array.from(skins.flatMap((k) => Array.from(k.bones))),
        Float32Array.from(skins.flatMap((k) => Array.from(k.inverseBinds))),
      );
    } catch (e) {
      throw asError(e);
    }
    this.skinViews = skins.map((k) => new ViewCache(Float32Array, k.bones.length * 16));
  }

  /**
   * After `apply`: every bone's world matrix and each skin's matrices (bone world · inverse
   * bind), the root bones hanging from `carrier` (its world matrix, 16 column-major floats).
   */
  skin(carrier: ArrayLike<number>): void {
    const raw = this.live;
    this.carrier.get(wasmMemory(), raw.carrier_ptr()).set(carrier); // in place: no allocation
    raw.skin();
  }

  /** The bones' world matrices after `skin` (T×16, zero-copy). */
  get worldMatrices(): Float32Array {
    return this.world.get(wasmMemory(), this.live.world_matrices_ptr());
  }

  /** Skin `s`'s matrices after `skin` (16 floats a slot, zero-copy). */
  skinMatrices(s: number): Float32Array {
    return this.skinViews[s].get(wasmMemory(), this.live.skin_matrices_ptr(s));
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
