/**
 * The desktop demo (first cut): one motion-matched character on the locomotion database,
 * driven by keyboard or gamepad, shown as the retargeted avatar (`?avatar=none` for the
 * skeleton only, `&skeleton=1` for both). Known gap: CMU's rest foot points down while the
 * avatar's is flat, so the T-pose retargeting tilts the avatar's toes up in stance and its
 * feet stand ~7 cm high — the feet need their own rest alignment (desktop-demo issue). `?dt=fixed` advances exactly 1/60 s per
 * rendered frame (deterministic tests); state for tests is on `window.__mm`.
 */
import * as THREE from 'three';
import { fetchAvatar } from '../avatar/avatar.ts';
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
import { createSettingsPanel } from './settings-panel.ts';

/** What tests read: only what they need. */
export interface DemoHook {
  ready: boolean;
  error: string | null;
  /** Runtime updates so far (one per rendered frame). */
  updates: number;
  frame: number;
  root: [number, number, number];
  /** Facing yaw of the root, radians (0 = +Z). */
  yaw: number;
  /** Contact onsets counted per foot (left, right), to see feet alternate. */
  steps: [number, number];
  searches: number;
  transitions: number;
  /** Avatar toe (ball) heights above the floor (left, right), m; NaN without an avatar. */
  avatarToes: [number, number];
}

declare global {
  interface Window {
    __mm: DemoHook;
  }
}

const hook: DemoHook = { ready: false, error: null, updates: 0, frame: 0, root: [0, 0, 0], yaw: 0, steps: [0, 0], searches: 0, transitions: 0, avatarToes: [NaN, NaN] };
window.__mm = hook;

function fail(message: string): void {
  hook.error = hook.error ? `${hook.error}\n${message}` : message;
  showError(message);
}
window.addEventListener('error', (e) => fail(`error: ${e.message}`));
window.addEventListener('unhandledrejection', (e) => fail(`error: ${errorMessage(e.reason)}`));

const _look = new THREE.Vector3();

/** The first connected gamepad, without allocating a closure per frame. */
function firstGamepad(): Gamepad | null {
  const pads = navigator.getGamepads?.() ?? [];
  for (const p of pads) if (p) return p;
  return null;
}

async function main(): Promise<void> {
  const params = new URLSearchParams(location.search);
  const fixedDt = params.get('dt') === 'fixed';
  const stage = new ViewerScene(document.getElementById('viewport') as HTMLElement);
  const camera = new FollowCamera(stage.camera, stage.renderer.domElement);
  await initWasm();
  const response = await fetch(params.get('db') ?? 'databases/locomotion.mmdb');
  if (!response.ok) throw new Error(`${response.url}: HTTP ${response.status}`);
  const crowd = new Crowd(new Uint8Array(await response.arrayBuffer()), 1);

  createSettingsPanel(crowd);
  const feet = findFootJoints(crowd);
  const skeleton = new SkeletonView(crowd.jointParents, feet.left, feet.right);
  const marker = new RootMarker();
  stage.scene.add(skeleton.object, marker.object);
  const j = crowd.numJoints;
  const world = new Float32Array(j * 3);
  const worldRotations = new Float32Array(j * 4);

  const avatar = params.get('avatar') === 'none' ? null : await fetchAvatar(params.get('avatar') ?? 'avatars/ubc_male.glb', crowd);
  if (avatar) {
    stage.scene.add(avatar.object);
    skeleton.object.visible = params.get('skeleton') === '1';
  }

  const keyboard = new KeyboardInput();
  keyboard.attach(window);
  const basis = new CameraBasis();
  const input = createMoveInput();
  const hud = document.getElementById('hud') as HTMLElement;
  let previousContacts = 0;
  let last = performance.now();
  let averageMs = 0;

  stage.renderer.setAnimationLoop((now: number) => {
    const dt = fixedDt ? 1 / 60 : Math.min(0.1, Math.max(0, (now - last) / 1000));
    last = now;
    stage.camera.getWorldDirection(_look);
    basis.setLook(_look.x, _look.z);
    const rotations = crowd.rotationsOf(0);
    const yaw = 2 * Math.atan2(rotations[1], rotations[3]); // the root is a pure yaw
    const pad = firstGamepad();
    if (keyboard.active || !readGamepad(pad, basis, input)) keyboard.read(basis, yaw, dt, input);
    crowd.setInput(0, input);
    const t = performance.now();
    crowd.update(dt);
    averageMs += (performance.now() - t - averageMs) * 0.05;

    forwardKinematics(crowd.jointParents, crowd.positionsOf(0), crowd.rotationsOf(0), world, worldRotations);
    if (avatar) avatar.pose(world, worldRotations, hook.avatarToes);
    const contacts = crowd.contactsOf(0);
    skeleton.update(world, (contacts & 1) !== 0, (contacts & 2) !== 0);
    marker.update(world, worldRotations);
    camera.follow(world[0], world[2], dt);
    stage.grid.follow(world[0], world[2]);
    stage.render();

    const onsets = contacts & ~previousContacts;
    previousContacts = contacts;
    if (onsets & 1) hook.steps[0]++;
    if (onsets & 2) hook.steps[1]++;
    hook.updates++;
    hook.frame = crowd.binding.frame(0);
    hook.root[0] = world[0];
    hook.root[1] = world[1];
    hook.root[2] = world[2];
    hook.yaw = 2 * Math.atan2(worldRotations[1], worldRotations[3]);
    hook.searches = crowd.binding.searches(0);
    hook.transitions = crowd.binding.transitions(0);
    hook.ready = true;
    hud.textContent = `frame ${hook.frame} · update ${averageMs.toFixed(3)} ms · searches ${hook.searches} · transitions ${hook.transitions}`;
  });
}

main().catch((e: unknown) => fail(errorMessage(e)));
