"""The 54 network inputs: frames, units, invariances, and the per-frame (runtime) builder
against the vectorized (training) one. No mocap needed: synthetic tracker motion."""

import numpy as np
import pytest

from orientation.features import (
    CONTEXT_OFFSET,
    CONTEXT_WINDOWS,
    MAX_DT,
    FeatureBuilder,
    frame_features,
    relative_yaw_of_output,
    tracker_features,
    yaw_slot,
)
from orientation.geometry import (
    hmd_yaw,
    quat_from_axis_angle,
    quat_from_rotvec,
    quat_from_yaw,
    quat_mul,
    quat_rotate,
    quat_to_rotvec,
    rotate_y,
    wrap_angle,
)

X = np.array([1.0, 0.0, 0.0])


def random_motion(n=200, seed=0, fps=90.0):
    """Smoothly moving and turning trackers (positions (n, 3, 3), quaternions (n, 3, 4), dt)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fps
    dt = np.full(n, 1.0 / fps)
    pos = np.zeros((n, 3, 3))
    rot = np.zeros((n, 3, 4))
    for k in range(3):
        a, f, ph = rng.uniform(0.1, 1.0, 3), rng.uniform(0.2, 2.0, 3), rng.uniform(0, 6, 3)
        pos[:, k] = a * np.sin(f * t[:, None] + ph) + [0.0, 1.5 - 0.5 * (k > 0), 0.0]
        w = rng.normal(0, 1.5, 3)
        rot[:, k] = quat_from_rotvec(np.outer(t, w) + rng.normal(0, 1, 3))
    return pos, rot, dt


def test_hmd_yaw_convention_and_robustness():
    # An HMD with yaw ψ looks along (sin ψ, 0, cos ψ): the viewer looks down local −Z, so its
    # rotation is R_y(ψ + π). Pitching up or down, even to ±90°, must not change the yaw.
    for psi in np.radians([-170, -90, -30, 0, 45, 120, 179]):
        base = quat_from_yaw(psi + np.pi)
        for pitch in np.radians([-90, -89.9, -60, 0, 30, 89.99, 90]):
            q = quat_mul(base, quat_from_axis_angle(X, pitch))
            assert abs(wrap_angle(hmd_yaw(q) - psi)) < 1e-9, (np.degrees(psi), np.degrees(pitch))
    # Without roll it is exactly the floor projection of the view direction.
    q = quat_mul(quat_from_yaw(0.7), quat_from_axis_angle(X, -0.4))
    d = quat_rotate(q, np.array([0, 0, -1.0]))
    assert abs(hmd_yaw(q) - np.arctan2(d[0], d[2])) < 1e-12


def test_yaw_slot_round_trip_and_garbage():
    phi = np.linspace(-3.1, 3.1, 50)
    back, ok = relative_yaw_of_output(yaw_slot(phi))
    assert ok.all() and np.allclose(back, phi, atol=1e-12)
    bad = np.array([[np.nan, 0, 0, 0, 1, 0], [0, 0, 0, 0, 1, 0], [np.inf, 0, 1, 0, 1, 0]])
    _, ok = relative_yaw_of_output(bad)
    assert not ok.any()
    # Scale does not matter, only the direction of (c0.x, c0.z).
    phi2, ok = relative_yaw_of_output(5.0 * yaw_slot(0.3))
    assert ok and abs(phi2 - 0.3) < 1e-12


def test_known_motion_in_the_hmd_frame():
    # HMD facing yaw ψ; a controller moving at v_world and spinning about world Y at ω.
    psi, fps, n = 0.8, 72.0, 5
    v_world, omega = np.array([0.3, -0.1, 1.2]), 2.0
    t = np.arange(n) / fps
    pos = np.zeros((n, 3, 3))
    pos[:, 1] = np.outer(t, v_world)
    rot = np.tile(quat_from_yaw(psi + np.pi), (n, 3, 1))
    rot[:, 1] = quat_from_yaw(omega * t)
    f, yaw = tracker_features(pos, rot, np.full(n, 1 / fps))
    assert np.allclose(yaw, psi)
    assert np.allclose(f[0, 18:24], 0.0), "frame 0 follows a reset: zero velocities"
    assert np.allclose(f[1:, 18:21], rotate_y(v_world, -psi), atol=1e-9)
    assert np.allclose(f[1:, 21:24], [0.0, omega, 0.0], atol=1e-9)
    # HMD rotation 6D in its own yaw frame is a pure R_y(π): c0 = (−1, 0, 0), c1 = (0, 1, 0).
    assert np.allclose(f[:, 0:6], [-1, 0, 0, 0, 1, 0], atol=1e-12)


def test_invariant_to_room_yaw_translation_and_quaternion_sign():
    pos, rot, dt = random_motion()
    f0, y0 = frame_features(pos, rot, dt)
    psi = 1.234
    pos2 = rotate_y(pos, psi) + np.array([3.0, 0.0, -2.0])
    rot2 = quat_mul(quat_from_yaw(np.full(rot.shape[:2], psi)), rot)
    rot2[::3] *= -1.0
    f1, y1 = frame_features(pos2, rot2, dt)
    assert np.allclose(f0, f1, atol=1e-9)
    assert np.allclose(wrap_angle(y1 - y0), psi)


def test_per_frame_builder_equals_vectorized():
    pos, rot, dt = random_motion(n=120, seed=3)
    dt[30] = 2 / 90  # dropped frame
    dt[60] = MAX_DT + 0.05  # pause: velocities restart from zero
    f, yaw = frame_features(pos, rot, dt)
    assert np.allclose(f[60, 6:12], 0.0) and np.allclose(f[60, 18:24], 0.0)
    assert np.allclose(f[60, 42:], 0.0), "the windows start again after a gap"
    fb = FeatureBuilder()
    for t in range(len(dt)):
        x = fb.update(pos[t], rot[t], dt[t])
        assert np.allclose(x[:36], f[t, :36], atol=2e-6, rtol=1e-6), t
        assert np.allclose(x[CONTEXT_OFFSET:], f[t, 36:], atol=2e-6, rtol=1e-6), t
        assert abs(fb.hmd_yaw - yaw[t]) < 1e-12
        assert np.allclose(x[36:42], yaw_slot(0.0)), "prev slot untouched by update (HMD forward after reset)"
    fb.set_previous(0.5)
    assert np.allclose(fb.x[36:42], yaw_slot(0.5))
    fb.reset()
    x = fb.update(pos[5], rot[5], 0.01)
    assert np.allclose(x[6:12], 0.0), "after reset the first frame has no velocity"


def test_context_hands_and_head_windows():
    # The headset walks at v (world) while facing yaw ψ; the hands are held at fixed offsets.
    psi, fps, n = -0.6, 90.0, 200
    v = np.array([0.4, 0.0, -1.1])
    t = np.arange(n) / fps
    pos = np.zeros((n, 3, 3))
    pos[:, 0] = np.outer(t, v) + [0.0, 1.6, 0.0]
    pos[:, 1] = pos[:, 0] + rotate_y(np.array([-0.25, -0.4, 0.3]), psi)
    pos[:, 2] = pos[:, 0] + rotate_y(np.array([0.2, -0.5, 0.35]), psi)
    rot = np.tile(quat_from_yaw(psi + np.pi), (n, 3, 1))
    f, _ = frame_features(pos, rot, np.full(n, 1 / fps))
    ctx = f[:, 36:]
    assert np.allclose(ctx[:, 0:3], [-0.25, -0.4, 0.3]) and np.allclose(ctx[:, 3:6], [0.2, -0.5, 0.35])
    local = rotate_y(v, -psi)[[0, 2]]
    assert np.allclose(ctx[0, 6:], 0.0), "frame 0 has no window"
    for i, w in enumerate(CONTEXT_WINDOWS):
        assert np.allclose(ctx[1:, 6 + 2 * i : 8 + 2 * i], local, atol=1e-9), w
    # A window over a stop and a start averages them: standing, then walking from frame 89. At
    # 95.3 Hz the 1-s window spans 95 frames (no frame sits exactly 1 s back).
    fps = 95.3
    pos2 = pos.copy()
    pos2[:, 0] = np.outer(np.maximum(np.arange(n) - 89, 0) / fps, v) + [0.0, 1.6, 0.0]
    f2, _ = frame_features(pos2, rot, np.full(n, 1 / fps))
    i = 89 + 45  # 45 frames into the walk: 45 of the 1-s window's 95 moved
    assert np.allclose(f2[i, 36 + 10 : 36 + 12], local * 45 / 95, atol=1e-9)
    assert np.allclose(f2[i, 36 + 6 : 36 + 8], local, atol=1e-9), "the 0.25-s window is all walk"


def test_angular_velocity_is_the_short_way_round():
    q0 = quat_from_yaw(np.radians(179.0))
    q1 = quat_from_yaw(np.radians(-179.0))
    w = quat_to_rotvec(quat_mul(q1, np.array([-q0[0], -q0[1], -q0[2], q0[3]])))
    assert np.allclose(w, [0, np.radians(2.0), 0])


def test_bad_input_is_rejected_with_a_message():
    pos, rot, dt = random_motion(n=10)
    bad = dt.copy()
    bad[4] = 0.0
    with pytest.raises(ValueError, match="frame 3 has dt"):
        tracker_features(pos, rot, bad)
    with pytest.raises(ValueError, match=r"pos \(n, 3, 3\)"):
        tracker_features(pos[:, :2], rot, dt)
    fb = FeatureBuilder()
    fb.update(pos[0], rot[0], 0.01)
    with pytest.raises(ValueError, match="dt must be positive"):
        fb.update(pos[1], rot[1], -0.01)
    with pytest.raises(ValueError, match="finite"):
        fb.update(np.full((3, 3), np.nan), rot[1], 0.01)
    with pytest.raises(ValueError, match="zero length"):
        fb.update(pos[1], np.zeros((3, 4)), 0.01)
