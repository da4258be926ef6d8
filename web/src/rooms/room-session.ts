/**
 * `RoomSession`: a page's person in a shared room, on the public API. It takes the local
 * `Character`'s step (`character.stepper`: every step quantized, sent and taken with the sent
 * numbers — `LocalAvatar`), and shows every other member as a `Character` of their own, fed by
 * the room stream (`RemoteAvatar` through a `RoomCharacter`), with a name label; members who
 * leave or time out are removed at once. Call `update(dt)` once a frame after the local
 * character's update; it steps and poses the remote members.
 *
 * Remote data is untrusted: the client screens joins (avatar URLs outside the page's origin
 * become the built-in avatar) and decodes every message with the protocol's checks; here a
 * database the page does not have or an avatar that fails to load becomes the page's own
 * database / the skeleton, with a note. Nothing from the room reaches the page as markup.
 */
import * as THREE from 'three';
import { DEFAULT_AVATAR, assetUrl } from '../assets.ts';
import type { Avatar } from '../avatar/avatar.ts';
import { loadSharedAvatar } from '../avatar/shared.ts';
import { Character, type CharacterStepper } from '../character/character.ts';
import { Database } from '../core/database.ts';
import { createTrackedInput, type DrivePath } from '../core/drive.ts';
import { errorMessage } from '../fetch.ts';
import { MISSING, TRACKED } from '../vr/trackers.ts';
import { VR_SETTINGS, DEFAULT_ALPHA } from '../vr/tracked-drive.ts';
import type { TrackerPose } from '../vr/body-yaw.ts';
import { compileNow } from '../views/stage.ts';
import { UpperBody } from '../vr/upper-body.ts';
import { LocalAvatar } from './local-avatar.ts';
import { NameLabel } from './name-label.ts';
import { angleToI16, fromMm, i16ToAngle, toMm, type AvatarChoice, type DeviceSet, type JoinInfo, type MemberInfo, type RoomTrackerPose } from './protocol.ts';
import { RemoteAvatar } from './remote-avatar.ts';
import { RoomCharacter } from './room-character.ts';
import { RoomClient, type RoomClientOptions } from './room-client.ts';
import { setRoomOf } from './room-of.ts';
import { trackedFromDrive } from './step-drive.ts';

export interface RoomSessionOptions {
  roomId: string;
  /** The local person's character: the session takes its `stepper` until `close()`. */
  character: Character;
  /** Where the other members' avatars go (the page's scene). */
  scene: THREE.Object3D;
  /**
   * The page's renderer, if it has one: the name labels' shader is compiled and linked with it as
   * the session starts, instead of in the frame that first shows someone (a second or more on a
   * software GPU; the others' models share the page's own avatar's programs).
   */
  renderer?: THREE.WebGLRenderer;
  mode: 'desktop' | 'vr';
  /** Shown above this person's avatar to the others (≤ 48 UTF-8 bytes). */
  name: string;
  /** How the others load this person's avatar: a same-origin URL or a built-in one (default: built-in 0). */
  avatar?: AvatarChoice;
  /** Database id (default: the character's database file name without `.mmdb`). */
  database?: string;
  /** Calibrated eye height, m (0: not calibrated). */
  height?: number;
  devices?: DeviceSet;
  /** VR: the head and grips to send each step (e.g. `TrackedDrive.trackers`), shown by the others. */
  trackers?: { head: TrackerPose; left: TrackerPose; right: TrackerPose };
  /** Built-in avatar URLs by id (default: [the shipped avatar]); null: the skeleton. */
  builtinAvatars?: readonly (string | null)[];
  /** Passed to the `RoomClient` (url, reconnect, avatarAllowList…). */
  client?: Partial<Omit<RoomClientOptions, 'roomId' | 'join'>>;
  /**
   * Refused or patched remote data, connection trouble: shown to the person. Called once per
   * cause and member (the text with its numbers taken out); repeats only count up in `notes`.
   */
  onNote?: (text: string) => void;
  /** Members came, went or changed. */
  onMembers?: () => void;
  /** Records sent and shown roots (tests: `trace`). */
  trace?: boolean;
}

/** One member as a page reads it (`RoomSession.list()`): a copy, made when asked. */
export interface RoomMemberView {
  /** Member id in the room (1–255; a reconnect gets a new one). */
  id: number;
  /** The name the member chose (plain text: never markup). */
  name: string;
  mode: 'desktop' | 'vr';
  /** Whether its avatar is drawn now (false while it loads or waits for its first state). */
  shown: boolean;
  /** Where its avatar is drawn (the scene's floor frame, m) and which way it faces (rad, 0 = +z); NaN before it is shown. */
  x: number;
  z: number;
  yaw: number;
}

/** A note as the page shows it: once per cause and member, with how many times it came. */
export interface RoomNote {
  text: string;
  count: number;
}

/** One other person in the room. */
export interface RoomMember {
  readonly id: number;
  readonly join: JoinInfo;
  /** Null while the avatar loads (the stream is kept meanwhile). */
  readonly character: Character | null;
  readonly remote: RemoteAvatar | null;
  readonly label: NameLabel;
  /** Where the avatar is drawn now (scene frame: m, rad). */
  readonly shown: { x: number; z: number; yaw: number };
}

interface Member extends RoomMember {
  character: Character | null;
  remote: RemoteAvatar | null;
  roomCharacter: RoomCharacter | null;
  /** A VR member's head turn and arms reaching its controllers, and the world trackers fed to it. */
  upperBody: RemoteUpperBody | null;
  /** Messages that arrived while the avatar loaded, replayed once it is there. */
  pending: (() => void)[];
  gone: boolean;
}

/** Messages kept per member while its avatar loads (~6 s of stream); more start it over. */
const MAX_PENDING = 128;

const _v = new THREE.Vector3();
const _q2 = new THREE.Quaternion();

/** A remote VR member's upper body and the world-space tracker poses handed to it each frame. */
interface RemoteUpperBody {
  body: UpperBody;
  poses: [WorldPose, WorldPose, WorldPose];
}
interface WorldPose extends TrackerPose {
  readonly position: Float64Array;
  readonly rotation: Float64Array;
  status: number;
}
const worldPose = (): WorldPose => ({ position: new Float64Array(3), rotation: new Float64Array([0, 0, 0, 1]), velocity: new Float64Array(3), angularVelocity: new Float64Array(3), status: TRACKED });

export class RoomSession {
  readonly client: RoomClient;
  readonly local: LocalAvatar;
  readonly members = new Map<number, RoomMember>();
  /**
   * With `trace`: `sent` = [memberId, senderTimeMs, x, z, yaw] of this person's character after
   * each step; `shown` = [fromId, senderTimeMs, x, z, yaw] of a remote avatar as drawn when a
   * message's last step has played. Matching the two by id and time gives the replay error.
   */
  readonly trace = { sent: [] as number[][], shown: [] as number[][] };
  /**
   * Notes by cause and member (the text with its numbers replaced by #): the first text and how
   * many came. `onNote` hears only the first of each, so a member sending garbage cannot fill
   * the page with lines.
   */
  readonly notes = new Map<string, RoomNote>();
  private readonly o: RoomSessionOptions;
  /** The database id this page replays on. */
  private readonly databaseId: string;
  private readonly own: RoomCharacter;
  private readonly stepper: CharacterStepper;
  private readonly sentTrackers: [RoomTrackerPose, RoomTrackerPose, RoomTrackerPose];
  /** The path object last sent (a new one from the character is a new path). */
  private sentPath: DrivePath | null = null;
  private readonly sentTracked = createTrackedInput();
  private warmLabel: NameLabel | null = null;
  /**
   * Other members' databases (a VR member plays `vr`, a desktop one `locomotion`), by id, each
   * fetched once from the asset folder: a copy replays its sender's inputs on the sender's
   * database, or it would not be the sender's motion.
   */
  private readonly databases = new Map<string, Promise<Database>>();
  private now = 0;
  private closed = false;
  /** Leaving the page leaves the room at once (a closed socket may otherwise linger until the server's idle timeout). */
  private readonly onPageHide = () => this.close();

  constructor(options: RoomSessionOptions) {
    this.o = options;
    if (options.renderer) {
      // Kept (not drawn) until close: disposing it would release the program it compiled.
      this.warmLabel = new NameLabel('');
      let root: THREE.Object3D = options.scene;
      while (root.parent) root = root.parent;
      compileNow(options.renderer, this.warmLabel.object, new THREE.PerspectiveCamera(), root instanceof THREE.Scene ? root : null);
    }
    const character = options.character;
    if (character.database.wholeUrl) {
      throw new Error(`${character.database.name} is a first part: await character.whole() before joining a room (the others replay this person on the whole database)`);
    }
    const database = options.database ?? databaseId(character.database);
    this.databaseId = /^[A-Za-z0-9._-]{1,64}$/.test(database) ? database : 'locomotion';
    this.client = new RoomClient({
      ...options.client,
      roomId: options.roomId,
      join: {
        name: options.name,
        avatar: options.avatar ?? { kind: 'builtin', id: 0 },
        database: this.databaseId,
        height: options.height ?? 0,
        mode: options.mode,
        devices: options.devices ?? (options.mode === 'vr' ? { headset: true, leftController: true, rightController: true } : { keyboard: true, pointer: true }),
        style: character.style,
      },
      // Someone joined: their copy of this person continues from this runtime's own floats.
      runtimeState: () => this.own.character.saveState(),
    });
    this.own = new RoomCharacter(character, false);
    this.local = new LocalAvatar(this.own, this.client.stream);
    this.local.setScale(character.metresPerDatabaseUnit);
    const pose = (): RoomTrackerPose => ({ tracked: false, fromHand: false, position: [0, 0, 0], rotation: [0, 0, 0, 1] });
    this.sentTrackers = [pose(), pose(), pose()];
    this.stepper = {
      step: (_c, dt) => this.stepLocal(dt),
      // A new style: the room hears the new profile, then this runtime restarts (a STATE with the
      // restart bit), as every copy does with the new style — copies stay the sender's floats.
      styleChanged: (style) => this.client.updateJoinAndRestart({ ...this.client.join, style }, () => this.restartOwn()),
    };
    character.stepper = this.stepper;

    const note = (text: string) => this.note(text);
    this.client.on('note', note);
    this.client.on('error', (code, reason) => note(`room: ${reason || 'closed'} (${code})`));
    this.client.on('welcome', (_id, members) => {
      for (const id of [...this.members.keys()]) this.remove(id);
      this.restartOwn();
      for (const m of members) this.add(m);
      options.onMembers?.();
    });
    this.client.on('memberJoined', (m) => (this.add(m), options.onMembers?.()));
    this.client.on('memberUpdated', (m) => {
      // A new profile (avatar, height): the member starts over with it from its next message.
      this.remove(m.id);
      this.add(m);
      options.onMembers?.();
    });
    this.client.on('memberLeft', (id) => (this.remove(id), options.onMembers?.()));
    globalThis.addEventListener?.('pagehide', this.onPageHide);
    setRoomOf(character, this);
    this.client.on('stream', (from, message, arrival) => this.feed(from, (m) => m.remote!.receive(message, arrival)));
    this.client.on('snapshot', (from, state, path) => this.feed(from, (m) => m.remote!.applySnapshot(state, path)));
    this.client.connect();
  }

  /** Connection state: connecting, open, reconnecting or closed. */
  get status(): string {
    return this.client.status;
  }

  /** This person's member id in the room (0 while not joined). */
  get memberId(): number {
    return this.client.memberId;
  }

  /**
   * The other members as the page shows them: id, name, mode, whether drawn, and where (x, z, yaw
   * of the drawn avatar's root in the scene, updated by `update`). Allocates: call it when needed,
   * not for every member every frame. Also reachable as `roomOf(character)?.list()` and
   * `<mm-avatar>`'s `room.list()`.
   */
  list(): RoomMemberView[] {
    const out: RoomMemberView[] = [];
    for (const m of this.members.values()) {
      const shown = !!m.remote?.shown && Number.isFinite(m.shown.x);
      out.push({ id: m.id, name: m.join.name, mode: m.join.mode, shown, x: shown ? m.shown.x : NaN, z: shown ? m.shown.z : NaN, yaw: shown ? m.shown.yaw : NaN });
    }
    return out;
  }

  /** Counts a note and passes the first of its cause and member on to `onNote`. */
  private note(text: string, member = 0): void {
    const key = member + text.replace(/-?\d+(\.\d+)?(e[-+]?\d+)?/gi, '#');
    const known = this.notes.get(key);
    if (known) {
      known.count++;
      return;
    }
    if (this.notes.size >= 256) return; // a bounded record: causes beyond are only dropped
    this.notes.set(key, { text, count: 1 });
    this.o.onNote?.(text);
  }

  /** Once a frame, after the local character's update: replays and poses the other members. */
  update(dt: number): void {
    this.now = performance.now();
    this.client.pump();
    for (const member of this.members.values()) {
      const m = member as Member;
      const rc = m.roomCharacter;
      if (!rc || !m.character || !m.remote) continue;
      m.character.update(dt); // its stepper replays the due steps (RemoteAvatar.update)
      rc.display.visible = m.remote.shown;
      rc.display.updateMatrixWorld();
      const root = m.character.root;
      rc.display.localToWorld(_v.set(root.x, root.y, root.z));
      const shown = m.shown as { x: number; z: number; yaw: number };
      shown.x = _v.x;
      shown.z = _v.z;
      shown.yaw = root.yaw + rc.display.rotation.y;
      if (m.upperBody && rc.trackers && m.remote.shown) this.applyUpperBody(m.upperBody, rc, shown.yaw);
      const head = m.character.avatar?.bone('head');
      if (head) head.getWorldPosition(_v);
      else _v.y += 1.8 * m.character.metresPerDatabaseUnit;
      m.label.object.position.set(shown.x, _v.y + 0.3, shown.z);
      m.label.object.visible = m.remote.shown;
    }
  }

  /** Leaves the room: the other members disappear and the character steps itself again. */
  close(): void {
    if (this.closed) return;
    this.closed = true;
    globalThis.removeEventListener?.('pagehide', this.onPageHide);
    setRoomOf(this.o.character, null);
    this.client.close();
    this.warmLabel?.dispose();
    for (const id of [...this.members.keys()]) this.remove(id);
    for (const d of this.databases.values()) void d.then((db) => db.release(), () => undefined);
    this.databases.clear();
    if (this.o.character.stepper === this.stepper) this.o.character.stepper = null;
  }

  // ---- the local member

  private stepLocal(dt: number): void {
    const c = this.o.character;
    const d = c.drive;
    const local = this.local;
    const scale = c.metresPerDatabaseUnit;
    if (d.mode === 'tracked') {
      local.setTracked(trackedFromDrive(d, scale, this.sentTracked), scale, Number.isFinite(d.clampDistance) ? d.clampDistance * scale : DEFAULT_ALPHA);
      const t = this.o.trackers;
      if (t) {
        this.copyTracker(t.head, this.sentTrackers[0]);
        this.copyTracker(t.left, this.sentTrackers[1]);
        this.copyTracker(t.right, this.sentTrackers[2]);
        local.setTrackers(this.sentTrackers);
      }
    } else {
      local.setScale(scale);
      if (d.mode === 'path' && d.path) {
        if (d.path !== this.sentPath) local.setPath(d.path.points, d.path.speeds, d.path.looped);
      } else local.setMove(d);
      this.sentPath = d.mode === 'path' ? d.path : null;
    }
    local.update(dt);
    // Not in the room (yet, or between reconnects): nothing to send; joining starts the stream over.
    if (!this.client.memberId) this.client.stream.flush();
    else if (this.o.trace) {
      const r = c.root;
      this.push(this.trace.sent, [this.client.memberId, this.client.stream.lastStepTime, r.x, r.z, r.yaw]);
    }
  }

  private copyTracker(s: TrackerPose, d: RoomTrackerPose): void {
    d.tracked = s.status === TRACKED;
    for (let k = 0; k < 3; k++) d.position[k] = s.position[k];
    for (let k = 0; k < 4; k++) d.rotation[k] = s.rotation[k];
  }

  /**
   * Joined (again): this person's copies start now. The runtime restarts at the root as the wire
   * carries it (1 mm, int16 yaw) — what every member present restarts its copy at from the
   * first STATE — so the copies compute the same motion from here on. A path being followed
   * is left (a fresh runtime would walk it again from its start).
   */
  private restartOwn(): void {
    const c = this.o.character;
    if (c.followingPath) {
      c.stop();
      this.note('joined the room: the path was stopped');
    }
    this.local.setScale(c.metresPerDatabaseUnit);
    const own = this.own;
    own.reset(-1, fromMm(toMm(own.rootX)), fromMm(toMm(own.rootZ)), i16ToAngle(angleToI16(own.rootYaw)));
    this.client.stream.report(own.rootX, own.rootZ, own.rootYaw, own.frame);
  }

  // ---- the other members

  private add(info: MemberInfo): void {
    const label = new NameLabel(info.join.name);
    label.object.visible = false;
    this.o.scene.add(label.object);
    const member: Member = {
      id: info.id,
      join: info.join,
      character: null,
      remote: null,
      roomCharacter: null,
      upperBody: null,
      label,
      shown: { x: NaN, z: NaN, yaw: NaN },
      pending: [],
      gone: false,
    };
    this.members.set(info.id, member);
    void this.load(member);
  }

  private async load(m: Member): Promise<void> {
    const note = (text: string) => this.note(`${m.join.name}: ${text}`, m.id);
    // Lost messages are the network's weather (and a late joiner never gets those before its
    // snapshot): the jitter buffer and the drift correction deal with them; not a note for people.
    const replayNote = (text: string) => (/message\(s\) lost/.test(text) ? undefined : note(text));
    const a = m.join.avatar;
    const builtins = this.o.builtinAvatars ?? [String(assetUrl(DEFAULT_AVATAR))];
    let url = a.kind === 'url' ? a.url : builtins[a.id];
    if (url === undefined) {
      note(`unknown built-in avatar ${a.kind === 'builtin' ? a.id : ''}; showing the first`);
      url = builtins[0];
    }
    let avatar: Avatar | null = null;
    try {
      if (url !== null) avatar = await this.avatarFor(url);
    } catch (e) {
      note(`avatar unavailable, showing the skeleton (${errorMessage(e)})`);
    }
    if (m.gone || this.closed) {
      avatar?.dispose();
      return;
    }
    let database = this.o.character.database;
    if (m.join.database !== this.databaseId) {
      try {
        database = await this.databaseFor(m.join.database);
      } catch (e) {
        note(`database "${m.join.database}" unavailable, replaying on "${this.databaseId}" (${errorMessage(e)})`);
      }
      if (m.gone || this.closed) {
        avatar?.dispose();
        return;
      }
    }
    // The sender's settings: VR or the defaults, in the sender's style (the runtime leaves out a
    // style the database lacks, as the sender's did).
    const settings = { ...(m.join.mode === 'vr' ? VR_SETTINGS : {}), style: m.join.style ?? 'neutral' };
    const character = new Character(database, avatar, { settings });
    const rc = new RoomCharacter(character, true);
    // A VR member's arms reach for its controllers as on its own page (built at rest, before the first pose).
    if (m.join.mode === 'vr' && avatar) {
      avatar.resetToRest();
      m.upperBody = { body: new UpperBody({ object: avatar.object, bones: avatar.bones, roles: avatar.roles }), poses: [worldPose(), worldPose(), worldPose()] };
    }
    // A copy that is not the sender's floats yet (a late joiner's, until the sender next stands
    // still) plays other frames now and then, mostly in turns, and one placed while its sender
    // runs starts from rest and lags: a shorter half-life than the default and a speed cap above
    // a run (4 m/s, 4 rad/s) keep it on the sender — still a blend, its per-frame change capped.
    const remote = new RemoteAvatar(rc, { drift: { halflife: 0.1, maxSpeed: 4, maxAngularSpeed: 4 }, onNote: replayNote, onPlayed: this.o.trace ? (time) => this.traceShown(m, rc, remote, time) : undefined });
    character.stepper = { step: (_c, dt) => remote.update(this.now, dt) };
    Object.assign(m, { character, roomCharacter: rc, remote });
    this.o.scene.add(rc.display);
    const pending = m.pending;
    m.pending = [];
    for (const f of pending) f();
    this.o.onMembers?.();
  }

  /** A member's database by id (`[A-Za-z0-9._-]{1,64}`, checked by the protocol): `databases/<id>.mmdb` beside the default assets. */
  private databaseFor(id: string): Promise<Database> {
    let db = this.databases.get(id);
    // The page's own database when the member plays the same one (the usual case): no second
    // download and decode of it on the way to showing them.
    const own = this.o.character.database;
    if (!db && id === databaseId(own) && !own.wholeUrl) {
      db = Promise.resolve(own.retain());
      this.databases.set(id, db);
    }
    if (!db) {
      db = Database.fetch(assetUrl(`databases/${id}.mmdb`));
      this.databases.set(id, db);
      db.catch(() => this.databases.delete(id));
    }
    return db;
  }

  private async avatarFor(url: string): Promise<Avatar> {
    // The page's own avatar when it is the same model (the usual case: everyone on the built-in
    // one): a clone shares its geometry, textures and shader programs.
    const own = this.o.character.avatar;
    if (own && !own.vrm && own.name === url) return own.clone();
    // Else one load per model on the page, cloned for each member who shows it (no second
    // download, parse or texture decode; avatar/shared.ts).
    return loadSharedAvatar(url);
  }

  private feed(from: number, f: (m: Member) => void): void {
    const m = this.members.get(from) as Member | undefined;
    if (!m) return;
    if (m.remote) f(m);
    else if (m.pending.length < MAX_PENDING) m.pending.push(() => f(m));
    else m.pending.length = 0; // the avatar takes very long: start over from later messages
  }

  private remove(id: number): void {
    const m = this.members.get(id) as Member | undefined;
    if (!m) return;
    m.gone = true;
    this.members.delete(id);
    m.label.dispose();
    m.roomCharacter?.display.removeFromParent();
    m.upperBody?.body.dispose();
    m.character?.dispose();
  }

  /**
   * A VR member's upper body on its copy: the replayed head and grips (room space) carried
   * through the display offset into the scene, then the same spine twist, head and arm IK as on
   * the member's own page.
   */
  private applyUpperBody(u: RemoteUpperBody, rc: RoomCharacter, yaw: number): void {
    const trackers = rc.trackers!;
    for (let i = 0; i < 3; i++) {
      const t = trackers[i], w = u.poses[i];
      rc.display.localToWorld(_v.set(t.position[0], t.position[1], t.position[2]));
      w.position[0] = _v.x;
      w.position[1] = _v.y;
      w.position[2] = _v.z;
      _q2.set(t.rotation[0], t.rotation[1], t.rotation[2], t.rotation[3]).premultiply(rc.display.quaternion);
      w.rotation[0] = _q2.x;
      w.rotation[1] = _q2.y;
      w.rotation[2] = _q2.z;
      w.rotation[3] = _q2.w;
      w.status = t.tracked ? TRACKED : MISSING;
    }
    u.body.apply(u.poses[0], u.poses[1], u.poses[2], yaw);
  }

  /**
   * A message of member `m` has played: where its avatar is drawn if the frame ended now — the
   * simulated root plus the display offset (the offset turns the body about its root, so only
   * its translation moves the root).
   */
  private traceShown(m: Member, rc: RoomCharacter, remote: RemoteAvatar, time: number): void {
    if (!remote.shown) return;
    const d = remote.drift;
    this.push(this.trace.shown, [m.id, time, rc.rootX + d.offsetX, rc.rootZ + d.offsetZ, rc.rootYaw + d.offsetYaw]);
  }

  private push(list: number[][], row: number[]): void {
    if (list.length >= 50_000) list.splice(0, 10_000);
    list.push(row);
  }
}

/** A database's id in a room: its file name without `.mmdb` (`locomotion`). */
function databaseId(database: Database): string {
  return (database.name.split('?')[0].split('/').pop() ?? '').replace(/\.mmdb$/, '');
}
