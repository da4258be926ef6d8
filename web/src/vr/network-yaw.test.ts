/**
 * The per-set body yaw on the real models (onnxruntime-web in Node) and the parity fixture's
 * poses: with both hands tracked, the main (feed-back) model's yaw; with a controller missing,
 * the recurrent model's. Both models step every frame either way, so each is warm at a switch.
 */
import fs from 'node:fs';
import path from 'node:path';
import * as ort from 'onnxruntime-web/wasm';
import { describe, expect, it } from 'vitest';
import { OrientationModel } from '../orientation/orientation-model.ts';
import { NetworkYawPredictor } from './network-yaw.ts';
import { MISSING, TRACKED } from './trackers.ts';

const ROOT = path.resolve(import.meta.dirname, '../../..');
const seq = (JSON.parse(fs.readFileSync(path.join(ROOT, 'training/fixtures/orientation_parity.json'), 'utf8')) as { sequence: { dt: number[]; positions: number[][]; quaternions: number[][] } }).sequence;

function pose(p: number[], q: number[], k: number, status: number) {
  return { position: p.slice(3 * k, 3 * k + 3), rotation: q.slice(4 * k, 4 * k + 4), velocity: [0, 0, 0], angularVelocity: [0, 0, 0], status };
}

describe('NetworkYawPredictor with a model for fewer devices', () => {
  it('both hands: the main model; a controller missing: the recurrent one; both step every frame', async () => {
    ort.env.wasm.numThreads = 1;
    const load = async (file: string) => OrientationModel.create(fs.readFileSync(path.join(ROOT, 'public/models', file)));
    const fewer = new NetworkYawPredictor(await load('orientation_gru.onnx'));
    const predictor = new NetworkYawPredictor(await load('orientation.onnx'), fewer);
    let [mainFrames, fewerFrames, differ] = [0, 0, 0];
    for (let t = 0; t < seq.dt.length; t++) {
      const missing = t >= 60 && t < 100; // the right controller is put down for a while
      const [p, q] = [seq.positions[t], seq.quaternions[t]];
      const poses = [pose(p, q, 0, TRACKED), pose(p, q, 1, TRACKED), pose(p, q, 2, missing ? MISSING : TRACKED)] as const;
      predictor.update(...poses, seq.dt[t]);
      await predictor.settle();
      expect(fewer.runs).toBe(predictor.runs);
      // What the next update returns (dt 0: no new run): this frame's finished runs.
      const [a, b] = [predictor.model.bodyYaw, fewer.model.bodyYaw];
      const yaw = predictor.update(...poses, 0);
      expect(predictor.usingFewer).toBe(missing);
      expect(yaw).toBe(missing ? b : a);
      if (Math.abs(a - b) > 1e-3) differ++;
      if (missing) fewerFrames++;
      else mainFrames++;
    }
    expect([mainFrames, fewerFrames]).toEqual([seq.dt.length - 40, 40]);
    expect(differ).toBeGreaterThan(100); // two different models: the choice is visible
    await predictor.model.release();
    await fewer.model.release();
  });
});
