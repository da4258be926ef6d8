/**
 * What the VR pipeline asks of a body-orientation predictor (docs/method.md §9): each frame, the
 * user's body (root) yaw from the HMD and controller states. Two implementations: the ONNX
 * orientation network (web/src/orientation, wrapped by an adapter) and the HMD-forward
 * dead-zone heuristic (fallback-yaw.ts), shown when the model is missing or fails to load.
 */

/** The tracker state a predictor reads (trackers.ts `TrackerView` is one). World = local-floor. */
export interface TrackerPose {
  readonly position: ArrayLike<number>;
  /** x, y, z, w. */
  readonly rotation: ArrayLike<number>;
  /** m/s, world. */
  readonly velocity: ArrayLike<number>;
  /** rad/s (axis × rate), world. */
  readonly angularVelocity: ArrayLike<number>;
  /** trackers.ts TRACKED, MISSING or FROZEN. */
  readonly status: number;
}

export interface BodyYawPredictor {
  /** 'network' or 'heuristic': shown in the page and read by tests. */
  readonly name: string;
  /**
   * Where the hips are on the floor, (x, z) from the head centre (`HMD_TO_HEAD_CENTRE` behind the
   * headset), world metres, as of the last update; NaN (or absent) when the predictor does not
   * say — the root's target is then the head centre itself.
   */
  readonly hips?: ArrayLike<number>;
  /** Advances by `dt` seconds and returns the body yaw, radians (0 = +Z, world). */
  update(hmd: TrackerPose, left: TrackerPose, right: TrackerPose, dt: number): number;
  /** Forgets history (session start, recentre); the next update starts from the HMD heading. */
  reset(): void;
}
