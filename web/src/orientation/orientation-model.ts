/**
 * The body-orientation network at run time (docs/method.md §9): raw headset and controller poses
 * in, the body's yaw out, the network's previous prediction fed back every frame.
 *
 * Runs `public/models/orientation.onnx` with onnxruntime-web's WASM backend. Mirrors
 * `training/orientation/predictors.py::run_network` step for step (the contract is
 * `docs/orientation-model.md`):
 *   1. inputs 0..35 and 42..53 from the poses and the real dt ({@link OrientationFeatures});
 *   2. previous slot = 6D of (previous body yaw − this frame's HMD yaw); after `reset()`, 0;
 *   3. run (a model from before the context takes the first 42); φ = atan2(−out[2], out[0]);
 *      a non-finite or degenerate output keeps the previous body yaw (the HMD yaw right after a
 *      reset);
 *   4. body yaw = HMD yaw + φ (radians, 0 = facing +Z, as the character's yaw).
 * A previous body yaw that is not finite counts as a reset (previous slot 0, fallback the HMD
 * yaw), so the loop can never keep a NaN.
 *
 * A model's second output `hips` [1, 2] (docs/orientation-model.md, "Output") says where the hips
 * are on the floor: (x, z) from the head centre, in the HMD-yaw frame, metres — {@link OrientationModel.hips},
 * NaN from a model without it or when it comes back not finite.
 *
 * A **recurrent** model file (two inputs, `features` [1, 36] and `state` [1, H]; two outputs,
 * the 6D and `state_out`: `training/orientation/gru.py`) is run the same way, except that
 * step 2 is its state instead of the previous slot: zeros after `reset()`, the last `state_out`
 * otherwise, and zeros again whenever it comes back not finite (`predictors.py::run_recurrent`).
 */
import * as ort from 'onnxruntime-web/wasm';
import { wrapAngle } from '../yaw.ts';
import { LEGACY_INPUTS, NUM_INPUTS, OrientationFeatures, PREV_OFFSET } from './features.ts';

/** Inputs before the previous slot: the three trackers' features (a recurrent model takes only these). */
const TRACKER_INPUTS = PREV_OFFSET;

/** The model the app serves (relative to the page). */
export const DEFAULT_MODEL_URL = 'models/orientation.onnx';

export interface OrientationModelOptions {
  /** WASM threads; 1 (the default) avoids needing cross-origin isolation and is fastest for this tiny model. */
  numThreads?: number;
}

export class OrientationModel {
  /** Inputs of the last update (exposed for debugging and tests). */
  readonly features = new OrientationFeatures();
  /** The network's last raw 6D output. */
  readonly output = new Float32Array(6);
  /**
   * Where the hips were at the last update: (x, z) on the floor from the head centre, metres, in
   * the HMD-yaw frame (+Z ahead, +X to the left); NaN without a `hips` output or when not finite.
   */
  readonly hips = new Float64Array([NaN, NaN]);
  private readonly feeds: Record<string, ort.Tensor>;
  private readonly outputName: string;
  private readonly hipsOutputName: string | null;
  private _bodyYaw = 0;
  private _relativeYaw = 0;
  private hasYaw = false;
  private busy = false;
  /** Recurrent models: the tracker inputs (0..35) and the state fed in, filled in place, and
   * the features' tracker part as a view made once (a per-frame `subarray` would allocate). */
  private readonly trackerInput: Float32Array | null;
  private readonly trackerSource: Float32Array | null;
  private readonly state: Float32Array | null;
  private readonly stateOutputName: string | null;

  private constructor(
    private readonly session: ort.InferenceSession,
    stateSize: number,
    inputs = NUM_INPUTS,
  ) {
    // The input tensors wrap our arrays: filled in place every frame, never copied by us.
    // (onnxruntime-web 1.30 leaves a pre-allocated CPU output tensor unwritten, so the result
    // is copied out of the tensor it returns; that allocation is the runtime's.)
    const [input, stateInput] = session.inputNames;
    if (stateSize > 0) {
      this.trackerInput = new Float32Array(TRACKER_INPUTS);
      this.trackerSource = this.features.input.subarray(0, TRACKER_INPUTS);
      this.state = new Float32Array(stateSize);
      this.stateOutputName = session.outputNames[1];
      this.feeds = { [input]: new ort.Tensor('float32', this.trackerInput, [1, TRACKER_INPUTS]), [stateInput]: new ort.Tensor('float32', this.state, [1, stateSize]) };
    } else {
      this.trackerInput = this.trackerSource = this.state = this.stateOutputName = null;
      // A 42-input model reads a view of the first 42 (made once: no per-frame copy).
      const x = inputs === NUM_INPUTS ? this.features.input : this.features.input.subarray(0, inputs);
      this.feeds = { [input]: new ort.Tensor('float32', x, [1, inputs]) };
    }
    this.outputName = session.outputNames[0];
    this.hipsOutputName = stateSize === 0 && session.outputNames.length === 2 ? session.outputNames[1] : null;
  }

  /** How many features the model takes: 54, 42 (a model from before the context), or 36 (recurrent). */
  get inputCount(): number {
    return this.feeds[this.session.inputNames[0]].dims[1];
  }

  /** Whether the model is recurrent (carries a state instead of the fed-back yaw). */
  get recurrent(): boolean {
    return this.state !== null;
  }

  /**
   * Loads the model from a URL or its bytes.
   * @throws Error naming the source when the model cannot be loaded or has the wrong shape.
   */
  static async create(source: string | Uint8Array | ArrayBuffer = DEFAULT_MODEL_URL, options: OrientationModelOptions = {}): Promise<OrientationModel> {
    ort.env.wasm.numThreads = options.numThreads ?? 1;
    let session: ort.InferenceSession;
    try {
      const opts: ort.InferenceSession.SessionOptions = { executionProviders: ['wasm'], graphOptimizationLevel: 'all' };
      session =
        typeof source === 'string'
          ? await ort.InferenceSession.create(source, opts)
          : await ort.InferenceSession.create(source instanceof Uint8Array ? source : new Uint8Array(source), opts);
    } catch (e) {
      const what = typeof source === 'string' ? source : `${source.byteLength} bytes`;
      throw new Error(`OrientationModel: cannot load the ONNX model (${what}): ${e instanceof Error ? e.message : String(e)}`);
    }
    const inputs = session.inputNames.length;
    const outputs = session.outputNames.length;
    if (inputs === 1 && (outputs === 1 || outputs === 2)) {
      // The feature count: 54, or 42 for a model from before the context (a dynamic size: 54).
      const meta = session.inputMetadata[0];
      const dim = meta?.isTensor ? meta.shape[1] : NUM_INPUTS;
      const count = typeof dim === 'number' ? dim : NUM_INPUTS;
      if (count === NUM_INPUTS || count === LEGACY_INPUTS) return new OrientationModel(session, 0, count);
      await session.release();
      throw new Error(`OrientationModel: the model takes ${count} features; expected ${NUM_INPUTS} (or ${LEGACY_INPUTS}, a model from before the context)`);
    }
    // Recurrent: the state's size is the second input's second dimension.
    const meta = session.inputMetadata[1];
    const size = inputs === 2 && outputs === 2 && meta?.isTensor ? meta.shape[1] : NaN;
    if (typeof size === 'number' && Number.isInteger(size) && size >= 1 && size <= 4096) return new OrientationModel(session, size);
    await session.release();
    throw new Error(`OrientationModel: expected 1 input and 1 or 2 outputs (the 6D, the hips; or features and a fixed-size state in, 6D and the state out), the model has ${inputs} and ${outputs}`);
  }

  /** Predicted body yaw, world (local-floor) radians, 0 = facing +Z. */
  get bodyYaw(): number {
    return this._bodyYaw;
  }

  /** Predicted body yaw relative to the HMD's yaw, radians in [−π, π). */
  get relativeYaw(): number {
    return this._relativeYaw;
  }

  /** HMD yaw of the last update, radians. */
  get hmdYaw(): number {
    return this.features.hmdYaw;
  }

  /**
   * One frame: poses as in {@link OrientationFeatures.update} (9 positions, 12 quaternion
   * numbers: HMD, left grip, right grip), `dt` the real time since the previous frame.
   * Await each call before the next (the state is sequential).
   * @returns the body yaw (radians, 0 = +Z).
   */
  async update(positions: ArrayLike<number>, quaternions: ArrayLike<number>, dt: number): Promise<number> {
    if (this.busy) throw new Error('OrientationModel.update: the previous update is still running (await it)');
    this.busy = true;
    try {
      const f = this.features;
      f.update(positions, quaternions, dt);
      const known = this.hasYaw && Number.isFinite(this._bodyYaw);
      if (this.trackerInput) this.trackerInput.set(this.trackerSource!);
      else f.setPrevious(known ? wrapAngle(this._bodyYaw - f.hmdYaw) : 0);
      const result = await this.session.run(this.feeds);
      const o = this.output;
      o.set(result[this.outputName].data as Float32Array);
      if (this.hipsOutputName) {
        const h = result[this.hipsOutputName].data as Float32Array;
        const ok = h.length >= 2 && Number.isFinite(h[0]) && Number.isFinite(h[1]);
        this.hips[0] = ok ? h[0] : NaN;
        this.hips[1] = ok ? h[1] : NaN;
      }
      const state = this.state;
      if (state) {
        const next = result[this.stateOutputName!].data as Float32Array;
        let finite = next.length === state.length;
        for (let i = 0; finite && i < next.length; i++) finite = Number.isFinite(next[i]);
        if (finite) state.set(next);
        else state.fill(0); // a NaN state would stay NaN: start the memory again
      }
      const cs = o[0];
      const sn = -o[2];
      if (Number.isFinite(cs) && Number.isFinite(sn) && Math.hypot(cs, sn) > 1e-6) {
        this._relativeYaw = Math.atan2(sn, cs);
        this._bodyYaw = f.hmdYaw + this._relativeYaw;
      } else if (!known) {
        this._bodyYaw = f.hmdYaw;
        this._relativeYaw = 0;
      } else {
        this._relativeYaw = wrapAngle(this._bodyYaw - f.hmdYaw);
      }
      this._bodyYaw = wrapAngle(this._bodyYaw);
      this.hasYaw = true;
      return this._bodyYaw;
    } finally {
      this.busy = false;
    }
  }

  /** Starts over (new session, recentred space, long pause): no velocities, previous = HMD forward. */
  reset(): void {
    this.features.reset();
    this.state?.fill(0);
    this.hasYaw = false;
    this._bodyYaw = 0;
    this._relativeYaw = 0;
    this.hips.fill(NaN);
  }

  /** Frees the ONNX session. */
  async release(): Promise<void> {
    await this.session.release();
  }
}
