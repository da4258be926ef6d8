"""The BVH oracle checked on its own, against rotations and FK computed a second way."""

import numpy as np
import pytest

import bvh_reference as bvh
from synthetic_bvh import ORDERS, make_bvh


def rodrigues(axis, degrees: float) -> np.ndarray:
    """exp([axis]x * angle) via Rodrigues' formula: a different construction from the
    element-wise axis matrices in bvh_reference."""
    k = np.asarray(axis, dtype=float)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = np.radians(degrees)
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K


UNIT = {"X": (1, 0, 0), "Y": (0, 1, 0), "Z": (0, 0, 1)}


def expected_world_positions(parsed: bvh.Bvh, frame: int) -> np.ndarray:
    """FK of one frame with 4x4 homogeneous matrices, composed per channel by Rodrigues."""
    world, column = [], 0
    for j, chans in enumerate(parsed.channels):
        local = np.eye(4)
        local[:3, 3] = parsed.offsets[j]
        for ch in chans:
            value = parsed.motion[frame, column]
            column += 1
            if ch.endswith("position"):
                local[:3, 3]["XYZ".index(ch[0])] = value
            else:
                step = np.eye(4)
                step[:3, :3] = rodrigues(UNIT[ch[0]], value)
                local = local @ step
        p = parsed.parents[j]
        world.append(local if p < 0 else world[p] @ local)
    return np.array([m[:3, 3] for m in world])


def write(tmp_path, text: str, name: str = "clip.bvh"):
    path = tmp_path / name
    path.write_bytes(text.encode())
    return path


def test_axis_rotations_are_right_handed():
    x, y, z = np.eye(3)
    assert np.allclose(bvh.axis_rotation(2, 90.0) @ x, y)
    assert np.allclose(bvh.axis_rotation(0, 90.0) @ y, z)
    assert np.allclose(bvh.axis_rotation(1, 90.0) @ z, x)


def test_first_listed_channel_is_outermost(tmp_path):
    """Zrotation 90, Xrotation 90 means Rz·Rx: the child at +Y goes to +Z (Rx first takes
    y to z, then Rz leaves z alone). The opposite order would give -X."""
    text = """HIERARCHY
ROOT A
{
  OFFSET 0 0 0
  CHANNELS 2 Zrotation Xrotation
  JOINT B
  {
    OFFSET 0 1 0
    CHANNELS 0
  }
}
MOTION
Frames: 1
Frame Time: 0.1
90 90
"""
    names, parents, pos = bvh.fk(write(tmp_path, text))
    assert names == ["A", "B"] and list(parents) == [-1, 0]
    assert np.allclose(pos[0, 1], [0, 0, 1])


@pytest.mark.parametrize("order", ORDERS)
def test_rotation_orders_match_rodrigues(tmp_path, order):
    path = write(tmp_path, make_bvh(order, frames=30, seed=ORDERS.index(order)))
    parsed = bvh.parse(path)
    _, rots = bvh.local_transforms(parsed)
    for frame in (0, 7, 29):
        column = 0
        for j, chans in enumerate(parsed.channels):
            expected = np.eye(3)
            for ch in chans:
                if ch.endswith("rotation"):
                    expected = expected @ rodrigues(UNIT[ch[0]], parsed.motion[frame, column])
                column += 1
            np.testing.assert_allclose(rots[frame, j], expected, atol=1e-12)
    names, _, pos = bvh.fk(path)
    for frame in (0, 13, 29):
        np.testing.assert_allclose(pos[frame], expected_world_positions(parsed, frame), atol=1e-12)
    assert names[0] == "Hips" and len(names) == 11  # End Sites are not joints


def test_position_channels_on_non_root_replace_offset_components(tmp_path):
    """B has only Zposition (interleaved with rotations): x, y come from OFFSET, z from the
    channel, and the rotation channels around it still compose in listed order."""
    text = """HIERARCHY
ROOT A
{
  OFFSET 5 5 5
  CHANNELS 3 Xposition Yposition Zposition
  JOINT B
  {
    OFFSET 0.1 0.2 0.3
    CHANNELS 3 Yrotation Zposition Xrotation
    JOINT C
    {
      OFFSET 0 1 0
      CHANNELS 0
      End Site
      {
        OFFSET 0 1 0
      }
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.1
1 2 3 0 0.7 0
1 2 3 90 0.7 90
"""
    names, parents, pos = bvh.fk(write(tmp_path, text), scale=2.0)
    assert names == ["A", "B", "C"]
    # root: position channels replace the (5,5,5) offset entirely
    np.testing.assert_allclose(pos[:, 0], [[2, 4, 6], [2, 4, 6]])
    np.testing.assert_allclose(pos[:, 1], [[2.2, 4.4, 7.4], [2.2, 4.4, 7.4]])
    # frame 0: no rotation; frame 1: Ry(90)·Rx(90) takes +Y to +Z, then to +X
    np.testing.assert_allclose(pos[0, 2], [2.2, 6.4, 7.4], atol=1e-12)
    np.testing.assert_allclose(pos[1, 2], [4.2, 4.4, 7.4], atol=1e-12)


def test_crlf_and_tabs_parse_identically(tmp_path):
    plain = bvh.fk(write(tmp_path, make_bvh("YXZ", frames=10), "plain.bvh"))
    crlf = bvh.fk(write(tmp_path, make_bvh("YXZ", frames=10, newline="\r\n", indent="\t"), "crlf.bvh"))
    assert plain[0] == crlf[0]
    assert np.array_equal(plain[1], crlf[1])
    assert np.array_equal(plain[2], crlf[2])
    assert b"\r\n\t" in (tmp_path / "crlf.bvh").read_bytes()


def test_scale_multiplies_translations(tmp_path):
    path = write(tmp_path, make_bvh("ZYX", frames=5))
    _, _, metres = bvh.fk(path)
    _, _, centimetres = bvh.fk(path, scale=100.0)
    np.testing.assert_allclose(centimetres, metres * 100.0, rtol=1e-12)


def test_wrong_number_count_is_rejected(tmp_path):
    text = make_bvh("XYZ", frames=3).rstrip("\n") + " 1.0\n"
    with pytest.raises(bvh.BvhError, match="numbers"):
        bvh.fk(write(tmp_path, text))
