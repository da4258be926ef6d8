/**
 * Yaw helpers shared by the VR modules. Project convention (docs/method.md): Y up, forward +Z, and a
 * yaw of 0 faces +Z; a positive yaw turns +Z toward +X. three.js cameras (and so the WebXR viewer
 * pose) look along −Z, which is why the HMD's heading is taken from its −Z axis.
 */

/** Wraps an angle to (−π, π]. */
export function wrapAngle(a: number): number {
  const w = a - 2 * Math.PI * Math.floor((a + Math.PI) / (2 * Math.PI));
  return w === -Math.PI ? Math.PI : w;
}

/** Yaw (0 = +Z) of a horizontal direction (x, z). */
export function yawOf(x: number, z: number): number {
  return Math.atan2(x, z);
}

/**
 * Facing yaw (0 = +Z) of a body from the line between its left and right joints (hips or
 * shoulders), `(dx, dz)` = left − right on the floor: forward = (left − right) × up = (−dz, 0, dx),
 * the database builder's virtual-root rule.
 */
export function facingYaw(dx: number, dz: number): number {
  return Math.atan2(-dz, dx);
}

/**
 * Heading yaw of a head-mounted display with rotation (x, y, z, w): where its view direction
 * (−Z) points on the floor. Looking straight down or up the view direction has no horizontal
 * part, so the head's up axis fills in (it points forward when looking down, backward when
 * looking up): h = f_h − f_y·u_h stays well defined for every orientation but upside down.
 */
export function headingYaw(qx: number, qy: number, qz: number, qw: number): number {
  // f = R·(0, 0, −1), u = R·(0, 1, 0), from the rotation matrix columns.
  const fx = -(2 * (qx * qz + qw * qy));
  const fy = -(2 * (qy * qz - qw * qx));
  const fz = -(1 - 2 * (qx * qx + qy * qy));
  const ux = 2 * (qx * qy - qw * qz);
  const uz = 2 * (qy * qz + qw * qx);
  return Math.atan2(fx - fy * ux, fz - fy * uz);
}

/** Yaw (0 = +Z) of a rotation's +Z axis on the floor: the facing of a body-frame quaternion. */
export function bodyYaw(qx: number, qy: number, qz: number, qw: number): number {
  return Math.atan2(2 * (qx * qz + qw * qy), 1 - 2 * (qx * qx + qy * qy));
}
