/**
 * `mm-avatar/vr`: the WebXR body — tracked devices drive the character (docs/vr.md). Its own
 * entry so a desktop app never bundles it: onnxruntime-web and the orientation models come with
 * this entry only (onnxruntime-web loads on demand, when the network predictor is asked for).
 *
 * ```ts
 * import { Character } from 'mm-avatar';
 * import { TrackedDrive, loadNetworkPredictor } from 'mm-avatar/vr';
 * ```
 *
 * @packageDocumentation
 * @module mm-avatar/vr
 */
export { DEFAULT_VR_DATABASE, DEFAULT_ORIENTATION_MODEL, DEFAULT_ORIENTATION_MODEL_RECURRENT, orientationModelUrl, vrDatabaseUrl } from './assets.ts';
export { DEFAULT_ALPHA, HIPS_GAIN, HIPS_OFFSET_HALFLIFE, HMD_TO_HEAD_CENTRE, MAX_HIPS_OFFSET, TrackedDrive, VR_SETTINGS } from './tracked-drive.ts';
export { HEAD, LEFT, NUM_TRACKERS, RIGHT, TrackerSample, gripFromHand, sampleXRFrame } from './tracker-sample.ts';
export { deviceKind, deviceSetName } from './device-set.ts';
export { TrackerState, TrackerView } from './trackers.ts';
export type { TrackerOptions } from './trackers.ts';
export type { BodyYawPredictor, TrackerPose } from './body-yaw.ts';
export { HeadingYawPredictor } from './fallback-yaw.ts';
export type { HeadingYawOptions } from './fallback-yaw.ts';
export { NetworkYawPredictor, loadNetworkPredictor } from './network-yaw.ts';
export type { OrientationModel } from '../orientation/orientation-model.ts';
export type { OrientationFeatures } from '../orientation/features.ts';
export { RecordingPlayer, TrackerRecorder, decodeRecording, encodeRecordingJson } from './recording.ts';
export type { Recording, RecordingMeta, RecordingTruth } from './recording.ts';
export { SCRIPT_DURATION, scriptedSample } from './scripted-motion.ts';
export { loadRecording } from './load-recording.ts';
export { EnterVrButton } from './enter-vr-button.ts';
export { SpectatorView } from './spectator-view.ts';
export { FIRST_PERSON_LAYER, FirstPerson, THIRD_PERSON_LAYER, setHeadsetView } from './first-person.ts';
export { UpperBody } from './upper-body.ts';
export type { UpperBodyOptions, UpperBodyRig } from './upper-body.ts';

// The VR replay benchmark (the VR page's `bench=1`, `npm run bench -- --vr`).
export { ELBOW_LIMIT, HIPS_MIN_RATIO, UPRIGHT_BAND, benchReplay, stats } from './replay-bench.ts';
export type { PoseCheck, ReplayBenchResult, Stats } from './replay-bench.ts';
