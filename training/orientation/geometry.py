"""Rotation helpers (numpy, float64, vectorized over leading axes).

Conventions are the project's (DESIGN.md): right-handed, Y up, metres, quaternions `(x, y, z, w)`,
and a *yaw* is the angle about +Y with 0 = facing +Z, so `forward = (sin yaw, 0, cos yaw)` and
`yaw = atan2(forward.x, forward.z)` (as `Quat::from_rotation_y(yaw)` in wasm-core).
`quat_mul` / `quat_rotate` are the `.mmdb` reader's, so FK and the simulation share one definition.
"""

from __future__ import annotations

import numpy as np

from mmdb import quat_mul, quat_rotate  # noqa: F401  (re-exported)

UP = np.array([0.0, 1.0, 0.0])


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Inverse of a unit quaternion."""
    q = np.asarray(q, dtype=np.float64)
    return np.concatenate([-q[..., :3], q[..., 3:]], axis=-1)


def quat_normalize(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_from_yaw(yaw) -> np.ndarray:
    """Pure rotation about +Y by `yaw` radians."""
    yaw = np.asarray(yaw, dtype=np.float64)
    z = np.zeros_like(yaw)
    return np.stack([z, np.sin(0.5 * yaw), z, np.cos(0.5 * yaw)], axis=-1)


def quat_from_axis_angle(axis, angle) -> np.ndarray:
    axis = np.asarray(axis, dtype=np.float64)
    angle = np.asarray(angle, dtype=np.float64)
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    return np.concatenate([axis * np.sin(0.5 * angle)[..., None], np.cos(0.5 * angle)[..., None]], axis=-1)


def quat_from_rotvec(v: np.ndarray) -> np.ndarray:
    """Quaternion of a rotation vector (axis × angle)."""
    v = np.asarray(v, dtype=np.float64)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    # sin(a/2)/a -> 1/2 as a -> 0; the guarded division keeps tiny vectors exact.
    s = np.where(angle > 1e-12, np.sin(0.5 * angle) / np.maximum(angle, 1e-300), 0.5)
    return np.concatenate([v * s, np.cos(0.5 * angle)], axis=-1)


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vector (axis × angle, angle in [0, π]) of a unit quaternion: the shorter way round."""
    q = np.asarray(q, dtype=np.float64)
    q = np.where(q[..., 3:] < 0.0, -q, q)
    xyz, w = q[..., :3], q[..., 3:]
    n = np.linalg.norm(xyz, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(n, w)
    # angle/n -> 2/w for small rotations (w ~ 1); both branches are finite.
    scale = np.where(n > 1e-12, angle / np.maximum(n, 1e-300), 2.0 / np.maximum(w, 1e-12))
    return xyz * scale


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3); column k is the image of the k-th basis vector."""
    q = np.asarray(q, dtype=np.float64)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit quaternion of one 3×3 rotation matrix (columns = rotated basis), w >= 0."""
    m = np.asarray(m, dtype=np.float64)
    if m.shape != (3, 3):
        raise ValueError(f"matrix_to_quat expects one 3x3 matrix, got shape {m.shape}")
    t = np.trace(m)
    # Shepperd: divide by the largest of the four candidates for numerical safety.
    if t > 0:
        s = 2.0 * np.sqrt(1.0 + t)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    q = np.array(q)
    return quat_normalize(q if q[3] >= 0 else -q)


def quat_from_basis(x_axis, y_axis, z_axis) -> np.ndarray:
    """Quaternion of the rotation taking the world basis to the given orthonormal columns."""
    m = np.stack([x_axis, y_axis, z_axis], axis=-1)
    if not np.allclose(m.T @ m, np.eye(3), atol=1e-6) or np.linalg.det(m) < 0:
        raise ValueError("quat_from_basis: axes are not a right-handed orthonormal basis")
    return matrix_to_quat(m)


def quat_hemisphere(q: np.ndarray, axis: int = 0) -> np.ndarray:
    """Flip signs along `axis` (time) so consecutive quaternions lie in one hemisphere."""
    q = np.array(q, dtype=np.float64, copy=True)
    q = np.moveaxis(q, axis, 0)
    for i in range(1, len(q)):
        flip = np.sum(q[i] * q[i - 1], axis=-1) < 0
        q[i][flip] *= -1
    return np.moveaxis(q, 0, axis)


def nlerp(q0: np.ndarray, q1: np.ndarray, t) -> np.ndarray:
    """Normalized lerp on the shorter arc. Between mocap frames (≤ 8.3 ms apart, a few degrees)
    it differs from slerp by < 1e-5 rad, far below tracker noise."""
    q0, q1 = np.asarray(q0, dtype=np.float64), np.asarray(q1, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]
    q1 = np.where(np.sum(q0 * q1, axis=-1, keepdims=True) < 0, -q1, q1)
    return quat_normalize((1.0 - t) * q0 + t * q1)


def wrap_angle(a):
    """Angles mapped to [-π, π)."""
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2.0 * np.pi) - np.pi


def yaw_of_direction(v: np.ndarray) -> np.ndarray:
    """Yaw (0 = +Z) of the floor projection of direction vectors."""
    v = np.asarray(v, dtype=np.float64)
    return np.arctan2(v[..., 0], v[..., 2])


def hmd_yaw(q_hmd: np.ndarray) -> np.ndarray:
    """The HMD's yaw: the floor projection of where it looks (WebXR views look down local −Z).

    The thesis projects the HMD's forward direction d onto the floor; that vanishes when looking
    straight up or down. Adding −d_y times the floor projection of the HMD's up vector u fixes
    it: for a head without roll, d = cos α·h + sin α·Y and u = −sin α·h + cos α·Y (h the
    horizontal heading, α the pitch), so proj(d) − d_y·proj(u) = (cos α + sin² α)·h, which
    points along h with length ≥ 1 for every |α| ≤ 90°. Without roll it is exactly the
    thesis's direction; with roll it stays defined and continuous.
    """
    d = quat_rotate(q_hmd, np.array([0.0, 0.0, -1.0]))
    u = quat_rotate(q_hmd, UP)
    fx = d[..., 0] - d[..., 1] * u[..., 0]
    fz = d[..., 2] - d[..., 1] * u[..., 2]
    return np.arctan2(fx, fz)


def rotate_y(v: np.ndarray, yaw) -> np.ndarray:
    """Rotate vectors about +Y by `yaw` (broadcast over leading axes)."""
    v = np.asarray(v, dtype=np.float64)
    c, s = np.cos(yaw), np.sin(yaw)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([c * x + s * z, y, -s * x + c * z], axis=-1)
