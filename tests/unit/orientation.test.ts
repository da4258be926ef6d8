import { createHash } from 'node:crypto';
import fs from 'node:fs';
import path from 'node:path';
import * as ort from 'onnxruntime-web/wasm';
import { beforeAll, describe, expect, it } from 'vitest';
import { MAX_DT, NUM_INPUTS, OrientationFeatures } from '../../web/src/orientation/features.ts';
import { headingYaw as hmdYaw, wrapAngle } from '../../web/src/yaw.ts';
import { OrientationModel } from '../../web/src/orientation/orientation-model.ts';

// Fixtures recorded from Python by `npm run train` (training/orientation/fixtures.py): raw
// tracker poses of a held-out take, the inputs the Python reference built each frame, and the
// PyTorch outputs of the committed model.
const ROOT = path.resolve(import.meta.dirname, '../..');
const MODEL_PATH = path.join(ROOT, 'public/models/orientation.onnx');

interface Fixture {
  model_sha256: string;
  rows: { inputs: number[][]; outputs: number[][] };
  sequence: {
    name: string;
    dt: number[];
    positions: number[][];
    quaternions: number[][];
    inputs: number[][];
    outputs: number[][];
    body_yaw: number[];
    hmd_yaw: number[];
  };
}
const fixture = JSON.parse(fs.readFileSync(path.join(ROOT, 'training/fixtures/orientation_parity.json'), 'utf8')) as Fixture;
const seq = fixture.sequence;

/** Largest |a − b| / (1 + |b|) (absolute near 0, relative for large velocities). */
function maxErr(a: ArrayLike<number>, b: ArrayLike<number>): number {
  let m = 0;
  for (let i = 0; i < b.length; i++) m = Math.max(m, Math.abs(a[i] - b[i]) / (1 + Math.abs(b[i])));
  return m;
}

describe('OrientationFeatures', () => {
  it('builds the same 54 inputs as the Python reference, frame by frame', () => {
    const f = new OrientationFeatures();
    let worst = 0;
    for (let t = 0; t < seq.dt.length; t++) {
      const out = f.update(seq.positions[t], seq.quaternions[t], seq.dt[t]);
      expect(out).toBe(f.input); // the one preallocated array, every frame
      expect(Math.abs(f.hmdYaw - seq.hmd_yaw[t])).toBeLessThan(1e-9);
      f.setPrevious(t === 0 ? 0 : wrapAngle(seq.body_yaw[t - 1] - f.hmdYaw));
      worst = Math.max(worst, maxErr(f.input, seq.inputs[t]));
    }
    expect(worst).toBeLessThan(1e-5);
    // The fixture covers a dropped frame and a pause longer than MAX_DT (velocities and the
    // context's windows restart), and more than the longest window (1 s) before the pause.
    expect(seq.dt.some((dt) => dt > MAX_DT)).toBe(true);
    expect(seq.dt.slice(1, seq.dt.findIndex((dt) => dt > MAX_DT)).reduce((a, b) => a + b, 0)).toBeGreaterThan(1);
  });

  it('yaw 0 is looking along +Z, and looking straight down keeps the heading', () => {
    // A viewer looks down its local −Z: facing +Z is a half turn about Y.
    expect(Math.abs(wrapAngle(hmdYaw(0, 1, 0, 0)))).toBeLessThan(1e-12);
    const yaw = 0.6;
    const qy = [0, Math.sin((yaw + Math.PI) / 2), 0, Math.cos((yaw + Math.PI) / 2)];
    for (const pitch of [-Math.PI / 2, -1, 0, 1.2, Math.PI / 2]) {
      const qx = [Math.sin(pitch / 2), 0, 0, Math.cos(pitch / 2)];
      // q = qy · qx
      const q = [
        qy[3] * qx[0] + qy[0] * qx[3] + qy[1] * qx[2] - qy[2] * qx[1],
        qy[3] * qx[1] - qy[0] * qx[2] + qy[1] * qx[3] + qy[2] * qx[0],
        qy[3] * qx[2] + qy[0] * qx[1] - qy[1] * qx[0] + qy[2] * qx[3],
        qy[3] * qx[3] - qy[0] * qx[0] - qy[1] * qx[1] - qy[2] * qx[2],
      ];
      expect(Math.abs(wrapAngle(hmdYaw(q[0], q[1], q[2], q[3]) - yaw))).toBeLessThan(1e-9);
    }
  });

  it('rejects bad input with a message', () => {
    const f = new OrientationFeatures();
    const p = seq.positions[0];
    const q = seq.quaternions[0];
    f.update(p, q, 0.011);
    expect(() => f.update(p, q, 0)).toThrow(/dt must be positive/);
    expect(() => f.update(p, q, Number.NaN)).toThrow(RangeError);
    expect(() => f.update(p.slice(0, 6), q, 0.011)).toThrow(/need 9 positions/);
    expect(() => f.update([...p.slice(0, 8), Number.NaN], q, 0.011)).toThrow(/position 8/);
    expect(() => f.update(p, new Array(12).fill(0), 0.011)).toThrow(/zero length/);
    f.reset();
    expect(Array.from(f.input.subarray(36, 42))).toEqual([1, 0, -0, 0, 1, 0]);
    expect(f.input.subarray(42).every((v) => v === 0)).toBe(true);
    expect(f.input.length).toBe(NUM_INPUTS);
  });
});

describe('OrientationModel (onnxruntime-web in Node)', () => {
  let bytes: Uint8Array;
  beforeAll(() => {
    ort.env.wasm.numThreads = 1;
    bytes = fs.readFileSync(MODEL_PATH);
  });

  it('is the model the fixture was recorded with', () => {
    expect(createHash('sha256').update(bytes).digest('hex')).toBe(fixture.model_sha256);
    expect(bytes.byteLength).toBeLessThan(64 * 1024);
  });

  it('gives the PyTorch outputs, the 6D and the hips, on recorded inputs (within 1e-4)', async () => {
    const session = await ort.InferenceSession.create(bytes);
    try {
      const n = fixture.rows.inputs.length;
      const x = new Float32Array(n * NUM_INPUTS);
      fixture.rows.inputs.forEach((row, i) => x.set(row, i * NUM_INPUTS));
      const out = await session.run({ [session.inputNames[0]]: new ort.Tensor('float32', x, [n, NUM_INPUTS]) });
      expect(session.outputNames).toEqual(['orientation6d', 'hips']);
      const y = out.orientation6d.data as Float32Array, hips = out.hips.data as Float32Array;
      let worst = 0;
      for (const [i, row] of fixture.rows.outputs.entries()) {
        expect(row.length).toBe(8); // the 6D, then the hips
        row.forEach((v, j) => (worst = Math.max(worst, Math.abs((j < 6 ? y[i * 6 + j] : hips[i * 2 + j - 6]) - v))));
      }
      console.log(`orientation model: max |onnxruntime-web − PyTorch| = ${worst.toExponential(2)} on ${n} recorded inputs`);
      expect(worst).toBeLessThan(1e-4);
    } finally {
      await session.release();
    }
  });

  it('runs the feedback loop like Python: same inputs, outputs (the 6D and the hips) and body yaw', async () => {
    const model = await OrientationModel.create(bytes);
    try {
      for (let pass = 0; pass < 2; pass++) {
        let worstIn = 0;
        let worstOut = 0;
        let worstYaw = 0;
        for (let t = 0; t < seq.dt.length; t++) {
          const yaw = await model.update(seq.positions[t], seq.quaternions[t], seq.dt[t]);
          worstIn = Math.max(worstIn, maxErr(model.features.input, seq.inputs[t]));
          worstOut = Math.max(worstOut, maxErr(model.output, seq.outputs[t].slice(0, 6)), maxErr(model.hips, seq.outputs[t].slice(6)));
          worstYaw = Math.max(worstYaw, Math.abs(wrapAngle(yaw - seq.body_yaw[t])));
          expect(Math.abs(wrapAngle(model.bodyYaw - model.hmdYaw - model.relativeYaw))).toBeLessThan(1e-9);
        }
        expect(worstIn).toBeLessThan(1e-5);
        expect(worstOut).toBeLessThan(1e-4);
        expect(worstYaw).toBeLessThan(1e-4);
        model.reset(); // the second pass must repeat the first exactly
        expect(Array.from(model.hips).every(Number.isNaN)).toBe(true);
      }
    } finally {
      await model.release();
    }
  });

  it('reports the median time per update', async () => {
    const model = await OrientationModel.create(bytes);
    try {
      const times: number[] = [];
      const n = seq.dt.length;
      for (let i = 0; i < 600; i++) {
        const t = i % n;
        if (t === 0) model.reset();
        const t0 = performance.now();
        await model.update(seq.positions[t], seq.quaternions[t], seq.dt[t]);
        times.push(performance.now() - t0);
      }
      times.sort((a, b) => a - b);
      const median = times[times.length >> 1];
      console.log(`orientation model: median ${median.toFixed(3)} ms per update (features + onnxruntime-web wasm, Node ${process.version})`);
      expect(median).toBeLessThan(10);
    } finally {
      await model.release();
    }
  });

  it('recovers from a NaN previous body yaw as from a reset (docs/orientation-model.md)', async () => {
    const model = await OrientationModel.create(bytes);
    try {
      for (let t = 0; t < 5; t++) await model.update(seq.positions[t], seq.quaternions[t], seq.dt[t]);
      // A corrupted state: the previous yaw is NaN. The next frame treats it as a reset.
      (model as unknown as { _bodyYaw: number })._bodyYaw = Number.NaN;
      const yaw = await model.update(seq.positions[5], seq.quaternions[5], seq.dt[5]);
      expect(Number.isFinite(yaw)).toBe(true);
      expect(model.features.input[36]).toBe(1); // previous slot: HMD forward, cos 0
      for (let t = 6; t < 40; t++) expect(Number.isFinite(await model.update(seq.positions[t], seq.quaternions[t], seq.dt[t]))).toBe(true);
    } finally {
      await model.release();
    }
  });

  it('runs a model from before the context on the first 42 inputs (and without the hips)', async () => {
    // training/fixtures/orientation_42.onnx: the shipped model until the context was added.
    const legacy = await OrientationModel.create(fs.readFileSync(path.join(ROOT, 'training/fixtures/orientation_42.onnx')));
    const model = await OrientationModel.create(bytes);
    try {
      expect([legacy.inputCount, model.inputCount]).toEqual([42, NUM_INPUTS]);
      let differ = 0;
      for (let t = 0; t < 60; t++) {
        const a = await legacy.update(seq.positions[t], seq.quaternions[t], seq.dt[t]);
        const b = await model.update(seq.positions[t], seq.quaternions[t], seq.dt[t]);
        expect(Number.isFinite(a)).toBe(true);
        differ = Math.max(differ, Math.abs(wrapAngle(a - b)));
      }
      expect(differ).toBeGreaterThan(0); // two networks, each run on its own inputs
      // It has no hips output: "not known", where the new one says where the hips are.
      expect(Array.from(legacy.hips).every(Number.isNaN)).toBe(true);
      expect(Array.from(model.hips).every(Number.isFinite)).toBe(true);
    } finally {
      await legacy.release();
      await model.release();
    }
  });

  it('fails clearly on a broken model and on overlapping updates', async () => {
    await expect(OrientationModel.create(new Uint8Array([1, 2, 3]))).rejects.toThrow(/cannot load the ONNX model \(3 bytes\)/);
    const model = await OrientationModel.create(bytes);
    try {
      const p = seq.positions[0];
      const q = seq.quaternions[0];
      const first = model.update(p, q, 0.011);
      await expect(model.update(p, q, 0.011)).rejects.toThrow(/still running/);
      await first;
    } finally {
      await model.release();
    }
  });
});

// The recurrent model the VR page averages with the network (training/orientation/gru.py),
// against the fixture the export wrote: the same loop, its state carried by the runner.
describe('OrientationModel, recurrent (onnxruntime-web in Node)', () => {
  const gruFixture = JSON.parse(fs.readFileSync(path.join(ROOT, 'training/fixtures/orientation_gru_parity.json'), 'utf8')) as Fixture;
  const gseq = gruFixture.sequence;
  let gru: Uint8Array;
  beforeAll(() => {
    ort.env.wasm.numThreads = 1;
    gru = fs.readFileSync(path.join(ROOT, 'public/models/orientation_gru.onnx'));
  });

  it('is the model the fixture was recorded with, and small', () => {
    expect(createHash('sha256').update(gru).digest('hex')).toBe(gruFixture.model_sha256);
    expect(gru.byteLength).toBeLessThan(96 * 1024);
  });

  it('carries its state like Python: same inputs, outputs and body yaw; a reset repeats the run; timed', async () => {
    const model = await OrientationModel.create(gru);
    try {
      expect(model.recurrent).toBe(true);
      const times: number[] = [];
      for (let pass = 0; pass < 2; pass++) {
        let worstIn = 0;
        let worstOut = 0;
        let worstYaw = 0;
        for (let t = 0; t < gseq.dt.length; t++) {
          const t0 = performance.now();
          const yaw = await model.update(gseq.positions[t], gseq.quaternions[t], gseq.dt[t]);
          times.push(performance.now() - t0);
          worstIn = Math.max(worstIn, maxErr(model.features.input.subarray(0, 36), gseq.inputs[t]));
          worstOut = Math.max(worstOut, maxErr(model.output, gseq.outputs[t]));
          worstYaw = Math.max(worstYaw, Math.abs(wrapAngle(yaw - gseq.body_yaw[t])));
        }
        expect(worstIn).toBeLessThan(1e-5);
        expect(worstOut).toBeLessThan(1e-4);
        expect(worstYaw).toBeLessThan(1e-4);
        if (pass === 0) console.log(`recurrent model: max |yaw − Python| ${worstYaw.toExponential(2)} rad over ${gseq.dt.length} frames`);
        model.reset();
      }
      times.sort((a, b) => a - b);
      console.log(`recurrent model: median ${times[times.length >> 1].toFixed(3)} ms per update (Node ${process.version})`);
    } finally {
      await model.release();
    }
  });

});
