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
 * @module mm-avatar
 */

// Characters: a database and an avatar → a three.js object; the per-frame recipe.
export { Character, RUN_SPEED, WALK_SPEED } from './character/character.ts';
export type { CharacterOptions, CharacterStepper, CreateOptions, MoveOptions, PathOptions, Root, TagQuery } from './character/character.ts';
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
export { DEFAULT_AVATAR, DEFAULT_DATABASE, assetBytes, assetUrl, hasAssetVersions, setAssetBase } from './assets.ts';
export { ASSET_CACHE, isVersioned } from './cache.ts';
export { registerOfflineCache } from './offline.ts';
export type { FetchOptions, FetchProgress } from './fetch.ts';

// The runtime underneath (advanced: crowds, tools).
export { CharacterRuntime } from './core/character.ts';
export type { RuntimeSettings } from './core/character.ts';
export { createDrive, createMoveInput, createTrackedInput } from './core/drive.ts';
export type { Drive, DriveMode, DrivePath, MoveInput, TrackedInput } from './core/drive.ts';
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

// The views the element and Character hand out (`el.stage`, `el.orbit`, `character.debugViews`).
export { Stage } from './views/stage.ts';
export { FloorGrid } from './views/floor-grid.ts';
export { FollowCamera } from './views/follow-camera.ts';
export { DebugViews, TrajectoryView } from './views/debug-views.ts';

// Angles (project convention: yaw 0 faces +Z, positive turns +Z toward +X).
export { bodyYaw, headingYaw, wrapAngle, yawOf } from './yaw.ts';

