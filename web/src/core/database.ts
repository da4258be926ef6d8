/**
 * `Database`: a loaded `.mmdb` motion database (wraps `RawDatabase`, which also holds the search
 * index). One database is shared by any number of characters: it is reference-counted
 * (`retain`/`release`) and its WASM memory is freed with the last reference.
 */
import { DEFAULT_DATABASE, DEFAULT_FIRST_PART, assetUrl, siblingAssetUrl } from '../assets.ts';
import { type FetchOptions, fetchBytes, mark } from '../fetch.ts';
import { RawDatabase } from './raw.ts';
import type { RoleName } from './roles.ts';
import { ViewCache } from './view-cache.ts';
import { asError, freeRaw, initWasm, wasmMemory } from './wasm.ts';

/** One clip (a contiguous range of frames from one source file). */
export interface ClipInfo {
  readonly name: string;
  /** First frame, inclusive. */
  readonly start: number;
  /** End frame, exclusive. */
  readonly end: number;
  readonly mirrored: boolean;
}

/** A tag and its [start, end) frame ranges. */
export interface TagInfo {
  readonly name: string;
  readonly ranges: readonly [number, number][];
}

/** One feature group (see docs/mmdb-format.md). */
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

/** What `RawDatabase.header_json` says (the part of `mmdb inspect --json` read here). */
interface Header {
  num_frames: number;
  fps: number;
  joints: { name: string; parent: number }[];
  sites: { name: string; joint: number }[];
  clips: { name: string; start: number; end: number; mirrored: boolean }[];
  tags: { name: string; ranges: [number, number][] }[];
  features: FeatureGroupInfo[];
  toe_height_in_contact: number | null;
}

/** Prefix of a style's tag (`style:angry`; the Rust `tag_query::STYLE_PREFIX`). */
export const STYLE_PREFIX = 'style:';

export class Database {
  /** Where it came from (a URL or a file name), for messages. */
  readonly name: string;
  readonly numFrames: number;
  readonly numJoints: number;
  /** Frames per second of the database (frame time is 1 / fps). */
  readonly fps: number;
  readonly numFeatures: number;
  readonly jointNames: readonly string[];
  /** Parent index of each joint; -1 for joint 0 (the virtual root). */
  readonly jointParents: Int32Array;
  readonly clips: readonly ClipInfo[];
  readonly tags: readonly TagInfo[];
  /**
   * Motion styles of its clips (`neutral`, `angry`, `akimbo`…: the `style:<name>` tags), in tag
   * order; empty when the database was built without styles. `Character.setStyle` picks one.
   */
  readonly styles: readonly string[];
  readonly features: readonly FeatureGroupInfo[];
  /** Joint of each role present in the skeleton (`left_toe` may be a foot's end point). */
  readonly roles: ReadonlyMap<RoleName, number>;
  /** Height of a planted toe above the floor (m), if the database knows it. */
  readonly toeHeight: number | undefined;
  /**
   * When this database is the first part of a larger one (a `.first.mmdb`: a few clips a page
   * starts on while the rest downloads, docs/mmdb-format.md `PART`), where the whole is;
   * otherwise null. A `Character` on a first part moves to the whole by itself after its first
   * frames, playing the same frame there (`Character.whole()`).
   */
  readonly wholeUrl: string | null;

  private raw_: RawDatabase | null;
  private references = 1;
  private readonly onFree: (() => void) | undefined;
  private readonly _localPositions: ViewCache<Float32Array>;
  private readonly _localRotations: ViewCache<Float32Array>;
  private readonly _contacts: ViewCache<Uint8Array>;
  private readonly _features: ViewCache<Float32Array>;
  private readonly _worldPositions: ViewCache<Float32Array>;
  private readonly _worldRotations: ViewCache<Float32Array>;

  private constructor(raw: RawDatabase, name: string, onFree?: () => void) {
    this.raw_ = raw;
    this.name = name;
    this.onFree = onFree;
    const s = JSON.parse(raw.header_json()) as Header;
    this.numFrames = s.num_frames;
    this.numJoints = s.joints.length;
    this.fps = s.fps;
    this.numFeatures = raw.num_features();
    this.jointNames = s.joints.map((j) => j.name);
    this.jointParents = Int32Array.from(s.joints.map((j) => j.parent));
    this.clips = s.clips.map((c) => ({ name: c.name, start: c.start, end: c.end, mirrored: c.mirrored }));
    this.tags = s.tags.map((t) => ({ name: t.name, ranges: t.ranges }));
    this.styles = this.tags.filter((t) => t.name.startsWith(STYLE_PREFIX)).map((t) => t.name.slice(STYLE_PREFIX.length));
    this.features = s.features;
    this.roles = new Map(s.sites.filter((x) => x.joint >= 0).map((x) => [x.name as RoleName, x.joint]));
    this.toeHeight = s.toe_height_in_contact ?? undefined;
    const whole = raw.whole_name();
    this.wholeUrl = whole === undefined ? null : siblingAssetUrl(name, whole);
    const F = this.numFrames, J = this.numJoints;
    this._localPositions = new ViewCache(Float32Array, F * J * 3);
    this._localRotations = new ViewCache(Float32Array, F * J * 4);
    this._contacts = new ViewCache(Uint8Array, F * 2);
    this._features = new ViewCache(Float32Array, F * this.numFeatures);
    this._worldPositions = new ViewCache(Float32Array, J * 3);
    this._worldRotations = new ViewCache(Float32Array, J * 4);
  }

  /**
   * Parses and validates `.mmdb` bytes (copied into WASM memory). The WASM module must be
   * initialized (`initWasm()`). Throws an Error naming `name` and what is wrong.
   */
  static fromBytes(bytes: Uint8Array, name = 'database', onFree?: () => void): Database {
    let raw: RawDatabase;
    try {
      raw = new RawDatabase(bytes);
    } catch (e) {
      throw new Error(`${name}: ${asError(e).message}`);
    }
    return new Database(raw, name, onFree);
  }

  /** Fetches and loads a `.mmdb` file (initializing the WASM module if needed). */
  static async fetch(url: string | URL, options: FetchOptions = {}): Promise<Database> {
    const [bytes] = await Promise.all([fetchBytes(url, { stage: 'database', ...options }), initWasm(undefined, options)]);
    return Database.fromBytes(bytes, String(url));
  }

  /** Whether this database is the first part of `whole` (the file its `PART` names). */
  isPartOf(whole: Database): boolean {
    return this.raw.is_part_of(whole.raw);
  }

  /** The binding, for the other raw-layer classes. @internal */
  get raw(): RawDatabase {
    if (!this.raw_) throw new Error(`${this.name}: database used after it was freed`);
    return this.raw_;
  }

  get isFreed(): boolean {
    return this.raw_ === null;
  }

  /** One more owner (a character); pair with `release()`. */
  retain(): this {
    this.raw; // throws when freed
    this.references++;
    return this;
  }

  /** Drops one owner; the last one frees the WASM memory. */
  release(): void {
    if (!this.raw_) return;
    if (--this.references > 0) return;
    freeRaw(this.raw_, 'rawdatabase');
    this.raw_ = null;
    this.onFree?.();
  }

  /** Local positions, `F×J×3` (joint 0: world position of the virtual root). */
  get localPositions(): Float32Array {
    return this._localPositions.get(wasmMemory(), this.raw.local_positions_ptr());
  }

  /** Local rotations `(x, y, z, w)`, `F×J×4`. */
  get localRotations(): Float32Array {
    return this._localRotations.get(wasmMemory(), this.raw.local_rotations_ptr());
  }

  /** Foot contacts, `F×2` (left, right); 1 = in contact. */
  get contacts(): Uint8Array {
    return this._contacts.get(wasmMemory(), this.raw.contacts_ptr());
  }

  /** Normalized feature matrix, `F×D`. */
  get featureMatrix(): Float32Array {
    return this._features.get(wasmMemory(), this.raw.features_ptr());
  }

  /**
   * World joint positions (`J×3`) of `frame` (the runtime's FK). The view is reused: the next
   * call overwrites it. Rotations of the same frame: `worldRotations()`.
   */
  worldPositions(frame: number): Float32Array {
    return this._worldPositions.get(wasmMemory(), this.raw.world_positions(frame));
  }

  /** World rotations (`J×4`) of the frame of the last `worldPositions()` call (reused view). */
  worldRotations(): Float32Array {
    return this._worldRotations.get(wasmMemory(), this.raw.world_rotations_ptr());
  }

  /** World joint positions of the rest pose (J×3, a copy). */
  restPositions(): Float32Array {
    return this._worldPositions.get(wasmMemory(), this.raw.rest_positions()).slice();
  }

  /** Index of the clip containing `frame`. */
  clipAt(frame: number): number {
    return this.raw.clip_at(frame);
  }

  /** Tags whose ranges contain `frame`. */
  tagsAt(frame: number): string[] {
    return this.tags.filter((t) => t.ranges.some(([s, e]) => frame >= s && frame < e)).map((t) => t.name);
  }
}

/** Databases loaded by URL, shared by everyone who asks for the same one. */
const shared = new Map<string, Promise<Database>>();

/**
 * Loads a database once and shares it: every call with the same URL gets the same `Database`
 * with one more reference (`release()` it when done; characters retain their own). Bytes are
 * loaded as a new, unshared database.
 */
export async function loadDatabase(source: string | URL | Uint8Array, options: FetchOptions = {}): Promise<Database> {
  if (source instanceof Uint8Array) {
    await initWasm();
    return Database.fromBytes(source, 'database');
  }
  const href = new URL(String(source), typeof location !== 'undefined' ? location.href : undefined).href;
  let pending = shared.get(href);
  if (pending) {
    const db = await pending;
    if (!db.isFreed) return db.retain();
  }
  pending = (async () => {
    const [bytes] = await Promise.all([fetchBytes(href, { stage: 'database', ...options }), initWasm(undefined, options)]);
    const db = Database.fromBytes(bytes, href, () => shared.delete(href));
    mark('mm:database-ready');
    return db;
  })();
  shared.set(href, pending);
  try {
    return await pending;
  } catch (e) {
    shared.delete(href);
    throw e;
  }
}

/**
 * The shipped database, the way the defaults load it: its first part (`DEFAULT_FIRST_PART`,
 * ~0.5 MB compressed: the first frame comes after it; characters move to the whole after it),
 * or the whole when the first part is not there (an asset folder without it). @internal
 */
export async function loadDefaultDatabase(options: FetchOptions = {}): Promise<Database> {
  try {
    return await loadDatabase(assetUrl(DEFAULT_FIRST_PART), options);
  } catch (e) {
    if (options.signal?.aborted) throw e;
    return loadDatabase(assetUrl(DEFAULT_DATABASE), options);
  }
}

/** One database a site serves (`databases/index.json`, written by the set-up). */
export interface DatabaseEntry {
  /** Short name (`locomotion`). */
  readonly name: string;
  /** Where to load it from (versioned by its content hash). */
  readonly url: string;
  readonly bytes: number;
}

/**
 * The databases a site serves, from its generated `databases/index.json` (default: the one
 * beside the library's default assets). Rejects with a message naming the URL when there is no
 * index; pages then offer only the database they loaded.
 */
export async function listDatabases(indexUrl: string | URL = assetUrl('databases/index.json')): Promise<DatabaseEntry[]> {
  const href = String(indexUrl);
  const bytes = await fetchBytes(href, { stage: 'database index', cache: false });
  let index: { databases?: { name: string; file: string; bytes: number; sha256?: string }[] };
  try {
    index = JSON.parse(new TextDecoder().decode(bytes)) as typeof index;
  } catch (e) {
    throw new Error(`${href}: not a database index (${e instanceof Error ? e.message : String(e)})`);
  }
  return (index.databases ?? []).map((d) => {
    const url = new URL(d.file, href);
    if (d.sha256) url.searchParams.set('v', d.sha256);
    return { name: d.name, url: url.href, bytes: d.bytes };
  });
}
