"""The 54 network inputs from raw tracker poses (docs/method.md §9; thesis Eq. for x = (x^v, x^w,
x^r, x^d), plus where the hands are and where the head has been going), and the 6D output's
meaning. `docs/orientation-model.md` is the contract; `web/src/orientation/features.ts` computes
the same numbers in the browser.

Input vector, float32[54]:
    for tracker in (hmd, left controller, right controller):        12 floats each
        rotation 6D  = first two columns of R_H⁻¹·R_tracker         (6)
        velocity     = R_H⁻¹·(p_t − p_{t−1}) / dt                   (3, m/s)
        angular vel. = R_H⁻¹·rotvec(q_t · q_{t−1}⁻¹) / dt           (3, rad/s, world axis)
    previous body orientation, 6D of R_H⁻¹·R_body(prev)              (6)
    context:
        each controller relative to the headset, R_H⁻¹·(p_k − p_hmd)  (6, m)
        the headset's mean velocity over the last 0.25, 0.5 and 1 s, (x, z) of
        R_H⁻¹·(p_hmd,t − p_hmd,j) / (t − t_j)                         (6, m/s)
R_H is the pure yaw of the HMD (`geometry.hmd_yaw`) *of the current frame*: the thesis's frame
"HMD forward projected on the floor, world up, their cross product" — so a body that keeps
still while the head turns keeps a changing previous-slot value, and the network only ever sees
relative directions (independent of where the user faces in the room).

Why the context (leave-one-person-out, `npm run eval`): the thesis's inputs say how the devices
turn and move this frame, not where the hands are (held in front of the chest, they point the
torso's way) nor where the head has been going for the last second (a walker's hips face along
it; a glance does not move it). With them the held-out mean is 11.5° → 10.7° with look-around and
10.3° → 9.9° without, and the yaw's frame-to-frame jerk 2.46 → 1.83°/frame² (README). The hands'
own windowed velocities added nothing (11.1° / 10.4°). The first 42 inputs are the thesis's, in
the same order, so a 42-input model (before the context) still runs on the first 42.

Velocities are backward differences with the frame's real dt (Quest Browser runs 72/90/120 Hz),
so they are causal, as at run time. After a reset, or after a gap longer than `MAX_DT`, the
velocities and angular velocities are zero for that frame, and the windows start again there:
frame j is the oldest frame since then with t_j ≥ t − window (t: the sum of the dts since the
reset), so a window is shorter until that much time has passed, and zero on its first frame.

Output, 6D: first two columns of R_H⁻¹·R_body; for the pure-yaw body rotation it is
(cos φ, 0, −sin φ, 0, 1, 0) with φ = body yaw − HMD yaw. `relative_yaw_of_output` recovers φ.
"""

from __future__ import annotations

import numpy as np

from .geometry import hmd_yaw, quat_conj, quat_from_yaw, quat_mul, quat_to_matrix, quat_to_rotvec, rotate_y

NUM_TRACKERS = 3
TRACKER_FEATURES = 12
TRACKER_INPUTS = NUM_TRACKERS * TRACKER_FEATURES  # 36: what a recurrent model takes
PREV = slice(36, 42)
LEGACY_INPUTS = 42  # the thesis's inputs: a model from before the context takes these
CONTEXT_OFFSET = 42
CONTEXT_WINDOWS = (0.25, 0.5, 1.0)  # s: the headset's mean-velocity windows
CONTEXT_INPUTS = 6 + 2 * len(CONTEXT_WINDOWS)  # 12
NUM_INPUTS = CONTEXT_OFFSET + CONTEXT_INPUTS  # 54
FRAME_INPUTS = TRACKER_INPUTS + CONTEXT_INPUTS  # 48: every input but the previous slot
# Where a frame's features (`frame_features`, 48 wide) go in the input vector.
FRAME_COLUMNS = np.r_[0:TRACKER_INPUTS, CONTEXT_OFFSET:NUM_INPUTS]
MAX_DT = 0.25  # s; a longer gap (paused session, lost frames) is a discontinuity, not motion
# The head centre, the point a head turns about: this far behind the headset along its heading
# on the floor (web/src/vr/tracked-drive.ts HMD_TO_HEAD_CENTRE, MMVR's HMD = head + 0.10 m).
HMD_TO_HEAD_CENTRE = 0.1
HIPS_OUTPUTS = 2  # the second output: where the hips are, (x, z) from the head centre in the HMD-yaw frame
# The share of that offset the VR page's root target takes (tracked-drive.ts HIPS_GAIN): on people
# the network never saw its guess is half signal — the held-out replays' root distance is least at
# half of it (docs/vr.md, "Where the root goes").
HIPS_GAIN = 0.5

FEATURE_NAMES = [
    f"{t}.{k}"
    for t in ("hmd", "left", "right")
    for k in (
        "rot.c0.x",
        "rot.c0.y",
        "rot.c0.z",
        "rot.c1.x",
        "rot.c1.y",
        "rot.c1.z",
        "vel.x",
        "vel.y",
        "vel.z",
        "angvel.x",
        "angvel.y",
        "angvel.z",
    )
]
FEATURE_NAMES += ["prev.c0.x", "prev.c0.y", "prev.c0.z", "prev.c1.x", "prev.c1.y", "prev.c1.z"]
FEATURE_NAMES += [f"{t}.rel.{a}" for t in ("left", "right") for a in "xyz"]
FEATURE_NAMES += [f"hmd.vel{w:g}s.{a}" for w in CONTEXT_WINDOWS for a in "xz"]


def check_dt(dt: np.ndarray) -> None:
    dt = np.asarray(dt)
    bad = ~(np.isfinite(dt) & (dt > 0))
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"dt must be positive and finite seconds; frame {i} has dt = {dt.flat[i]!r}")


def yaw_slot(relative_yaw) -> np.ndarray:
    """6D of a pure yaw rotation by φ: (cos φ, 0, −sin φ, 0, 1, 0), shape (..., 6)."""
    phi = np.asarray(relative_yaw, dtype=np.float64)
    c, s, z = np.cos(phi), np.sin(phi), np.zeros_like(phi)
    return np.stack([c, z, -s, z, np.ones_like(phi), z], axis=-1)


def relative_yaw_of_output(out: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """φ from 6D outputs (..., 6), and whether it is usable (finite, not degenerate).

    Only the first column matters for a yaw: it is the body's +X axis in the HMD-yaw frame,
    (cos φ, ·, −sin φ), so φ = atan2(−c0.z, c0.x); its vertical part is ignored.
    """
    out = np.asarray(out, dtype=np.float64)
    c, s = out[..., 0], -out[..., 2]
    ok = np.isfinite(c) & np.isfinite(s) & (np.hypot(c, s) > 1e-6)
    return np.where(ok, np.arctan2(np.where(ok, s, 0.0), np.where(ok, c, 1.0)), 0.0), ok


def hips_target(hmd_pos: np.ndarray, yaw: np.ndarray, hips: np.ndarray) -> np.ndarray:
    """The second output's truth: the hips on the floor (n, 2) (x, z) relative to the head centre
    on the floor (`HMD_TO_HEAD_CENTRE` behind the headset `hmd_pos` (n, 3) along its yaw), in the
    HMD-yaw frame (+Z ahead, +X to the left) → (n, 2) metres."""
    d = np.zeros((len(yaw), 3))
    d[:, 0], d[:, 2] = hips[:, 0] - hmd_pos[:, 0], hips[:, 1] - hmd_pos[:, 2]
    local = rotate_y(d, -np.asarray(yaw))
    return np.stack([local[:, 0], local[:, 2] + HMD_TO_HEAD_CENTRE], axis=1)


def _rot6(q_rel: np.ndarray) -> np.ndarray:
    m = quat_to_matrix(q_rel)
    return np.concatenate([m[..., :, 0], m[..., :, 1]], axis=-1)


def tracker_features(pos: np.ndarray, rot: np.ndarray, dt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inputs 0..35 for a whole sequence, and the HMD yaw per frame.

    pos (n, 3, 3), rot (n, 3, 4) [frame, tracker (hmd, left, right), ...], dt (n,) seconds since
    the previous frame (dt[0] unused: frame 0 follows a reset). Returns ((n, 36), (n,)) float64.
    """
    pos, rot, dt = np.asarray(pos, np.float64), np.asarray(rot, np.float64), np.asarray(dt, np.float64)
    n = len(dt)
    if pos.shape != (n, NUM_TRACKERS, 3) or rot.shape != (n, NUM_TRACKERS, 4):
        raise ValueError(
            f"expected pos (n, 3, 3) and rot (n, 3, 4) for n = {n} frames, got {pos.shape} and {rot.shape}"
        )
    check_dt(dt[1:])
    rot = rot / np.linalg.norm(rot, axis=-1, keepdims=True)
    yaw = hmd_yaw(rot[:, 0])
    vel = np.zeros_like(pos)
    ang = np.zeros_like(pos)
    if n > 1:
        cont = (dt[1:] <= MAX_DT)[:, None, None]
        vel[1:] = np.where(cont, (pos[1:] - pos[:-1]) / dt[1:, None, None], 0.0)
        ang[1:] = np.where(cont, quat_to_rotvec(quat_mul(rot[1:], quat_conj(rot[:-1]))) / dt[1:, None, None], 0.0)
    inv = quat_from_yaw(-yaw)[:, None, :]
    out = np.concatenate(
        [
            _rot6(quat_mul(np.broadcast_to(inv, rot.shape), rot)),
            rotate_y(vel, -yaw[:, None]),
            rotate_y(ang, -yaw[:, None]),
        ],
        axis=-1,
    )  # (n, 3, 12)
    return out.reshape(n, 36), yaw


def window_starts(dt: np.ndarray, window: float) -> np.ndarray:
    """Per frame i, the frame j its window starts at: the oldest frame since the last reset or
    gap (frame 0, or a dt over `MAX_DT`) with t_j ≥ t_i − window. t is the running sum of dt[1:]
    (sequential, as the runtime adds it), so the browser finds the same j."""
    n = len(dt)
    t = np.concatenate([[0.0], np.cumsum(dt[1:])])
    restart = np.concatenate([[True], dt[1:] > MAX_DT])
    segment = np.maximum.accumulate(np.where(restart, np.arange(n), 0))
    return np.maximum(np.searchsorted(t, t - window, side="left"), segment), t


def context_features(pos: np.ndarray, yaw: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Inputs 42..53 for a whole sequence: pos (n, 3, 3), the HMD yaw (n,), dt (n,) → (n, 12)."""
    n = len(dt)
    rel = rotate_y(pos[:, 1:] - pos[:, :1], -yaw[:, None]).reshape(n, 6)
    cols = [rel]
    for w in CONTEXT_WINDOWS:
        j, t = window_starts(dt, w)
        span = t - t[j]
        v = (pos[:, 0] - pos[j, 0]) / np.where(span > 0.0, span, 1.0)[:, None]
        v = np.where((span > 0.0)[:, None], v, 0.0)
        cols.append(rotate_y(v, -yaw)[:, [0, 2]])
    return np.concatenate(cols, axis=1)


def frame_features(pos: np.ndarray, rot: np.ndarray, dt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every input but the previous slot, for a whole sequence: ((n, 48), HMD yaw (n,)) — inputs
    0..35 then 42..53 (`FRAME_COLUMNS` says where each goes)."""
    f, yaw = tracker_features(pos, rot, dt)
    pos, dt = np.asarray(pos, np.float64), np.asarray(dt, np.float64)
    return np.concatenate([f, context_features(pos, yaw, dt)], axis=1), yaw


class FeatureBuilder:
    """Frame-by-frame inputs, exactly as the runtime computes them (the reference for
    `features.ts`): `update` with the current poses and dt fills `x[0:36]` and `x[42:54]`; the
    caller sets the previous-orientation slot `x[36:42]` with `set_previous`."""

    def __init__(self):
        self.x = np.zeros(NUM_INPUTS, dtype=np.float32)
        self.hmd_yaw = 0.0
        self._pos = np.zeros((3, 3))
        self._rot = np.zeros((3, 4))
        self._has_prev = False
        self._t = 0.0
        self._history: list[tuple[float, np.ndarray]] = []  # (t, headset position) since the restart
        self.reset()

    def reset(self) -> None:
        """Forget the previous poses: the next frame has zero velocities; prev slot = HMD forward."""
        self._has_prev = False
        self._t = 0.0
        self._history.clear()
        self.x[:] = 0.0
        self.x[PREV] = yaw_slot(0.0)

    def update(self, pos: np.ndarray, rot: np.ndarray, dt: float) -> np.ndarray:
        pos, rot = np.asarray(pos, np.float64), np.asarray(rot, np.float64)
        if pos.shape != (3, 3) or rot.shape != (3, 4):
            raise ValueError(f"expected pos (3, 3) and rot (3, 4), got {pos.shape} and {rot.shape}")
        if not (np.isfinite(pos).all() and np.isfinite(rot).all()):
            raise ValueError("tracker poses must be finite")
        norms = np.linalg.norm(rot, axis=-1, keepdims=True)
        if (norms < 1e-6).any():
            raise ValueError("tracker quaternion has zero length")
        rot = rot / norms
        if self._has_prev:
            check_dt(np.array([dt]))
        moving = self._has_prev and dt <= MAX_DT
        yaw = float(hmd_yaw(rot[0]))
        inv = quat_from_yaw(-yaw)
        for k in range(3):
            base = 12 * k
            self.x[base : base + 6] = _rot6(quat_mul(inv, rot[k]))
            if moving:
                v = (pos[k] - self._pos[k]) / dt
                w = quat_to_rotvec(quat_mul(rot[k], quat_conj(self._rot[k]))) / dt
                self.x[base + 6 : base + 9] = rotate_y(v, -yaw)
                self.x[base + 9 : base + 12] = rotate_y(w, -yaw)
            else:
                self.x[base + 6 : base + 12] = 0.0
        if self._has_prev:
            self._t += dt
        if not moving:
            self._history.clear()  # a reset or a gap: the windows start again here
        self._history.append((self._t, pos[0].copy()))
        oldest = self._t - max(CONTEXT_WINDOWS)
        while self._history[0][0] < oldest:  # never needed again: t only grows
            self._history.pop(0)
        rel = rotate_y(pos[1:] - pos[:1], -yaw)
        self.x[CONTEXT_OFFSET : CONTEXT_OFFSET + 6] = rel.reshape(6)
        for i, w in enumerate(CONTEXT_WINDOWS):
            tj, pj = next(h for h in self._history if h[0] >= self._t - w)
            span = self._t - tj
            v = rotate_y((pos[0] - pj) / span, -yaw) if span > 0.0 else np.zeros(3)
            self.x[CONTEXT_OFFSET + 6 + 2 * i : CONTEXT_OFFSET + 8 + 2 * i] = v[[0, 2]]
        self._pos[:], self._rot[:] = pos, rot
        self._has_prev = True
        self.hmd_yaw = yaw
        return self.x

    def set_previous(self, relative_yaw: float) -> None:
        self.x[PREV] = yaw_slot(relative_yaw)
