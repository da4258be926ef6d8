/**
 * The VR page (vr.html): a WebXR `immersive-vr` session on `local-floor` where the headset and
 * both controllers drive a full-body motion-matched avatar (`TrackedDrive`), on the public entries
 * and the pages' kit (three's Reflector; iwer only with `emulate=1`).
 * Loading: the character first (stages named in the toolbar; a failed avatar → the skeleton, a note);
 * then the whole database, the network and onnxruntime, the heuristic driving until then (shown).
 *
 * URL parameters: `emulate=1` (iwer, a Quest 3; `devui=0` without its panel), `replay=URL` or
 * `replay=scripted` (play a recording on the desktop page; `bench=1` also scores it), `dt=fixed`
 * (1/60 s per frame; `dt=0.05`: that many seconds), `model=URL` (orientation model; a missing one
 * falls back, visibly, to the heuristic), `predictor=heuristic`, `alpha=0.2`, `mirror=0|<texture px>`,
 * `spectator=0`, `settings={...}`, `db=`, `avatar=URL|none`, `room=<id>`, `name=` (a shared room:
 * `RoomPanel`). Tests: `window.__vr`.
 */
import * as THREE from 'three';
import { DEFAULT_AVATAR, assetUrl, registerOfflineCache, FollowCamera, Stage } from '../../index.ts';
import {
  ControllerMarkers, LoadingStatus, RecordButton, UpdateTimer, YawPredictorChoice, catchPageErrors, createMirror,
  emulateQuest3, errorMessage, loadPageCharacter, showError,
} from '../kit.ts';
import {
  DEFAULT_ALPHA, EnterVrButton, FIRST_PERSON_LAYER, FirstPerson, HeadingYawPredictor, LEFT, RIGHT, RecordingPlayer,
  type ReplayBenchResult, SpectatorView, THIRD_PERSON_LAYER, TrackedDrive, TrackerSample, benchReplay, deviceSetName,
  loadRecording, orientationModelUrl, sampleXRFrame, scriptedSample, setHeadsetView, vrDatabaseUrl,
} from '../../vr/index.ts';
import type { RoomPanel } from '../../rooms/index.ts';

const $ = <T extends HTMLElement>(id: string) => document.getElementById(id) as T;
const hook = {
  ready: false, error: null as string | null, mode: 'idle' as 'idle' | 'xr' | 'replay', inXR: false, frames: 0,
  target: [0, 0], hmd: [0, 0, 0], root: [0, 0, 0], rootYaw: 0, bodyYaw: 0,
  predictor: '', predictorFallback: null as string | null, networkLoaded: false, predictorRuns: 0, predictorSkipped: 0,
  predictorFailures: 0, yawModel: '', alpha: DEFAULT_ALPHA, hipsHeight: NaN, toeHeights: [NaN, NaN], hipsDrop: 0,
  avatarScale: 1, handErrors: [NaN, NaN], trackerStatus: [0, 0, 0], updateMs: { median: NaN, p95: NaN, last: NaN },
  replayDone: false, replayDuration: NaN, bench: null as ReplayBenchResult | null,
  eyeHeight: NaN, headTrianglesHidden: 0, deviceSet: '', hands: [0, 0, 0, 0, 0, 0], room: null as RoomPanel | null,
  body: false, shownHips: [0, 0, 0], // body tracking drives; the avatar's hips on the floor (x, z) and facing
  views: () => ({ headsetWhole: false, headsetHeadless: false, spectatorWhole: false, pageWhole: false }),
  emulator: null as unknown, beforeFrame: null as ((frame: number) => void) | null,
  enterVR: () => Promise.reject(new Error('not ready')) as Promise<void>, exitVR: () => Promise.resolve(),
  calibrate: (_eye?: number) => undefined as void, setPredictor: (_name: string) => undefined as void,
  setAlpha: (_a: number) => undefined as void, startRecording: () => undefined as void, stopRecording: () => '',
};
declare global {
  interface Window { __vr: typeof hook }
}
window.__vr = hook;
const fail = catchPageErrors(hook);

async function main(): Promise<void> {
  const params = new URLSearchParams(location.search);
  const fixedDt = params.get('dt') === 'fixed' ? 1 / 60 : Number(params.get('dt')) || 0; // s per frame; 0: real time
  const emulated = params.get('emulate') === '1';
  if (emulated) hook.emulator = await emulateQuest3(params.get('devui') !== '0');
  const avatarParam = params.get('avatar'); // the downloads start before the stage: they go on while it is built
  const loading = LoadingStatus.attach($('hud'));
  const avatar = avatarParam === 'none' ? null : (avatarParam ?? assetUrl(DEFAULT_AVATAR));
  const database = params.get('db') ?? vrDatabaseUrl(true); // its first part: the whole follows the first frame
  const pending = loadPageCharacter({ database, avatar, status: loading });
  const stage = new Stage($('viewport'));
  const renderer = stage.renderer;
  renderer.xr.enabled = true;
  renderer.xr.setReferenceSpaceType('local-floor');
  stage.camera.position.set(2.2, 1.6, 3.2);
  const spectator = new FollowCamera(stage.camera, renderer.domElement);
  const pip = params.get('spectator') === '0' ? null : new SpectatorView($('viewport'));
  const loaded = await pending;
  if (!loaded) return void (hook.error = $('hud').textContent);
  const { character, avatarNote } = loaded;
  loading.finish(avatarNote ? (showError(avatarNote), 'skeleton: the avatar did not load') : null);
  stage.scene.add(character.object3d);
  const heuristic = new HeadingYawPredictor();
  const drive = new TrackedDrive(character, heuristic);
  // First person: the headset sees a headless copy, the mirror and the spectator the whole avatar.
  const head = character.avatar?.bone('head');
  if (head) {
    hook.headTrianglesHidden = new FirstPerson(character.avatar!.object, head).hiddenTriangles;
    FirstPerson.attach(stage.scene);
  }
  const sees = (c: THREE.Camera, layer: number) => c.layers.isEnabled(layer);
  hook.views = () => ({
    headsetWhole: sees(renderer.xr.getCamera(), THIRD_PERSON_LAYER),
    headsetHeadless: sees(renderer.xr.getCamera(), FIRST_PERSON_LAYER),
    spectatorWhole: !!pip && sees(pip.camera, THIRD_PERSON_LAYER),
    pageWhole: sees(stage.camera, THIRD_PERSON_LAYER) && !sees(stage.camera, FIRST_PERSON_LAYER),
  });
  const hips = character.avatar?.bone('hips') ?? null;

  const alphaInput = $<HTMLInputElement>('alpha');
  const setAlpha = (alpha: number) => {
    const a = Math.min(0.3, Math.max(0.1, Number.isFinite(alpha) ? alpha : DEFAULT_ALPHA));
    drive.setAlpha(a);
    [hook.alpha, alphaInput.value, $('alpha-value').textContent] = [a, String(a), `${a.toFixed(2)} m`];
  };
  setAlpha(Number(params.get('alpha') ?? DEFAULT_ALPHA));
  if (params.get('settings')) character.settings = JSON.parse(params.get('settings')!) as Record<string, unknown>;
  alphaInput.addEventListener('input', () => setAlpha(Number(alphaInput.value)));
  hook.setAlpha = setAlpha;

  // Body yaw: the heuristic until the network has loaded (after the first frame), the network
  // then, the heuristic for good if it cannot load — and the page says which and why.
  const yaw = new YawPredictorChoice(drive, heuristic, {
    model: params.get('model') ?? String(orientationModelUrl()),
    recurrentModel: params.get('model') ? null : orientationModelUrl(true),
    prefer: params.get('predictor') ?? 'network',
    select: $<HTMLSelectElement>('predictor'),
    status: $('predictor-status'),
    onChange: ({ network, fallback }) => {
      [hook.predictor, hook.predictorFallback, hook.networkLoaded] = [drive.predictor.name, fallback, network !== null];
    },
  });
  hook.setPredictor = (name) => yaw.choose(name);

  // A mirror in front of the start position; markers at the controller grips.
  if (params.get('mirror') !== '0') stage.scene.add(createMirror(Number(params.get('mirror')) || 512));
  const markers = new ControllerMarkers();
  stage.scene.add(...markers.meshes);

  // Enter VR; three.js copies the headset's pose into the camera while presenting: keep the
  // spectator's and give it back afterwards.
  const button = new EnterVrButton(renderer, fail);
  $('vr-slot').appendChild(button.element);
  await button.init();
  performance.mark('mm:enter-vr-ready');
  [hook.enterVR, hook.exitVR] = [() => button.enter(), () => button.exit()];
  let xrFrames = 0;
  const spectatorPose = new THREE.Matrix4();
  renderer.xr.addEventListener('sessionstart', () => {
    spectatorPose.copy(stage.camera.matrix);
    setHeadsetView(stage.camera, true);
    drive.reset();
    xrFrames = 0;
  });
  renderer.xr.addEventListener('sessionend', () => {
    spectatorPose.decompose(stage.camera.position, stage.camera.quaternion, stage.camera.scale);
    setHeadsetView(stage.camera, false);
    stage.resize();
    drive.reset();
  });

  // Recording and calibration.
  const meta = () => ({ page: 'vr.html', mode: hook.mode, eyeHeight: hook.eyeHeight, userAgent: navigator.userAgent });
  const recorder = new RecordButton($<HTMLButtonElement>('record'), meta);
  [hook.startRecording, hook.stopRecording] = [() => recorder.start(), () => recorder.stop()];
  hook.calibrate = (eyeHeight = drive.trackers.head.position[1]) => {
    try {
      drive.calibrate(eyeHeight);
      [hook.eyeHeight, hook.avatarScale] = [eyeHeight, drive.scale];
      setAlpha(hook.alpha);
      $('calibrate').textContent = `Calibrated ${eyeHeight.toFixed(2)} m`;
    } catch (e) {
      fail(errorMessage(e));
    }
  };
  $('calibrate').addEventListener('click', () => hook.calibrate());

  // Replay (and its benchmark).
  const replayUrl = params.get('replay');
  const player = replayUrl ? new RecordingPlayer(await loadRecording(replayUrl)) : null;
  hook.replayDuration = player?.duration ?? NaN;
  const recordedEye = player?.recording.meta.eyeHeight;
  if (typeof recordedEye === 'number') hook.calibrate(recordedEye);
  if (player && params.get('bench') === '1') {
    await yaw.load();
    hook.bench = await benchReplay(drive, player, yaw.network, heuristic, replayUrl ?? '');
    yaw.choose(yaw.network && params.get('predictor') !== 'heuristic' ? 'network' : 'heuristic');
  }

  const sample = new TrackerSample();
  const timer = new UpdateTimer(600);
  let replayTime = 0;
  let last = performance.now();
  renderer.setAnimationLoop((now: number, frame?: XRFrame) => {
    const realDt = Math.min(0.1, Math.max(0, (now - last) / 1000));
    last = now;
    hook.beforeFrame?.(hook.frames);
    const space = renderer.xr.getReferenceSpace();
    if (frame && space) {
      hook.mode = 'xr';
      sampleXRFrame(frame, space, fixedDt ? xrFrames++ * fixedDt : now / 1000, sample, emulated);
    } else if (player) {
      hook.mode = 'replay';
      player.sampleAt(replayTime, sample);
      replayTime += fixedDt || realDt;
      hook.replayDone = replayTime > player.duration;
    } else {
      // Desktop, no XR: a user standing still at the origin, no controllers (the arms hang).
      hook.mode = 'idle';
      if (hook.frames === 0) scriptedSample(0, sample), (sample.tracked[LEFT] = sample.tracked[RIGHT] = 0);
      sample.time = hook.frames / 60;
      sample.bodyTracked.fill(0); // no stale body after a session
    }
    hook.inXR = renderer.xr.isPresenting;
    $('try-hint').hidden = hook.mode !== 'idle' || emulated;
    recorder.add(sample);
    drive.update(sample, fixedDt || undefined);
    hook.room?.update(fixedDt || realDt);
    timer.add(drive.lastUpdateMs);
    const tr = drive.trackers;
    markers.update(tr);
    const root = character.root;
    if (!hook.inXR) spectator.follow(root.x, root.z, fixedDt || realDt);
    stage.follow(root.x, root.z);
    stage.render();
    if (pip) {
      pip.visible = hook.inXR;
      if (hook.inXR) pip.render(stage.scene, root.x, root.z, root.yaw);
    }
    hook.frames++;
    [hook.target[0], hook.target[1]] = drive.rootTarget; // the root's target: what α clamps to
    [hook.hmd[0], hook.hmd[1], hook.hmd[2]] = tr.head.position;
    [hook.root[0], hook.root[1], hook.root[2]] = [root.x, root.y, root.z];
    [hook.rootYaw, hook.bodyYaw, hook.predictor] = [root.yaw, drive.yaw, drive.predictor.name];
    const net = yaw.network;
    if (net) [hook.predictorRuns, hook.predictorSkipped, hook.yawModel] = [net.runs, net.skipped, net.source];
    if (net) hook.predictorFailures = net.failures + (net.recurrent?.failures ?? 0);
    hook.hipsHeight = hips ? hips.matrixWorld.elements[13] : NaN;
    const [scale, toes] = [character.object3d.scale.x, character.avatar?.toeHeights ?? [NaN, NaN]];
    [hook.toeHeights[0], hook.toeHeights[1], hook.hipsDrop] = [toes[0] * scale, toes[1] * scale, drive.hipsDrop];
    if (drive.upperBody) [hook.handErrors[0], hook.handErrors[1]] = drive.upperBody.handError;
    for (let k = 0; k < 3; k++) hook.trackerStatus[k] = tr.status[k]; // head, LEFT, RIGHT
    if (drive.upperBody) for (let k = 0; k < 6; k++) hook.hands[k] = drive.upperBody.handPositions[k];
    drive.shownHips(hook.shownHips);
    yaw.showBody((hook.body = drive.bodyTracked));
    const devices = deviceSetName(tr.status, sample.hand);
    if (devices !== hook.deviceSet) $('devices').textContent = hook.deviceSet = devices;
    hook.updateMs.last = drive.lastUpdateMs;
    if (hook.frames % 30 === 0) {
      [hook.updateMs.median, hook.updateMs.p95] = [timer.median(), timer.quantile(0.95)];
      const height = tr.head.position[1] / hook.eyeHeight;
      const ratio = Number.isFinite(hook.eyeHeight) ? ` · height ${height.toFixed(2)}` : '';
      const bench = hook.bench ? ` · bench median ${hook.bench.median.toFixed(3)} ms` : '';
      const [update, runs] = [hook.updateMs.median.toFixed(2), net ? ` · model runs ${net.runs}` : ''];
      $('hud').textContent = `${hook.mode} · frame ${hook.frames} · VR update ${update} ms${runs}${ratio}${bench}`;
    }
    if (!hook.ready) {
      performance.mark('mm:first-frame');
      void import('../../rooms/index.ts').then(({ RoomPanel }) => { // its ~85 kB after the first frame
        const options = { character, scene: stage.scene, parent: $('toolbar'), mode: 'vr' as const, renderer };
        hook.room = new RoomPanel({ ...options, trackers: drive.trackers, onNote: showError, trace: fixedDt > 0 });
      });
      // Then the whole, the network (the heuristic drives till then), the cache: one at a time.
      void character.whole().catch(() => undefined).then(() => yaw.load()).then(() => registerOfflineCache());
    }
    hook.ready = true;
  });
}

main().catch((e: unknown) => fail(errorMessage(e)));
