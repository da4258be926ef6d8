/**
 * `CharacterRuntime`: one motion-matched character in the runtime (wraps `RawCharacter`): input
 * or a path or a tracked user in, the world pose out as zero-copy views. The public
 * `Character` (../character/character.ts) adds the avatar, the scene object and units.
 */
import type { Database } from './database.ts';
import { DRIVE_FIELDS, type Drive, type DrivePath, writeDrive } from './drive.ts';
import { RawCharacter } from './raw.ts';
import { ViewCache } from './view-cache.ts';
import { asError, freeRaw, wasmMemory } from './wasm.ts';

/** The runtime settings (docs/runtime.md lists them; `CharacterSettings` in Rust). */
export type RuntimeSettings = Record<string, unknown>;

/**
 * A settings patch as JSON. JSON has no NaN or ∞ (`JSON.stringify` writes `null`, which the
 * runtime would report as "invalid type: null"): such a value is refused here by name.
 */
function settingsJson(patch: RuntimeSettings): string {
  const check = (o: Record<string, unknown>, path: string) => {
    for (const [k, v] of Object.entries(o)) {
      if (typeof v === 'number' && !Number.isFinite(v)) throw new Error(`settings: ${path}${k} is ${v}, expected a finite number`);
      if (typeof v === 'object' && v !== null && !Array.isArray(v)) check(v as Record<string, unknown>, `${path}${k}.`);
    }
  };
  if (typeof patch === 'object' && patch !== null) check(patch, '');
  return JSON.stringify(patch);
}

export class CharacterRuntime {
  private database_: Database;
  readonly numJoints: number;
  private raw_: RawCharacter | null;
  /** The drive's path object the runtime follows (null: none, or one given by `setPath`). */
  private path: DrivePath | null = null;
  private readonly views = {
    positions: null as unknown as ViewCache<Float32Array>,
    rotations: null as unknown as ViewCache<Float32Array>,
    root: new ViewCache(Float32Array, 4),
    simulation: new ViewCache(Float32Array, 7),
    toes: new ViewCache(Float32Array, 6),
    drive: new ViewCache(Float32Array, DRIVE_FIELDS.length),
    predictedPositions: null as unknown as ViewCache<Float32Array>,
    predictedRotations: null as unknown as ViewCache<Float32Array>,
    matched: null as unknown as ViewCache<Float32Array>,
  };

  /** A character on `database` (retained until `free()`), with a settings patch. */
  constructor(database: Database, settings: RuntimeSettings = {}) {
    try {
      this.raw_ = new RawCharacter(database.raw, settingsJson(settings));
    } catch (e) {
      throw asError(e);
    }
    this.database_ = database.retain();
    const j = (this.numJoints = database.numJoints);
    const k = this.raw_.num_predictions();
    this.views.positions = new ViewCache(Float32Array, j * 3);
    this.views.rotations = new ViewCache(Float32Array, j * 4);
    this.views.predictedPositions = new ViewCache(Float32Array, k * 3);
    this.views.predictedRotations = new ViewCache(Float32Array, k * 4);
    this.views.matched = new ViewCache(Float32Array, this.raw_.num_matched() * 4);
  }

  /** The database it plays (retained): the one it was made on, or the whole after `enterWhole`. */
  get database(): Database {
    return this.database_;
  }

  /**
   * Moves from the first part it plays to `whole` (`Database.isPartOf`), playing the same
   * frame there: nothing it shows changes. Throws, changing nothing, for another database.
   */
  enterWhole(whole: Database): void {
    try {
      this.raw.enter_whole(whole.raw);
    } catch (e) {
      throw asError(e);
    }
    this.database_.release();
    this.database_ = whole.retain();
  }

  /** The binding, for other raw-layer classes (the retargeter). @internal */
  get raw(): RawCharacter {
    if (!this.raw_) throw new Error('character used after free()');
    return this.raw_;
  }

  get isFreed(): boolean {
    return this.raw_ === null;
  }

  /**
   * The drive value for the next `update` (database units; see `Drive`), in one call: its path
   * first when it is not the one the runtime follows (a new path starts at its beginning).
   * Throws on a path the runtime cannot follow; nothing changes then.
   */
  setDrive(drive: Readonly<Drive>): void {
    const raw = this.raw;
    if (drive.mode === 'path' && drive.path && drive.path !== this.path) {
      this.setPath(drive.path.points, drive.path.speeds, drive.path.looped);
      this.path = drive.path;
    }
    try {
      writeDrive(drive, this.views.drive.get(wasmMemory(), raw.drive_ptr())); // in place: no copy, no allocation
      raw.apply_drive();
    } catch (e) {
      throw asError(e); // an unknown mode: a value not made by `createDrive`
    }
    if (drive.mode !== 'path') this.path = null;
  }

  /** Follow `points` (x, z pairs, database units) at `speeds` m/s per segment. Throws on a bad path. */
  setPath(points: Float32Array, speeds: Float32Array, looped: boolean): void {
    try {
      this.raw.set_path(points, speeds, looped);
    } catch (e) {
      throw asError(e);
    }
    this.path = null;
  }

  /**
   * VR: the head centre `headDrop` below its standing height (database units) with the headset
   * pitched `pitch` rad (negative: down) → hips drop and torso bend (docs/vr.md, "Crouching and
   * bending over"); read them back with `hipsDrop` and `torsoBend`.
   */
  setCrouch(headDrop: number, pitch: number): void {
    this.raw.set_crouch(headDrop, pitch);
  }

  /** The hips drop (database units) and torso bend (rad) asked for. */
  get hipsDrop(): number {
    return this.raw.hips_drop();
  }

  get torsoBend(): number {
    return this.raw.torso_bend();
  }

  teleport(x: number, z: number, yaw: number): void {
    this.raw.teleport(x, z, yaw);
  }

  /** Teleports and plays database `frame` from there, moving as it moves (a late joiner's copy of someone walking). */
  teleportPlaying(frame: number, x: number, z: number, yaw: number): void {
    this.raw.teleport_playing(frame, x, z, yaw);
  }

  /**
   * The runtime state as bytes (~4.7 KB for 32 joints): `loadState` on a runtime of the same
   * database continues from these exact floats (a shared room's late joiner; docs/rooms.md).
   */
  saveState(): Uint8Array {
    return this.raw.save_state();
  }

  /** Continues from `saveState` bytes (set a path it follows first); throws with the reason on bytes it refuses, changing nothing. */
  loadState(bytes: Uint8Array): void {
    try {
      this.raw.load_state(bytes);
    } catch (e) {
      throw asError(e);
    }
  }

  /** Patches settings; throws on unknown keys or wrong types. */
  setSettings(patch: RuntimeSettings): void {
    try {
      this.raw.set_settings_json(settingsJson(patch));
    } catch (e) {
      throw asError(e);
    }
  }

  settings(): RuntimeSettings {
    return JSON.parse(this.raw.settings_json()) as RuntimeSettings;
  }

  update(dt: number): void {
    this.raw.update(dt);
  }

  /** World joint positions of the shown pose, J×3 (zero-copy view). */
  get worldPositions(): Float32Array {
    return this.views.positions.get(wasmMemory(), this.raw.world_positions_ptr());
  }
  /** World joint rotations of the shown pose, J×4 (x, y, z, w). */
  get worldRotations(): Float32Array {
    return this.views.rotations.get(wasmMemory(), this.raw.world_rotations_ptr());
  }
  /** Root x, y, z and yaw (rad, 0 = +Z). */
  get root(): Float32Array {
    return this.views.root.get(wasmMemory(), this.raw.root_ptr());
  }
  /** The simulated character: position (3), facing quaternion (4). */
  get simulation(): Float32Array {
    return this.views.simulation.get(wasmMemory(), this.raw.simulation_ptr());
  }
  /** Toe points of the shown pose: left xyz, right xyz. */
  get toes(): Float32Array {
    return this.views.toes.get(wasmMemory(), this.raw.toes_ptr());
  }
  /** K×3 world positions of the trajectory asked for at the last search. */
  get predictedPositions(): Float32Array {
    return this.views.predictedPositions.get(wasmMemory(), this.raw.predicted_positions_ptr());
  }
  /** K×4 world facings of that trajectory. */
  get predictedRotations(): Float32Array {
    return this.views.predictedRotations.get(wasmMemory(), this.raw.predicted_rotations_ptr());
  }
  /** The trajectory stored with the frame playing: per point x, z, direction x, z (world). */
  matchedTrajectory(): Float32Array {
    return this.views.matched.get(wasmMemory(), this.raw.matched_trajectory());
  }

  get frame(): number {
    return this.raw.frame();
  }
  /** Bits: 1 left foot, 2 right foot. */
  get contacts(): number {
    return this.raw.contacts();
  }
  get footLocks(): number {
    return this.raw.foot_locks();
  }
  /** Feet stepping back under a dragged body (lifted on purpose, contact or not). Bits: 1 left foot, 2 right foot. */
  get footSteps(): number {
    return this.raw.foot_steps();
  }
  get searches(): number {
    return this.raw.searches();
  }
  get transitions(): number {
    return this.raw.transitions();
  }
  get searchCost(): number {
    return this.raw.search_cost();
  }
  get bestCost(): number {
    return this.raw.best_cost();
  }
  /**
   * What the runtime refused or repaired since creation: inputs that were not numbers or out of
   * range (the last good value was used), `dt` gaps searched afresh instead of simulated, and
   * recoveries from a non-finite state. Not for every frame (allocates).
   */
  faults(): { rejectedInputs: number; gaps: number; recoveries: number } {
    const [rejectedInputs, gaps, recoveries] = this.raw.faults();
    return { rejectedInputs, gaps, recoveries };
  }
  /** Planted-toe sliding since the last teleport, database units (the runtime's measure). */
  get skating(): number {
    return this.raw.skating();
  }

  free(): void {
    if (!this.raw_) return;
    freeRaw(this.raw_, 'rawcharacter');
    this.raw_ = null;
    this.database.release();
  }
}
