/**
 * The Hamilton product on plain numbers, for the VR modules' SoA arrays (no three.js objects in
 * the tracker pipeline): out[o..o+4] = a · b, quaternions as (x, y, z, w).
 */
export function mulQuat(out: { [i: number]: number }, o: number, ax: number, ay: number, az: number, aw: number, bx: number, by: number, bz: number, bw: number): void {
  out[o] = aw * bx + ax * bw + ay * bz - az * by;
  out[o + 1] = aw * by - ax * bz + ay * bw + az * bx;
  out[o + 2] = aw * bz + ax * by - ay * bx + az * bw;
  out[o + 3] = aw * bw - ax * bx - ay * by - az * bz;
}
