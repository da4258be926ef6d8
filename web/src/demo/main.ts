/**
 * The desktop demo: one motion-matched character driven by keyboard, gamepad or a path,
 * shown as a retargeted skinned avatar (and/or its skeleton), with debug views, a performance
 * HUD and every knob in lil-gui. Drop BVH files to build a database in the page, a `.mmdb` to
 * load one, a `.glb`/`.vrm` to swap the avatar.
 *
 * URL parameters: `db=<url>`, `avatar=<url>|none`, `roles=<JSON role → joint name>` (manual
 * joint map), `skeleton=1`, `shadows=0`, `dt=fixed`
 * (exactly 1/60 s per rendered frame, for deterministic tests). State for tests is on
 * `window.__mm`.
 */
import GUI from 'lil-gui';
import * as THREE from 'three';
import { type Avatar, loadAvatar } from '../avatar/avatar.ts';
import { type RoleOverrides } from '../avatar/joint-maps.ts';
import { DatabaseBuilder } from '../core/builder.ts';
import { Crowd } from '../core/crowd.ts';
import { forwardKinematics } from '../core/forward-kinematics.ts';
import { initWasm } from '../core/wasm.ts';
import { readGamepad } from '../input/gamepad.ts';
import { CameraBasis, createMoveInput } from '../input/input.ts';
import { KeyboardInput } from '../input/keyboard.ts';
import { errorMessage, showError } from '../viewer/error-box.ts';
import { findFootJoints } from '../viewer/feet.ts';
import { FollowCamera } from '../viewer/follow-camera.ts';
import { RootMarker } from '../viewer/root-marker.ts';
import { ViewerScene } from '../viewer/scene.ts';
import { SkeletonView } from '../viewer/skeleton-view.ts';
import { DebugViews } from './debug-views.ts';
import { type DroppedFiles, installDropTarget } from './drop.ts';
import { PathEditor } from './path-editor.ts';
import { PerfHud } from './perf-hud.ts';
import { createSettingsPanel } from './settings-panel.ts';

/** What tests read: only what they need. */
export interface DemoHook {
  ready: boolean;
  /** Errors that broke the page (not the reported, recovered ones such as a bad dropped file). */
  error: string | null;
  /** The last message shown for a file that could not be used. */
  fileError: string | null;
  /** Runtime updates so far (one per rendered frame). */
  updates: number;
  frame: number;
  root: [number, number, number];
  /** Facing yaw of the root, radians (0 = +Z). */
  yaw: number;
  /** Contact bits now (1 left, 2 right) and onsets counted per foot, to see feet alternate. */
  contacts: number;
  steps: [number, number];
  searches: number;
  transitions: number;
  /** Avatar toe (ball) heights above the floor (left, right), m; NaN without an avatar. */
  avatarToes: [number, number];
  /** The avatar's toe height standing on the floor (its rest pose), m. */
  avatarStandingToe: number;
  /** Avatar toe height minus standing height for each foot in contact, every frame (the last 2048+). */
  toeErrors: number[];
  /** Name of the database playing, its frame count, and of the avatar. */
  database: string;
  databaseFrames: number;
  avatar: string;
  /** Databases built or loaded so far (1 at start). */
  databaseLoads: number;
  /** Path mode: the editor's keypoints and whether the character follows them. */
  path: { points: number[]; following: boolean };
  /** Client pixel of a floor point (tests click the floor to place keypoints). */
  screenOf(x: number, z: number): { x: number; y: number };
}

declare global {
  interface Window {
    __mm: DemoHook;
  }
}

const hook: DemoHook = {
  ready: false,
  error: null,
  fileError: null,
  updates: 0,
  frame: 0,
  root: [0, 0, 0],
  yaw: 0,
  contacts: 0,
  steps: [0, 0],
  searches: 0,
  transitions: 0,
  avatarToes: [NaN, NaN],
  avatarStandingToe: NaN,
  toeErrors: [],
  database: '',
  databaseFrames: 0,
  avatar: '',
  databaseLoads: 0,
  path: { points: [], following: false },
  screenOf: () => ({ x: 0, y: 0 }),
};
window.__mm = hook;

function fail(message: string): void {
  hook.error = hook.error ? `${hook.error}\n${message}` : message;
  showError(message);
}
window.addEventListener('error', (e) => fail(`error: ${e.message}`));
window.addEventListener('unhandledrejection', (e) => fail(`error: ${errorMessage(e.reason)}`));

/** A file that could not be used: said in the page, everything else keeps working. */
function fileError(message: string): void {
  hook.fileError = message;
  showError(message);
}

const loading = document.getElementById('loading') as HTMLElement;
function progress(text: string | null): void {
  loading.hidden = text === null;
  if (text !== null) loading.textContent = text;
}

/** Fetches bytes with a progress line (`what`, MB so far / total). */
async function fetchBytes(url: string, what: string): Promise<Uint8Array> {
  const response = await fetch(url);
  if (!response.ok || !response.body) throw new Error(`${url}: HTTP ${response.status}`);
  const total = Number(response.headers.get('content-length')) || 0;
  const reader = response.body.getReader();
  const chunks: Uint8Array[] = [];
  let received = 0;
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    chunks.push(value);
    received += value.length;
    progress(`Loading ${what}… ${(received / 1e6).toFixed(1)}${total ? ` / ${(total / 1e6).toFixed(1)}` : ''} MB`);
  }
  const bytes = new Uint8Array(received);
  let o = 0;
  for (const c of chunks) {
    bytes.set(c, o);
    o += c.length;
  }
  return bytes;
}

/** The first connected gamepad, without allocating a closure per frame. */
function firstGamepad(): Gamepad | null {
  const pads = navigator.getGamepads?.() ?? [];
  for (const p of pads) if (p) return p;
  return null;
}

/** Lets the browser paint (progress text) before a long synchronous step. */
const nextPaint = () => new Promise<void>((resolve) => requestAnimationFrame(() => setTimeout(resolve, 0)));

/** Everything bound to one database: the crowd and the views of its skeleton. */
interface Rig {
  name: string;
  crowd: Crowd;
  avatar: Avatar | null;
  skeleton: SkeletonView;
  debug: DebugViews;
  world: Float32Array;
  worldRotations: Float32Array;
}

async function main(): Promise<void> {
  const params = new URLSearchParams(location.search);
  const fixedDt = params.get('dt') === 'fixed';
  // `?roles={"head":"Head_M","leftToes":""}`: the manual joint-map override for the avatar.
  let roleOverrides: RoleOverrides | undefined;
  try {
    roleOverrides = params.has('roles') ? (JSON.parse(params.get('roles')!) as RoleOverrides) : undefined;
  } catch (e) {
    fileError(`?roles= must be JSON like {"head":"Head_M"}: ${errorMessage(e)}`);
  }
  const stage = new ViewerScene(document.getElementById('viewport') as HTMLElement);
  stage.camera.position.set(2.2, 1.7, 3.8); // the whole body in view, a little from above
  const camera = new FollowCamera(stage.camera, stage.renderer.domElement);
  const marker = new RootMarker();
  stage.scene.add(marker.object);
  const view = {
    mesh: params.get('avatar') !== 'none',
    skeleton: params.get('skeleton') === '1' || params.get('avatar') === 'none',
    shadows: params.get('shadows') !== '0',
    simulation: true,
    trajectory: true,
    matched: true,
    locks: true,
  };
  stage.enableShadows(view.shadows);

  progress('Loading the motion-matching core…');
  await initWasm();
  const dbUrl = params.get('db') ?? 'databases/locomotion.mmdb';
  const dbBytes = await fetchBytes(dbUrl, 'motion database');
  const avatarUrl = params.get('avatar') === 'none' ? null : (params.get('avatar') ?? 'avatars/ubc_male.glb');
  let avatarSource: { bytes: Uint8Array; name: string } | null = avatarUrl ? { bytes: await fetchBytes(avatarUrl, 'avatar'), name: avatarUrl.split('/').pop()! } : null;
  progress('Preparing the character…');

  let rig: Rig | null = null;
  let settings: Record<string, unknown> | null = null;

  /** Binds an avatar to the rig's skeleton, or null (the error said) when it cannot be. */
  async function bindAvatar(crowd: Crowd, source: { bytes: Uint8Array; name: string }): Promise<Avatar | null> {
    try {
      const avatar = await loadAvatar(source.bytes, source.name, crowd, roleOverrides);
      avatar.object.visible = view.mesh;
      return avatar;
    } catch (e) {
      fileError(errorMessage(e)); // names the file
      return null;
    }
  }

  /** Switches to a database (throws, keeping the current one, when the bytes are bad). */
  async function useDatabase(bytes: Uint8Array, name: string): Promise<void> {
    const crowd = new Crowd(bytes, 1);
    const old = rig;
    if (old && settings) crowd.setSettings(settings);
    if (old) {
      // Carry the character over where it stands.
      const r = old.crowd.rotationsOf(0);
      const p = old.crowd.positionsOf(0);
      crowd.teleport(0, p[0], p[2], 2 * Math.atan2(r[1], r[3]));
    }
    const avatar = avatarSource ? await bindAvatar(crowd, avatarSource) : null;
    const feet = findFootJoints(crowd);
    const skeleton = new SkeletonView(crowd.jointParents, feet.left, feet.right);
    skeleton.object.visible = view.skeleton || !avatar;
    const toeSites = crowd.sites();
    const toe = (n: string) => toeSites.find((s) => s.name === n)?.joint ?? -1;
    const debug = new DebugViews(crowd, [toe('left_toe'), toe('right_toe')]);
    const j = crowd.numJoints;
    rig = { name, crowd, avatar, skeleton, debug, world: new Float32Array(j * 3), worldRotations: new Float32Array(j * 4) };
    applyViewToggles();
    if (avatar) stage.scene.add(avatar.object);
    stage.scene.add(skeleton.object, debug.object);
    if (old) disposeRig(old);
    settings ??= crowd.settings(0);
    hook.database = name;
    hook.databaseFrames = crowd.numFrames;
    hook.avatar = avatar ? avatarSource!.name : '';
    hook.databaseLoads++;
    if (path.points.length >= 4 && hook.path.following) followPath();
  }

  function disposeRig(old: Rig): void {
    if (old.avatar) {
      stage.scene.remove(old.avatar.object);
      old.avatar.dispose();
    }
    stage.scene.remove(old.skeleton.object, old.debug.object);
    old.skeleton.object.traverse((o) => (o as THREE.Mesh).geometry?.dispose());
    old.debug.dispose();
    old.crowd.free();
  }

  function applyViewToggles(): void {
    if (!rig) return;
    if (rig.avatar) rig.avatar.object.visible = view.mesh;
    rig.skeleton.object.visible = view.skeleton || !rig.avatar || !view.mesh;
    rig.debug.simulation.visible = view.simulation;
    rig.debug.requested.object.visible = view.trajectory;
    rig.debug.matched.object.visible = view.matched;
    rig.debug.locks.visible = view.locks;
    stage.enableShadows(view.shadows);
  }

  // ---- path mode
  const path = new PathEditor(stage.camera, stage.renderer.domElement);
  stage.scene.add(path.object);
  hook.path.points = path.points;
  // A new path starts where the character stands, so following it never jumps.
  path.onEditStart = () => {
    if (rig && path.points.length === 0) {
      const p = rig.crowd.positionsOf(0);
      path.add(p[0], p[2], path.walkSpeed);
    }
  };
  hook.screenOf = (x, z) => path.screenOf(x, z);
  function followPath(): void {
    if (!rig) return;
    if (path.points.length < 4) {
      fileError('Path: place at least 2 keypoints (turn on "edit", then click the floor).');
      return;
    }
    rig.crowd.setPath(0, Float32Array.from(path.points), path.segmentSpeeds(), path.looped && path.points.length >= 6);
    hook.path.following = true;
    path.editing = false;
    editController.updateDisplay();
  }
  function stopPath(): void {
    rig?.crowd.setPath(0, null);
    hook.path.following = false;
  }

  // ---- dropped files
  async function onDrop(files: DroppedFiles): Promise<void> {
    if (files.unknown.length) fileError(`Not used (drop .bvh, .mmdb, .glb or .vrm): ${files.unknown.join(', ')}`);
    try {
      if (files.bvh.length) await buildFromBvh(files.bvh);
      else if (files.databases.length) {
        const f = files.databases[0];
        try {
          await useDatabase(new Uint8Array(await f.arrayBuffer()), f.name);
        } catch (e) {
          fileError(`${f.name}: ${errorMessage(e)}`);
        }
      }
      if (files.avatars.length && rig) {
        const f = files.avatars[0];
        const source = { bytes: new Uint8Array(await f.arrayBuffer()), name: f.name };
        const avatar = await bindAvatar(rig.crowd, source);
        if (avatar) {
          if (rig.avatar) {
            stage.scene.remove(rig.avatar.object);
            rig.avatar.dispose();
          }
          avatarSource = source;
          rig.avatar = avatar;
          stage.scene.add(avatar.object);
          hook.avatar = f.name;
          applyViewToggles();
        }
      }
    } finally {
      progress(null);
    }
  }

  /** Builds a database from BVH files in the page (the WASM builder) and switches to it. */
  async function buildFromBvh(files: File[]): Promise<void> {
    const builder = new DatabaseBuilder({});
    try {
      for (let i = 0; i < files.length; i++) {
        progress(`Reading ${files[i].name} (${i + 1}/${files.length})…`);
        await nextPaint();
        builder.addBvh(files[i].name, new Uint8Array(await files[i].arrayBuffer()));
      }
      progress(`Building a database from ${files.length} file${files.length > 1 ? 's' : ''}…`);
      await nextPaint();
      const bytes = builder.build();
      for (const w of builder.warnings()) console.warn('database build:', w);
      const name = files.length === 1 ? files[0].name : `${files[0].name} + ${files.length - 1} more`;
      await useDatabase(bytes, name);
      databases[name] = bytes;
      databaseController.options(Object.keys(databases)).setValue(name);
    } catch (e) {
      // The importer's message names the file and line; the current database keeps playing.
      fileError(errorMessage(e));
    } finally {
      builder.free();
    }
  }

  // ---- panel
  const gui = new GUI({ title: 'Motion matching' });
  const databases: Record<string, Uint8Array | string> = { [dbUrl.split('/').pop()!.replace(/\.mmdb$/, '')]: dbBytes };
  const choice = { database: Object.keys(databases)[0] };
  const databaseController = gui
    .add(choice, 'database', Object.keys(databases))
    .name('database')
    .onChange(async (name: string) => {
      const entry = databases[name];
      if (!entry || name === rig?.name) return;
      try {
        await useDatabase(typeof entry === 'string' ? await fetchBytes(entry, name) : entry, name);
      } catch (e) {
        fileError(`${name}: ${errorMessage(e)}`);
      } finally {
        progress(null);
      }
    });
  const viewFolder = gui.addFolder('View');
  viewFolder.add(view, 'mesh').onChange(applyViewToggles);
  viewFolder.add(view, 'skeleton').onChange(applyViewToggles);
  viewFolder.add(view, 'shadows').onChange(applyViewToggles);
  const debugFolder = gui.addFolder('Debug views');
  debugFolder.add(view, 'simulation').name('simulated character').onChange(applyViewToggles);
  debugFolder.add(view, 'trajectory').name('requested trajectory').onChange(applyViewToggles);
  debugFolder.add(view, 'matched').name('matched trajectory').onChange(applyViewToggles);
  debugFolder.add(view, 'locks').name('foot locks').onChange(applyViewToggles);
  const pathFolder = gui.addFolder('Path mode');
  const editController = pathFolder.add(path, 'editing').name('edit (click the floor)');
  pathFolder.add(path, 'walkSpeed', 0.3, 3, 0.1).name('speed (m/s)');
  pathFolder.add(path, 'runSpeed', 1, 6, 0.1).name('Shift-click speed');
  pathFolder.add(path, 'looped').name('loop').onChange(() => path.redraw());
  pathFolder.add({ follow: followPath }, 'follow').name('follow the path');
  pathFolder.add({ stop: stopPath }, 'stop').name('stop (back to keys)');
  pathFolder.add({ clear: () => (stopPath(), path.clear()) }, 'clear').name('clear');

  await useDatabase(dbBytes, choice.database);
  createSettingsPanel(gui.addFolder('Runtime'), () => rig!.crowd);
  for (const f of [viewFolder, debugFolder, pathFolder]) f.close();
  // Other served databases, if the set-up built them.
  for (const name of ['bench53k']) {
    fetch(`databases/${name}.mmdb`, { method: 'HEAD' })
      .then((r) => {
        if (!r.ok) return;
        databases[name] = `databases/${name}.mmdb`;
        databaseController.options(Object.keys(databases)).setValue(choice.database);
      })
      .catch(() => {});
  }
  installDropTarget(document.body, document.getElementById('drop-overlay') as HTMLElement, (files) => void onDrop(files));
  progress(null);

  const keyboard = new KeyboardInput();
  keyboard.attach(window);
  const basis = new CameraBasis();
  const input = createMoveInput();
  const look = new THREE.Vector3();
  const info = document.getElementById('hud') as HTMLElement;
  const perf = new PerfHud(document.getElementById('perf') as HTMLElement);
  let previousContacts = 0;
  let last = performance.now();

  stage.renderer.setAnimationLoop((now: number) => {
    const r = rig;
    if (!r) return;
    const { crowd, world, worldRotations } = r;
    const dt = fixedDt ? 1 / 60 : Math.min(0.1, Math.max(0, (now - last) / 1000));
    last = now;
    stage.camera.getWorldDirection(look);
    basis.setLook(look.x, look.z);
    const rotations = crowd.rotationsOf(0);
    const yaw = 2 * Math.atan2(rotations[1], rotations[3]); // the root is a pure yaw
    const pad = firstGamepad();
    if (keyboard.active || !readGamepad(pad, basis, input)) keyboard.read(basis, yaw, dt, input);
    // Moving by hand takes the character back from a path.
    if (hook.path.following && (input.moveX !== 0 || input.moveZ !== 0)) stopPath();
    crowd.setInput(0, input);
    const searchesBefore = crowd.binding.searches(0);
    const t0 = performance.now();
    crowd.update(dt);
    const t1 = performance.now();
    forwardKinematics(crowd.jointParents, crowd.positionsOf(0), crowd.rotationsOf(0), world, worldRotations);
    const contacts = crowd.contactsOf(0);
    if (r.avatar && view.mesh) r.avatar.pose(world, worldRotations, contacts, dt, hook.avatarToes);
    const t2 = performance.now();
    r.skeleton.update(world, (contacts & 1) !== 0, (contacts & 2) !== 0);
    r.debug.update(world);
    marker.update(world, worldRotations);
    camera.follow(world[0], world[2], dt);
    stage.grid.follow(world[0], world[2]);
    stage.followLight(world[0], world[2]);
    stage.render();

    const onsets = contacts & ~previousContacts;
    previousContacts = contacts;
    if (onsets & 1) hook.steps[0]++;
    if (onsets & 2) hook.steps[1]++;
    hook.updates++;
    hook.contacts = contacts;
    hook.frame = crowd.binding.frame(0);
    hook.root[0] = world[0];
    hook.root[1] = world[1];
    hook.root[2] = world[2];
    hook.yaw = 2 * Math.atan2(worldRotations[1], worldRotations[3]);
    hook.searches = crowd.binding.searches(0);
    hook.transitions = crowd.binding.transitions(0);
    hook.avatarStandingToe = r.avatar?.standingToeHeight ?? NaN;
    if (r.avatar && view.mesh) {
      for (let side = 0; side < 2; side++) {
        if (contacts & (1 << side)) hook.toeErrors.push(hook.avatarToes[side] - hook.avatarStandingToe);
      }
      // Keep the last 2048–4096 in place (no per-frame allocation).
      if (hook.toeErrors.length >= 4096) {
        hook.toeErrors.copyWithin(0, 2048);
        hook.toeErrors.length -= 2048;
      }
    }
    hook.ready = true;
    perf.frame(now, t1 - t0, t2 - t0, hook.searches !== searchesBefore);
    if (hook.updates % 10 === 0) perf.showFrame(info, r, hook.frame);
  });
}

main().catch((e: unknown) => fail(errorMessage(e)));
