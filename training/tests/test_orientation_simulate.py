"""Tracker simulation sanity on real mocap (one small cmu-daz subject and one cmu-asf take set):
devices where they belong, WebXR frames, augmentations doing what they say."""

from dataclasses import replace

import numpy as np
import pytest

import mmdb
from orientation import data
from orientation.features import hips_target, tracker_features
from orientation.geometry import hmd_yaw, quat_mul, quat_rotate, rotate_y, wrap_angle
from orientation.simulate import EVAL_AUGMENT, TRAIN_AUGMENT, Augment, simulate, spring_process

QUIET = Augment(
    speed=(1.0, 1.0),
    dropped_frame_prob=0.0,
    look_around=False,
    global_yaw=False,
    noise_pos=(0.0, 0.0),
    noise_rot=(0.0, 0.0),
    frozen_prob=0.0,
    hmd_jitter=0.0,
    hmd_rot_jitter=0.0,
    controller_jitter=0.0,
    controller_rot_jitter=0.0,
)


@pytest.fixture(scope="module")
def clips(mocap, mmdb_cli):
    out = data.load_subjects([("cmu-daz", "05"), ("cmu-daz", "02")], mirrored=None, log=lambda *_: None)
    assert len(out) == 8 and sum(c.mirrored for c in out) == 4
    return out


def test_split_is_by_subject():
    assert not set(data.TRAIN_SUBJECTS) & set(data.TEST_SUBJECTS)
    # Held out: both CMU skeletons, a 100STYLE style, and CMU 14 (back- and side-steps, gestures).
    assert {f for f, _ in data.TEST_SUBJECTS} == {"cmu-asf", "cmu-daz", "100style"}
    assert ("cmu-asf", "14") in data.TEST_SUBJECTS
    # CMU Daz 02 and CMU ASF 02 are one person: both on the same side of the split.
    assert (("cmu-asf", "02") in data.TRAIN_SUBJECTS) == (("cmu-daz", "02") in data.TRAIN_SUBJECTS)


def test_rig_follows_the_webxr_frames(clips):
    rig = data.rig_of(mmdb.load(data.ensure_database("cmu-daz", "05", log=lambda *_: None)))
    # Rest pose faces +Z: the HMD (looking down its −Z) then looks along +Z, up is +Y.
    assert np.allclose(quat_rotate(rig.hmd_align, [0, 0, -1.0]), [0, 0, 1], atol=1e-6)
    assert np.allclose(quat_rotate(rig.hmd_align, [0, 1.0, 0]), [0, 1, 0], atol=1e-6)
    for s, sign in ((0, 1.0), (1, -1.0)):
        # Grip −Z forward (+Z), +Y back toward the elbow; +X out of the back of the right hand
        # and out of the palm of the left one (palms down in the T-pose: up for right, down for left).
        assert quat_rotate(rig.grip_align[s], [0, 0, -1.0])[2] > 0.9
        assert np.dot(quat_rotate(rig.grip_align[s], [0, 1.0, 0]), rig.hand_axis[s]) < -0.99
        assert quat_rotate(rig.grip_align[s], [1.0, 0, 0])[1] * sign < -0.9
    assert rig.hand_axis[0][0] > 0.9 and rig.hand_axis[1][0] < -0.9, "left hand on +X (facing +Z)"


@pytest.mark.parametrize("folder,subject", [("cmu-asf", "03"), ("cmu-daz", "12"), ("100style", "Angry")])
def test_headset_is_calibrated_from_the_walk(folder, subject, mocap, mmdb_cli):
    """Mocap head frames are off the face by a constant (CMU 03: +42° of yaw, 100STYLE: −45° of
    pitch at rest); the calibrated headset looks where the person walks, 10° down, no roll."""
    from orientation.motion_classes import CLASSES, travel_of

    path = data.ensure_database(folder, subject, log=lambda *_: None)
    rest = data.rig_of(mmdb.load(path))
    for side in (False, True):
        clips = data.load_clips(path, data.subject_name(folder, subject), mirrored=side)
        assert not np.allclose(clips[0].rig.hmd_align, rest.hmd_align, atol=1e-3)
        yaw_off, pitch = [], []
        for c in clips:
            walk = c.classes == CLASSES.index("forward")
            q = quat_mul(c.head_rot[walk], np.broadcast_to(c.rig.hmd_align, (walk.sum(), 4)))
            view = quat_rotate(q, np.broadcast_to([0, 0, -1.0], (walk.sum(), 3)))
            yaw_off.append(wrap_angle(hmd_yaw(q) - travel_of(c.root_pos, c.fps)[1][walk]))
            pitch.append(np.arcsin(view[:, 1]))
        assert abs(np.degrees(np.median(np.concatenate(yaw_off)))) < 4.0, (folder, subject, side)
        assert abs(np.degrees(np.median(np.concatenate(pitch))) + 10.0) < 4.0, (folder, subject, side)


def test_headset_calibration_needs_a_walk(clips):
    standing = replace(clips[0], root_pos=np.zeros_like(clips[0].root_pos))
    assert data.calibrate_headset([standing]) is None


def test_devices_sit_on_the_body(clips):
    rng = np.random.default_rng(0)
    for clip in clips:
        seq = simulate(clip, rng, QUIET, fps=120.0)
        n = min(seq.num_frames, clip.num_frames)
        # 120 Hz at speed 1 samples the database frames exactly.
        assert np.allclose(seq.body_yaw[:n], clip.body_yaw[:n])
        assert np.allclose(np.linalg.norm(seq.pos[:n, 0] - clip.head_pos[:n], axis=1), 0.10, atol=1e-6)
        for s in range(2):
            d = np.linalg.norm(seq.pos[:n, 1 + s] - clip.hand_pos[s, :n], axis=1)
            assert np.allclose(d, 0.175, atol=1e-6)
        # The HMD looks where the body faces (mean within 15°); walking goes forward.
        off = np.degrees(np.abs(wrap_angle(hmd_yaw(seq.rot[:, 0]) - seq.body_yaw)))
        assert off.mean() < 15.0, (clip.name, off.mean())
        for k in (1, 2) if "02_03" not in clip.name else ():  # 02_03 jogs: forearms up
            # Hands hang or swing beside the body, fist forward: grip −Z points forward (and up
            # as far as the elbow bends), on average, in the body's frame.
            fwd = rotate_y(quat_rotate(seq.rot[:, k], [0, 0, -1.0]), -seq.body_yaw).mean(0)
            assert fwd[2] > 0.25 and fwd[2] > abs(fwd[0]), (clip.name, k, fwd)
        v = np.diff(seq.pos[:, 0], axis=0) * 120
        v_mean = v[:, [0, 2]].mean(0)
        assert np.linalg.norm(v_mean) > 0.4, "these takes walk"


def test_frame_rates_speed_and_dropped_frames(clips):
    rng = np.random.default_rng(1)
    aug = replace(TRAIN_AUGMENT, dropped_frame_prob=0.2, speed=(1.25, 1.25))
    for fps in (72.0, 90.0, 120.0):
        seq = simulate(clips[0], rng, aug, fps=fps)
        steps = np.round(seq.dt * fps)
        assert set(np.unique(steps)) == {1.0, 2.0} and np.allclose(seq.dt, steps / fps)
        assert abs(seq.dt[1:].sum() * 1.25 - clips[0].seconds) < 2.5 / fps
    seqs = [simulate(clips[0], np.random.default_rng(i), TRAIN_AUGMENT) for i in range(30)]
    assert {s.fps for s in seqs} == {72.0, 90.0, 120.0}


def test_look_around_turns_only_the_headset(clips):
    rng = np.random.default_rng(2)
    base = replace(QUIET, look_around=True, look_pitch=(0.0, 0.0))
    seq = simulate(clips[0], rng, base, fps=120.0)
    assert np.abs(seq.look_yaw).max() <= np.radians(60.0) + 1e-9
    quiet = simulate(clips[0], np.random.default_rng(2), QUIET, fps=120.0)
    added = wrap_angle(hmd_yaw(seq.rot[:, 0]) - hmd_yaw(quiet.rot[:, 0]))
    assert np.allclose(added, seq.look_yaw, atol=1e-6)
    assert np.allclose(seq.pos[:, 1:], quiet.pos[:, 1:]) and np.allclose(seq.body_yaw, quiet.body_yaw)
    # The HMD turns about the head joint: its distance to the head stays 0.10 m.
    n = min(seq.num_frames, clips[0].num_frames)
    assert np.allclose(np.linalg.norm(seq.pos[:n, 0] - clips[0].head_pos[:n], axis=1), 0.10, atol=1e-6)


def test_look_process_is_smooth_and_covers_the_range():
    t = np.arange(0, 600.0, 1 / 90)
    m = np.radians(60.0)
    a = spring_process(t, np.random.default_rng(3), -m, m, TRAIN_AUGMENT.look_hold, TRAIN_AUGMENT.look_halflife, 0.3)
    assert a.min() >= -m and a.max() <= m and a.min() < -0.9 * m and a.max() > 0.9 * m
    rate = np.degrees(np.abs(np.diff(a))) * 90
    # Fast voluntary head turns peak at a few hundred °/s: a spring, not a jump.
    assert 150.0 < rate.max() < 550.0, rate.max()
    assert (np.abs(a) > 0.5 * m).mean() > 0.2


def test_global_yaw_does_not_change_features_and_frozen_controller_stops(clips):
    aug = replace(EVAL_AUGMENT, noise_pos=(0.0, 0.0), noise_rot=(0.0, 0.0), global_yaw=False)
    a = simulate(clips[1], np.random.default_rng(5), aug, fps=72.0)
    b = simulate(clips[1], np.random.default_rng(5), replace(aug, global_yaw=True), fps=72.0)
    assert not np.allclose(a.pos, b.pos)
    fa, _ = tracker_features(a.pos, a.rot, a.dt)
    fb, _ = tracker_features(b.pos, b.rot, b.dt)
    assert np.allclose(fa, fb, atol=1e-7)
    frozen = simulate(clips[1], np.random.default_rng(6), replace(QUIET, frozen_prob=1.0), fps=72.0)
    f, _ = tracker_features(frozen.pos, frozen.rot, frozen.dt)
    assert np.allclose(frozen.pos[-1, 1:], frozen.pos[-2, 1:])
    assert np.allclose(f[-1, 12 + 6 : 12 + 12], 0.0) and np.allclose(f[-1, 24 + 6 : 24 + 12], 0.0)


def test_noise_is_there_but_small(clips):
    aug = replace(QUIET, noise_pos=(0.001, 0.001), noise_rot=(0.3, 0.3))
    noisy = simulate(clips[0], np.random.default_rng(7), aug, fps=90.0)
    clean = simulate(clips[0], np.random.default_rng(7), QUIET, fps=90.0)
    d = np.linalg.norm(noisy.pos - clean.pos, axis=-1)
    assert 0.0005 < d.mean() < 0.003


def test_how_the_devices_are_held_and_worn(clips):
    """The device-variation options: a fixed grip turn rotates each controller about its own
    axes (the left one mirrored) and nothing else; a headset pitch turns the headset about its
    x axis; a head height scales the person; none draws a random number when fixed."""
    clip = clips[0]
    clip.upright_head = float(np.percentile(clip.head_pos[:, 1], 90))
    base = simulate(clip, np.random.default_rng(3), QUIET, fps=90.0)

    def rel(a, b):  # rotation from b to a, in b's own frame: conj(b) · a
        return quat_mul(b * np.array([-1, -1, -1, 1.0]), a)

    turned = simulate(clip, np.random.default_rng(3), replace(QUIET, grip_rot=(0.0, 30.0, 0.0)), fps=90.0)
    assert np.allclose(turned.pos, base.pos) and np.allclose(turned.rot[:, 0], base.rot[:, 0])
    for s, sign in ((1, -1.0), (2, 1.0)):  # left mirrored: about its −y
        r = rel(turned.rot[:, s], base.rot[:, s])
        r *= np.sign(r[:, 3:4])
        assert np.allclose(r[:, 1], sign * np.sin(np.radians(15.0)), atol=1e-9), s
        assert np.allclose(r[:, [0, 2]], 0.0, atol=1e-9)
    pitched = simulate(clip, np.random.default_rng(3), replace(QUIET, hmd_pitch=15.0), fps=90.0)
    r = rel(pitched.rot[:, 0], base.rot[:, 0])
    r *= np.sign(r[:, 3:4])
    assert np.allclose(r[:, 0], np.sin(np.radians(7.5)), atol=1e-9) and np.allclose(pitched.rot[:, 1:], base.rot[:, 1:])
    tall = simulate(clip, np.random.default_rng(3), replace(QUIET, head_height=(1.9, 1.9)), fps=90.0)
    k = 1.9 / clip.upright_head
    assert np.allclose(tall.rot, base.rot)
    assert np.percentile(tall.pos[:, 0, 1], 90) == pytest.approx(np.percentile(base.pos[:, 0, 1], 90) * k, rel=0.02)


def test_the_hips_target_is_the_hips_from_the_head_centre_in_the_headset_frame(clips):
    """`features.hips_target`: the virtual root on the floor from the head centre (0.10 m behind
    the headset along its yaw), in the HMD-yaw frame — the same wherever the room puts the user
    (the simulation moves the hips with everything else), and a person's head sits a few cm in
    front of the hips while walking."""
    aug = replace(EVAL_AUGMENT, noise_pos=(0.0, 0.0), noise_rot=(0.0, 0.0), global_yaw=False)
    a = simulate(clips[1], np.random.default_rng(5), aug, fps=72.0)
    b = simulate(clips[1], np.random.default_rng(5), replace(aug, global_yaw=True), fps=72.0)
    assert not np.allclose(a.hips, b.hips)
    ta = hips_target(a.pos[:, 0], hmd_yaw(a.rot[:, 0]), a.hips)
    tb = hips_target(b.pos[:, 0], hmd_yaw(b.rot[:, 0]), b.hips)
    np.testing.assert_allclose(ta, tb, atol=1e-7)
    # In the body's frame (+Z ahead): the hips behind the head centre, by a walker's few cm.
    body = rotate_y(np.stack([ta[:, 0], np.zeros(len(ta)), ta[:, 1]], 1), hmd_yaw(a.rot[:, 0]) - a.body_yaw)
    assert -0.12 < np.median(body[:, 2]) < 0.01 and np.abs(np.median(body[:, 0])) < 0.05
    # Known geometry: a headset at the origin looking along +X (yaw π/2); hips 0.15 m behind it
    # and 0.2 m to its right (+Z) → 0.05 m behind the head centre, 0.2 m right (x = −0.2).
    t = hips_target(np.array([[0.0, 1.7, 0.0]]), np.array([np.pi / 2]), np.array([[-0.15, 0.2]]))
    np.testing.assert_allclose(t, [[-0.2, -0.05]], atol=1e-12)
