/**
 * The one drive value: everything that moves a character for its next step, in database units —
 * the mode, the move input, the tracked (VR) sample, the crouch, α and the path. The mirror of
 * the runtime's `DriveInput` (wasm-core/src/runtime/character/drive.rs), field for field: a
 * page's `Character` builds one from its devices, a shared room sends every step's value and each
 * copy replays it, and `CharacterRuntime.setDrive` hands it to the runtime in one call.
 * `DRIVE_FIELDS` is the flat order both sides read; `drive.test.ts` checks it against the runtime's.
 */

/**
 * What a player asks the character for this frame, on the ground plane (the runtime's `Input`).
 * Devices write into one preallocated `MoveInput` per frame.
 */
export interface MoveInput {
  /** Desired move direction (x, z); length 0–1 is the stick magnitude. */
  moveX: number;
  moveZ: number;
  /** Desired facing (x, z), unit length; used while strafing. */
  faceX: number;
  faceZ: number;
  run: boolean;
  /** Keep facing (faceX, faceZ) while moving in any direction (side-steps, backwards). */
  strafe: boolean;
}

export function createMoveInput(): MoveInput {
  return { moveX: 0, moveZ: 0, faceX: 0, faceZ: 1, run: false, strafe: false };
}

/** Copies the move input of `from` into `to` (and nothing else: either may be a whole `Drive`). */
export function copyMoveInput(from: Readonly<MoveInput>, to: MoveInput): void {
  to.moveX = from.moveX;
  to.moveZ = from.moveZ;
  to.faceX = from.faceX;
  to.faceZ = from.faceZ;
  to.run = from.run;
  to.strafe = from.strafe;
}

/**
 * What a tracked user (VR) asks of the character this frame, on the floor: the head centre's
 * floor position, its ground velocity, the body yaw (rad, 0 = +Z), how far the hips go down
 * (crouching) and how far the torso bends forward (rad, bending over). With `body` (WebXR body
 * tracking) the position, velocity and yaw are the tracked hips', which the shown hips follow.
 * Metres of the caller's frame where a page writes it (`Character.setTracked`, a room's wire),
 * database units in a `Drive`.
 */
export interface TrackedInput {
  headX: number;
  headZ: number;
  velocityX: number;
  velocityZ: number;
  yaw: number;
  body: boolean;
  hipsDrop: number;
  bend: number;
}

export function createTrackedInput(): TrackedInput {
  return { headX: 0, headZ: 0, velocityX: 0, velocityZ: 0, yaw: 0, body: false, hipsDrop: 0, bend: 0 };
}

/** `move`: the move input; `path`: along `path`; `tracked`: the tracked sample (VR). */
export type DriveMode = 'move' | 'path' | 'tracked';

/** A path on the floor: keypoints (x, z interleaved) and speeds per segment, database units. */
export interface DrivePath {
  readonly points: Float32Array;
  /** Per segment (count − 1, or count when looped). */
  readonly speeds: Float32Array;
  readonly looped: boolean;
}

/**
 * The drive value (database units). The crouch (`hipsDrop`, `bend`) applies in every mode;
 * `clampDistance` (α) when it is a number ≥ 0 (NaN: unchanged). A path is handed to the runtime
 * when it is not the object the runtime follows (a new object starts it from its beginning).
 */
export interface Drive extends MoveInput, TrackedInput {
  mode: DriveMode;
  clampDistance: number;
  path: DrivePath | null;
}

export function createDrive(): Drive {
  return { mode: 'move', ...createMoveInput(), ...createTrackedInput(), clampDistance: NaN, path: null };
}

/** The runtime's flat order (`DriveInput::FIELDS`). */
export const DRIVE_FIELDS = [
  'mode',
  'move_x',
  'move_z',
  'face_x',
  'face_z',
  'run',
  'strafe',
  'head_x',
  'head_z',
  'velocity_x',
  'velocity_z',
  'yaw',
  'body',
  'hips_drop',
  'bend',
  'clamp_distance',
] as const;

const MODES: readonly DriveMode[] = ['move', 'path', 'tracked'];

/** Writes `d` flat into `out` (`DRIVE_FIELDS.length` numbers) for `RawCharacter.apply_drive` (at its `drive_ptr`). */
export function writeDrive(d: Readonly<Drive>, out: Float32Array): Float32Array {
  out[0] = MODES.indexOf(d.mode);
  out[1] = d.moveX;
  out[2] = d.moveZ;
  out[3] = d.faceX;
  out[4] = d.faceZ;
  out[5] = d.run ? 1 : 0;
  out[6] = d.strafe ? 1 : 0;
  out[7] = d.headX;
  out[8] = d.headZ;
  out[9] = d.velocityX;
  out[10] = d.velocityZ;
  out[11] = d.yaw;
  out[12] = d.body ? 1 : 0;
  out[13] = d.hipsDrop;
  out[14] = d.bend;
  out[15] = d.clampDistance;
  return out;
}
