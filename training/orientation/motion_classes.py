"""What the body is doing, frame by frame: the motion classes of the per-class evaluation and of
the data survey (docs/orientation-model.md, "Motion classes").

From the mocap ground truth of a clip (the virtual root: hips on the floor, smoothed facing; the
wrists; the head), per frame:

- **moving** (root speed ≥ 0.3 m/s over ±0.25 s): `forward`, `sideways` or `backward` by the
  angle between the travel direction and the facing: < 60°, 60–120°, > 120°;
- **in place** (root speed < 0.2 m/s): `turn_in_place` if the facing turns faster than 30°/s
  (over ±0.5 s); else `gesturing` if a wrist moves faster than 0.35 m/s relative to the root
  (over ±0.25 s) or is raised above the head minus 0.3 m; else `standing`;
- **crouching** (before all of the above): the head lower than `CROUCH_RATIO` of its height
  standing upright (the person's 90th percentile) — crouching, kneeling, bending over;
- `other`: 0.2–0.3 m/s (shuffling, starting, stopping) — scored in the overall numbers only.

The speed and angle thresholds are the ones the shared mocap's survey uses (its SOURCES.md),
so class durations here and there are comparable.
"""

from __future__ import annotations

import numpy as np

CLASSES = ("forward", "backward", "sideways", "turn_in_place", "standing", "gesturing", "crouching")
OTHER = -1

MOVING_SPEED = 0.3  # m/s
IN_PLACE_SPEED = 0.2  # m/s
TURN_RATE = np.radians(30.0)  # rad/s
HAND_SPEED = 0.35  # m/s, relative to the root
HAND_RAISED = 0.3  # m below the head
SPEED_WINDOW = 0.25  # s, half-width
TURN_WINDOW = 0.5  # s, half-width
CROUCH_RATIO = 0.8  # of the upright head height


def _central(x: np.ndarray, k: int, fps: float) -> np.ndarray:
    """(x[i + k] − x[i − k]) / (2k / fps), indices clamped to the clip (one-sided at the ends)."""
    n = len(x)
    i = np.arange(n)
    a, b = np.clip(i - k, 0, n - 1), np.clip(i + k, 0, n - 1)
    span = np.maximum(b - a, 1)[(...,) + (None,) * (x.ndim - 1)]
    return (x[b] - x[a]) * fps / span


def travel_of(root_pos: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Root speed on the floor (m/s) and direction of travel (yaw, 0 = +Z) per frame, over
    ±`SPEED_WINDOW`."""
    k = max(1, int(round(SPEED_WINDOW * fps)))
    v = _central(root_pos[:, [0, 2]], k, fps)
    return np.hypot(v[:, 0], v[:, 1]), np.arctan2(v[:, 0], v[:, 1])


def classify(
    root_pos: np.ndarray,
    body_yaw: np.ndarray,
    hand_pos: np.ndarray,
    head_pos: np.ndarray,
    fps: float,
    upright_head: float = 0.0,
) -> np.ndarray:
    """Class index per frame (into `CLASSES`, or `OTHER`).

    root_pos (n, 3) virtual-root position, body_yaw (n,) unwrapped facing (0 = +Z), hand_pos
    (2, n, 3) wrists, head_pos (n, 3); world, metres; `upright_head` the head's height standing
    (0: no crouching class).
    """
    n = len(body_yaw)
    k = max(1, int(round(SPEED_WINDOW * fps)))
    kt = max(1, int(round(TURN_WINDOW * fps)))
    speed, travel = travel_of(root_pos, fps)
    off = np.abs((travel - body_yaw + np.pi) % (2 * np.pi) - np.pi)
    turn = np.abs(_central(body_yaw, kt, fps))
    # Wrists in the root's frame (yaw only), their speed there, and their height under the head.
    c, s = np.cos(-body_yaw), np.sin(-body_yaw)
    rel = hand_pos - root_pos[None]
    rel = np.stack([c * rel[..., 0] + s * rel[..., 2], rel[..., 1], -s * rel[..., 0] + c * rel[..., 2]], axis=-1)
    hand_speed = np.max([np.linalg.norm(_central(rel[h], k, fps), axis=-1) for h in range(2)], axis=0)
    raised = np.max(hand_pos[..., 1], axis=0) > head_pos[:, 1] - HAND_RAISED

    out = np.full(n, OTHER, dtype=int)
    moving = speed >= MOVING_SPEED
    out[moving & (off < np.radians(60))] = CLASSES.index("forward")
    out[moving & (off >= np.radians(60)) & (off <= np.radians(120))] = CLASSES.index("sideways")
    out[moving & (off > np.radians(120))] = CLASSES.index("backward")
    still = speed < IN_PLACE_SPEED
    out[still & (turn > TURN_RATE)] = CLASSES.index("turn_in_place")
    calm = still & (turn <= TURN_RATE)
    gesture = (hand_speed > HAND_SPEED) | raised
    out[calm & gesture] = CLASSES.index("gesturing")
    out[calm & ~gesture] = CLASSES.index("standing")
    if upright_head > 0:
        out[head_pos[:, 1] < CROUCH_RATIO * upright_head] = CLASSES.index("crouching")
    return out


def with_crouching(clip) -> np.ndarray:
    """A clip's classes with `crouching` (its head under `CROUCH_RATIO` of its upright height)."""
    return classify(clip.root_pos, clip.body_yaw, clip.hand_pos, clip.head_pos, clip.fps, clip.upright_head)


def seconds_per_class(classes: np.ndarray, fps: float) -> dict[str, float]:
    out = {name: float((classes == i).sum() / fps) for i, name in enumerate(CLASSES)}
    out["other"] = float((classes == OTHER).sum() / fps)
    return out
