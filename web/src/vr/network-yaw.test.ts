/**
 * The per-set body yaw on the real models (onnxruntime-web in Node) and the parity fixture's
 * poses (2 s): the main (feed-back) model alone while the recurrent one warms up, then with both
 * hands tracked the mean of the two on the circle, with a controller missing the recurrent
 * model's — the weight moving there at `BLEND_RATE` a second. Both step every frame either way.
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

describe('NetworkYawPredictor with a model for fewer devices', () => {
  it('warm-up: the main model; then both hands: the mean of both; a controller missing: the recurrent one', async () => {
    ort.env.wasm.numThreads = 1;
    const load = async (file: string) => OrientationModel.create(fs.readFileSync(path.join(ROOT, 'public/models', file)));
    const fewer = new NetworkYawPredictor(await load('orientation_gru.onnx'));
    const predictor = new NetworkYawPredictor(await load('orientation.onnx'), fewer);
    const seen = { main: 0, both: 0, fewer: 0 };
    let [differ, weight] = [0, 0];
    for (let t = 0; t < seq.dt.length; t++) {
      const missing = t >= 130; // the right controller is put down after the warm-up
      const [p, q] = [seq.positions[t], seq.quaternions[t]];
      const poses = [pose(p, q, 0, TRACKED), pose(p, q, 1, TRACKED), pose(p, q, 2, missing ? MISSING : TRACKED)] as const;
      predictor.update(...poses, seq.dt[t]);
      await predictor.settle();
      expect(fewer.runs).toBe(predictor.runs);
      // The weight moves toward its target by at most BLEND_RATE · dt.
      expect(Math.abs(predictor.weight - weight)).toBeLessThanOrEqual(BLEND_RATE * seq.dt[t] + 1e-9);
      weight = predictor.weight;
      // What the next update returns (dt 0: no new run, no blend step): this frame's runs.
      const [a, b] = [predictor.model.bodyYaw, fewer.model.bodyYaw];
      const yaw = predictor.update(...poses, 0);
      const want = fewer.age < RECURRENT_WARMUP ? 'main' : missing ? 'fewer' : 'both';
      expect(predictor.source).toBe(want);
      seen[want]++;
      const w = predictor.weight;
      if (want === 'main') expect(w).toBe(0);
      const mix = Math.atan2((1 - w) * Math.sin(a) + w * Math.sin(b), (1 - w) * Math.cos(a) + w * Math.cos(b));
      expect(w === 0 ? yaw === a : w === 1 ? yaw === b : Math.abs(yaw - mix) < 1e-12).toBe(true);
      if (Math.abs(a - b) > 1e-3) differ++;
    }
    // Warm-up first, then both, then the recurrent model's weight rising past ½ toward 1.
    expect(seen.main).toBeGreaterThan(100);
    expect(seen.both).toBeGreaterThan(10);
    expect(seen.fewer).toBe(seq.dt.length - 130);
    expect(weight).toBeGreaterThan(0.7);
    expect(differ).toBeGreaterThan(100); // two different models: the choice is visible
    await predictor.model.release();
    await fewer.model.release();
  });
});
