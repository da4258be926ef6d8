/**
 * `Crowd`: motion-matched characters on one database, wrapping the WASM `RawCrowd` and owning
 * its lifetime (`free()`). Poses are zero-copy views of WASM memory (recreated only if the
 * memory grows); nothing is allocated per frame.
 */
import { type MoveInput } from '../input/input.ts';
import { type SiteInfo } from './database.ts';
import { RawCrowd } from './pkg/mmcore.js';
import { ViewCache } from './view-cache.ts';
import { wasmMemory } from './wasm.ts';

/** One feature group of the database (see docs/mmdb-format.md). */
export interface FeatureGroupInfo {
  name: string;
  kind: 'position' | 'velocity' | 'direction';
  trajectory: boolean;
  axes: 'xyz' | 'xz';
  joint: string;
  offsets: number[];
  /** [first, end) feature dimensions. */
  dims: [number, number];
  mean: number[];
  /** raw = normalized × scale + mean (one scale per group). */
  scale: number;
}

/** A tag and its [start, end) frame ranges. */
export interface TagInfo {
  name: string;
  ranges: [number, number][];
}

export class Crowd {
  readonly numCharacters: number;
  readonly numJoints: number;
  /** Frames in the database. */
  readonly numFrames: number;
  readonly jointNames: readonly string[];
  /** Parent of each joint, -1 for joint 0 (the root). */
  readonly jointParents: Int32Array;
  /** Height of the toe joints above the floor when planted (m), if the database knows it. */
  readonly toeHeight: number | undefined;
  /** Feature groups (layout, normalization) as `mmdb inspect --json` lists them. */
  readonly features: readonly FeatureGroupInfo[];
  /** Clip names by clip index (`binding.clip(i)`; the builder marks mirrored ones). */
  readonly clipNames: readonly string[];
  readonly tags: readonly TagInfo[];
  private readonly _sites: SiteInfo[];
  private readonly simulation: ViewCache<Float32Array>;
  private readonly predictedPositions: ViewCache<Float32Array>[];
  private readonly predictedRotations: ViewCache<Float32Array>[];
  private readonly currentFeatures: ViewCache<Float32Array>;
  private raw: RawCrowd | null;
  private readonly positions: ViewCache<Float32Array>[];
  private readonly rotations: ViewCache<Float32Array>[];

  /** Loads `.mmdb` bytes (throws the loader's message on a bad file) with `count` characters. */
  constructor(bytes: Uint8Array, count = 1) {
    this.raw = new RawCrowd(bytes, count);
    this.numCharacters = count;
    this.numJoints = this.raw.num_joints();
    const info = JSON.parse(this.raw.inspect_json()) as {
      joints: { name: string; parent: number }[];
      sites: SiteInfo[];
      toe_height_in_contact: number | null;
      features: FeatureGroupInfo[];
      clips: { name: string; mirrored: boolean }[];
      tags: TagInfo[];
      num_frames: number;
    };
    this.numFrames = info.num_frames;
    this.toeHeight = info.toe_height_in_contact ?? undefined;
    this.jointNames = info.joints.map((j) => j.name);
    this.jointParents = Int32Array.from(info.joints.map((j) => j.parent));
    this._sites = info.sites.map((s) => ({ name: s.name, joint: s.joint }));
    this.features = info.features;
    this.clipNames = info.clips.map((c) => c.name);
    this.tags = info.tags;
    const k = this.raw.num_predictions();
    this.simulation = new ViewCache(Float32Array, 7);
    this.predictedPositions = Array.from({ length: count }, () => new ViewCache(Float32Array, k * 3));
    this.predictedRotations = Array.from({ length: count }, () => new ViewCache(Float32Array, k * 4));
    this.currentFeatures = new ViewCache(Float32Array, this.raw.num_features());
    this.positions = Array.from({ length: count }, () => new ViewCache(Float32Array, this.numJoints * 3));
    this.rotations = Array.from({ length: count }, () => new ViewCache(Float32Array, this.numJoints * 4));
  }

  /** Named body points (`left_foot`, `left_toe`, …) of the database skeleton. */
  sites(): SiteInfo[] {
    return this._sites;
  }

  private get live(): RawCrowd {
    if (!this.raw) throw new Error('Crowd used after free()');
    return this.raw;
  }

  setInput(i: number, input: MoveInput): void {
    this.live.set_input(i, input.moveX, input.moveZ, input.faceX, input.faceZ, input.run, input.strafe);
  }

  /** Advances every character by `dt` seconds. */
  update(dt: number): void {
    this.live.update(dt);
  }

  /** `J×3`: joint 0 the root's world position, the others local positions. */
  positionsOf(i: number): Float32Array {
    return this.positions[i].get(wasmMemory(), this.live.pose_positions_ptr(i));
  }

  /** `J×4` (x, y, z, w): joint 0 the root's world rotation, the others local rotations. */
  rotationsOf(i: number): Float32Array {
    return this.rotations[i].get(wasmMemory(), this.live.pose_rotations_ptr(i));
  }

  /** Bits: 1 left foot, 2 right foot. */
  contactsOf(i: number): number {
    return this.live.contacts(i);
  }

  /** Patches settings of every character (docs/runtime.md lists the keys); throws on typos. */
  setSettings(patch: Record<string, unknown>): void {
    this.live.set_settings_json(JSON.stringify(patch));
  }

  settings(i = 0): Record<string, unknown> {
    return JSON.parse(this.live.settings_json(i)) as Record<string, unknown>;
  }

  /**
   * Follow a tracked user (VR); call every frame with the raw head floor position (m), its
   * ground velocity (m/s) and the predicted body yaw (rad, 0 = +Z). The runtime spring-smooths
   * velocity and yaw (THESIS_NOTES §9). `setPath(i, null)` returns to input control.
   */
  setTracked(i: number, headX: number, headZ: number, velocityX: number, velocityZ: number, yaw: number): void {
    this.live.set_tracked(i, headX, headZ, velocityX, velocityZ, yaw);
  }

  /** Follow `points` (x, z pairs) at `speeds` m/s per segment, or `null` to return to input. */
  setPath(i: number, points: Float32Array | null, speeds?: Float32Array, looped = false): void {
    if (points === null) this.live.clear_path(i);
    else this.live.set_path(i, points, speeds ?? new Float32Array(), looped);
  }

  /**
   * Lowers character `i`'s hips `drop` m (database units) below the animation, legs bent by IK
   * so the feet stay planted: crouching a VR user with any database.
   */
  setHipsDrop(i: number, drop: number): void {
    this.live.set_hips_drop(i, drop);
  }

  /** Places character `i` at (x, z) facing `yaw` (rad, 0 = +Z). */
  teleport(i: number, x: number, z: number, yaw: number): void {
    this.live.teleport(i, x, z, yaw);
  }

  /** Simulated character: position (3) then facing quaternion (4). A view valid until the next call. */
  simulationOf(i: number): Float32Array {
    return this.simulation.get(wasmMemory(), this.live.simulation_ptr(i));
  }

  /** `K×3` world positions of the predicted trajectory at the last search. */
  predictedPositionsOf(i: number): Float32Array {
    return this.predictedPositions[i].get(wasmMemory(), this.live.predicted_positions_ptr(i));
  }

  /** `K×4` world facings (x, y, z, w) of the predicted trajectory at the last search. */
  predictedRotationsOf(i: number): Float32Array {
    return this.predictedRotations[i].get(wasmMemory(), this.live.predicted_rotations_ptr(i));
  }

  /** `D` normalized features of the frame playing (what was matched). */
  currentFeaturesOf(i: number): Float32Array {
    return this.currentFeatures.get(wasmMemory(), this.live.current_features_ptr(i));
  }

  /** The underlying binding, for debug views not wrapped here. */
  get binding(): RawCrowd {
    return this.live;
  }

  free(): void {
    this.raw?.free();
    this.raw = null;
  }
}
