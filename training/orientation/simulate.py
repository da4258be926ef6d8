"""Simulated VR trackers from mocap, with the augmentations a VR user needs (docs/method.md §9).

A `MocapClip` (world transforms at 120 fps) becomes a `TrackerSequence`: what WebXR would report
each frame in a `local-floor` reference space — headset and two controller grip poses
(positions in metres, quaternions (x, y, z, w), Y up), the frame's real `dt`, and the ground
truth body yaw (the virtual root's, 0 = +Z).

Devices (thesis: fixed offsets between head/wrists and trackers; randomized here a little):
- HMD = head joint + ~0.10 m forward, oriented as a WebXR viewer (looks down its −Z).
- Controller = hand (wrist) joint + ~0.175 m along the hand, oriented as a WebXR grip space.

Augmentations, each drawn per sequence from `Augment`:
- frame rate 72/90/120 Hz (Quest Browser) with dropped frames (dt doubles), velocities use the
  actual dt; playback speed 0.8–1.25× (time scaling: slower and faster people);
- looking around: a smooth random head yaw relative to the body up to ±90° in training (±60°
  in the evaluation) and some pitch,
  rotating the HMD about the head joint — the case where HMD-forward fails;
- random global yaw and position (the features must not care; a test checks they don't);
- mirroring: the builder's mirrored clips (`data.load_clips`);
- tracker noise (position and rotation jitter), random device offsets;
- a controller put down: from a random time on its pose stays frozen (hand at rest / lost).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .data import MocapClip
from .geometry import (
    hmd_yaw,
    nlerp,
    quat_conj,
    quat_from_axis_angle,
    quat_from_rotvec,
    quat_from_yaw,
    quat_mul,
    quat_rotate,
    rotate_y,
)

DEG = np.pi / 180.0

# An absent controller's pose on the VR page (web/src/vr/trackers.ts DEFAULT_TRACKER_OPTIONS):
# at the side of the head's heading, hangSide out, hangForward ahead, at hangHeight × head height.
HANG_SIDE, HANG_HEIGHT, HANG_FORWARD = 0.2, 0.5, 0.05


def hanging_pose(head_pos: np.ndarray, head_rot: np.ndarray, tracker: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions and rotations (n, 3) / (n, 4) the VR page shows for absent controller
    `tracker` (1 left, 2 right) under a headset at `head_pos`, `head_rot` (n, 3) / (n, 4)."""
    yaw = hmd_yaw(head_rot)
    side = HANG_SIDE if tracker == 1 else -HANG_SIDE  # left is +X when facing +Z
    local = np.stack([np.full_like(yaw, side), np.zeros_like(yaw), np.full_like(yaw, HANG_FORWARD)], axis=-1)
    pos = head_pos + rotate_y(local, yaw)
    pos[:, 1] = head_pos[:, 1] * HANG_HEIGHT
    return pos, quat_from_yaw(yaw + np.pi)  # the back of the hand outward, thumb forward


TRACKERS = ("hmd", "left", "right")


@dataclass(frozen=True)
class Augment:
    """Ranges of the per-sequence random choices (angles in degrees, lengths in metres)."""

    fps: tuple[float, ...] = (72.0, 90.0, 120.0)
    speed: tuple[float, float] = (0.8, 1.25)  # playback rate, drawn log-uniformly
    dropped_frame_prob: float = 0.02
    look_around: bool = True
    look_prob: float = 1.0  # share of the sequences that look around (drawn only when < 1)
    look_yaw_max: float = 60.0
    look_pitch: tuple[float, float] = (-35.0, 20.0)  # down, up
    look_hold: tuple[float, float] = (0.3, 2.5)  # seconds between new look targets (log-uniform)
    look_halflife: tuple[float, float] = (0.12, 0.3)  # spring half-life: a 120° turn peaks ≤ ~510°/s
    look_ahead_prob: float = 0.3  # chance that a new target is "straight ahead"
    global_yaw: bool = True
    noise_pos: tuple[float, float] = (0.0, 0.0007)  # per-sequence sigma range
    noise_rot: tuple[float, float] = (0.0, 0.2)
    frozen_prob: float = 0.15  # per controller and sequence
    # An absent controller (asleep, hands free): per controller and sequence, from a random time
    # on (or the whole take), the pose the VR page feeds the network instead (`hanging_pose`).
    absent_prob: float = 0.0
    # Arms doing something else (training only): per controller and sequence, the chance that
    # its pose blends, by a smooth random weight, toward a wandering random pose near the body.
    arms_prob: float = 0.0
    arms_box: tuple = ((-0.6, 0.6), (-0.9, 0.25), (-0.25, 0.6))  # body frame from the head: lateral, up, forward (m)
    arms_hold: tuple[float, float] = (0.3, 3.0)
    arms_halflife: tuple[float, float] = (0.1, 0.3)
    arms_idle_prob: float = 0.3  # chance that a new blend target is 0 (the real arm)
    hmd_forward: float = 0.10
    hmd_jitter: float = 0.02
    hmd_rot_jitter: float = 3.0
    controller_length: float = 0.175
    controller_jitter: float = 0.025
    controller_rot_jitter: float = 6.0
    # How a person holds the controllers and wears the headset, drawn per sequence (degrees): each
    # grip turned about each of its axes by up to `grip_rot_max` (the left grip mirrored), the
    # headset pitched on the face by up to `hmd_pitch_max`. `grip_rot` / `hmd_pitch` instead fix
    # them (the device-variation table); the left grip gets (x, −y, −z), the mirror image.
    grip_rot_max: float = 0.0
    hmd_pitch_max: float = 0.0
    grip_rot: tuple[float, float, float] | None = None
    hmd_pitch: float | None = None
    hmd_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m, in the viewer frame, added
    # The person's size: every position scaled about the floor so the upright head stands at a
    # height drawn from this range (m), or None for the mocap's own.
    head_height: tuple[float, float] | None = None


# Training looks further around (±90°) than the evaluation's ±60°: people glance over their
# shoulder, and a head already turned (held-out subject 03's head segment sits ~40° off its
# hips while it walks loops) plus a ±60° glance reaches ~100°. Trained at ±60°, the held-out
# error was 12–31° whenever the head was more than 75° off the body; at ±90° it is 7–20°.
#
# Arms: the mocap's arms swing with the gait (or carry a style: 100STYLE's Angry fists), and a
# network trained on them alone reads the body's facing off the hands. Held out, hands on hips
# (100STYLE Akimbo) or directing traffic (CMU 14) then looked like nothing it knew: 60° and 35°
# mean error (12-epoch runs: half the controllers wandering, 32° and 28°; all of them, most of
# the time, 26° and 24°). So every training controller wanders, 80% of the time, through random
# poses near the body (any orientation): the hands are one cue among others. (That was six
# people; the shipped recipe, trained on eighteen with the hands' place an input, lets only a
# quarter wander: `train.MODELS["main"]`.)
# absent_prob 0.25: a quarter of the controllers absent (hanging, as the VR page shows them) from
# some time on — npm run eval, one controller 29.8° → 26.4°, two 21.8° → 21.6°, headset only
# 30.5° → 31.3° (≈ the heuristics, 30.2°; one seed: ±1–2° is noise).
#
# How people hold controllers and wear headsets (grips turned up to ±30° about each axis, the
# headset pitched ±15° on the face) and their size (upright head 1.4–1.9 m): `npm run eval`,
# leave-one-person-out, 12.0° → 11.5° with look-around and 10.9° → 10.3° without, the error's
# spread across those grip and headset settings 1.1° → 1.4° (one seed each: ±0.5° is noise).
TRAIN_AUGMENT = Augment(
    look_yaw_max=90.0,
    arms_prob=1.0,
    arms_idle_prob=0.2,
    absent_prob=0.25,
    grip_rot_max=30.0,
    hmd_pitch_max=15.0,
    head_height=(1.4, 1.9),
)
# Evaluation: real motion at its real speed, plausible noise, no devices put down.
EVAL_AUGMENT = Augment(
    speed=(1.0, 1.0), dropped_frame_prob=0.01, frozen_prob=0.0, noise_pos=(0.0005, 0.0005), noise_rot=(0.1, 0.1)
)


@dataclass
class TrackerSequence:
    """Raw device poses as WebXR gives them, one row per frame."""

    name: str
    fps: float
    dt: np.ndarray  # (n,) seconds since the previous frame (dt[0]: nominal 1/fps)
    pos: np.ndarray  # (n, 3, 3) [frame, tracker (hmd, left, right), xyz]
    rot: np.ndarray  # (n, 3, 4) quaternions (x, y, z, w)
    body_yaw: np.ndarray  # (n,) ground truth, unwrapped radians, 0 = +Z
    look_yaw: np.ndarray = field(default=None)  # (n,) the added head yaw (0 without look-around)
    classes: np.ndarray = field(default=None)  # (n,) motion class per frame (motion_classes)
    subject: str = ""
    hips: np.ndarray = field(default=None)  # (n, 2) ground truth: the hips on the floor (x, z), the virtual root

    @property
    def num_frames(self) -> int:
        return len(self.dt)


def spring_process(
    times: np.ndarray,
    rng: np.random.Generator,
    low: float,
    high: float,
    hold: tuple[float, float],
    halflife: tuple[float, float],
    zero_prob: float,
) -> np.ndarray:
    """A smooth random signal in [low, high]: hold random targets for random durations and
    follow them with a critically damped spring (docs/method.md §4's exact step), as a person
    glances somewhere, holds, and looks elsewhere. Hold times are log-uniform in `hold`: quick
    glances and long stretches (watching something while walking) alike."""
    out = np.empty(len(times))
    hold_log = np.log(hold)
    x = rng.uniform(low, high) if rng.random() > zero_prob else 0.0
    v, target, switch = 0.0, x, times[0] + np.exp(rng.uniform(*hold_log))
    y = 2.0 * np.log(2.0) / rng.uniform(*halflife)
    prev_t = times[0]
    for i, t in enumerate(times):
        if t >= switch:
            target = 0.0 if rng.random() < zero_prob else rng.uniform(low, high)
            switch = t + np.exp(rng.uniform(*hold_log))
            y = 2.0 * np.log(2.0) / rng.uniform(*halflife)
        dt = t - prev_t
        j0 = x - target
        j1 = v + j0 * y
        e = np.exp(-y * dt)
        x = e * (j0 + j1 * dt) + target
        v = e * (v - j1 * y * dt)
        out[i] = min(max(x, low), high)
        prev_t = t
    return out


def _sample(clip: MocapClip, src_t: np.ndarray):
    """Clip transforms at source times (seconds), lerp/nlerp between the 120 fps frames."""
    f = np.clip(src_t * clip.fps, 0.0, clip.num_frames - 1.0)
    i0 = np.minimum(np.floor(f).astype(int), clip.num_frames - 2)
    a = f - i0
    lerp = lambda x: x[..., i0, :] + a[:, None] * (x[..., i0 + 1, :] - x[..., i0, :])  # noqa: E731
    yaw = clip.body_yaw[i0] + a * (clip.body_yaw[i0 + 1] - clip.body_yaw[i0])
    head_pos = lerp(clip.head_pos)
    head_rot = nlerp(clip.head_rot[i0], clip.head_rot[i0 + 1], a)
    hand_pos = lerp(clip.hand_pos)
    hand_rot = np.stack([nlerp(clip.hand_rot[s, i0], clip.hand_rot[s, i0 + 1], a) for s in range(2)])
    return yaw, head_pos, head_rot, hand_pos, hand_rot, lerp(clip.root_pos)


def _random_rotation(rng: np.random.Generator, sigma_deg: float) -> np.ndarray:
    return quat_from_rotvec(rng.normal(0.0, sigma_deg * DEG, 3))


def simulate(
    clip: MocapClip, rng: np.random.Generator, aug: Augment = TRAIN_AUGMENT, fps: float | None = None
) -> TrackerSequence:
    """One randomized tracker sequence from a clip (`fps` forces the frame rate)."""
    if clip.num_frames < 2:
        raise ValueError(f"clip {clip.name} has {clip.num_frames} frame(s); at least 2 are needed")
    fps = float(fps if fps is not None else rng.choice(aug.fps))
    lo, hi = np.log(aug.speed[0]), np.log(aug.speed[1])
    speed = float(np.exp(rng.uniform(lo, hi))) if hi > lo else float(aug.speed[0])

    # Output clock: whole display frames, some dropped (the browser skips a frame: dt doubles).
    n_max = int(np.ceil(clip.seconds / speed * fps)) + 2
    steps = 1 + (rng.random(n_max) < aug.dropped_frame_prob)
    steps[0] = 0
    t = np.cumsum(steps) / fps
    t = t[t * speed <= clip.seconds + 1e-9]
    if len(t) < 2:
        raise ValueError(f"clip {clip.name} is too short for {fps} fps at speed {speed:.2f}")
    dt = np.diff(t, prepend=t[0] - 1.0 / fps)
    body_yaw, head_pos, head_rot, hand_pos, hand_rot, hips = _sample(clip, t * speed)
    classes = clip.classes[np.clip(np.rint(t * speed * clip.fps).astype(int), 0, clip.num_frames - 1)]
    rig = clip.rig
    n = len(t)
    if aug.head_height is not None and clip.upright_head > 0:
        lo, hi = aug.head_height
        k = (lo if lo == hi else rng.uniform(lo, hi)) / clip.upright_head  # no draw when fixed
        head_pos, hand_pos, hips = head_pos * k, hand_pos * k, hips * k
        # x, z too: a taller person's steps and reach are longer in proportion.

    # Devices on the body, with per-sequence offsets (how the headset sits, how the hand holds).
    hmd_nominal = quat_mul(head_rot, rig.hmd_align)
    hmd_local = np.array([0.0, 0.0, -aug.hmd_forward]) + rng.uniform(-aug.hmd_jitter, aug.hmd_jitter, 3)
    hmd_local = hmd_local + np.asarray(aug.hmd_offset)
    hmd_rot = quat_mul(hmd_nominal, _random_rotation(rng, aug.hmd_rot_jitter))
    pitch0 = (
        aug.hmd_pitch
        if aug.hmd_pitch is not None
        else (rng.uniform(-aug.hmd_pitch_max, aug.hmd_pitch_max) if aug.hmd_pitch_max > 0 else 0.0)
    )
    if pitch0:
        hmd_rot = quat_mul(hmd_rot, quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), pitch0 * DEG))
    hmd_pos = head_pos + quat_rotate(hmd_nominal, hmd_local)
    pos, rot = [hmd_pos], [hmd_rot]
    for s in range(2):
        length = aug.controller_length + rng.uniform(-aug.controller_jitter, aug.controller_jitter)
        local = rig.hand_axis[s] * length + quat_rotate(
            rig.grip_align[s], rng.uniform(-aug.controller_jitter, aug.controller_jitter, 3)
        )
        pos.append(hand_pos[s] + quat_rotate(hand_rot[s], local))
        grip = quat_mul(quat_mul(hand_rot[s], rig.grip_align[s]), _random_rotation(rng, aug.controller_rot_jitter))
        held = None
        if aug.grip_rot is not None:
            held = np.asarray(aug.grip_rot, dtype=float) * (1.0 if s == 1 else np.array([1.0, -1.0, -1.0]))
        elif aug.grip_rot_max > 0:
            held = rng.uniform(-aug.grip_rot_max, aug.grip_rot_max, 3)
        if held is not None and np.any(held):
            grip = quat_mul(grip, quat_from_rotvec(held * DEG))
        rot.append(grip)
    pos, rot = np.stack(pos, axis=1), np.stack(rot, axis=1)  # (n, 3, .)

    # Arms doing something else: blend toward a random pose wandering near the body.
    if aug.arms_prob > 0:
        for s in (1, 2):
            if rng.random() >= aug.arms_prob:
                continue
            w = spring_process(t, rng, 0.0, 1.0, aug.arms_hold, aug.arms_halflife, aug.arms_idle_prob)
            local = np.stack(
                [spring_process(t, rng, lo, hi, aug.arms_hold, aug.arms_halflife, 0.0) for lo, hi in aug.arms_box],
                axis=1,
            )
            anchor = head_pos + rotate_y(local, body_yaw)
            rv = np.stack(
                [spring_process(t, rng, -np.pi, np.pi, aug.arms_hold, aug.arms_halflife, 0.0) for _ in range(3)], axis=1
            )
            wander = quat_mul(quat_from_yaw(body_yaw), quat_from_rotvec(rv))
            pos[:, s] = pos[:, s] + w[:, None] * (anchor - pos[:, s])
            rot[:, s] = nlerp(rot[:, s], wander, w)

    # Looking around: turn the headset about the head joint, yaw in world, pitch in the view.
    look_yaw = np.zeros(n)
    if aug.look_around and (aug.look_prob >= 1.0 or rng.random() < aug.look_prob):
        m = aug.look_yaw_max * DEG
        look_yaw = spring_process(t, rng, -m, m, aug.look_hold, aug.look_halflife, aug.look_ahead_prob)
        pitch = spring_process(
            t, rng, aug.look_pitch[0] * DEG, aug.look_pitch[1] * DEG, aug.look_hold, aug.look_halflife, 0.5
        )
        new = quat_mul(
            quat_mul(quat_from_yaw(look_yaw), rot[:, 0]), quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), pitch)
        )
        delta = quat_mul(new, quat_conj(rot[:, 0]))
        pos[:, 0] = head_pos + quat_rotate(delta, pos[:, 0] - head_pos)
        rot[:, 0] = new

    # A controller put down (or tracking lost): its pose stays where it was from some time on.
    for s in (1, 2):
        if rng.random() < aug.frozen_prob:
            k0 = int(rng.integers(0, max(1, int(0.8 * n))))
            pos[k0:, s] = pos[k0, s]
            rot[k0:, s] = rot[k0, s]
    for s in (1, 2) if aug.absent_prob > 0 else ():  # no draw when off: the same sequences as before
        if rng.random() < aug.absent_prob:
            k0 = 0 if rng.random() < 0.5 else int(rng.integers(0, max(1, int(0.8 * n))))
            pos[k0:, s], rot[k0:, s] = hanging_pose(pos[k0:, 0], rot[k0:, 0], s)

    # Where the user stands in the room and which way the mocap faces are arbitrary.
    if aug.global_yaw:
        psi = rng.uniform(-np.pi, np.pi)
        offset = np.array([rng.uniform(-2, 2), 0.0, rng.uniform(-2, 2)])
        pos = rotate_y(pos, psi) + offset
        hips = rotate_y(hips, psi) + offset
        rot = quat_mul(quat_from_yaw(np.full((n, 3), psi)), rot)
        body_yaw = body_yaw + psi

    # Tracker noise: per-frame jitter, a sigma per sequence.
    sp, sr = rng.uniform(*aug.noise_pos), rng.uniform(*aug.noise_rot) * DEG
    if sp > 0:
        pos = pos + rng.normal(0.0, sp, pos.shape)
    if sr > 0:
        rot = quat_mul(rot, quat_from_rotvec(rng.normal(0.0, sr, (n, 3, 3))))
    return TrackerSequence(
        name=f"{clip.name} @{fps:g}Hz x{speed:.2f}",
        fps=fps,
        dt=dt,
        pos=pos,
        rot=rot,
        body_yaw=body_yaw,
        look_yaw=look_yaw,
        classes=classes,
        subject=clip.subject,
        hips=hips[:, [0, 2]],
    )


def without_look_around(aug: Augment) -> Augment:
    return replace(aug, look_around=False)
