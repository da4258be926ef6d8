/**
 * The body yaw on the real models (onnxruntime-web in Node) and the parity fixture's poses
 * (1.7 s): the main (feed-back) model alone while the recurrent one warms up, then the mean of the
 * two on the circle — with both hands tracked and with a controller missing alike — the weight
 * moving there at `BLEND_RATE` a second. Both step every frame either way.
 */
import fs from 'node:fs';
import path from 'node:path';
import * as ort from 'onnxruntime-web/wasm';
import { describe, expect, it } from 'vitest';
import { OrientationModel } from '../orientation/orientation-model.ts';
import { BLEND_RATE, NetworkYawPredictor, RECURRENT_WARMUP } from './network-yaw.ts';
import { MISSING, TRACKED } from './trackers.ts';

const ROOT = path.resolve(import.meta.dirname, '../../..');
const seq = (JSON.parse(fs.readFileSync(path.join(ROOT, 'training/fixtures/orientation_parity.json'), 'utf8')) as { sequence: { dt: number[]; positions: number[][]; quaternions: number[][] } }).sequence;

function pose(p: number[], q: number[], k: number, status: number) {
  return { position: p.slice(3 * k, 3 * k + 3), rotation: q.slice(4 * k, 4 * k + 4), velocity: [0, 0, 0], angularVelocity: [0, 0, 0], status };
}

describe('NetworkYawPredictor with the recurrent model', () => {
  it('warm-up: the main model; then the mean of both, whatever devices are tracked', async () => {
    ort.env.wasm.numThreads = 1;
    const load = async (file: string) => OrientationModel.create(fs.readFileSync(path.join(ROOT, 'public/models', file)));
    const recurrent = new NetworkYawPredictor(await load('orientation_gru.onnx'));
    const predictor = new NetworkYawPredictor(await load('orientation.onnx'), recurrent);
    const seen = { main: 0, both: 0 };
    let [differ, weight, missed] = [0, 0, 0];
    for (let t = 0; t < seq.dt.length; t++) {
      const missing = t >= 130; // the right controller is put down after the warm-up
      const [p, q] = [seq.positions[t], seq.quaternions[t]];
      const poses = [pose(p, q, 0, TRACKED), pose(p, q, 1, TRACKED), pose(p, q, 2, missing ? MISSING : TRACKED)] as const;
      predictor.update(...poses, seq.dt[t]);
      await predictor.settle();
      expect(recurrent.runs).toBe(predictor.runs);
      // The weight moves toward its target by at most BLEND_RATE · dt.
      expect(Math.abs(predictor.weight - weight)).toBeLessThanOrEqual(BLEND_RATE * seq.dt[t] + 1e-9);
      weight = predictor.weight;
      // What the next update returns (dt 0: no new run, no blend step): this frame's runs.
      const [a, b] = [predictor.model.bodyYaw, recurrent.model.bodyYaw];
      const yaw = predictor.update(...poses, 0);
      const want = recurrent.age < RECURRENT_WARMUP ? 'main' : 'both';
      expect(predictor.source).toBe(want);
      seen[want]++;
      const w = predictor.weight;
      if (want === 'main') expect(w).toBe(0);
      const mix = Math.atan2((1 - w) * Math.sin(a) + w * Math.sin(b), (1 - w) * Math.cos(a) + w * Math.cos(b));
      expect(w === 0 ? yaw === a : Math.abs(yaw - mix) < 1e-12).toBe(true);
      expect(w).toBeLessThanOrEqual(0.5);
      if (missing) missed++;
      if (Math.abs(a - b) > 1e-3) differ++;
    }
    // Warm-up first, then both (the weight reaching ½ a quarter of a second later), a controller
    // put down changing nothing.
    expect(seen.main).toBeGreaterThan(100);
    expect(seen.both).toBeGreaterThan(10);
    expect(missed).toBe(seq.dt.length - 130);
    expect(weight).toBe(0.5);
    expect(differ).toBeGreaterThan(100); // two different models: the choice is visible
    await predictor.model.release();
    await recurrent.model.release();
  });
});
