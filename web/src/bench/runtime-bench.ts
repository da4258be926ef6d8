/**
 * The character-update benchmark, shared by Node (`scripts/bench.mjs` through vite) and the
 * bench page in Chromium, with the same input script as `mmdb bench-runtime` (native): a
 * zig-zag, a backward run and a stop, each 2 s, at 60 Hz.
 */

import { createMoveInput } from '../core/drive.ts';
import { Crowd } from '../core/crowd.ts';
import { Database } from '../core/database.ts';

export interface RuntimeBenchResult {
  database: string;
  /** One character's full update (search, playback, inertialization, adjustment, foot lock). */
  update_ms_median: number;
  update_ms_p95: number;
  crowd_size: number;
  /** Median crowd update / crowd size. */
  crowd_ms_per_character: number;
  characters_in_4ms: number;
}

/** Input of step `step` (60 Hz): [moveX, moveZ, run]. */
function input(step: number): [number, number, boolean] {
  const phase = Math.floor(step / 120) % 4;
  const dir = ([[0.7, 0.7], [-0.7, 0.7], [0, -1], [0, 0]] as const)[phase];
  return [dir[0], dir[1], phase === 2];
}

/** Crowd updates run before the timed ones (see `benchRuntime`). */
const WARM_UP = 120;

const quantile = (sorted: number[], q: number): number => sorted[Math.min(sorted.length - 1, Math.floor(sorted.length * q))];

/** The update benchmark on the `.mmdb` `bytes` (the WASM module must be initialized). */
export function benchRuntime(database: string, bytes: Uint8Array, crowdSize = 256): RuntimeBenchResult {
  const db = Database.fromBytes(bytes, database);
  const one = new Crowd(db, 1);
  const move = createMoveInput();
  const set = (crowd: Crowd, i: number, step: number) => {
    [move.moveX, move.moveZ, move.run] = input(step);
    crowd.setInput(i, move);
  };
  const times: number[] = [];
  try {
    for (let step = 0; step < 3600; step++) {
      set(one, 0, step);
      const t = performance.now();
      one.update(1 / 60);
      times.push(performance.now() - t);
    }
  } finally {
    one.free();
  }
  times.sort((a, b) => a - b);

  const crowd = new Crowd(db, crowdSize);
  db.release(); // the crowds hold it
  const crowdTimes: number[] = [];
  try {
    // Timed after WARM_UP steps: a block of frames' velocities is derived the first time any
    // character plays one of them (Database::frame_velocities), once per database — work the
    // crowd's steady state does not do again, and that loading once did before any update.
    for (let step = 0; step < WARM_UP + 240; step++) {
      for (let i = 0; i < crowdSize; i++) set(crowd, i, step + 37 * i);
      const t = performance.now();
      crowd.update(1 / 60);
      if (step >= WARM_UP) crowdTimes.push(performance.now() - t);
    }
  } finally {
    crowd.free();
  }
  crowdTimes.sort((a, b) => a - b);
  const perCharacter = quantile(crowdTimes, 0.5) / crowdSize;
  return {
    database,
    update_ms_median: quantile(times, 0.5),
    update_ms_p95: quantile(times, 0.95),
    crowd_size: crowdSize,
    crowd_ms_per_character: perCharacter,
    characters_in_4ms: Math.floor(4 / perCharacter),
  };
}
