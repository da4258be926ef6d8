"""The evaluation's device sets put an absent controller where the VR page does."""

import re

import numpy as np

from orientation import data, evaluate, simulate
from orientation.geometry import quat_from_yaw, quat_rotate
from orientation.simulate import TrackerSequence


def test_hanging_pose_matches_the_page():
    # The constants are the page's defaults (web/src/vr/trackers.ts), read from the source.
    ts = (data.REPO / "web" / "src" / "vr" / "trackers.ts").read_text()
    for name, value in (
        ("hangSide", simulate.HANG_SIDE),
        ("hangHeight", simulate.HANG_HEIGHT),
        ("hangForward", simulate.HANG_FORWARD),
    ):
        m = re.search(rf"^\s*{name}: ([0-9.]+),", ts, re.M)
        assert m and float(m.group(1)) == value, f"{name}: the page says {m and m.group(1)}, the evaluation {value}"

    # A headset looking along +Z (WebXR views look down −Z: R_y(π)) at 1.6 m: the body's left is +X.
    n = 4
    pos = np.zeros((n, 3, 3))
    pos[:, 0] = (1.0, 1.6, 2.0)
    pos[:, 1:] = (0.0, 1.0, 2.3)
    rot = np.tile(np.array([0.0, 0.0, 0.0, 1.0]), (n, 3, 1))
    rot[:, 0] = quat_from_yaw(np.pi)
    seq = TrackerSequence("t", 90.0, np.full(n, 1 / 90), pos, rot, np.zeros(n))
    one = evaluate.with_absent(seq, (2,))
    np.testing.assert_allclose(one.pos[:, 1], pos[:, 1])  # the left one stays
    np.testing.assert_allclose(one.pos[:, 2], np.tile([1.0 - 0.2, 0.8, 2.05], (n, 1)), atol=1e-12)
    both = evaluate.with_absent(seq, (1, 2))
    np.testing.assert_allclose(both.pos[:, 1], np.tile([1.0 + 0.2, 0.8, 2.05], (n, 1)), atol=1e-12)
    # Grip −Z (the thumb) forward, +X (the back of a right hand) outward = −X.
    np.testing.assert_allclose(quat_rotate(both.rot[0, 2], np.array([0.0, 0.0, -1.0])), [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(quat_rotate(both.rot[0, 2], np.array([1.0, 0.0, 0.0])), [-1, 0, 0], atol=1e-12)
    assert evaluate.with_absent(seq, ()) is seq


def test_page_yaw_blend_matches_the_page():
    """`predictors.page_yaw` (what eval and replay score) uses the page's warm-up and blend rate
    (web/src/vr/network-yaw.ts), read from the source."""
    from orientation import predictors

    ts = (data.REPO / "web" / "src" / "vr" / "network-yaw.ts").read_text()
    for name, value in (("RECURRENT_WARMUP", predictors.RECURRENT_WARMUP), ("BLEND_RATE", predictors.BLEND_RATE)):
        m = re.search(rf"^export const {name} = ([0-9.]+);", ts, re.M)
        assert m and float(m.group(1)) == value, f"{name}: the page says {m and m.group(1)}, Python {value}"
