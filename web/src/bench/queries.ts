/**
 * Realistic motion-matching queries for the search benchmark: a database frame's features (the
 * pose part of the query is the current frame's, as in the runtime) with its trajectory turned
 * and its speed changed, as when the user steers somewhere else. Deterministic (seeded).
 */

import type { FeatureGroupInfo } from '../core/database.ts';

/** A query and the frame it was made from (the "current frame", excluded ±20 around it). */
export interface BenchQuery {
  readonly source: number;
  readonly values: Float32Array;
}

/** mulberry32: a tiny seeded PRNG, uniform in [0, 1). */
export function seededRandom(seed: number): () => number {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

/**
 * `count` queries from random valid frames of a row-major normalized `features` matrix: the
 * ground-plane (x, z) trajectory features are rotated about Y by up to ±135° and the
 * trajectory positions scaled by 0.6–1.4 (in raw units, then normalized again).
 */
export function realisticQueries(
  features: Float32Array,
  groups: readonly FeatureGroupInfo[],
  isValid: (frame: number) => boolean,
  count: number,
  seed: number,
): BenchQuery[] {
  const numDims = groups.reduce((n, g) => Math.max(n, g.dims[1]), 0);
  const numFrames = features.length / numDims;
  const random = seededRandom(seed);
  const queries: BenchQuery[] = [];
  for (let attempts = 0; queries.length < count && attempts < 100 * count; attempts++) {
    const source = Math.floor(random() * numFrames);
    if (!isValid(source)) continue;
    const values = features.slice(source * numDims, (source + 1) * numDims);
    const angle = (random() * 2 - 1) * 0.75 * Math.PI;
    const speed = 0.6 + 0.8 * random();
    const [c, s] = [Math.cos(angle), Math.sin(angle)];
    for (const g of groups) {
      if (!g.trajectory || g.axes !== 'xz') continue;
      const factor = g.kind === 'position' ? speed : 1;
      for (let d = g.dims[0]; d + 1 < g.dims[1]; d += 2) {
        const [mx, mz] = [g.mean[d - g.dims[0]], g.mean[d + 1 - g.dims[0]]];
        const x = values[d] * g.scale + mx;
        const z = values[d + 1] * g.scale + mz;
        values[d] = (factor * (c * x + s * z) - mx) / g.scale;
        values[d + 1] = (factor * (-s * x + c * z) - mz) / g.scale;
      }
    }
    queries.push({ source, values });
  }
  if (queries.length < count) throw new Error(`found only ${queries.length} valid frames to make queries from`);
  return queries;
}
