/**
 * The motion-matching avatar engine for the web: the one public entry.
 *
 * ```ts
 * import { Character, defineMMAvatar } from 'mm-avatar';
 * const character = await Character.create({ database: 'databases/locomotion.mmdb', avatar: 'avatars/ubc_male.glb' });
 * scene.add(character.object3d);
 * character.walkTo(3, 2);
 * renderer.setAnimationLoop(() => { character.update(1 / 60); renderer.render(scene, camera); });
 * ```
 *
 * Or in any page: `<script type="module" src="mm-avatar.js"></script><mm-avatar></mm-avatar>`.
 *
 * @packageDocumentation
 */

// Characters: a database and an avatar → a three.js object; the per-frame recipe.
export { Character, RUN_SPEED, WALK_SPEED } from './character/character.ts';
export type { CharacterDrive, CharacterOptions, CharacterStepper, CreateOptions, MoveOptions, PathOptions, Root, TagQuery } from './character/character.ts';
export { Avatar } from './avatar/avatar.ts';
export type { AvatarOptions } from './avatar/avatar.ts';

// The embeddable element.
export { MMAvatarElement, defineMMAvatar } from './element/mm-avatar.ts';
export type { ErrorDetail, ProgressDetail } from './element/mm-avatar.ts';

// Databases, loading, the WASM module.
export { Database, listDatabases, loadDatabase } from './core/database.ts';
export type { ClipInfo, DatabaseEntry, FeatureGroupInfo, TagInfo } from './core/database.ts';
export { DatabaseBuilder } from './core/builder.ts';
export { initWasm, initWasmSync, liveObjects } from './core/wasm.ts';
export type { LiveObjects, WasmExports } from './core/wasm.ts';
export { DEFAULT_AVATAR, DEFAULT_DATABASE, DEFAULT_VR_DATABASE, DEFAULT_ORIENTATION_MODEL, DEFAULT_ORIENTATION_MODEL_FEWER_DEVICES, assetBytes, assetUrl, hasAssetVersions, setAssetBase } from './assets.ts';
export { errorMessage, fetchBytes } from './fetch.ts';
export { ASSET_CACHE, isVersioned } from './cache.ts';
export { registerOfflineCache } from './offline.ts';
export type { FetchOptions, FetchProgress } from './fetch.ts';

// The runtime underneath (advanced: crowds, benchmarks, tools).
export { CharacterRuntime, createMoveInput, createTrackedInput } from './core/character.ts';
export type { MoveInput, RuntimeSettings, TrackedInput } from './core/character.ts';
export { Crowd } from './core/crowd.ts';
export { SEARCH_METHODS, SearchIndex } from './core/search.ts';
export { ROLE_NAMES, findRoles } from './core/roles.ts';
export type { RoleName, RoleOverrides } from './core/roles.ts';
export { RUNTIME_SETTINGS } from './character/settings.ts';
export type { SettingInfo } from './character/settings.ts';

// Devices.
export { MoveControls } from './input/move-controls.ts';
export { KeyboardInput } from './input/keyboard.ts';
export { readGamepad } from './input/gamepad.ts';
export type { GamepadLike } from './input/gamepad.ts';
export { CameraBasis } from './input/input.ts';

// Scene helpers.
export { Stage } from './views/stage.ts';
export { FloorGrid } from './views/floor-grid.ts';
export { FollowCamera } from './views/follow-camera.ts';
export { SkeletonView } from './views/skeleton-view.ts';
export { DebugViews, TrajectoryView } from './views/debug-views.ts';
export { PathEditor } from './views/path-editor.ts';
export { RootMarker } from './views/root-marker.ts';
export { Playback } from './views/playback.ts';
export { UpdateTimer } from './views/update-timer.ts';

// VR: tracked devices drive the character.
export { DEFAULT_ALPHA, HMD_TO_HEAD_CENTRE, TrackedDrive, VR_SETTINGS } from './vr/tracked-drive.ts';
export { HEAD, LEFT, NUM_TRACKERS, RIGHT, TrackerSample, gripFromHand, sampleXRFrame } from './vr/tracker-sample.ts';
export { deviceKind, deviceSetName } from './vr/device-set.ts';
export { TrackerState, TrackerView } from './vr/trackers.ts';
export type { TrackerOptions } from './vr/trackers.ts';
export type { BodyYawPredictor, TrackerPose } from './vr/body-yaw.ts';
export { HeadingYawPredictor } from './vr/fallback-yaw.ts';
export type { HeadingYawOptions } from './vr/fallback-yaw.ts';
export { NetworkYawPredictor, loadNetworkPredictor } from './vr/network-yaw.ts';
export type { OrientationModel } from './orientation/orientation-model.ts';
export type { OrientationFeatures } from './orientation/features.ts';
export { RecordingPlayer, TrackerRecorder, decodeRecording, encodeRecordingJson } from './vr/recording.ts';
export type { Recording, RecordingMeta, RecordingTruth } from './vr/recording.ts';
export { SCRIPT_DURATION, scriptedSample } from './vr/scripted-motion.ts';
export { loadRecording } from './vr/load-recording.ts';
export { EnterVrButton } from './vr/enter-vr-button.ts';
export { SpectatorView } from './vr/spectator-view.ts';
export { FIRST_PERSON_LAYER, FirstPerson, THIRD_PERSON_LAYER, setHeadsetView } from './vr/first-person.ts';
export { UpperBody } from './vr/upper-body.ts';
export type { UpperBodyOptions, UpperBodyRig } from './vr/upper-body.ts';

// Shared rooms: people see each other's avatars over the network (docs/rooms.md).
export { RoomCharacter, RoomClient, RoomPanel, RoomSession, NameLabel, qrCodeImage, roomIdFromUrl, roomOf, roomUrl } from './rooms/index.ts';
export { DriftCorrector, InputStream, JitterBuffer, LocalAvatar, RemoteAvatar, measureBandwidth } from './rooms/index.ts';
export { CloseCode, PROTOCOL_VERSION, ProtocolError, TICKS_PER_SECOND, createRoomId, decodeClientMessage, decodeServerMessage, isRoomId } from './rooms/index.ts';
export type { RoomMember, RoomMemberView, RoomNote, RoomPanelOptions, RoomSessionOptions, RoomClientEvents, RoomClientOptions, RoomStatus, DrivenCharacter, PathInput } from './rooms/index.ts';
export type { AvatarChoice, DeviceSet, JoinInfo, LeaveReasonName, MemberInfo, MoveStep, PathMessage, RoomTrackerPose, StateMessage, StreamMessage, TrackedStep } from './rooms/index.ts';
export { LeaveReason, TickClock } from './rooms/index.ts';
export type { BandwidthOptions, BandwidthResult, DriftCorrectorOptions, JitterBufferOptions, JitterStats, PushResult, Released, RemoteAvatarOptions, RemoteAvatarStats, WebSocketLike } from './rooms/index.ts';
export type { ClientMessage, DeviceMode, DriveMode, MoveMessage, ServerMessage, StreamReport, TrackedMessage } from './rooms/index.ts';

// Page helpers.
export { installDropTarget, sortDroppedFiles } from './ui/drop.ts';
export type { DroppedFiles } from './ui/drop.ts';
export { showError } from './ui/error-box.ts';
export { LoadingStatus, describeProgress, shortUrl } from './ui/loading-status.ts';
export { loadPageCharacter } from './ui/page-loader.ts';
export { saveTextFile } from './ui/save-file.ts';
export type { PageCharacter, PageCharacterOptions } from './ui/page-loader.ts';

// Angles (project convention: yaw 0 faces +Z, positive turns +Z toward +X).
export { bodyYaw, headingYaw, wrapAngle, yawOf } from './yaw.ts';

// Benchmarks (the bench page, `npm run bench`).
export { benchSearch } from './bench/search-bench.ts';
export type { MethodTiming, SearchBenchOptions, SearchBenchResult } from './bench/search-bench.ts';
export { benchRuntime } from './bench/runtime-bench.ts';
export type { RuntimeBenchResult } from './bench/runtime-bench.ts';
export { realisticQueries, seededRandom } from './bench/queries.ts';
export type { BenchQuery } from './bench/queries.ts';
export { ELBOW_LIMIT, HIPS_MIN_RATIO, UPRIGHT_BAND, benchReplay, stats } from './vr/replay-bench.ts';
export type { PoseCheck, ReplayBenchResult, Stats } from './vr/replay-bench.ts';
