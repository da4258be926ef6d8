/**
 * The orientation network as a BodyYawPredictor (docs/method.md §9), on the browser runner of
 * web/src/orientation (`OrientationModel`, onnxruntime-web's WASM backend; contract in
 * docs/orientation-model.md).
 *
 * The runner's `update` is asynchronous and the frame must never wait for it: each frame starts
 * one run with this frame's poses and returns the last *finished* prediction — one frame old in
 * a live session (the run finishes long before the next frame) and in replays, which `settle()`
 * between frames. A frame that arrives while a run is still pending is not fed (the next run sees
 * the summed dt, so velocities stay right) and counted in `skipped`. The feedback of the previous
 * prediction is the runner's own.
 *
 * Inputs are the tracker state's output poses (a missing or frozen controller is the hanging
 * hand trackers.ts shows; the network was trained with controllers that stop moving, which a
 * hand hanging at the side resembles more than a pose left floating in the room).
 *
 * With `recurrent` (the recurrent model, docs/orientation-model.md), both run every frame and the yaw
 * is the mean of the two models' on the circle, whatever devices are tracked: they err
 * differently, and on held-out people (both models trained without them) the mean beats either
 * alone — two controllers 18.7° against the feed-back network's 20.6° and the recurrent one's
 * 22.1°, one controller 20.7° against 21.8° and 23.0°, headset only 26.3° against 29.1° and
 * 26.8° (README, "Per device set"). (Before the network had its context inputs, the recurrent
 * model alone was the better one with fewer devices, and the page used it there.)
 * For its first `RECURRENT_WARMUP` s after a reset the recurrent model is not used (its loss
 * skipped its first 30 frames in training): blending it in at 0.5–1 s changed a search early in
 * the short held-in replays and moved the walk's root up to 20 cm (p95 5 → 20 cm); from 1.25 s
 * on no held-in replay changed (`npm run replay`), so 1.5 s.
 * The recurrent model's weight (0, then ½) moves to its target at `BLEND_RATE` a second, so the
 * end of the warm-up blends over a quarter of a second: a sudden 20° step of the yaw made the
 * drive search afresh and moved the root up to 18 cm (held-in walk replay).
 */
import type { OrientationModel } from '../orientation/orientation-model.ts'; // type only: onnxruntime loads on demand
import type { BodyYawPredictor, TrackerPose } from './body-yaw.ts';
import { type FetchOptions, fetchBytes } from '../fetch.ts';
import { headingYaw } from '../yaw.ts';

/** Seconds of input the recurrent model needs after a reset before its yaw is used. */
export const RECURRENT_WARMUP = 1.5;
/** How fast (per second) the recurrent model's weight in the yaw moves to its target. */
export const BLEND_RATE = 2;

export class NetworkYawPredictor implements BodyYawPredictor {
  readonly name = 'network';
  /** Runs finished since construction (never reset: tests compare it with frames). */
  runs = 0;
  /** Frames not fed because a run was still pending. */
  skipped = 0;
  /** Runs that failed (non-finite poses…); the last message. */
  failures = 0;
  lastError: string | null = null;
  /** Milliseconds from starting the last finished run to its result (features + onnxruntime). */
  lastRunMs = 0;
  private yaw = 0;
  private started = false;
  private pending: Promise<void> | null = null;
  private pendingDt = 0;
  private runStart = 0;
  private generation = 0;
  private modelNeedsReset = true;
  private runGeneration = 0;
  private readonly positions = new Float64Array(9);
  private readonly quaternions = new Float64Array(12);
  private readonly onResult = (yaw: number) => {
    this.pending = null;
    if (this.runGeneration !== this.generation) return; // a reset happened meanwhile
    this.yaw = yaw;
    // The model's hips are in its run's HMD-yaw frame: turned into the room's (rotate_y by that yaw).
    const m = this.model, a = m.hmdYaw, x = m.hips[0], z = m.hips[1];
    this.hips[0] = Math.cos(a) * x + Math.sin(a) * z;
    this.hips[1] = Math.cos(a) * z - Math.sin(a) * x;
    this.runs++;
    this.lastRunMs = performance.now() - this.runStart;
  };
  private readonly onError = (e: unknown) => {
    this.pending = null;
    this.failures++;
    this.lastError = e instanceof Error ? e.message : String(e);
  };

  /**
   * Where the last update's yaw came from: this model alone ('main': no `recurrent`, or it is warming
   * up), or the mean of both ('both').
   */
  source: 'main' | 'both' = 'main';
  /** Seconds of input since the last reset. */
  age = 0;
  /**
   * Where the hips are (`BodyYawPredictor.hips`): this model's last finished run, NaN from a
   * model without the hips output (the recurrent one) and after a reset until the first run.
   */
  readonly hips = new Float64Array([NaN, NaN]);
  /** The weight of `recurrent`'s yaw in the one returned (0, then ½). */
  weight = 0;

  /** `recurrent`: the recurrent model, whose yaw is averaged with this one's (optional). */
  constructor(
    readonly model: OrientationModel,
    readonly recurrent: NetworkYawPredictor | null = null,
  ) {}

  update(hmd: TrackerPose, left: TrackerPose, right: TrackerPose, dt: number): number {
    const elapsed = dt > 0 ? dt : 0;
    this.age += elapsed;
    const own = this.updateOwn(hmd, left, right, dt);
    if (!this.recurrent) return own;
    const other = this.recurrent.update(hmd, left, right, dt);
    // Both were reset together and stepped alike: this age is the recurrent model's too.
    this.source = this.age < RECURRENT_WARMUP ? 'main' : 'both';
    const target = this.source === 'main' ? 0 : 0.5;
    const step = BLEND_RATE * elapsed;
    this.weight += Math.max(-step, Math.min(step, target - this.weight));
    const w = this.weight;
    if (w === 0) return own;
    // The weighted mean on the circle (`predictors.py::page_yaw`; `own` if they cancel).
    const s = (1 - w) * Math.sin(own) + w * Math.sin(other);
    const c = (1 - w) * Math.cos(own) + w * Math.cos(other);
    return Math.hypot(s, c) > 1e-6 ? Math.atan2(s, c) : own;
  }

  private updateOwn(hmd: TrackerPose, left: TrackerPose, right: TrackerPose, dt: number): number {
    const q = hmd.rotation;
    if (!this.started) {
      // Until the first run finishes the body faces where the head looks (the model's own
      // reset state).
      this.yaw = headingYaw(q[0], q[1], q[2], q[3]);
    }
    this.pendingDt += dt > 0 ? dt : 0;
    if (this.pending) {
      this.skipped++;
      return this.yaw;
    }
    if (this.modelNeedsReset) {
      this.modelNeedsReset = false;
      this.model.reset();
    }
    // The runner wants a positive dt after its first frame; a zero-length frame is not fed.
    if (this.started && !(this.pendingDt > 0)) return this.yaw;
    const p = this.positions, r = this.quaternions;
    for (let k = 0; k < 3; k++) {
      const t = k === 0 ? hmd : k === 1 ? left : right;
      p[3 * k] = t.position[0];
      p[3 * k + 1] = t.position[1];
      p[3 * k + 2] = t.position[2];
      r[4 * k] = t.rotation[0];
      r[4 * k + 1] = t.rotation[1];
      r[4 * k + 2] = t.rotation[2];
      r[4 * k + 3] = t.rotation[3];
    }
    const step = this.pendingDt;
    this.pendingDt = 0;
    this.started = true;
    this.runStart = performance.now();
    this.runGeneration = this.generation;
    this.pending = this.model.update(p, r, step).then(this.onResult, this.onError);
    return this.yaw;
  }

  /** Resolves when the pending run (if any) has finished: replays call it between frames. */
  settle(): Promise<void> {
    const own = this.pending ?? Promise.resolve();
    return this.recurrent ? Promise.all([own, this.recurrent.settle()]).then(() => undefined) : own;
  }

  reset(): void {
    this.age = 0;
    this.weight = 0;
    this.hips.fill(NaN);
    this.recurrent?.reset();
    this.generation++;
    this.started = false;
    this.pendingDt = 0;
    // A pending run's result is dropped by its generation; the runner resets before its next run.
    this.modelNeedsReset = true;
  }
}

/**
 * Loads the model at `url` and onnxruntime-web, in parallel and on demand (pages that never use
 * the network never fetch either; the VR page asks after its first frame). The model's bytes go
 * through the library's fetch (progress, a URL in every message, the cache for a versioned URL).
 * Rejects with a message the page shows when it cannot.
 */
export async function loadNetworkPredictor(url: string | URL, options: FetchOptions & { recurrentModel?: string | URL | null } = {}): Promise<NetworkYawPredictor> {
  const { recurrentModel, ...fetchOptions } = options;
  const fetchModel = (u: string | URL) => fetchBytes(u, { stage: 'model', ...fetchOptions });
  // The recurrent model is optional: without it (not served, broken) the network's yaw is used alone.
  const recurrentFetch = recurrentModel ? fetchModel(recurrentModel).catch((e: unknown) => (console.warn(`recurrent orientation model unavailable (${String(recurrentModel)}): ${String(e)}`), null)) : null;
  const [{ OrientationModel }, bytes, recurrentBytes] = await Promise.all([import('../orientation/orientation-model.ts'), fetchModel(url), recurrentFetch]);
  let recurrentPredictor: NetworkYawPredictor | null = null;
  if (recurrentBytes) {
    try {
      recurrentPredictor = new NetworkYawPredictor(await OrientationModel.create(recurrentBytes));
    } catch (e) {
      console.warn(`recurrent orientation model unusable (${String(recurrentModel)}): ${String(e)}`);
    }
  }
  return new NetworkYawPredictor(await OrientationModel.create(bytes), recurrentPredictor);
}
