// The runtime benchmarks' input script for Node (web/src/bench/runtime-bench.ts has the
// browser's): zig-zag, a backward run and a stop, 2 s each at 60 Hz; person `i` of a crowd
// plays it 37 steps after person `i − 1`. Returns `[x, z, run]` for step `step`.
export function crowdInput(step) {
  const phase = Math.floor(step / 120) % 4;
  const [x, z] = [[0.7, 0.7], [-0.7, 0.7], [0, -1], [0, 0]][phase];
  return [x, z, phase === 2];
}
