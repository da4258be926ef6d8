/**
 * The VR page (vr.html): a WebXR `immersive-vr` session on `local-floor` where the headset and
 * both controllers drive a full-body motion-matched avatar (THESIS_NOTES §9).
 *
 * URL parameters:
 * - `emulate=1`: install the iwer emulator (Quest 3) over the browser's WebXR; `devui=0` leaves
 *   out its control panel (tests).
 * - `replay=URL` (or `replay=scripted`): play a tracker recording on the desktop page, no XR,
 *   watched by a spectator camera; `bench=1` also times the whole VR update over the replay.
 * - `dt=fixed`: every frame advances exactly 1/60 s and tracker timestamps are frame/60
 *   (deterministic tests).
 * - `model=URL`: the orientation model (default models/orientation.onnx); `predictor=heuristic`
 *   starts with the heuristic; `alpha=0.2`: the root↔head clamp (m); `mirror=0`: no mirror.
 *
 * State for tests is on `window.__vr`.
 */
import * as THREE from 'three';
import { Reflector } from 'three/addons/objects/Reflector.js';
import { type Avatar, fetchAvatar } from '../avatar/avatar.ts';
import { Crowd } from '../core/crowd.ts';
import { initWasm } from '../core/wasm.ts';
import { errorMessage, showError } from '../viewer/error-box.ts';
import { FollowCamera } from '../viewer/follow-camera.ts';
import { ViewerScene } from '../viewer/scene.ts';
import { type BodyYawPredictor } from './body-yaw.ts';
import { installEmulator } from './emulator.ts';
import { EnterVrButton } from './enter-vr-button.ts';
import { HeadingYawPredictor } from './fallback-yaw.ts';
import { loadNetworkPredictor } from './network-yaw.ts';
import { VrPipeline } from './pipeline.ts';
import { decodeRecording, encodeRecordingJson, type Recording, RecordingPlayer, TrackerRecorder } from './recording.ts';
import { SCRIPT_DURATION, scriptedSample } from './scripted-motion.ts';
import { LEFT, RIGHT, sampleXRFrame, TrackerSample } from './tracker-sample.ts';
import { UpdateTimer } from './update-timer.ts';

/** What tests read (and the few calls they make). */
export interface VrHook {
  ready: boolean;
  error: string | null;
  /** 'idle' (desktop, no XR), 'xr' or 'replay'. */
  mode: 'idle' | 'xr' | 'replay';
  inXR: boolean;
  /** Frames run through the VR pipeline so far. */
  frames: number;
  /** Head centre on the floor (x, z). */
  head: [number, number];
  /** HMD position (x, y, z). */
  hmd: [number, number, number];
  /** Character root (x, y, z) and yaw; body yaw from the predictor (rad, 0 = +Z). */
  root: [number, number, number];
  rootYaw: number;
  bodyYaw: number;
  predictor: string;
  /** Why the network is not used, or null. */
  predictorFallback: string | null;
  /** How the character is driven: the runtime's tracked mode or the stick-input stand-in. */
  drive: 'tracked' | 'input';
  /** Avatar wrist ↔ controller-implied wrist, m (left, right); tracker status (head, left, right). */
  handErrors: [number, number];
  trackerStatus: [number, number, number];
  /** Median / last VR update (trackers → upper body), ms. */
  updateMs: { median: number; p95: number; last: number };
  /** Replay only: reached the end; `bench=1`: the timing over the whole replay. */
  replayDone: boolean;
  bench: { frames: number; median: number; p95: number; mean: number } | null;
  eyeHeight: number;
  /** The iwer device with `emulate=1`. */
  emulator: unknown;
  /** Called at the start of every frame with the frame counter (tests script iwer poses here). */
  beforeFrame: ((frame: number) => void) | null;
  enterVR(): Promise<void>;
  exitVR(): Promise<void>;
  startRecording(): void;
  /** Stops and returns the recording as JSON text. */
  stopRecording(): string;
}

declare global {
  interface Window {
    __vr: VrHook;
  }
}

const hook: VrHook = {
  ready: false,
  error: null,
  mode: 'idle',
  inXR: false,
  frames: 0,
  head: [0, 0],
  hmd: [0, 0, 0],
  root: [0, 0, 0],
  rootYaw: 0,
  bodyYaw: 0,
  predictor: '',
  predictorFallback: null,
  drive: 'input',
  handErrors: [NaN, NaN],
  trackerStatus: [0, 0, 0],
  updateMs: { median: NaN, p95: NaN, last: NaN },
  replayDone: false,
  bench: null,
  eyeHeight: NaN,
  emulator: null,
  beforeFrame: null,
  enterVR: () => Promise.reject(new Error('not ready')),
  exitVR: () => Promise.resolve(),
  startRecording: () => undefined,
  stopRecording: () => '',
};
window.__vr = hook;

function fail(message: string): void {
  hook.error = hook.error ? `${hook.error}\n${message}` : message;
  showError(message);
}
window.addEventListener('error', (e) => fail(`error: ${e.message}`));
window.addEventListener('unhandledrejection', (e) => fail(`error: ${errorMessage(e.reason)}`));

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;

/** Small markers at the controller grips (seen in the mirror, the spectator view and tests). */
function controllerMarker(color: number): THREE.Mesh {
  const m = new THREE.Mesh(new THREE.BoxGeometry(0.04, 0.04, 0.12), new THREE.MeshStandardMaterial({ color, roughness: 0.6 }));
  m.matrixAutoUpdate = true;
  return m;
}

async function loadRecording(url: string): Promise<Recording> {
  if (url === 'scripted') {
    const recorder = new TrackerRecorder(Math.ceil(SCRIPT_DURATION * 72) + 2);
    const s = new TrackerSample();
    for (let f = 0; f / 72 <= SCRIPT_DURATION; f++) {
      scriptedSample(f / 72, s);
      recorder.add(s);
    }
    return recorder.toRecording({ source: 'scripted-motion.ts', rate: 72 });
  }
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
  return decodeRecording(new Uint8Array(await response.arrayBuffer()), url);
}

/** Offers a file download of `text`. */
function download(name: string, text: string): void {
  const a = document.createElement('a');
  a.href = URL.createObjectURL(new Blob([text], { type: 'application/json' }));
  a.download = name;
  a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}

async function main(): Promise<void> {
  const params = new URLSearchParams(location.search);
  const fixedDt = params.get('dt') === 'fixed';
  const replayUrl = params.get('replay');
  const emulated = params.get('emulate') === '1';
  if (emulated) hook.emulator = await installEmulator(params.get('devui') !== '0');

  const stage = new ViewerScene($('viewport'));
  const renderer = stage.renderer;
  renderer.xr.enabled = true;
  renderer.xr.setReferenceSpaceType('local-floor');
  const spectator = new FollowCamera(stage.camera, renderer.domElement);
  stage.camera.position.set(2.2, 1.6, 3.2);

  await initWasm();
  const response = await fetch(params.get('db') ?? 'databases/locomotion.mmdb');
  if (!response.ok) throw new Error(`${response.url}: HTTP ${response.status}`);
  const crowd = new Crowd(new Uint8Array(await response.arrayBuffer()), 1);
  const alphaInput = $<HTMLInputElement>('alpha');
  const setAlpha = (alpha: number) => {
    crowd.setSettings({ clamping: true, clamp_distance: alpha });
    alphaInput.value = String(alpha);
    $('alpha-value').textContent = `${alpha.toFixed(2)} m`;
  };
  setAlpha(Number(params.get('alpha') ?? 0.2));
  alphaInput.addEventListener('input', () => setAlpha(Number(alphaInput.value)));

  const avatar: Avatar | null = params.get('avatar') === 'none' ? null : await fetchAvatar(params.get('avatar') ?? 'avatars/ubc_male.glb', crowd);
  if (avatar) stage.scene.add(avatar.object);

  // Body yaw: the network if it loads, else the heuristic — and the page says which and why.
  const heuristic = new HeadingYawPredictor();
  const pipeline = new VrPipeline(crowd, avatar, heuristic);
  let network: BodyYawPredictor | null = null;
  const select = $<HTMLSelectElement>('predictor');
  const status = $('predictor-status');
  const showPredictor = () => {
    hook.predictor = pipeline.predictor.name;
    select.value = pipeline.predictor.name === 'network' ? 'network' : 'heuristic';
    status.textContent = network ? `using the ${pipeline.predictor.name}` : 'fallback: heuristic (no model)';
    status.title = hook.predictorFallback ?? '';
    status.classList.toggle('fallback', !network);
  };
  try {
    network = await loadNetworkPredictor(params.get('model') ?? 'models/orientation.onnx');
    if (params.get('predictor') !== 'heuristic') pipeline.setPredictor(network);
  } catch (e) {
    hook.predictorFallback = `orientation model unavailable: ${errorMessage(e)}`;
    (select.querySelector('option[value="network"]') as HTMLOptionElement).disabled = true;
  }
  select.addEventListener('change', () => {
    pipeline.setPredictor(select.value === 'network' && network ? network : heuristic);
    showPredictor();
  });
  showPredictor();
  hook.drive = pipeline.driver.mode;

  // Scene furniture: a mirror in front of the start position, controller markers.
  if (params.get('mirror') !== '0') {
    const mirror = new Reflector(new THREE.PlaneGeometry(1.6, 2.2), { textureWidth: 512, textureHeight: 704, color: 0xb8c0c8, multisample: 0 });
    mirror.position.set(0, 1.1, -3);
    stage.scene.add(mirror);
  }
  const markers = [controllerMarker(0x4fa3ff), controllerMarker(0xff7a4f)];
  stage.scene.add(markers[0], markers[1]);

  // Enter VR.
  const button = new EnterVrButton(renderer, fail);
  $('vr-slot').appendChild(button.element);
  await button.init();
  hook.enterVR = () => button.enter();
  hook.exitVR = () => button.exit();
  // three.js copies the headset's pose and projection into the camera while presenting: keep
  // the spectator's and give it back afterwards.
  let xrFrames = 0;
  const spectatorPose = new THREE.Matrix4();
  renderer.xr.addEventListener('sessionstart', () => {
    spectatorPose.copy(stage.camera.matrix);
    pipeline.reset();
    xrFrames = 0;
  });
  renderer.xr.addEventListener('sessionend', () => {
    spectatorPose.decompose(stage.camera.position, stage.camera.quaternion, stage.camera.scale);
    stage.resize();
    pipeline.reset();
  });

  // Recording.
  const recorder = new TrackerRecorder();
  let recording = false;
  const recordButton = $<HTMLButtonElement>('record');
  const startRecording = () => {
    recorder.clear();
    recording = true;
    recordButton.textContent = 'Stop recording';
    recordButton.classList.add('recording');
  };
  const stopRecording = (): string => {
    recording = false;
    recordButton.textContent = 'Record';
    recordButton.classList.remove('recording');
    if (recorder.frames === 0) return '';
    return encodeRecordingJson(recorder.toRecording({ page: 'vr.html', mode: hook.mode, eyeHeight: hook.eyeHeight, userAgent: navigator.userAgent }));
  };
  hook.startRecording = startRecording;
  hook.stopRecording = stopRecording;
  recordButton.addEventListener('click', () => {
    if (!recording) startRecording();
    else {
      const text = stopRecording();
      if (text) download(`vr-session-${new Date().toISOString().replace(/[:.]/g, '-')}.json`, text);
    }
  });

  // Height calibration (THESIS_NOTES §9): the standing eye height; the ratio picks databases.
  $('calibrate').addEventListener('click', () => {
    hook.eyeHeight = pipeline.trackers.head.position[1];
  });

  // Replay.
  const player = replayUrl ? new RecordingPlayer(await loadRecording(replayUrl)) : null;
  if (player && params.get('bench') === '1') hook.bench = benchmark(pipeline, player);

  const sample = new TrackerSample();
  const timer = new UpdateTimer(600);
  const hud = $('hud');
  let replayTime = 0;
  let last = performance.now();

  renderer.setAnimationLoop((now: number, frame?: XRFrame) => {
    const realDt = Math.min(0.1, Math.max(0, (now - last) / 1000));
    last = now;
    hook.beforeFrame?.(hook.frames);
    const space = renderer.xr.getReferenceSpace();
    if (frame && space) {
      hook.mode = 'xr';
      sampleXRFrame(frame, space, fixedDt ? xrFrames / 60 : now / 1000, sample, emulated);
      xrFrames++;
    } else if (player) {
      hook.mode = 'replay';
      player.sampleAt(replayTime, sample);
      replayTime += fixedDt ? 1 / 60 : realDt;
      hook.replayDone = replayTime > player.duration;
    } else {
      // Desktop, no XR: a user standing still — at the origin, or where the last session ended.
      hook.mode = 'idle';
      if (hook.frames === 0) scriptedSample(0, sample);
      sample.time = hook.frames / 60;
    }
    hook.inXR = renderer.xr.isPresenting;
    if (recording) recorder.add(sample);
    // First person: the head would fill the eyes' view (the mirror shows it headless too).
    if (pipeline.upperBody) pipeline.upperBody.options.hideHead = hook.inXR;
    pipeline.update(sample, fixedDt ? 1 / 60 : undefined);
    timer.add(pipeline.lastUpdateMs);

    const tr = pipeline.trackers;
    for (let k = 0; k < 2; k++) {
      const view = k === 0 ? tr.left : tr.right;
      markers[k].position.set(view.position[0], view.position[1], view.position[2]);
      markers[k].quaternion.set(view.rotation[0], view.rotation[1], view.rotation[2], view.rotation[3]);
    }
    if (!hook.inXR) spectator.follow(pipeline.root[0], pipeline.root[2], fixedDt ? 1 / 60 : realDt);
    stage.grid.follow(pipeline.root[0], pipeline.root[2]);
    stage.render();

    hook.frames++;
    hook.head[0] = pipeline.headFloor[0];
    hook.head[1] = pipeline.headFloor[1];
    hook.hmd[0] = tr.head.position[0];
    hook.hmd[1] = tr.head.position[1];
    hook.hmd[2] = tr.head.position[2];
    hook.root[0] = pipeline.root[0];
    hook.root[1] = pipeline.root[1];
    hook.root[2] = pipeline.root[2];
    hook.rootYaw = pipeline.rootYaw;
    hook.bodyYaw = pipeline.yaw;
    hook.predictor = pipeline.predictor.name;
    if (pipeline.upperBody) {
      hook.handErrors[0] = pipeline.upperBody.handError[0];
      hook.handErrors[1] = pipeline.upperBody.handError[1];
    }
    hook.trackerStatus[0] = tr.status[0];
    hook.trackerStatus[1] = tr.status[LEFT];
    hook.trackerStatus[2] = tr.status[RIGHT];
    hook.updateMs.last = pipeline.lastUpdateMs;
    if (hook.frames % 30 === 0) {
      hook.updateMs.median = timer.median();
      hook.updateMs.p95 = timer.quantile(0.95);
      const ratio = Number.isFinite(hook.eyeHeight) ? ` · height ${(tr.head.position[1] / hook.eyeHeight).toFixed(2)}` : '';
      const bench = hook.bench ? ` · bench median ${hook.bench.median.toFixed(3)} ms` : '';
      hud.textContent = `${hook.mode} · frame ${hook.frames} · VR update ${hook.updateMs.median.toFixed(2)} ms${ratio}${bench}`;
    }
    hook.ready = true;
  });
}

/** Times the whole VR update over every frame of the replay at 72 Hz (after one warm-up pass). */
function benchmark(pipeline: VrPipeline, player: RecordingPlayer): VrHook['bench'] {
  const sample = new TrackerSample();
  const frames = Math.floor(player.duration * 72);
  const timer = new UpdateTimer(frames);
  for (let pass = 0; pass < 2; pass++) {
    pipeline.reset();
    for (let f = 0; f <= frames; f++) {
      player.sampleAt(f / 72, sample);
      pipeline.update(sample);
      if (pass === 1) timer.add(pipeline.lastUpdateMs);
    }
  }
  pipeline.reset();
  return { frames: timer.count, median: timer.median(), p95: timer.quantile(0.95), mean: timer.mean() };
}

main().catch((e: unknown) => fail(errorMessage(e)));
