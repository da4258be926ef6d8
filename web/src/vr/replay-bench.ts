/**
 * The VR replay benchmark (docs/vr.md): a recording replayed through the whole VR recipe
 * (`TrackedDrive`) as fast as possible — the network's run awaited between frames, as a live
 * frame would have it finished — measuring the update time, the user↔avatar root distance
 * (recordings with ground truth), the avatar↔head gap α clamps, body-yaw errors, and planted-
 * toe skating (the runtime's one measure, `Character.runtime.skating`).
 */
import { headingYaw, wrapAngle } from '../yaw.ts';
import { UpdateTimer } from '../views/update-timer.ts';
import type { BodyYawPredictor } from './body-yaw.ts';
import type { NetworkYawPredictor } from './network-yaw.ts';
import type { RecordingPlayer } from './recording.ts';
import { TrackerSample } from './tracker-sample.ts';
import { HMD_TO_HEAD_CENTRE, type TrackedDrive } from './tracked-drive.ts';

/** Error statistics, degrees or metres. */
export interface Stats {
  mean: number;
  median: number;
  p95: number;
  max: number;
}

export interface ReplayBenchResult {
  recording: string;
  frames: number;
  /** The whole synchronous VR update (trackers → upper body), ms. */
  median: number;
  p95: number;
  mean: number;
  /** One network run (features + onnxruntime), ms. */
  modelMedian: number;
  modelP95: number;
  alpha: number;
  /** Predictor of the timed pass and its run count over the pass. */
  predictor: string;
  modelRuns: number;
  /** With ground truth: avatar root ↔ user root on the floor, m. */
  rootDistance: Stats | null;
  /** With ground truth: the avatar's shown hips on the floor ↔ the user's root (their hips' floor point), m. */
  hipsDistance: Stats | null;
  /** Avatar root ↔ its target on the floor (the predicted hips, else the head centre: what α clamps), m. */
  targetGap: Stats;
  /** Body-yaw error vs ground truth, degrees: the network, the heuristic, raw HMD forward. */
  yawError: { network: Stats | null; heuristic: Stats | null; hmdForward: Stats | null };
  /** Root distance with the heuristic driving the avatar, m. */
  rootDistanceHeuristic: Stats | null;
  /** Planted-toe sliding (room units), cm/s. */
  skatingCmPerS: number;
  /** Mean head and avatar root ground speeds, m/s. */
  headSpeed: number;
  rootSpeed: number;
  /** Room metres per database metre. */
  scale: number;
  /** The pose checks (docs/vr.md), over the timed pass; null without an avatar. */
  pose: PoseCheck | null;
}

/**
 * The VR pose checks: upright frames are those whose headset is within `UPRIGHT_BAND` of the
 * reference (calibrated) eye height; on them the crouch should keep the hips ≥ 95 % of their
 * standing height. Bent-over frames are those whose head centre is more than `BENT_DROP` below
 * the reference with the headset looking down more than `BENT_PITCH`: the user bends at the
 * waist (in the mocap, with the headset looking down past 45°, the hips take 9–18 % of the
 * head's drop), so the crouch should give the hips at most half of it — not kneel. An elbow more than
 * `ELBOW_LIMIT` behind the torso's frontal plane (through its shoulder) while its controller is
 * not is an arm bent the wrong way.
 */
export interface PoseCheck {
  uprightFrames: number;
  /**
   * Upright frames whose hips the crouch lowered by more than 5 % of their standing (rest-pose)
   * height, and the largest such drop (m). The animation's own hips are not counted: a walk's
   * hips are 93–96 % of the straight-legged rest pose's by themselves (gait), which the mocap
   * walker did too.
   */
  hipsLowFrames: number;
  hipsDropMax: number;
  /** Hips height over the rest pose's, lowest and mean, on upright frames (information). */
  hipsMinRatio: number;
  hipsMeanRatio: number;
  /** Bent-over frames, those whose hips the crouch lowered by more than half the head's drop, and the largest hips drop there (m). */
  bentFrames: number;
  bentKneelFrames: number;
  bentDropMax: number;
  /** Arm-frames (two per frame) with an elbow behind the torso while its controller is not, and the worst such elbow (m). */
  elbowBehindFrames: number;
  elbowBehindMax: number;
}

export const UPRIGHT_BAND = 0.05;
export const HIPS_MIN_RATIO = 0.95;
export const ELBOW_LIMIT = 0.05;
export const BENT_DROP = 0.1;
export const BENT_PITCH = (-45 * Math.PI) / 180;
export const BENT_HIPS_SHARE = 0.5;

/** Mean, median, p95 and max of the first `count` values; null when empty. */
export function stats(values: Float64Array, count: number): Stats | null {
  if (count === 0) return null;
  const s = values.slice(0, count).sort();
  let sum = 0;
  for (let i = 0; i < count; i++) sum += s[i];
  const q = (p: number) => s[Math.min(count - 1, Math.round(p * (count - 1)))];
  return { mean: sum / count, median: q(0.5), p95: q(0.95), max: s[count - 1] };
}

/**
 * Replays every frame of `player`'s recording: a warm-up pass, a timed pass with the network
 * (or the heuristic when there is none) and, with ground truth, a pass with the heuristic.
 */
export async function benchReplay(drive: TrackedDrive, player: RecordingPlayer, network: NetworkYawPredictor | null, heuristic: BodyYawPredictor, name: string): Promise<ReplayBenchResult> {
  const rec = player.recording;
  const truth = rec.truth;
  const n = rec.frames;
  const character = drive.character;
  const sample = new TrackerSample();
  const timer = new UpdateTimer(n);
  const modelTimer = new UpdateTimer(n);
  const dist = new Float64Array(n), hipsDist = new Float64Array(n), shown = new Float64Array(3), gap = new Float64Array(n), yawErr = new Float64Array(n), hmdErr = new Float64Array(n);
  let headPath = 0, rootPath = 0;
  const last = new Float64Array(4);
  const hips = character.avatar?.bone('hips') ?? null;
  const body = drive.upperBody;
  const pose: PoseCheck | null = hips && body && drive.avatarHipsHeight > 0 ? { uprightFrames: 0, hipsLowFrames: 0, hipsMinRatio: Infinity, hipsMeanRatio: 0, hipsDropMax: 0, bentFrames: 0, bentKneelFrames: 0, bentDropMax: 0, elbowBehindFrames: 0, elbowBehindMax: 0 } : null;

  const pass = async (predictor: BodyYawPredictor, timed: boolean) => {
    drive.setPredictor(predictor);
    drive.reset();
    player.sampleAt(0, sample);
    const q = sample.rotation;
    const heading = headingYaw(q[0], q[1], q[2], q[3]);
    character.teleport(sample.position[0] - HMD_TO_HEAD_CENTRE * Math.sin(heading), sample.position[2] - HMD_TO_HEAD_CENTRE * Math.cos(heading), truth ? truth.bodyYaw[0] : heading);
    timer.count = modelTimer.count = 0;
    headPath = rootPath = 0;
    const runs0 = network?.runs ?? 0;
    let count = 0;
    for (let f = 0; f < n; f++) {
      player.sampleAt(rec.time[f] - rec.time[0], sample);
      drive.update(sample);
      if (predictor === network) {
        await network.settle();
        if (timed) modelTimer.add(network.lastRunMs);
      }
      const root = character.root;
      if (truth) yawErr[count] = (Math.abs(wrapAngle(drive.yaw - truth.bodyYaw[f])) * 180) / Math.PI;
      if (timed && pose) {
        if (Math.abs(drive.trackers.head.position[1] - drive.referenceEyeHeight) <= UPRIGHT_BAND) {
          const ratio = hips!.matrixWorld.elements[13] / (drive.avatarHipsHeight * drive.scale);
          pose.uprightFrames++;
          if (drive.hipsDrop > (1 - HIPS_MIN_RATIO) * drive.avatarHipsHeight * drive.scale) pose.hipsLowFrames++;
          pose.hipsMinRatio = Math.min(pose.hipsMinRatio, ratio);
          pose.hipsMeanRatio += ratio;
          pose.hipsDropMax = Math.max(pose.hipsDropMax, drive.hipsDrop);
        }
        const headDrop = drive.referenceEyeHeight - drive.headCentreHeight;
        if (headDrop > BENT_DROP && drive.headsetPitch < BENT_PITCH) {
          pose.bentFrames++;
          if (drive.hipsDrop > BENT_HIPS_SHARE * headDrop) pose.bentKneelFrames++;
          pose.bentDropMax = Math.max(pose.bentDropMax, drive.hipsDrop);
        }
        for (let k = 0; k < 2; k++) {
          if (body!.elbowBehind[k] > ELBOW_LIMIT && !(body!.targetBehind[k] > ELBOW_LIMIT)) {
            pose.elbowBehindFrames++;
            pose.elbowBehindMax = Math.max(pose.elbowBehindMax, body!.elbowBehind[k]);
          }
        }
      }
      if (timed) {
        timer.add(drive.lastUpdateMs);
        gap[count] = Math.hypot(root.x - drive.rootTarget[0], root.z - drive.rootTarget[1]);
        if (truth) {
          const h = drive.trackers.head.rotation;
          hmdErr[count] = (Math.abs(wrapAngle(headingYaw(h[0], h[1], h[2], h[3]) - truth.bodyYaw[f])) * 180) / Math.PI;
        }
        if (f > 0) {
          headPath += Math.hypot(drive.headFloor[0] - last[0], drive.headFloor[1] - last[1]);
          rootPath += Math.hypot(root.x - last[2], root.z - last[3]);
        }
        [last[0], last[1], last[2], last[3]] = [drive.headFloor[0], drive.headFloor[1], root.x, root.z];
      }
      if (truth) dist[count] = Math.hypot(root.x - truth.root[2 * f], root.z - truth.root[2 * f + 1]);
      if (truth && timed) {
        drive.shownHips(shown);
        hipsDist[count] = Math.hypot(shown[0] - truth.root[2 * f], shown[1] - truth.root[2 * f + 1]);
      }
      count++;
    }
    return { count, runs: (network?.runs ?? 0) - runs0 };
  };

  const main = network ?? heuristic;
  await pass(main, false); // warm-up: JIT, onnxruntime
  const timed = await pass(main, true);
  const duration = rec.time[n - 1] - rec.time[0];
  const scale = character.metresPerDatabaseUnit;
  const result: ReplayBenchResult = {
    recording: name,
    frames: timer.count,
    median: timer.median(),
    p95: timer.quantile(0.95),
    mean: timer.mean(),
    modelMedian: network ? modelTimer.median() : NaN,
    modelP95: network ? modelTimer.quantile(0.95) : NaN,
    alpha: drive.clampDistance,
    predictor: main.name,
    modelRuns: timed.runs,
    rootDistance: truth ? stats(dist, timed.count) : null,
    hipsDistance: truth ? stats(hipsDist, timed.count) : null,
    targetGap: stats(gap, timed.count) ?? { mean: NaN, median: NaN, p95: NaN, max: NaN },
    yawError: { network: truth && network ? stats(yawErr, timed.count) : null, heuristic: null, hmdForward: truth ? stats(hmdErr, timed.count) : null },
    rootDistanceHeuristic: null,
    skatingCmPerS: duration > 0 ? (100 * character.runtime.skating * scale) / duration : NaN,
    headSpeed: headPath / duration,
    rootSpeed: rootPath / duration,
    scale,
    pose,
  };
  if (pose?.uprightFrames) pose.hipsMeanRatio /= pose.uprightFrames;
  if (truth) {
    const h = await pass(heuristic, false);
    result.yawError.heuristic = stats(yawErr, h.count);
    result.rootDistanceHeuristic = stats(dist, h.count);
  }
  drive.reset();
  return result;
}
