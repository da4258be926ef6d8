/**
 * `Character`: the library's front door for one animated person. A database (shared) and an
 * avatar (or none: the skeleton) become a three.js object to add to any scene; `update(dt)`
 * runs the per-frame recipe once — drive → runtime update (search, playback, inertialization,
 * foot lock, world pose) → avatar retarget → skin (at render) — and the debug views.
 *
 * One position space. The runtime works in database metres; the avatar may be smaller or
 * larger than the mocap actor, so the whole character is drawn at `worldScale` (avatar metres
 * per database metre: the avatar's hips scale) — avatar, skeleton, debug views and the root
 * reported to callers all go through the same two conversions (`toDatabase`, `fromDatabase`),
 * through `object3d`'s own transform. Camera, path and input positions are in the frame of
 * `object3d`'s parent.
 */
import * as THREE from 'three';
import { Avatar, type AvatarOptions } from '../avatar/avatar.ts';
import { loadSharedAvatar } from '../avatar/shared.ts';
import { CharacterRuntime, type RuntimeSettings } from '../core/character.ts';
import { createDrive, type Drive, type MoveInput } from '../core/drive.ts';
import { type Database, loadDatabase, loadDefaultDatabase } from '../core/database.ts';
import { DEFAULT_AVATAR, assetUrl } from '../assets.ts';
import { type FetchOptions, errorMessage, mark } from '../fetch.ts';
import { DebugViews } from '../views/debug-views.ts';
import { SkeletonView } from '../views/skeleton-view.ts';

/** Root of the character: position (m) and yaw (rad, 0 = facing +Z) in `object3d`'s parent frame. */
export interface Root {
  x: number;
  y: number;
  z: number;
  yaw: number;
}

export interface MoveOptions {
  run?: boolean;
  /** Keep facing this direction (x, z) while moving (side-steps, backwards). */
  face?: { x: number; z: number };
}

export interface PathOptions {
  /** m/s of every segment (default 1.4, or 3.5 with `run`), or one per segment. */
  speed?: number | readonly number[];
  run?: boolean;
  /** Back to the first point and round again. */
  loop?: boolean;
}

export interface CharacterOptions {
  /** Runtime settings over the defaults (docs/runtime.md). */
  settings?: RuntimeSettings;
  /** Draw the skeleton (default: only without an avatar). */
  skeleton?: boolean;
  /** Show the debug views (simulated character, requested and matched trajectories, foot locks). */
  debug?: boolean;
}

export interface CreateOptions extends CharacterOptions, FetchOptions {
  /**
   * A database, or where to load one (shared by URL); default the shipped locomotion database
   * (`DEFAULT_DATABASE`, fetched only then; from a bundler, where it put the file): its first
   * part first, the whole after the first frame (`Character.whole()`).
   */
  database?: Database | string | URL | Uint8Array;
  /**
   * An avatar, a GLB/VRM URL or bytes, a three.js object with skinned meshes, or null: skeleton
   * only; default the shipped avatar (`DEFAULT_AVATAR`, fetched only then). A URL is loaded
   * once for every character on the page that shows it (and every `<mm-avatar>`): the others
   * get clones sharing its geometry, materials and textures (`Avatar.clone`; a VRM loads for each).
   */
  avatar?: Avatar | string | URL | Uint8Array | THREE.Object3D | null;
  /** Avatar loading options (manual joint map). */
  avatarOptions?: AvatarOptions;
}

/**
 * Boolean tag queries over the database's tags (`database.tags`): searches return only frames
 * carrying every `require` tag and none of the `exclude` ones; a frame lacking any `prefer` tag
 * costs `style_bias` more, like a frame of another style (docs/runtime.md, "Styles and tags").
 */
export interface TagQuery {
  require?: readonly string[];
  exclude?: readonly string[];
  prefer?: readonly string[];
}

/**
 * Takes over a character's simulation step. With a stepper set, the drive methods only build
 * the drive value (`character.drive`; paths are still checked) and `update(dt)` calls
 * `stepper.step(character, dt)` instead of stepping the runtime with it, then poses the avatar
 * as usual. A shared room needs this: its local member quantizes and sends every step's value
 * before taking it, and a remote member replays the values its sender sent (web/src/rooms), each
 * through `applyDrive` and `advance`.
 */
export interface CharacterStepper {
  /** The character's style changed (`setStyle`): a shared room tells the others. */
  styleChanged?(style: string): void;
  step(character: Character, dt: number): void;
}

/** Walking and running speeds of paths (m/s). */
export const WALK_SPEED = 1.4;
export const RUN_SPEED = 3.5;

const _v = new THREE.Vector3();
const _q = new THREE.Quaternion();
const _m = new THREE.Matrix4();
const _e = new THREE.Euler();

export class Character {
  /** Add this to a scene. Move, turn or scale it to place the character's floor frame. */
  readonly object3d = new THREE.Group();
  private runtime_: CharacterRuntime;
  /** Drawn in database units: the skeleton and the debug views. */
  private readonly databaseSpace = new THREE.Group();
  private avatar_: Avatar | null = null;
  private skeletonView: SkeletonView;
  private debugViews_: DebugViews | null = null;
  /** The one drive value (database units): what the drive methods build and `update` hands to the runtime. */
  private readonly drive_: Drive = createDrive();
  /** Takes over `update`'s simulation step when set (see `CharacterStepper`); null: the character steps itself. */
  stepper: CharacterStepper | null = null;
  private readonly root_: Root = { x: 0, y: 0, z: 0, yaw: 0 };
  private worldScale_ = 1;
  private showSkeleton_: boolean | undefined;
  private disposed = false;
  /** The whole database's load for a character on a first part (`whole()`), and the advances before it starts. */
  private whole_: Promise<Database> | null = null;
  private advances = 0;

  /**
   * The one dispose rule: after `dispose()` every method and property of the character throws
   * this error (`dispose()` itself may be called again; `isDisposed` tells).
   */
  private live(): void {
    if (this.disposed) throw new Error('Character used after dispose()');
  }

  /** Whether `dispose()` was called. */
  get isDisposed(): boolean {
    return this.disposed;
  }

  /** The motion-matching runtime of this character. */
  get runtime(): CharacterRuntime {
    this.live();
    return this.runtime_;
  }

  /**
   * A character on `database` (retained until `dispose()`) with `avatar` (owned: disposed
   * with the character), standing at the origin facing +Z.
   */
  constructor(database: Database, avatar: Avatar | null = null, options: CharacterOptions = {}) {
    this.runtime_ = new CharacterRuntime(database, options.settings);
    this.object3d.name = 'mm-character';
    this.object3d.add(this.databaseSpace);
    this.showSkeleton_ = options.skeleton;
    this.skeletonView = this.makeSkeletonView(database);
    this.setAvatar(avatar);
    if (options.debug) this.debug = true;
    this.pose(0);
  }

  /**
   * Loads what is needed (database shared by URL, avatar: in parallel) and makes a character.
   * `Character.create()` alone: the shipped database and avatar.
   */
  static async create(options: CreateOptions = {}): Promise<Character> {
    const { database, avatar = assetUrl(DEFAULT_AVATAR), avatarOptions, ...rest } = options;
    // The avatar downloads while the database does; a failed database drops it.
    // A URL is loaded once for every character on the page that shows it (avatar/shared.ts).
    const avatarLoad: Promise<Avatar | null> =
      avatar instanceof Avatar || avatar === null
        ? Promise.resolve(avatar)
        : typeof avatar === 'string' || avatar instanceof URL
          ? loadSharedAvatar(avatar, { ...avatarOptions, ...rest })
          : Avatar.load(avatar, { ...avatarOptions, ...rest });
    avatarLoad.catch(() => undefined);
    let db: Database;
    try {
      if (database === undefined) db = await loadDefaultDatabase(rest);
      else db = typeof database === 'object' && !(database instanceof URL) && !(database instanceof Uint8Array) ? database.retain() : await loadDatabase(database, rest);
    } catch (e) {
      void avatarLoad.then((a) => a !== avatar && a?.dispose(), () => undefined);
      throw e;
    }
    try {
      const a = await avatarLoad;
      return new Character(db, a, options);
    } finally {
      db.release(); // the character holds its own reference
    }
  }

  /** The database it plays: a first part moves to its whole after the first frame (`whole()`). */
  get database(): Database {
    return this.runtime.database;
  }

  get avatar(): Avatar | null {
    this.live();
    return this.avatar_;
  }

  /** Avatar metres per database metre: how large the character is drawn. */
  get worldScale(): number {
    this.live();
    return this.worldScale_;
  }

  /**
   * Swaps the avatar (null: the skeleton). The character keeps standing where it stands: the
   * runtime is re-placed for the new scale. The old avatar is disposed.
   */
  setAvatar(avatar: Avatar | null): void {
    this.live();
    const before = this.root;
    const scale = avatar ? avatar.bind(this.database) : 1;
    if (this.avatar_ && this.avatar_ !== avatar) {
      this.object3d.remove(this.avatar_.object);
      this.avatar_.dispose();
    }
    this.avatar_ = avatar;
    if (avatar) this.object3d.add(avatar.object);
    this.worldScale_ = scale;
    this.databaseSpace.scale.setScalar(scale);
    this.updateSkeletonVisibility();
    if (before) this.teleport(before.x, before.z, before.yaw);
  }

  /**
   * Starts the runtime afresh on the same database with the same settings, at the database
   * origin: no inertialization from the motion before (shared rooms start every copy of a
   * member's character this way, then place it, so the copies compute the same motion).
   */
  restartRuntime(): void {
    const old = this.runtime;
    this.runtime_ = new CharacterRuntime(old.database, old.settings());
    old.free();
    this.leavePath();
    // The debug views stay (same database, same trajectory sizes): rebuilding them would drop a
    // page's choice of which to show, and their materials' programs (a compile each, seconds in
    // all on a software GPU, when a room's welcome restarts the runtime).
  }

  /**
   * Switches to another database (same or different skeleton): the character carries over
   * where it stands; the avatar is re-bound.
   */
  setDatabase(database: Database): void {
    const before = this.root;
    const settings = this.runtime.settings();
    const old = this.runtime;
    this.runtime_ = new CharacterRuntime(database, settings);
    old.free();
    [this.whole_, this.advances] = [null, 0]; // a first part given here loads its own whole
    this.leavePath();
    this.databaseSpace.remove(this.skeletonView.object);
    disposeObject(this.skeletonView.object);
    this.skeletonView = this.makeSkeletonView(database);
    const debug = this.debug;
    this.debug = false;
    this.debug = debug;
    this.setAvatar(this.avatar_);
    this.teleport(before.x, before.z, before.yaw);
  }

  private makeSkeletonView(database: Database): SkeletonView {
    const feet = (side: 'left' | 'right') => [database.roles.get(`${side}_foot`), database.roles.get(`${side}_toe`)].filter((j): j is number => j !== undefined);
    const view = new SkeletonView(database.jointParents, feet('left'), feet('right'));
    this.databaseSpace.add(view.object);
    view.object.visible = this.showSkeleton_ ?? !this.avatar_;
    return view;
  }

  private updateSkeletonVisibility(): void {
    this.skeletonView.object.visible = this.showSkeleton_ ?? !this.avatar_;
  }

  /** Whether the skeleton is drawn (default: only without an avatar). */
  get showSkeleton(): boolean {
    this.live();
    return this.skeletonView.object.visible;
  }
  set showSkeleton(on: boolean) {
    this.live();
    this.showSkeleton_ = on;
    this.updateSkeletonVisibility();
  }

  /** The debug views (simulated character, trajectories, foot locks), or null when off. */
  get debugViews(): DebugViews | null {
    this.live();
    return this.debugViews_;
  }
  get debug(): boolean {
    this.live();
    return this.debugViews_ !== null;
  }
  set debug(on: boolean) {
    this.live();
    if (on === (this.debugViews_ !== null)) return;
    if (on) {
      this.debugViews_ = new DebugViews(this.runtime);
      this.databaseSpace.add(this.debugViews_.object);
    } else if (this.debugViews_) {
      this.databaseSpace.remove(this.debugViews_.object);
      this.debugViews_.dispose();
      this.debugViews_ = null;
    }
  }

  // ---- units: the one conversion between the caller's frame and the runtime's

  /** A floor point (x, z) of `object3d`'s parent frame in database units (into `out`). */
  toDatabase(x: number, z: number, out: THREE.Vector3 = _v): THREE.Vector3 {
    this.live();
    this.object3d.updateMatrix();
    return out.set(x, 0, z).applyMatrix4(_m.copy(this.object3d.matrix).invert()).multiplyScalar(1 / this.worldScale_);
  }

  /** A direction (x, z) of the parent frame in database axes (length kept up to scale). */
  private directionToDatabase(x: number, z: number): THREE.Vector3 {
    this.object3d.updateMatrix();
    return _v.set(x, 0, z).applyQuaternion(_q.copy(this.object3d.quaternion).invert());
  }

  /** A database point in `object3d`'s parent frame (into `out`). */
  fromDatabase(x: number, y: number, z: number, out: THREE.Vector3 = _v): THREE.Vector3 {
    this.live();
    this.object3d.updateMatrix();
    return out.set(x, y, z).multiplyScalar(this.worldScale_).applyMatrix4(this.object3d.matrix);
  }

  /** Parent-frame metres per database metre (world scale × `object3d`'s own scale). */
  get metresPerDatabaseUnit(): number {
    this.live();
    return this.worldScale_ * this.object3d.scale.x;
  }

  /** Yaw of `object3d` about +Y in its parent frame. */
  private get frameYaw(): number {
    return _e.setFromQuaternion(this.object3d.quaternion, 'YXZ').y;
  }

  // ---- driving

  /**
   * Move input: walk toward direction (x, z) of the parent frame, length 0–1 = stick amount
   * (longer is clamped); (0, 0) stands. Leaves a path.
   */
  setMove(x: number, z: number, options: MoveOptions = {}): void {
    this.live();
    const d = this.drive_;
    const m = this.directionToDatabase(x, z);
    d.moveX = m.x;
    d.moveZ = m.z;
    d.run = options.run ?? false;
    d.strafe = options.face !== undefined;
    if (options.face) {
      const f = this.directionToDatabase(options.face.x, options.face.z);
      const l = Math.hypot(f.x, f.z) || 1;
      d.faceX = f.x / l;
      d.faceZ = f.z / l;
    }
    d.mode = 'move';
  }

  /** The move input as devices write it (parent-frame directions); see `setMove`. */
  setInput(input: Readonly<MoveInput>): void {
    this.setMove(input.moveX, input.moveZ, { run: input.run, face: input.strafe ? { x: input.faceX, z: input.faceZ } : undefined });
  }

  /** Walks (or runs) from where it stands to (x, z) and stops there. */
  walkTo(x: number, z: number, options: PathOptions = {}): void {
    const r = this.root;
    this.followPath([[r.x, r.z], [x, z]], options);
  }

  /**
   * Follows keypoints [[x, z], …] (parent frame) from the first, at `speed` m/s; stops at the
   * last unless `loop`. Throws on a path the runtime cannot follow (fewer than 2 points…).
   */
  followPath(points: readonly (readonly [number, number])[], options: PathOptions = {}): void {
    const loop = options.loop ?? false;
    const base = options.run ? RUN_SPEED : WALK_SPEED;
    const segments = loop ? points.length : points.length - 1;
    const speeds = new Float32Array(Math.max(0, segments));
    const k = 1 / this.metresPerDatabaseUnit;
    for (let i = 0; i < speeds.length; i++) {
      const s = typeof options.speed === 'number' ? options.speed : (options.speed?.[i] ?? base);
      speeds[i] = s * k;
    }
    const flat = new Float32Array(points.length * 2);
    points.forEach(([x, z], i) => {
      const p = this.toDatabase(x, z);
      flat[2 * i] = p.x;
      flat[2 * i + 1] = p.z;
    });
    this.runtime.setPath(flat, speeds, loop); // throws here on a bad path, before the drive changes
    const d = this.drive_;
    d.moveX = d.moveZ = 0;
    d.mode = 'path';
    d.path = { points: flat, speeds, looped: loop }; // a new object: the runtime starts it afresh
  }

  /** Whether the character is on a path (`walkTo`, `followPath`) rather than move input. */
  get followingPath(): boolean {
    this.live();
    return this.drive_.mode === 'path';
  }

  /**
   * The drive value the drive methods built (database units; the same object, updated by each
   * call): what `update` hands to the runtime, and what a shared room sends.
   */
  get drive(): Readonly<Drive> {
    this.live();
    return this.drive_;
  }

  /** Stands still: no move input, no path. */
  stop(): void {
    this.live();
    this.leavePath();
    this.drive_.moveX = this.drive_.moveZ = 0;
    this.drive_.strafe = false;
    this.drive_.mode = 'move';
  }

  /** A runtime restarted or switched off its path: move input again, standing. */
  private leavePath(): void {
    if (this.drive_.mode !== 'path') return;
    this.drive_.mode = 'move';
    this.drive_.moveX = this.drive_.moveZ = 0;
  }

  /** Places the character at (x, z) facing `yaw` (parent frame). */
  teleport(x: number, z: number, yaw = 0): void {
    const p = this.toDatabase(x, z);
    this.runtime.teleport(p.x, p.z, yaw - this.frameYaw);
    this.pose(0);
  }

  /**
   * Tracked drive (VR): the root's target on the floor — the head centre, or where the hips are
   * thought to be (`TrackedDrive.rootTarget`) — the head's ground velocity (parent frame, m, m/s)
   * and the body yaw (rad) this frame; α clamps the root to the target. With `body`, the tracked
   * hips' floor position, velocity and facing instead, which the shown hips follow (WebXR body
   * tracking). See `TrackedDrive` for the whole VR recipe.
   */
  setTracked(headX: number, headZ: number, velocityX: number, velocityZ: number, yaw: number, body = false): void {
    this.live();
    const d = this.drive_;
    const p = this.toDatabase(headX, headZ);
    d.headX = p.x;
    d.headZ = p.z;
    const v = this.directionToDatabase(velocityX, velocityZ).multiplyScalar(1 / this.metresPerDatabaseUnit);
    d.velocityX = v.x;
    d.velocityZ = v.z;
    d.yaw = yaw - this.frameYaw;
    d.body = body;
    d.mode = 'tracked';
  }

  /** Lowers the hips `drop` metres (parent frame) with the feet kept planted (VR crouching). */
  setHipsDrop(drop: number): void {
    this.live();
    this.drive_.hipsDrop = drop / this.metresPerDatabaseUnit;
    this.drive_.bend = 0;
  }

  /**
   * VR crouching and bending over: the user's head centre is `headDrop` m (parent frame) below
   * its standing height, the headset pitched `pitch` rad (negative: looking down). The runtime
   * splits the drop between the hips (knees bend, feet planted) and a forward bend of the torso
   * by the headset's pitch (docs/vr.md, "Crouching and bending over"); the drive value holds the
   * split (`hipsDrop` database units, `bend` rad).
   */
  setCrouch(headDrop: number, pitch: number): void {
    const runtime = this.runtime;
    runtime.setCrouch(headDrop / this.metresPerDatabaseUnit, pitch);
    this.drive_.hipsDrop = runtime.hipsDrop;
    this.drive_.bend = runtime.torsoBend;
  }

  /**
   * α: how far (m, parent frame) the character may lag where it is asked to be. Throws on a
   * value that is not a number ≥ 0 (NaN, ∞, a string), changing nothing.
   */
  setAlpha(alpha: number): void {
    this.live();
    if (!(typeof alpha === 'number' && alpha >= 0 && alpha < Infinity)) throw new Error(`setAlpha: α must be a number of metres ≥ 0, got ${String(alpha)}`);
    this.drive_.clampDistance = alpha / this.metresPerDatabaseUnit;
  }

  // ---- the simulation in database units (shared rooms replay it: web/src/rooms)

  /**
   * Hands a drive value (database units) to the runtime now, its path first when new: what
   * `update` does with the character's own value, and a room's stepper with the value it sent
   * or received. Throws on a path the runtime cannot follow; nothing changes then.
   */
  applyDrive(drive: Readonly<Drive>): void {
    this.runtime.setDrive(drive);
  }

  /** Advances the simulation `dt` seconds under the drive last applied, without posing. */
  advance(dt: number): void {
    // On a first part, the whole loads once the first frame is out (its bytes must not delay it).
    if (this.advances < 2 && ++this.advances === 2 && this.runtime.database.wholeUrl) {
      this.whole().catch((e: unknown) => this.disposed || console.warn(errorMessage(e)));
    }
    this.runtime.update(dt);
  }

  /**
   * The whole database, once the character plays it. A character made on a first part
   * (`Database.wholeUrl`: what `Character.create()` and `<mm-avatar>` start on by default) loads
   * the whole after its first frame, or when this is called, and moves onto it as soon as it is
   * here, between two updates, playing the same frame there: nothing it shows changes. Resolves
   * at once on a database that is no first part. Rejects, the character staying on the part,
   * when the whole cannot be loaded or is not the file the part names (another build); calling
   * it again then tries again.
   */
  whole(): Promise<Database> {
    const part = this.runtime.database;
    if (!part.wholeUrl) return Promise.resolve(part);
    // A failed load is not kept: the next call tries again.
    return (this.whole_ ??= this.loadWhole(part, part.wholeUrl).catch((e: unknown) => {
      this.whole_ = null;
      throw e;
    }));
  }

  private async loadWhole(part: Database, url: string): Promise<Database> {
    let whole: Database;
    try {
      whole = await loadDatabase(url, { stage: 'whole database', background: true });
    } catch (e) {
      throw new Error(`${part.name} is a first part; its whole did not load, so the character keeps the part: ${errorMessage(e)}`);
    }
    try {
      if (this.disposed) throw new Error('Character disposed before its whole database loaded');
      if (this.runtime.database !== part) throw new Error(`the character was given another database before ${url} loaded`);
      if (!part.isPartOf(whole)) {
        throw new Error(`${url} is not the database ${part.name} is the first part of (another build?): the character keeps the part`);
      }
      this.runtime.enterWhole(whole);
      mark('mm:whole-database'); // for load benchmarks: the whole in use (scripts/bench-load.mjs)
      return whole;
    } finally {
      whole.release(); // the runtime holds its own reference
    }
  }

  /**
   * Starts the runtime afresh (see `restartRuntime`) placed at (x, z, yaw) database units:
   * playing database `frame` from there, moving as it moves, or (`frame` −1) searching from the
   * placed root at its first update. Copies restarted from the same numbers compute the same motion.
   */
  restartAt(frame: number, x: number, z: number, yaw: number): void {
    this.restartRuntime();
    if (frame >= 0) this.runtime.teleportPlaying(frame, x, z, yaw);
    else this.runtime.teleport(x, z, yaw);
  }

  /** The runtime's whole state (`CharacterRuntime.saveState`): a copy that loads it continues from these exact floats. */
  saveState(): Uint8Array {
    return this.runtime.saveState();
  }

  /** Continues from `saveState` bytes (a path it follows applied first). Throws with the reason on bytes it refuses. */
  loadState(bytes: Uint8Array): void {
    this.runtime.loadState(bytes);
  }

  /** The root in database units: x, y, z and yaw (a zero-copy view, valid until the next call). */
  get databaseRoot(): Float32Array {
    return this.runtime.root;
  }

  // ---- style and tags

  /** The motion styles the database offers (`database.styles`; empty without styles). */
  get styles(): readonly string[] {
    return this.database.styles;
  }

  /** The style searches prefer: `neutral` unless `setStyle` chose another. */
  get style(): string {
    const style = this.runtime.settings().style;
    return typeof style === 'string' ? style : 'neutral';
  }

  /**
   * Prefers `style`'s clips (one of `styles`): a frame of another style costs `style_bias`
   * (default 10) more in every search, so the character moves in that style wherever the
   * database has the move and falls back to the others where it does not. `neutral` (the
   * default) plays stylized clips only where nothing neutral fits.
   *
   * @throws Error naming the style and the database's styles when it has no such style.
   */
  setStyle(style: string): void {
    const styles = this.database.styles;
    if (!styles.includes(style)) {
      const have = styles.length ? `it has ${styles.join(', ')}` : 'it was built without styles';
      throw new Error(`unknown style ${JSON.stringify(style)} for the database ${this.database.name}: ${have}`);
    }
    if (style === this.style) return;
    this.runtime.setSettings({ style });
    this.stepper?.styleChanged?.(style);
  }

  /**
   * Restricts and biases the searches by tags (see {@link TagQuery}); `{}` lifts it.
   *
   * @throws Error naming any tag the database does not have (nothing changes).
   */
  setTagQuery(query: TagQuery): void {
    const known = new Set(this.database.tags.map((t) => t.name));
    const lists = { require: query.require ?? [], exclude: query.exclude ?? [], prefer: query.prefer ?? [] };
    for (const [field, names] of Object.entries(lists)) {
      const unknown = names.filter((n) => !known.has(n));
      if (unknown.length) {
        throw new Error(`${field}: no tag ${unknown.map((n) => JSON.stringify(n)).join(', ')} in the database ${this.database.name} (it has ${[...known].join(', ')})`);
      }
    }
    this.runtime.setSettings({ require_tags: lists.require, exclude_tags: lists.exclude, prefer_tags: lists.prefer });
  }

  // ---- the frame

  /** Advances `dt` seconds and poses everything (the per-frame recipe). */
  update(dt: number): void {
    this.live();
    if (this.stepper) this.stepper.step(this, dt);
    else {
      this.applyDrive(this.drive_);
      this.advance(dt);
    }
    this.pose(dt);
  }

  /**
   * Poses the avatar (and skeleton, debug views) from the runtime's world pose, `dt` seconds after
   * the last pose: what `update` does after advancing. For code that steps the simulation itself
   * (`applyDrive`, `advance`) and poses apart, e.g. a crowd timing each part; calling `update`
   * after `advance` would advance twice.
   */
  pose(dt: number): void {
    this.live();
    const runtime = this.runtime;
    if (this.avatar_) this.avatar_.pose(runtime, dt);
    if (this.skeletonView.object.visible) {
      const c = runtime.contacts;
      this.skeletonView.update(runtime.worldPositions, (c & 1) !== 0, (c & 2) !== 0);
    }
    this.debugViews_?.update(this.runtime);
  }

  // ---- reading

  /** Where the character stands now (parent frame; the same object, updated by each call). */
  get root(): Readonly<Root> {
    const r = this.runtime.root;
    const p = this.fromDatabase(r[0], r[1], r[2]);
    this.root_.x = p.x;
    this.root_.y = p.y;
    this.root_.z = p.z;
    this.root_.yaw = r[3] + this.frameYaw;
    return this.root_;
  }

  /** World joint position of the shown pose (parent frame), e.g. of a role's joint. */
  jointPosition(joint: number, out = new THREE.Vector3()): THREE.Vector3 {
    const w = this.runtime.worldPositions;
    return this.fromDatabase(w[3 * joint], w[3 * joint + 1], w[3 * joint + 2], out);
  }

  /** The database frame playing. */
  get frame(): number {
    return this.runtime.frame;
  }

  /** Name of the clip playing. */
  get clip(): string {
    return this.database.clips[this.database.clipAt(this.runtime.frame)]?.name ?? '';
  }

  /** Tags of the frame playing (`walk`, `run`, `turn`…). */
  get tags(): string[] {
    return this.database.tagsAt(this.runtime.frame);
  }

  /** Foot contacts of the frame playing: bit 1 left, bit 2 right. */
  get contacts(): number {
    return this.runtime.contacts;
  }

  /** Runtime settings (docs/runtime.md). */
  get settings(): RuntimeSettings {
    return this.runtime.settings();
  }
  set settings(patch: RuntimeSettings) {
    this.runtime.setSettings(patch);
  }

  /** Frees the runtime's WASM memory (and the database's, with its last character) and GPU objects. */
  dispose(): void {
    if (this.disposed) return;
    this.debug = false;
    this.disposed = true;
    if (this.avatar_) {
      this.object3d.remove(this.avatar_.object);
      this.avatar_.dispose();
      this.avatar_ = null;
    }
    disposeObject(this.databaseSpace);
    this.object3d.removeFromParent();
    this.runtime_.free();
  }
}

function disposeObject(root: THREE.Object3D): void {
  root.traverse((o) => {
    const m = o as THREE.Mesh;
    m.geometry?.dispose();
    for (const mat of Array.isArray(m.material) ? m.material : m.material ? [m.material] : []) mat.dispose();
  });
}
