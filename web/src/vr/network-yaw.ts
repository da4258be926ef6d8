/**
 * The orientation network as a BodyYawPredictor (THESIS_NOTES §9). The ONNX runner lives in
 * web/src/orientation (onnxruntime-web); until it lands this loader rejects, and the page falls
 * back, visibly, to the HMD-forward heuristic — the same path as a missing or broken model file.
 */
import { type BodyYawPredictor } from './body-yaw.ts';

/** Loads the model at `url`; rejects with a message the page shows when it cannot. */
export async function loadNetworkPredictor(url: string): Promise<BodyYawPredictor> {
  throw new Error(`${url}: the orientation model runner (web/src/orientation) is not in this build yet`);
}
