import fs from 'node:fs';
import path from 'node:path';
import { beforeAll, describe, expect, it } from 'vitest';
import { initWasmSync } from '../core/wasm.ts';
import { decodeRecording, encodeRecordingBinary, encodeRecordingJson, type Recording, RecordingPlayer, TrackerRecorder } from './recording.ts';
import { SCRIPT_DURATION, scriptedSample } from './scripted-motion.ts';
import { BODY_JOINTS, HEAD, HIPS, NUM_BODY_JOINTS, RIGHT, TrackerSample } from './tracker-sample.ts';

function scripted(hz = 72, seconds = SCRIPT_DURATION): Recording {
  const recorder = new TrackerRecorder(16); // grows
  const s = new TrackerSample();
  for (let f = 0; f * (1 / hz) <= seconds; f++) {
    scriptedSample(f / hz, s);
    s.time += 100; // recordings start at 0 whatever the clock said
    if (f % 50 === 7) s.tracked[RIGHT] = 0;
    recorder.add(s);
  }
  return recorder.toRecording({ device: 'test', rate: hz });
}

const ROOT = path.resolve(import.meta.dirname, '../../..');

beforeAll(() => {
  // The validator is the runtime's (the one `mmdb replay` runs).
  initWasmSync(fs.readFileSync(path.join(ROOT, 'web/src/core/pkg/mmcore_bg.wasm')));
});

describe('recordings', () => {
  it('reads the shared hostile recordings as `mmdb replay` does: same verdict, same message', () => {
    const doc = JSON.parse(fs.readFileSync(path.join(ROOT, 'wasm-core/tests/corpus/recordings/cases.json'), 'utf8')) as { cases: { name: string; text: string; expect: string | null }[] };
    expect(doc.cases.length).toBeGreaterThanOrEqual(20);
    const wrong = doc.cases.flatMap((c) => {
      try {
        decodeRecording(c.text, 'case.json');
        return c.expect === null ? [] : [`${c.name}: accepted, expected ${c.expect}`];
      } catch (e) {
        const message = e instanceof Error ? e.message : String(e);
        return c.expect !== null && message === `case.json: ${c.expect}` ? [] : [`${c.name}: ${message}`];
      }
    });
    expect(wrong).toEqual([]);
  });

  it('round-trips through JSON to 0.1 mm / 1e-6', () => {
    const r = scripted();
    const back = decodeRecording(encodeRecordingJson(r), 'test.json');
    expect(back.frames).toBe(r.frames);
    expect(back.meta).toEqual({ device: 'test', rate: 72 });
    expect(back.time[0]).toBe(0);
    expect(Array.from(back.tracked)).toEqual(Array.from(r.tracked));
    for (let i = 0; i < r.position.length; i++) expect(Math.abs(back.position[i] - r.position[i])).toBeLessThan(1e-5);
    for (let i = 0; i < r.rotation.length; i++) expect(Math.abs(back.rotation[i] - r.rotation[i])).toBeLessThan(1e-6);
  });

  it('carries optional ground truth in JSON and rejects a truth of the wrong length', () => {
    const r = scripted(72, 1);
    const truth = { bodyYaw: Float64Array.from({ length: r.frames }, (_, i) => i * 0.01), root: new Float64Array(2 * r.frames).fill(0.5) };
    const back = decodeRecording(encodeRecordingJson({ ...r, truth }), 'truth.json');
    expect(back.truth?.bodyYaw.length).toBe(r.frames);
    expect(back.truth?.bodyYaw[10]).toBeCloseTo(0.1, 5);
    expect(back.truth?.root[3]).toBe(0.5);
    expect(decodeRecording(encodeRecordingJson(r)).truth).toBeUndefined();
    const bad = JSON.parse(encodeRecordingJson({ ...r, truth })) as { truth: { root: number[] } };
    bad.truth.root.pop();
    expect(() => decodeRecording(JSON.stringify(bad), 'bad.json')).toThrow(/bad\.json: truth\.root has \d+ values/);
  });

  it('round-trips through the binary encoding (float32 poses), and from bytes of JSON', () => {
    const r = scripted(90);
    const bytes = encodeRecordingBinary(r);
    expect(bytes.length).toBeLessThan(r.frames * 110 + 100);
    const back = decodeRecording(bytes, 'test.mmtr');
    expect(back.frames).toBe(r.frames);
    expect(Array.from(back.time)).toEqual(Array.from(r.time));
    for (let i = 0; i < r.position.length; i++) expect(Math.abs(back.position[i] - r.position[i])).toBeLessThan(1e-6);
    expect(Array.from(back.tracked)).toEqual(Array.from(r.tracked));
    expect(decodeRecording(new TextEncoder().encode(encodeRecordingJson(r))).frames).toBe(r.frames);
  });

  it('carries the tracked body: recorded when tracked, JSON and binary (version 2) round trips, replayed by joint name', () => {
    const recorder = new TrackerRecorder(4);
    const s = new TrackerSample();
    for (let f = 0; f < 30; f++) {
      scriptedSample(f / 60, s);
      s.bodyTracked.fill(f >= 10 ? 1 : 0);
      for (let j = 0; j < NUM_BODY_JOINTS; j++) s.bodyPosition.set([0.1 * j, 0.9, -0.01 * f], 3 * j);
      recorder.add(s);
    }
    const r = recorder.toRecording();
    expect(r.body?.joints).toEqual([...BODY_JOINTS]);
    expect(r.body?.tracked[9 * NUM_BODY_JOINTS]).toBe(0);
    for (const back of [decodeRecording(encodeRecordingJson(r), 'b.json'), decodeRecording(encodeRecordingBinary(r), 'b.mmtr')]) {
      expect(back.body?.joints).toEqual([...BODY_JOINTS]);
      expect(Array.from(back.body!.tracked)).toEqual(Array.from(r.body!.tracked));
      for (let i = 0; i < r.body!.position.length; i++) expect(Math.abs(back.body!.position[i] - r.body!.position[i])).toBeLessThan(1e-5);
    }
    expect(new DataView(encodeRecordingBinary(r).buffer).getUint32(4, true)).toBe(2);
    expect(new DataView(encodeRecordingBinary(scripted(30, 1)).buffer).getUint32(4, true)).toBe(1);
    // Never tracked: no body at all. Replayed: joints found by name, whatever the recording's order.
    expect(scripted(30, 1).body).toBeUndefined();
    const reordered = { ...r, body: { ...r.body!, joints: [...BODY_JOINTS].reverse() } };
    const out = new TrackerSample();
    new RecordingPlayer(reordered).sampleAt(20 / 60, out);
    expect(out.bodyTracked[HIPS]).toBe(1);
    expect(out.bodyPosition[3 * HIPS]).toBeCloseTo(0.1 * (NUM_BODY_JOINTS - 1), 6);
    new RecordingPlayer(r).sampleAt(5 / 60, out);
    expect(Array.from(out.bodyTracked)).toEqual(new Array(NUM_BODY_JOINTS).fill(0));
  });

  it('rejects bad files with messages that say what is wrong', () => {
    const good = JSON.parse(encodeRecordingJson(scripted(30, 1)));
    const bad = (patch: object) => JSON.stringify({ ...good, ...patch });
    expect(() => decodeRecording('{', 'a.json')).toThrow(/^a\.json: not JSON/);
    expect(() => decodeRecording('[]', 'a.json')).toThrow(/expected a JSON object/);
    expect(() => decodeRecording(bad({ format: 'x' }))).toThrow(/"format" must be "mm-vr-recording"/);
    expect(() => decodeRecording(bad({ version: 2 }))).toThrow(/unsupported version 2/);
    expect(() => decodeRecording(bad({ frames: 5 }))).toThrow(/time has 31 values, expected frames × 1 = 5/);
    expect(() => decodeRecording(bad({ position: good.position.slice(1) }))).toThrow(/position has/);
    expect(() => decodeRecording(bad({ time: [1, ...good.time.slice(1)] }))).toThrow(/time must increase/);
    expect(() => decodeRecording(bad({ rotation: good.rotation.map((v: number) => v * 2) }))).toThrow(/not a unit quaternion/);
    expect(() => decodeRecording(bad({ tracked: good.tracked.map(() => 3) }))).toThrow(/must be 0 or 1/);
    expect(() => decodeRecording(bad({ time: good.time.map((v: number, i: number) => (i === 3 ? 'x' : v)) }))).toThrow(/"time"\[3\] is not a number/);
    const bytes = encodeRecordingBinary(scripted(30, 1));
    expect(() => decodeRecording(bytes.subarray(0, bytes.length - 1), 'b.mmtr')).toThrow(/^b\.mmtr: .* bytes, but a header of 31 frames/);
    const v2 = bytes.slice();
    v2[4] = 9;
    expect(() => decodeRecording(v2)).toThrow(/unsupported binary version 9/);
  });

  it('replays by interpolating between frames, at any rate', () => {
    const r = scripted(72);
    const player = new RecordingPlayer(r);
    const s = new TrackerSample();
    const direct = new TrackerSample();
    for (let t = 0; t < SCRIPT_DURATION; t += 1 / 90) {
      player.sampleAt(t, s);
      scriptedSample(t, direct);
      expect(Math.abs(s.position[3 * HEAD + 2] - direct.position[3 * HEAD + 2])).toBeLessThan(2e-3);
      expect(Math.hypot(s.rotation[0], s.rotation[1], s.rotation[2], s.rotation[3])).toBeCloseTo(1, 9);
    }
    // Past the end it holds the last frame; seeking backward works.
    player.sampleAt(1e9, s);
    expect(s.position[3 * HEAD + 2]).toBeCloseTo(r.position[(r.frames - 1) * 9 + 2], 9);
    player.sampleAt(0, s);
    expect(s.position[3 * HEAD + 2]).toBeCloseTo(r.position[2], 9);
    // A tracker missing at a frame is missing on both sides of it.
    player.sampleAt(r.time[7] - 0.001, s);
    expect(s.tracked[RIGHT]).toBe(0);
  });

  it('the recorder skips non-increasing times and refuses an empty recording', () => {
    const rec = new TrackerRecorder(2);
    expect(() => rec.toRecording()).toThrow(/nothing recorded/);
    const s = new TrackerSample();
    s.time = 1;
    rec.add(s);
    rec.add(s);
    s.time = 0.5;
    rec.add(s);
    expect(rec.frames).toBe(1);
  });
});
