"""The motion classes of the per-class evaluation, on synthetic motion with known answers."""

import numpy as np

from orientation.motion_classes import CLASSES, OTHER, classify


def _run(velocity, yaw_rate=0.0, hands_speed=0.0, seconds=4.0, fps=60.0):
    n = int(seconds * fps)
    t = np.arange(n) / fps
    yaw = yaw_rate * t
    root = np.zeros((n, 3))
    root[:, 0], root[:, 2] = velocity[0] * t, velocity[1] * t
    head = root + np.array([0.0, 1.6, 0.0])
    hands = np.stack([root + np.array([0.2, 0.9, 0.0]), root + np.array([-0.2, 0.9, 0.0])])
    # A hand circling at `hands_speed` (radius 0.15 m) in front of the body.
    w = hands_speed / 0.15
    hands[0, :, 0] += 0.15 * np.cos(w * t)
    hands[0, :, 2] += 0.15 * np.sin(w * t)
    return classify(root, yaw, hands, head, fps)[int(fps) : -int(fps)]


def test_classes_follow_the_root_and_the_hands():
    name = lambda c: CLASSES[c] if c != OTHER else "other"  # noqa: E731
    assert {name(c) for c in _run((0.0, 1.2))} == {"forward"}
    assert {name(c) for c in _run((0.0, -0.9))} == {"backward"}
    assert {name(c) for c in _run((0.6, 0.0))} == {"sideways"}
    assert {name(c) for c in _run((0.0, 0.0), yaw_rate=np.radians(90))} == {"turn_in_place"}
    assert {name(c) for c in _run((0.0, 0.0))} == {"standing"}
    assert {name(c) for c in _run((0.0, 0.0), hands_speed=1.0)} == {"gesturing"}
    assert {name(c) for c in _run((0.0, 0.25))} == {"other"}
