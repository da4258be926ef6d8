/**
 * The desktop demo (index.html): `<mm-avatar>` full page, plus a panel with every runtime knob,
 * path editing, view toggles, the database and style choice; files dropped on the page (BVH,
 * VRMA, glTF clips → a database built here, `.mmdb`, `.glb`/`.vrm`); a HUD. The public entries
 * and the pages' kit only.
 *
 * URL parameters: `db=<url>`, `avatar=<url>|none`, `roles=<JSON role → bone name>` (manual
 * joint map), `skeleton=1`, `shadows=0`, `dt=fixed` (exactly 1/60 s per frame, for tests;
 * `dt=0.05`: that many s), `steps=2` (updates per drawn frame), `room=<id>` and `name=` (a
 * shared room: `RoomPanel`; the HUD reads `el.room.list()`). Tests: `window.__mm`.
 */
import GUI from 'lil-gui';
import * as THREE from 'three';
import {
  Avatar, Database, RUNTIME_SETTINGS, type RoleOverrides, defineMMAvatar, listDatabases, registerOfflineCache,
} from '../../index.ts';
import {
  type DroppedFiles, PathEditor, UpdateTimer, addSettingsFolders, catchPageErrors, droppedDatabase, errorMessage,
  installDropTarget, setOptions, showError,
} from '../kit.ts';
import type { RoomPanel } from '../../rooms/index.ts';

const hook = {
  ready: false,
  error: null as string | null,
  /** The last message for a file that could not be used (the page keeps working). */
  fileError: null as string | null,
  ...{ updates: 0, frame: 0, root: [0, 0, 0], yaw: 0, contacts: 0, searches: 0, transitions: 0 },
  /** Contact onsets per foot (left, right): feet alternate. */
  steps: [0, 0],
  /** Avatar toe heights (m) and its standing toe height; toe height − standing for each foot in contact. */
  avatarToes: [NaN, NaN],
  avatarStandingToe: NaN,
  toeErrors: [] as number[],
  /** Avatar hips (x, z) and where the foot-lock rings and the avatar's toes are (x, z, NaN when unlocked). */
  hips: [NaN, NaN],
  lockRings: [NaN, NaN, NaN, NaN],
  toes: [NaN, NaN, NaN, NaN],
  ...{ database: '', style: '', databaseFrames: 0, avatar: '', databaseLoads: 0, wholeTried: false },
  path: { points: [] as number[], following: false },
  screenOf: (x: number, z: number) => ({ x: x * 0, y: z * 0 }),
};
declare global {
  interface Window { __mm: typeof hook }
}
window.__mm = hook;

catchPageErrors(hook);
const fileError = (message: string) => showError((hook.fileError = message));

defineMMAvatar();
const params = new URLSearchParams(location.search);
const el = document.createElement('mm-avatar');
el.id = 'avatar';
el.setAttribute('controls', 'keyboard gamepad');
el.setAttribute('debug', ''); // the debug views exist (and are compiled) before the first frame
el.setAttribute('alt', 'A motion-matched character; focus it and walk with WASD');
if (params.get('db')) el.setAttribute('database', params.get('db')!);
// A manual joint map (?roles=) applies when the page loads the avatar itself, below.
let roles: RoleOverrides | undefined;
try {
  roles = params.has('roles') ? (JSON.parse(params.get('roles')!) as RoleOverrides) : undefined;
} catch (e) {
  fileError(`?roles= must be JSON like {"head":"Head_M"}: ${errorMessage(e)}`);
}
const avatarParam = params.get('avatar');
if (avatarParam === 'none' || roles) el.setAttribute('avatar', 'none');
else if (avatarParam) el.setAttribute('avatar', avatarParam);
if (params.get('dt')) el.timeStep = params.get('dt') === 'fixed' ? 1 / 60 : Number(params.get('dt')) || null;
if (params.get('steps')) el.stepsPerFrame = Number(params.get('steps'));
document.getElementById('viewport')!.append(el);
el.addEventListener('error', (e) => fileError((e as unknown as CustomEvent<{ message: string }>).detail.message));

el.addEventListener('load', async () => {
  const character = el.character!;
  const stage = el.stage!;
  el.orbit!.controls.enableZoom = true; // a full page: the wheel zooms
  stage.camera.position.set(2.2, 1.7, 3.8);
  const [skeleton, shadows] = [params.get('skeleton') === '1', params.get('shadows') !== '0'];
  const view = { mesh: true, skeleton, shadows, simulation: true, trajectory: true, matched: true, locks: true };
  const apply = () => {
    if (character.avatar) character.avatar.object.visible = view.mesh;
    character.showSkeleton = view.skeleton || !character.avatar || !view.mesh;
    const d = character.debugViews!;
    [d.simulation.visible, d.requested.object.visible] = [view.simulation, view.trajectory];
    [d.matched.object.visible, d.locks.visible] = [view.matched, view.locks];
    stage.enableShadows(view.shadows && hook.wholeTried); // once the whole is in or failed: their compile held it ~1 s
  };
  const useAvatar = (avatar: Avatar | null) => {
    character.setAvatar(avatar);
    hook.avatar = avatar?.name.split('?')[0].split('/').pop() ?? '';
    hook.avatarStandingToe = avatar?.standingToeHeight ?? NaN;
    apply();
  };
  const loaded = character.database; // a first part goes by its whole's name (the character moves there)
  const loadedName = (loaded.wholeUrl ?? loaded.name).split('?')[0].split('/').pop()!.replace(/\.mmdb$/, '');
  const databases: Record<string, Database | string> = { [loadedName]: loaded.wholeUrl ?? loaded };
  let refreshStyles = () => {};
  const useDatabase = (db: Database, name: string) => {
    character.setDatabase(db);
    [hook.database, hook.databaseFrames] = [name, db.numFrames];
    hook.databaseLoads++;
    refreshStyles();
    apply();
  };
  [hook.database, hook.databaseFrames, hook.databaseLoads] = [loadedName, loaded.numFrames, 1];
  const whole = (db: Database) => hook.database === loadedName && [hook.databaseFrames = db.numFrames, refreshStyles()];
  void character.whole().then(whole, () => undefined).then(() => ((hook.wholeTried = true), apply())); // failed: warned
  useAvatar(character.avatar);
  if (roles && avatarParam !== 'none') {
    const url = avatarParam ?? 'avatars/ubc_male.glb';
    await Avatar.load(url, { roles }).then(useAvatar, (e: unknown) => fileError(errorMessage(e)));
  }

  // ---- path mode
  const path = new PathEditor(stage.camera, stage.renderer.domElement);
  stage.scene.add(path.object);
  hook.path.points = path.points;
  hook.screenOf = (x, z) => el.screenOf(x, z);
  path.onEditStart = () => {
    if (path.points.length === 0) path.add(character.root.x, character.root.z, path.walkSpeed);
  };
  const follow = () => {
    if (path.points.length < 4) {
      return fileError('Path: place at least 2 keypoints (turn on "edit", then click the floor).');
    }
    const points = [];
    for (let i = 0; i < path.points.length; i += 2) points.push([path.points[i], path.points[i + 1]] as const);
    character.followPath(points, { speed: [...path.segmentSpeeds()], loop: path.looped && points.length >= 3 });
    hook.path.following = true;
    path.editing = false;
    editing.updateDisplay();
  };
  const stopPath = () => (character.stop(), (hook.path.following = false));

  // ---- panel
  const gui = new GUI({ title: 'Motion matching' });
  const choice = { database: hook.database, style: character.style };
  const onDatabase = async (name: string) => {
    const entry = databases[name];
    if (!entry || name === hook.database) return;
    try {
      useDatabase(typeof entry === 'string' ? await Database.fetch(entry) : entry, name);
    } catch (e) {
      fileError(errorMessage(e));
    }
  };
  let databaseSelect = gui.add(choice, 'database', Object.keys(databases)).onChange(onDatabase);
  const onStyle = (style: string) => (character.setStyle(style), (hook.style = style));
  // The styles the database's tags name (neutral, angry, akimbo…); hidden for a database without.
  let styleSelect = gui.add(choice, 'style', ['neutral']);
  refreshStyles = () => {
    styleSelect = setOptions(styleSelect, [...character.styles], (hook.style = character.style), onStyle);
    styleSelect.show(character.styles.length > 0);
  };
  refreshStyles();
  const showDatabases = (name: string) => {
    databaseSelect = setOptions(databaseSelect, Object.keys(databases), name, onDatabase);
  };
  // Only databases the site serves (its generated databases/index.json), besides the one loaded.
  void listDatabases().then((list) => {
    for (const d of list) databases[d.name] ??= d.url;
    showDatabases(hook.database);
  }, () => undefined);
  void registerOfflineCache(); // after the first frame: repeat visits and offline from Cache Storage
  const folder = (title: string) => gui.addFolder(title).close();
  const viewFolder = folder('View');
  for (const key of ['mesh', 'skeleton', 'shadows'] as const) viewFolder.add(view, key).onChange(apply);
  const debug = folder('Debug views');
  for (const key of ['simulation', 'trajectory', 'matched', 'locks'] as const) debug.add(view, key).onChange(apply);
  const pathFolder = folder('Path mode');
  const editing = pathFolder.add(path, 'editing').name('edit (click the floor)');
  pathFolder.add(path, 'walkSpeed', 0.3, 3, 0.1).name('speed (m/s)');
  pathFolder.add(path, 'runSpeed', 1, 6, 0.1).name('Shift-click speed');
  pathFolder.add(path, 'looped').name('loop').onChange(() => path.redraw());
  pathFolder.add({ follow }, 'follow').name('follow the path');
  pathFolder.add({ stop: stopPath }, 'stop').name('stop (back to keys)');
  pathFolder.add({ clear: () => (stopPath(), path.clear()) }, 'clear');
  const runtime = gui.addFolder('Runtime').close();
  addSettingsFolders(runtime, RUNTIME_SETTINGS, character.settings, (patch) => (el.character!.settings = patch));

  // ---- dropped files: motion (BVH, .vrma, glTF clips) → a database built here; .mmdb; .glb/.vrm → the avatar
  installDropTarget(document.body, document.getElementById('drop-overlay')!, (files) => void onDrop(files));
  const onDrop = async (files: DroppedFiles) => {
    const { unknown } = files;
    if (unknown.length) fileError(`Not used (drop .bvh, .vrma, .glb, .mmdb or .vrm): ${unknown.join(', ')}`);
    try {
      const db = await droppedDatabase(files);
      if (db) [databases[db.name] = db, useDatabase(db, db.name), showDatabases(db.name)];
      const [avatar] = files.avatars;
      if (avatar) useAvatar(await Avatar.load(new Uint8Array(await avatar.arrayBuffer()), { name: avatar.name }));
    } catch (e) {
      fileError(errorMessage(e)); // names the file (and line)
    }
  };
  // ---- the room (its ~85 kB of code fetched now), joined once the scene is drawn once (every shader linked)
  stage.render();
  let room: RoomPanel | null = null;
  void import('../../rooms/index.ts').then(({ RoomPanel }) => (room = new RoomPanel({
    character, scene: stage.scene, renderer: stage.renderer, mode: 'desktop', onNote: fileError,
    parent: document.getElementById('toolbar')!, trace: el.timeStep !== null,
    avatar: avatarParam && avatarParam !== 'none' ? { kind: 'url', url: avatarParam } : undefined,
  })));
  // ---- per update: the hook and the HUD
  const hud = document.getElementById('hud')!;
  const timer = new UpdateTimer(64);
  const v = new THREE.Vector3();
  let previousContacts = 0;
  el.afterUpdate = (dt) => {
    room?.update(dt);
    const [r, rt, contacts] = [character.root, character.runtime, character.contacts];
    hook.path.following = character.followingPath; // a move key takes the character back from a path
    const onsets = contacts & ~previousContacts;
    previousContacts = contacts;
    if (onsets & 1) hook.steps[0]++;
    if (onsets & 2) hook.steps[1]++;
    hook.updates++;
    [hook.root[0], hook.root[1], hook.root[2], hook.yaw] = [r.x, r.y, r.z, r.yaw];
    [hook.contacts, hook.frame, hook.searches, hook.transitions] = [contacts, rt.frame, rt.searches, rt.transitions];
    const avatar = character.avatar;
    if (avatar?.object.visible) {
      [hook.avatarToes[0], hook.avatarToes[1]] = avatar.toeHeights;
      const [planted, standing] = [contacts & ~rt.footSteps, avatar.standingToeHeight]; // in contact, not stepping
      for (let s = 0; s < 2; s++) if (planted & (1 << s)) hook.toeErrors.push(avatar.toeHeights[s] - standing);
      if (hook.toeErrors.length >= 4096) hook.toeErrors.splice(0, 2048);
      const hips = avatar.bone('hips')?.getWorldPosition(v);
      [hook.hips[0], hook.hips[1]] = hips ? [hips.x, hips.z] : [NaN, NaN];
      for (const [k, role] of [[0, 'left_toe'], [1, 'right_toe']] as const) {
        const toe = avatar.bone(role)?.getWorldPosition(v);
        [hook.toes[2 * k], hook.toes[2 * k + 1]] = toe ? [toe.x, toe.z] : [NaN, NaN];
      }
    }
    character.debugViews?.locks.children.forEach((ring, k) => {
      const p = ring.visible ? ring.getWorldPosition(v) : null;
      [hook.lockRings[2 * k], hook.lockRings[2 * k + 1]] = p ? [p.x, p.z] : [NaN, NaN];
    });
    timer.add(el.lastUpdateMs);
    if (hook.updates % 15 === 1) { // from the first update on: "loading…" never outlives the load
      const cost = `cost ${rt.searchCost.toFixed(2)} → ${rt.bestCost.toFixed(2)}`;
      const members = (el.room?.list() ?? []).filter((m) => m.shown); // the room's public API
      const near = members.map((m) => [Math.hypot(m.x - r.x, m.z - r.z), m.name] as const).sort((a, b) => a[0] - b[0]);
      const nearest = near.length ? ` · nearest: ${near[0][1]} ${near[0][0].toFixed(1)} m` : '';
      const update = `update ${timer.median().toFixed(3)} ms (median of 64)`;
      const playing = `${character.clip} · frame ${rt.frame} · ${character.tags.join(' ') || '—'}`;
      hud.textContent = `${playing} · ${cost} · ${update}${nearest}`;
    }
    hook.ready = true;
  };
});
