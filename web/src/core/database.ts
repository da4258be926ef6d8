/**
 * `Database`: a loaded `.mmdb` motion database, wrapping the WASM `RawDatabase` and owning its
 * lifetime (`free()`). Pose arrays are exposed as zero-copy typed views over WASM memory.
 */
import { RawDatabase } from './pkg/mmcore.js';
import { ViewCache } from './view-cache.ts';
import { wasmMemory } from './wasm.ts';

/** One clip (a contiguous range of frames from one source file). */
export interface ClipInfo {
  readonly name: string;
  /** First frame, inclusive. */
  readonly start: number;
  /** End frame, exclusive. */
  readonly end: number;
  readonly mirrored: boolean;
}

/** A named point rigidly attached to a joint (see docs/mmdb-format.md, `SKEL`). */
export interface SiteInfo {
  readonly name: string;
  /** Joint index, or -1 when the skeleton has no such joint. */
  readonly joint: number;
}

export class Database {
  readonly numFrames: number;
  readonly numJoints: number;
  /** Frames per second of the database (frame time is 1 / fps). */
  readonly fps: number;
  /** Floats per frame in the feature matrix. */
  readonly numFeatures: number;
  readonly numClips: number;
  readonly jointNames: readonly string[];
  /** Parent index of each joint; -1 for joint 0 (the virtual root). */
  readonly jointParents: Int32Array;
  readonly clips: readonly ClipInfo[];

  private raw: RawDatabase | null;
  private readonly _localPositions: ViewCache<Float32Array>;
  private readonly _localRotations: ViewCache<Float32Array>;
  private readonly _contacts: ViewCache<Uint8Array>;
  private readonly _features: ViewCache<Float32Array>;
  private readonly _worldPositions: ViewCache<Float32Array>;
  private readonly _worldRotations: ViewCache<Float32Array>;
  private _inspect: Record<string, unknown> | null = null;

  private constructor(raw: RawDatabase) {
    this.raw = raw;
    this.numFrames = raw.num_frames();
    this.numJoints = raw.num_joints();
    this.fps = raw.fps();
    this.numFeatures = raw.num_features();
    this.numClips = raw.num_clips();
    const names: string[] = [];
    this.jointParents = new Int32Array(this.numJoints);
    for (let j = 0; j < this.numJoints; j++) {
      names.push(raw.joint_name(j));
      this.jointParents[j] = raw.joint_parent(j);
    }
    this.jointNames = names;
    const clips: ClipInfo[] = [];
    for (let c = 0; c < this.numClips; c++) {
      clips.push({ name: raw.clip_name(c), start: raw.clip_start(c), end: raw.clip_end(c), mirrored: raw.clip_mirrored(c) });
    }
    this.clips = clips;
    const F = this.numFrames;
    const J = this.numJoints;
    this._localPositions = new ViewCache(Float32Array, F * J * 3);
    this._localRotations = new ViewCache(Float32Array, F * J * 4);
    this._contacts = new ViewCache(Uint8Array, F * 2);
    this._features = new ViewCache(Float32Array, F * this.numFeatures);
    this._worldPositions = new ViewCache(Float32Array, J * 3);
    this._worldRotations = new ViewCache(Float32Array, J * 4);
  }

  /**
   * Parses and validates `.mmdb` bytes (copied into WASM memory).
   * Precondition: the WASM module is initialized (`initWasm()`).
   * Throws an Error naming what is wrong with a bad file.
   */
  static fromBytes(bytes: Uint8Array): Database {
    let raw: RawDatabase;
    try {
      raw = new RawDatabase(bytes);
    } catch (e) {
      // wasm-bindgen may throw a JsValue string rather than an Error.
      throw e instanceof Error ? e : new Error(String(e));
    }
    return new Database(raw);
  }

  /** Fetches and loads a `.mmdb` file; rejects with a message naming the URL on failure. */
  static async fetch(url: string, init?: RequestInit): Promise<Database> {
    let res: Response;
    try {
      res = await fetch(url, { headers: { Accept: 'application/octet-stream' }, ...init });
    } catch (e) {
      throw new Error(`could not fetch ${url}: ${e instanceof Error ? e.message : String(e)}`);
    }
    // A dev server's SPA fallback answers unknown paths with index.html: treat that as missing.
    const type = res.headers.get('content-type') ?? '';
    if (!res.ok || type.includes('text/html')) {
      throw new Error(`could not load ${url}: ${res.ok ? 'not found (the server answered with an HTML page)' : `HTTP ${res.status} ${res.statusText}`}`);
    }
    const bytes = new Uint8Array(await res.arrayBuffer());
    try {
      return Database.fromBytes(bytes);
    } catch (e) {
      throw new Error(`${url}: ${e instanceof Error ? e.message : String(e)}`);
    }
  }

  private get r(): RawDatabase {
    if (!this.raw) throw new Error('Database used after free()');
    return this.raw;
  }

  /** Local positions, `F×J×3` (joint 0: world position of the virtual root). */
  get localPositions(): Float32Array {
    return this._localPositions.get(wasmMemory(), this.r.local_positions_ptr());
  }

  /** Local rotations `(x, y, z, w)`, `F×J×4`. */
  get localRotations(): Float32Array {
    return this._localRotations.get(wasmMemory(), this.r.local_rotations_ptr());
  }

  /** Foot contacts, `F×2` (left, right); 1 = in contact. */
  get contacts(): Uint8Array {
    return this._contacts.get(wasmMemory(), this.r.contacts_ptr());
  }

  /** Normalized feature matrix, `F×D`. */
  get features(): Float32Array {
    return this._features.get(wasmMemory(), this.r.features_ptr());
  }

  /**
   * World positions (`J×3`) of `frame` by forward kinematics. The returned view is reused: it
   * is overwritten by the next call. Allocates nothing after the first call.
   */
  worldPositions(frame: number): Float32Array {
    return this._worldPositions.get(wasmMemory(), this.r.world_positions(frame));
  }

  /** World rotations (`J×4`) of the frame of the last `worldPositions()` call (reused view). */
  worldRotations(): Float32Array {
    return this._worldRotations.get(wasmMemory(), this.r.world_rotations_ptr());
  }

  /** Index of the clip containing `frame`. */
  clipAt(frame: number): number {
    return this.r.clip_at(frame);
  }

  /** The same JSON as `mmdb inspect --json`, parsed (cached). */
  inspect(): Record<string, unknown> {
    this._inspect ??= JSON.parse(this.r.inspect_json()) as Record<string, unknown>;
    return this._inspect;
  }

  /** Named sites (`left_foot`, `left_toe`, ...) from the inspect JSON, when it lists them. */
  sites(): SiteInfo[] {
    const raw = this.inspect()['sites'];
    if (!Array.isArray(raw)) return [];
    const out: SiteInfo[] = [];
    for (const s of raw as unknown[]) {
      if (s && typeof s === 'object') {
        const o = s as Record<string, unknown>;
        const name = typeof o['name'] === 'string' ? o['name'] : undefined;
        const joint = typeof o['joint'] === 'number' ? o['joint'] : typeof o['joint_index'] === 'number' ? o['joint_index'] : undefined;
        if (name !== undefined && joint !== undefined) out.push({ name, joint });
      }
    }
    return out;
  }

  /** Index of the joint named `name`, or -1. */
  jointIndex(name: string): number {
    return this.jointNames.indexOf(name);
  }

  /** Releases the WASM-side database. Views obtained earlier must not be used afterwards. */
  free(): void {
    this.raw?.free();
    this.raw = null;
  }
}
