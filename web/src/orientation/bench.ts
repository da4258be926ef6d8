/**
 * Browser benchmark of the orientation model (`bench.html`): median time per
 * `OrientationModel.update` (features + onnxruntime-web) on the parity fixture's poses, and the
 * largest difference to the recorded PyTorch outputs. Results in `window.__orientationBench`.
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
}

declare global {
  interface Window {
    __orientationBench: BenchResult;
  }
}

const result: BenchResult = {
  done: false, error: null, userAgent: navigator.userAgent, crossOriginIsolated,
  updates: 0, medianMs: NaN, p95Ms: NaN, maxOutputError: NaN,
};
window.__orientationBench = result;
const out = document.getElementById('out') as HTMLElement;

async function main(): Promise<void> {
  const fixture = (await (await fetch('/training/fixtures/orientation_parity.json')).json()) as {
    sequence: { dt: number[]; positions: number[][]; quaternions: number[][]; outputs: number[][] };
  };
  const seq = fixture.sequence;
  const model = await OrientationModel.create(`${import.meta.env.BASE_URL}models/orientation.onnx`);
  const n = seq.dt.length;
  // Parity pass: the recorded PyTorch outputs, frame by frame in the feedback loop.
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
  Object.assign(result, {
    updates: per.length * batch, medianMs: per[per.length >> 1], p95Ms: per[Math.floor(per.length * 0.95)], maxOutputError: maxErr,
  });
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
