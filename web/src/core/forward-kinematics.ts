/**
 * Forward kinematics of one pose in TypeScript, allocation-free: joint 0's local transform is
 * its world transform; `rot[j] = rot[p]·local[j]`, `pos[j] = pos[p] + rot[p]·t[j]` — the same
 * rule as the Rust core (docs/mmdb-format.md), for drawing poses the runtime writes.
 */
export function forwardKinematics(
  parents: Int32Array,
  localPositions: Float32Array,
  localRotations: Float32Array,
  outPositions: Float32Array,
  outRotations: Float32Array,
): void {
  const n = parents.length;
  for (let j = 0; j < n; j++) {
    const p = parents[j];
    const lx = localPositions[3 * j], ly = localPositions[3 * j + 1], lz = localPositions[3 * j + 2];
    const qx = localRotations[4 * j], qy = localRotations[4 * j + 1], qz = localRotations[4 * j + 2], qw = localRotations[4 * j + 3];
    if (p < 0) {
      outPositions[3 * j] = lx;
      outPositions[3 * j + 1] = ly;
      outPositions[3 * j + 2] = lz;
      outRotations[4 * j] = qx;
      outRotations[4 * j + 1] = qy;
      outRotations[4 * j + 2] = qz;
      outRotations[4 * j + 3] = qw;
      continue;
    }
    const px = outRotations[4 * p], py = outRotations[4 * p + 1], pz = outRotations[4 * p + 2], pw = outRotations[4 * p + 3];
    // Rotate the local offset by the parent's rotation: v + 2w(u×v) + 2u×(u×v).
    const tx = 2 * (py * lz - pz * ly), ty = 2 * (pz * lx - px * lz), tz = 2 * (px * ly - py * lx);
    outPositions[3 * j] = outPositions[3 * p] + lx + pw * tx + (py * tz - pz * ty);
    outPositions[3 * j + 1] = outPositions[3 * p + 1] + ly + pw * ty + (pz * tx - px * tz);
    outPositions[3 * j + 2] = outPositions[3 * p + 2] + lz + pw * tz + (px * ty - py * tx);
    // Parent · local (Hamilton product).
    outRotations[4 * j] = pw * qx + px * qw + py * qz - pz * qy;
    outRotations[4 * j + 1] = pw * qy - px * qz + py * qw + pz * qx;
    outRotations[4 * j + 2] = pw * qz + px * qy - py * qx + pz * qw;
    outRotations[4 * j + 3] = pw * qw - px * qx - py * qy - pz * qz;
  }
}
