/**
 * Browser benchmark of the orientation models (`bench.html`): median time per
 * `OrientationModel.update` (features + onnxruntime-web) on each parity fixture's poses, and the
 * largest difference to the recorded PyTorch outputs — the main model and the recurrent one. Results in `window.__orientationBench`.
 */
import { OrientationModel } from './orientation-model.ts';

interface BenchResult {
  done: boolean;
  error: string | null;
  userAgent: string;
  crossOriginIsolated: boolean;
  updates: number;
  medianMs: number;
  p95Ms: number;
  maxOutputError: number;
  recurrent: { updates: number; medianMs: number; p95Ms: number; maxOutputError: number } | null;
}

declare global {
  interface Window {
    __orientationBench: BenchResult;
  }
}

const result: BenchResult = {
  done: false, error: null, userAgent: navigator.userAgent, crossOriginIsolated,
  updates: 0, medianMs: NaN, p95Ms: NaN, maxOutputError: NaN, recurrent: null,
};
window.__orientationBench = result;
const out = document.getElementById('out') as HTMLElement;

interface Sequence {
  dt: number[];
  positions: number[][];
  quaternions: number[][];
  outputs: number[][];
}

/** Median and p95 ms per update of the model at `modelPath` on a fixture's poses, and its largest output difference. */
async function benchModel(modelPath: string, fixturePath: string): Promise<{ updates: number; medianMs: number; p95Ms: number; maxOutputError: number }> {
  const seq = ((await (await fetch(fixturePath)).json()) as { sequence: Sequence }).sequence;
  const model = await OrientationModel.create(`${import.meta.env.BASE_URL}${modelPath}`);
  const n = seq.dt.length;
  // Parity pass: the recorded PyTorch outputs, frame by frame in the model's loop.
  let maxErr = 0;
  for (let t = 0; t < n; t++) {
    await model.update(seq.positions[t], seq.quaternions[t], seq.dt[t]);
    for (let j = 0; j < 6; j++) maxErr = Math.max(maxErr, Math.abs(model.output[j] - seq.outputs[t][j]));
  }
  // Timing: batches of 20 updates (the timer is coarse without cross-origin isolation).
  const per: number[] = [];
  const batch = 20;
  for (let b = 0; b < 150; b++) {
    const t0 = performance.now();
    for (let i = 0; i < batch; i++) {
      const t = (b * batch + i) % n;
      if (t === 0) model.reset();
      await model.update(seq.positions[t], seq.quaternions[t], seq.dt[t]);
    }
    per.push((performance.now() - t0) / batch);
  }
  per.sort((a, b) => a - b);
  await model.release();
  return { updates: per.length * batch, medianMs: per[per.length >> 1], p95Ms: per[Math.floor(per.length * 0.95)], maxOutputError: maxErr };
}

async function main(): Promise<void> {
  Object.assign(result, await benchModel('models/orientation.onnx', '/training/fixtures/orientation_parity.json'));
  // The recurrent model (the VR page runs both every frame and averages them).
  result.recurrent = await benchModel('models/orientation_gru.onnx', '/training/fixtures/orientation_gru_parity.json');
  out.textContent = JSON.stringify(result, null, 1);
}

main()
  .catch((e: unknown) => {
    result.error = e instanceof Error ? `${e.message}\n${e.stack ?? ''}` : String(e);
    out.textContent = `error: ${result.error}`;
  })
  .finally(() => {
    result.done = true;
  });
