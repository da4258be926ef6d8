/**
 * A room's steps as drive values: the one conversion between what the wire carries (move steps
 * in database axes; tracked steps in room metres, quantized) and the engine's drive value
 * (`Drive`, database units). The sender's own copy and every receiver's run these same lines on
 * the same numbers, so each copy gives its runtime the same floats.
 */
import { copyMoveInput, type Drive, type DrivePath, type MoveInput, type TrackedInput } from '../core/drive.ts';

/** A move step (database axes) into `out`. A move step carries no crouch: the hips stand. */
export function driveFromMove(step: Readonly<MoveInput>, out: Drive): Drive {
  out.mode = 'move';
  copyMoveInput(step, out);
  out.hipsDrop = out.bend = 0;
  return out;
}

/** Following `path` (database units) into `out`; a new path object starts from its beginning. */
export function driveFromPath(path: DrivePath, out: Drive): Drive {
  out.mode = 'path';
  out.path = path;
  out.hipsDrop = out.bend = 0;
  return out;
}

/**
 * A tracked step (room metres) into `out`: `scale` room metres per database unit and α (m), as
 * the wire carries them (float32, whole cm).
 */
export function driveFromTracked(step: Readonly<TrackedInput>, scale: number, alpha: number, out: Drive): Drive {
  out.mode = 'tracked';
  out.headX = step.headX / scale;
  out.headZ = step.headZ / scale;
  out.velocityX = step.velocityX / scale;
  out.velocityZ = step.velocityZ / scale;
  out.yaw = step.yaw;
  out.body = step.body;
  out.hipsDrop = step.hipsDrop / scale;
  out.bend = step.bend;
  out.clampDistance = alpha / scale;
  return out;
}

/** The tracked part of a drive value (database units) in room metres (`scale` m per unit), into `out`: what a sender records. */
export function trackedFromDrive(drive: Readonly<Drive>, scale: number, out: TrackedInput): TrackedInput {
  out.headX = drive.headX * scale;
  out.headZ = drive.headZ * scale;
  out.velocityX = drive.velocityX * scale;
  out.velocityZ = drive.velocityZ * scale;
  out.yaw = drive.yaw;
  out.body = drive.body;
  out.hipsDrop = drive.hipsDrop * scale;
  out.bend = drive.bend;
  return out;
}
