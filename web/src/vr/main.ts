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
 * - `model=URL`: the orientation model (default models/orientation.onnx; a missing or broken file
 *   falls back, visibly, to the heuristic); `predictor=heuristic` starts with the heuristic;
 *   `alpha=0.2`: the root↔head clamp (m, slider 0.1–0.3); `mirror=0`: no mirror, `mirror=256`:
 *   its texture width.
 * - A recording whose meta has `eyeHeight` calibrates with it; `bench=1` replays it as fast as
 *   possible with the network, then the heuristic, and reports the numbers of docs/vr.md.
 *
 * State for tests is on `window.__vr`.
 */
import * as THREE from 'three';
import { Reflector } from 'three/addons/objects/Reflector.js';
import { type Avatar, fetchAvatar } from '../avatar/avatar.ts';
import { Crowd } from '../core/crowd.ts';
import { initWasm } from '../core/wasm.ts';
import { errorMessage, showError } from '../viewer/error-box.ts';
import { SpectatorView } from './spectator-view.ts';
import { FollowCamera } from '../viewer/follow-camera.ts';
import { ViewerScene } from '../viewer/scene.ts';
import { type BodyYawPredictor } from './body-yaw.ts';
import { installEmulator } from './emulator.ts';
import { EnterVrButton } from './enter-vr-button.ts';
import { HeadingYawPredictor } from './fallback-yaw.ts';
import { loadNetworkPredictor, type NetworkYawPredictor } from './network-yaw.ts';
import { DEFAULT_ALPHA, VrPipeline } from './pipeline.ts';
import { decodeRecording, encodeRecordingJson, type Recording, RecordingPlayer, TrackerRecorder } from './recording.ts';
import { SCRIPT_DURATION, scriptedSample } from './scripted-motion.ts';
import { LEFT, RIGHT, sampleXRFrame, TrackerSample } from './tracker-sample.ts';
import { UpdateTimer } from './update-timer.ts';
import { headingYaw, wrapAngle } from './yaw.ts';

/** Error statistics, degrees or metres. */
export interface Stats {
  mean: number;
  median: number;
  p95: number;
  max: number;
}

/** `bench=1`: the replay benchmark (docs/vr.md). */
export interface VrBench {
  recording: string;
  frames: number;
  /** The whole synchronous VR update (trackers → upper body), ms. */
  median: number;
  p95: number;
  mean: number;
  /** One network run (features + onnxruntime, started in the update, finished before the next frame), ms. */
  modelMedian: number;
  modelP95: number;
  alpha: number;
  /** Predictor of the timed pass and its run count over the pass. */
  predictor: string;
  modelRuns: number;
  /** With ground truth (synthetic recordings): avatar root ↔ user root on the floor, m. */
  rootDistance: Stats | null;
  /** Avatar root ↔ head centre floor projection (what α clamps), m. */
  headGap: Stats;
  /** Body-yaw error vs ground truth, degrees: the network, the dead-zone heuristic, raw HMD forward. */
  yawError: { network: Stats | null; heuristic: Stats | null; hmdForward: Stats | null };
  /** Root distance with the heuristic driving the avatar, m. */
  rootDistanceHeuristic: Stats | null;
  /** Planted-toe sliding of the database skeleton in room units (docs/runtime.md's measure), cm/s. */
  skatingCmPerS: number;
  /** The same, counting only toes the runtime flags in contact. */
  skatingContactCmPerS: number;
  /** Mean head and avatar root ground speeds, m/s. */
  headSpeed: number;
  rootSpeed: number;
  units: { worldPerDb: number; hipsScale: number; avatarScale: number; avatarEyeHeight: number; databaseEyeHeight: number };
}

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
  /** The network loaded; its finished runs, frames it skipped (a run still pending), failures. */
  networkLoaded: boolean;
  predictorRuns: number;
  predictorSkipped: number;
  predictorFailures: number;
  /** α (m). */
  alpha: number;
  /** Avatar hips bone height, toe heights (m, room); hips drop (m) and avatar scale. */
  hipsHeight: number;
  toeHeights: [number, number];
  hipsDrop: number;
  avatarScale: number;
  /** Avatar wrist ↔ controller-implied wrist, m (left, right); tracker status (head, left, right). */
  handErrors: [number, number];
  trackerStatus: [number, number, number];
  /** Median / last VR update (trackers → upper body), ms. */
  updateMs: { median: number; p95: number; last: number };
  /** Replay only: reached the end; `bench=1`: the timing over the whole replay. */
  replayDone: boolean;
  bench: VrBench | null;
  /** Calibrated eye height (NaN before calibration). */
  eyeHeight: number;
  /** The iwer device with `emulate=1`. */
  emulator: unknown;
  /** Called at the start of every frame with the frame counter (tests script iwer poses here). */
  beforeFrame: ((frame: number) => void) | null;
  enterVR(): Promise<void>;
  /** Calibrates with `eyeHeight` (default: the HMD's height now). */
  calibrate(eyeHeight?: number): void;
  setPredictor(name: 'network' | 'heuristic'): void;
  setAlpha(alpha: number): void;
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
  networkLoaded: false,
  predictorRuns: 0,
  predictorSkipped: 0,
  predictorFailures: 0,
  alpha: DEFAULT_ALPHA,
  hipsHeight: NaN,
  toeHeights: [NaN, NaN],
  hipsDrop: 0,
  avatarScale: 1,
  handErrors: [NaN, NaN],
  trackerStatus: [0, 0, 0],
  updateMs: { median: NaN, p95: NaN, last: NaN },
  replayDone: false,
  bench: null,
  eyeHeight: NaN,
  emulator: null,
  beforeFrame: null,
  enterVR: () => Promise.reject(new Error('not ready')),
  calibrate: () => undefined,
  setPredictor: () => undefined,
  setAlpha: () => undefined,
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
  // While the headset presents, the page shows a third-person view (`spectator=0`: none).
  const pip = params.get('spectator') === '0' ? null : new SpectatorView($('viewport'));
  let head: THREE.Object3D | null = null; // the avatar's head bone, set once the avatar loads
  stage.camera.position.set(2.2, 1.6, 3.2);

  await initWasm();
  const response = await fetch(params.get('db') ?? 'databases/locomotion.mmdb');
  if (!response.ok) throw new Error(`${response.url}: HTTP ${response.status}`);
  const crowd = new Crowd(new Uint8Array(await response.arrayBuffer()), 1);

  const avatar: Avatar | null = params.get('avatar') === 'none' ? null : await fetchAvatar(params.get('avatar') ?? 'avatars/ubc_male.glb', crowd);
  if (avatar) stage.scene.add(avatar.object);
  head = avatar && avatar.roles.has('head') ? avatar.bones[avatar.roles.get('head')!] : null;
  const hipsBone = avatar && avatar.roles.has('hips') ? avatar.bones[avatar.roles.get('hips')!] : null;

  // Body yaw: the network if it loads, else the heuristic — and the page says which and why.
  const heuristic = new HeadingYawPredictor();
  const pipeline = new VrPipeline(crowd, avatar, heuristic);

  // α: the runtime's clamp (the pipeline converts it to database units).
  const alphaInput = $<HTMLInputElement>('alpha');
  const setAlpha = (alpha: number) => {
    const a = Math.min(0.3, Math.max(0.1, Number.isFinite(alpha) ? alpha : DEFAULT_ALPHA));
    pipeline.setAlpha(a);
    hook.alpha = a;
    alphaInput.value = String(a);
    $('alpha-value').textContent = `${a.toFixed(2)} m`;
  };
  setAlpha(Number(params.get('alpha') ?? DEFAULT_ALPHA));
  // `settings={...}`: runtime settings on top of the VR defaults (tuning; docs/runtime.md keys).
  if (params.get('settings')) crowd.setSettings(JSON.parse(params.get('settings')!) as Record<string, unknown>);
  alphaInput.addEventListener('input', () => setAlpha(Number(alphaInput.value)));
  hook.setAlpha = setAlpha;

  let network: NetworkYawPredictor | null = null;
  const modelUrl = params.get('model') ?? 'models/orientation.onnx';
  const select = $<HTMLSelectElement>('predictor');
  const status = $('predictor-status');
  const showPredictor = () => {
    hook.predictor = pipeline.predictor.name;
    select.value = pipeline.predictor.name === 'network' ? 'network' : 'heuristic';
    status.textContent = network ? `body yaw: ${pipeline.predictor.name}` : 'fallback: heuristic — the orientation model did not load';
    status.title = hook.predictorFallback ?? `model: ${modelUrl}`;
    status.classList.toggle('fallback', !network);
  };
  try {
    network = await loadNetworkPredictor(modelUrl);
    hook.networkLoaded = true;
    if (params.get('predictor') !== 'heuristic') pipeline.setPredictor(network);
  } catch (e) {
    hook.predictorFallback = `orientation model unavailable (${modelUrl}): ${errorMessage(e)}`;
    console.warn(hook.predictorFallback);
    (select.querySelector('option[value="network"]') as HTMLOptionElement).disabled = true;
  }
  const choosePredictor = (name: string) => {
    pipeline.setPredictor(name === 'network' && network ? network : heuristic);
    showPredictor();
  };
  select.addEventListener('change', () => choosePredictor(select.value));
  hook.setPredictor = choosePredictor;
  showPredictor();

  // Scene furniture: a mirror in front of the start position, controller markers.
  if (params.get('mirror') !== '0') {
    // `mirror=<px>`: its texture width (default 512; tests use less, software rendering is slow).
    const width = Math.max(64, Math.min(2048, Number(params.get('mirror')) || 512));
    const mirror = new Reflector(new THREE.PlaneGeometry(1.6, 2.2), { textureWidth: width, textureHeight: Math.round(width * 1.375), color: 0xb8c0c8, multisample: 0 });
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
  const calibrate = (eyeHeight = pipeline.trackers.head.position[1]) => {
    try {
      pipeline.calibrate(eyeHeight);
      hook.eyeHeight = eyeHeight;
      hook.avatarScale = pipeline.avatarScale;
      setAlpha(hook.alpha);
      $('calibrate').textContent = `Calibrated ${eyeHeight.toFixed(2)} m`;
    } catch (e) {
      fail(errorMessage(e));
    }
  };
  $('calibrate').addEventListener('click', () => calibrate());
  hook.calibrate = calibrate;

  // Replay.
  const player = replayUrl ? new RecordingPlayer(await loadRecording(replayUrl)) : null;
  const recordedEye = player?.recording.meta.eyeHeight;
  if (typeof recordedEye === 'number') calibrate(recordedEye);
  if (player && params.get('bench') === '1') {
    hook.bench = await benchmark(pipeline, player, network, heuristic, replayUrl ?? '');
    choosePredictor(network && params.get('predictor') !== 'heuristic' ? 'network' : 'heuristic');
  }

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
    if (pip) {
      pip.visible = hook.inXR;
      if (hook.inXR) {
        // Others see the head that first person hides.
        const hidden = head ? head.scale.x : 1;
        if (head) head.scale.setScalar(1);
        head?.updateMatrixWorld(true);
        pip.render(stage.scene, pipeline.root[0], pipeline.root[2], pipeline.rootYaw);
        if (head) head.scale.setScalar(hidden);
        head?.updateMatrixWorld(true);
      }
    }

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
    if (network) {
      hook.predictorRuns = network.runs;
      hook.predictorSkipped = network.skipped;
      hook.predictorFailures = network.failures;
    }
    hook.hipsHeight = hipsBone ? hipsBone.matrixWorld.elements[13] : NaN;
    hook.toeHeights[0] = pipeline.toeHeights[0];
    hook.toeHeights[1] = pipeline.toeHeights[1];
    hook.hipsDrop = pipeline.hipsDrop;
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
      const runs = network ? ` · model runs ${network.runs}` : '';
      hud.textContent = `${hook.mode} · frame ${hook.frames} · VR update ${hook.updateMs.median.toFixed(2)} ms${runs}${ratio}${bench}`;
    }
    hook.ready = true;
  });
}

/** Mean, median, p95 and max of `values` (NaN-free); null when empty. */
function stats(values: Float64Array, count: number): Stats | null {
  if (count === 0) return null;
  const s = values.slice(0, count).sort();
  let sum = 0;
  for (let i = 0; i < count; i++) sum += s[i];
  const q = (p: number) => s[Math.min(count - 1, Math.round(p * (count - 1)))];
  return { mean: sum / count, median: q(0.5), p95: q(0.95), max: s[count - 1] };
}

/**
 * Replays every frame of the recording as fast as possible (the network's run awaited between
 * frames, as a live frame would have it finished): a warm-up pass, a timed pass with the network
 * (or the heuristic when it did not load) measuring root distance, head gap, skating and yaw
 * errors, and a pass with the heuristic for its yaw error and root distance.
 */
async function benchmark(pipeline: VrPipeline, player: RecordingPlayer, network: NetworkYawPredictor | null, heuristic: BodyYawPredictor, name: string): Promise<VrBench> {
  const rec = player.recording;
  const truth = rec.truth;
  const n = rec.frames;
  const crowd = pipeline.crowd;
  const sample = new TrackerSample();
  const timer = new UpdateTimer(n);
  const modelTimer = new UpdateTimer(n);
  const dist = new Float64Array(n), gap = new Float64Array(n), yawErr = new Float64Array(n), hmdErr = new Float64Array(n);
  const sites = crowd.sites();
  const toes = ['left_toe', 'right_toe'].map((s) => sites.find((x) => x.name === s)?.joint ?? -1);
  const previousToes = new Float64Array(6);
  const H = 0.033;
  let skating = 0;
  let skatingContact = 0;
  let headPath = 0;
  let rootPath = 0;
  let gapCount = 0;
  const last = new Float64Array(4);

  const pass = async (predictor: BodyYawPredictor, measure: 'timed' | 'yaw' | 'none') => {
    pipeline.setPredictor(predictor);
    pipeline.reset();
    player.sampleAt(0, sample);
    const q = sample.rotation;
    const heading = headingYaw(q[0], q[1], q[2], q[3]);
    const k = 1 / pipeline.worldPerDb;
    crowd.teleport(0, (sample.position[0] - 0.1 * Math.sin(heading)) * k, (sample.position[2] - 0.1 * Math.cos(heading)) * k, truth ? truth.bodyYaw[0] : heading);
    timer.count = 0;
    modelTimer.count = 0;
    skating = 0;
    skatingContact = 0;
    headPath = 0;
    rootPath = 0;
    gapCount = 0;
    const runs0 = network?.runs ?? 0;
    let count = 0;
    for (let f = 0; f < n; f++) {
      player.sampleAt(rec.time[f] - rec.time[0], sample);
      pipeline.update(sample);
      if (predictor === network) {
        await network.settle();
        if (measure === 'timed') modelTimer.add(network.lastRunMs);
      }
      const yaw = pipeline.yaw;
      if (truth) yawErr[count] = (Math.abs(wrapAngle(yaw - truth.bodyYaw[f])) * 180) / Math.PI;
      if (measure === 'timed') {
        timer.add(pipeline.lastUpdateMs);
        gap[gapCount++] = Math.hypot(pipeline.root[0] - pipeline.headFloor[0], pipeline.root[2] - pipeline.headFloor[1]);
        if (truth) {
          const h = pipeline.trackers.head.rotation;
          hmdErr[count] = (Math.abs(wrapAngle(headingYaw(h[0], h[1], h[2], h[3]) - truth.bodyYaw[f])) * 180) / Math.PI;
        }
        // Skating (docs/runtime.md): d_xz·(2 − 2^(h/H)) per toe while h < H, in room units.
        const s = pipeline.worldPerDb;
        const contacts = crowd.contactsOf(0);
        if (f > 0) {
          headPath += Math.hypot(pipeline.headFloor[0] - last[0], pipeline.headFloor[1] - last[1]);
          rootPath += Math.hypot(pipeline.root[0] - last[2], pipeline.root[2] - last[3]);
        }
        last[0] = pipeline.headFloor[0];
        last[1] = pipeline.headFloor[1];
        last[2] = pipeline.root[0];
        last[3] = pipeline.root[2];
        for (let side = 0; side < 2; side++) {
          const j = toes[side];
          if (j < 0) continue;
          const x = pipeline.world[3 * j] * s, y = pipeline.world[3 * j + 1] * s, z = pipeline.world[3 * j + 2] * s;
          const h = y - (crowd.toeHeight ?? 0) * s;
          const d = Math.hypot(x - previousToes[3 * side], z - previousToes[3 * side + 2]);
          if (f > 0 && h < H) skating += d * (2 - 2 ** (Math.max(0, h) / H));
          if (f > 0 && contacts & (1 << side)) skatingContact += d;
          previousToes[3 * side] = x;
          previousToes[3 * side + 1] = y;
          previousToes[3 * side + 2] = z;
        }
      }
      if (truth) dist[count] = Math.hypot(pipeline.root[0] - truth.root[2 * f], pipeline.root[2] - truth.root[2 * f + 1]);
      count++;
    }
    return { count, runs: (network?.runs ?? 0) - runs0 };
  };

  const main = network ?? heuristic;
  await pass(main, 'none'); // warm-up: JIT, onnxruntime
  const timed = await pass(main, 'timed');
  const duration = rec.time[n - 1] - rec.time[0];
  const result: VrBench = {
    recording: name,
    frames: timer.count,
    median: timer.median(),
    p95: timer.quantile(0.95),
    mean: timer.mean(),
    modelMedian: network ? modelTimer.median() : NaN,
    modelP95: network ? modelTimer.quantile(0.95) : NaN,
    alpha: pipeline.clampDistance,
    predictor: main.name,
    modelRuns: timed.runs,
    rootDistance: truth ? stats(dist, timed.count) : null,
    headGap: stats(gap, gapCount) ?? { mean: NaN, median: NaN, p95: NaN, max: NaN },
    yawError: {
      network: truth && network ? stats(yawErr, timed.count) : null,
      heuristic: null,
      hmdForward: truth ? stats(hmdErr, timed.count) : null,
    },
    rootDistanceHeuristic: null,
    skatingCmPerS: duration > 0 ? (100 * skating) / duration : NaN,
    skatingContactCmPerS: duration > 0 ? (100 * skatingContact) / duration : NaN,
    headSpeed: headPath / duration,
    rootSpeed: rootPath / duration,
    units: { worldPerDb: pipeline.worldPerDb, hipsScale: pipeline.hipsScale, avatarScale: pipeline.avatarScale, avatarEyeHeight: pipeline.avatarEyeHeight, databaseEyeHeight: pipeline.databaseEyeHeight },
  };
  if (truth) {
    const h = await pass(heuristic, 'yaw');
    result.yawError.heuristic = stats(yawErr, h.count);
    result.rootDistanceHeuristic = stats(dist, h.count);
  }
  pipeline.reset();
  return result;
}

main().catch((e: unknown) => fail(errorMessage(e)));
