"""mmdb.py on a hand-built file: values, FK, and every rejection the format doc requires."""

import struct

import numpy as np
import pytest

import mmdb
from mmdb_writer import (
    F,
    YAW,
    assemble,
    patch,
    sample_file,
    sample_file_v2,
    sample_sections,
    sample_sections_v2,
    section_entries,
)


def test_reads_every_field():
    db = mmdb.load(sample_file())
    assert (db.num_frames, db.num_joints, db.num_features, db.fps) == (4, 2, 3, 30.0)
    assert db.joint_names == ["VirtualRoot", "Hips"]
    assert db.parents.dtype == np.int32 and list(db.parents) == [-1, 0]
    assert db.sites["hips"][0] == 1 and db.sites["left_toe"][0] == -1
    assert [(c.name, c.start, c.end, c.mirrored, c.source_fps) for c in db.clips] == [("walk0", 0, 4, False, 120.0)]
    assert db.tags == {"walk": [(0, 4)]}
    assert db.local_velocities.shape == (4, 2, 3) and db.local_velocities[3, 1, 2] == 23
    assert db.local_angular_velocities[0, 0, 1] == -1
    assert db.contacts.dtype == bool and db.contacts.tolist() == [[1, 0], [1, 1], [0, 1], [0, 0]]
    assert db.valid.tolist() == [True, True, False, False]
    g = db.feature_groups[0]
    assert (g.name, g.kind, g.trajectory, g.axes, g.joint, g.offsets, g.first_dim, g.num_dims) == (
        "hips_position",
        mmdb.KIND_POSITION,
        False,
        mmdb.AXES_XYZ,
        1,
        [0],
        0,
        3,
    )
    assert db.feature_scale.tolist() == [2, 2, 2] and db.features.shape == (4, 3)


def test_forward_kinematics_through_the_virtual_root():
    db = mmdb.load(sample_file())
    pos = mmdb.world_positions(db)
    expected = np.stack([np.arange(F) * 0.1 + 0.5 * np.sin(YAW), np.full(F, 0.9), 1.0 + 0.5 * np.cos(YAW)], axis=1)
    np.testing.assert_allclose(pos[:, 1], expected, atol=1e-6)
    p2, r2 = mmdb.world_transforms(db, 2)
    np.testing.assert_array_equal(p2, pos[2])
    np.testing.assert_allclose(r2[1], db.local_rotations[2, 0], atol=1e-7)
    char, _ = mmdb.world_transforms(db, 3, character_space=True)
    np.testing.assert_allclose(char[1], [0.0, 0.9, 0.5], atol=1e-6)


def test_quaternion_helpers_match_rotation_by_hand():
    half = np.sqrt(0.5)
    qy90 = np.array([0.0, half, 0.0, half])
    qx90 = np.array([half, 0.0, 0.0, half])
    np.testing.assert_allclose(mmdb.quat_rotate(qy90, [0.0, 0.0, 1.0]), [1, 0, 0], atol=1e-12)
    # qy90·qx90 applies x first: +Y -> +Z -> +X
    q = mmdb.quat_mul(qy90, qx90)
    np.testing.assert_allclose(mmdb.quat_rotate(q, [0.0, 1.0, 0.0]), [1, 0, 0], atol=1e-12)


def test_unknown_sections_are_ignored():
    sections = list(sample_sections().items()) + [("XTRA", b"hello")]
    assert mmdb.load(assemble(sections)).extra_sections == {"XTRA": b"hello"}


def test_accepts_a_path(tmp_path):
    path = tmp_path / "a.mmdb"
    path.write_bytes(sample_file())
    assert mmdb.load(path).num_frames == 4 and mmdb.load(str(path)).num_frames == 4


def rotation_error(a, b):
    """Angles (rad) between unit quaternions, as 2·asin|(a⁻¹b).xyz| in f64 (an arccos of the dot
    product cannot resolve angles below ~1e-4 rad from f32 inputs)."""
    a, b = (q.astype(np.float64) / np.linalg.norm(q.astype(np.float64), axis=-1, keepdims=True) for q in (a, b))
    d = mmdb.quat_mul(a * np.array([-1.0, -1.0, -1.0, 1.0]), b)
    return 2 * np.arcsin(np.minimum(np.linalg.norm(d[..., :3], axis=-1), 1.0))


def test_version_2_reads_the_same_database():
    """The v2 twin of the sample: positions and features bit-exact, rotations within the
    documented 2/32767 rad, velocities derived by the documented differences."""
    v1, v2 = mmdb.load(sample_file()), mmdb.load(sample_file_v2())
    assert (v1.version, v2.version) == (1, 2)
    assert np.array_equal(v1.local_positions, v2.local_positions)
    assert np.array_equal(v1.features.view(np.uint32), v2.features.view(np.uint32))
    assert rotation_error(v1.local_rotations, v2.local_rotations).max() <= 2 / 32767
    assert [(c.source_fps, c.source_start) for c in v2.clips] == [(120.0, 0)]
    # The root moves 0.1 m and turns 30° per frame at 30 fps: 3 m/s along x, 5π rad/s about y,
    # at every frame (central inside the clip, one-sided at its ends); the hips do not move.
    np.testing.assert_allclose(v2.local_velocities[:, 0], [[3.0, 0, 0]] * F, atol=1e-5)
    np.testing.assert_allclose(v2.local_angular_velocities[:, 0], [[0, 5 * np.pi, 0]] * F, atol=2 * 30 * 2 / 32767)
    assert not v2.local_velocities[:, 1].any()
    # A clip boundary stops the differences: two clips of two frames each.
    two = mmdb.load(sample_file_v2(clips=((0, 2), (2, 4))))
    assert [c.source_start for c in two.clips] == [0, 7]
    np.testing.assert_allclose(two.local_velocities[:, 0, 0], [3.0] * F, atol=1e-5)


def _v2_corruptions():
    secs = sample_sections_v2()
    panm = secs["PANM"]
    swapped = panm[:4] + panm[8:12] + panm[4:8] + panm[12:]
    q = np.frombuffer(secs["QROT"], "<i2").copy()
    q[0] = 20000  # joint 0's x at frame 0: no longer a unit quaternion
    return [
        ("PANM order", assemble(list({**secs, "PANM": swapped}.items()), version=2), "must increase"),
        ("PANM length", assemble(list({**secs, "PANM": panm[:-4]}.items()), version=2), "section PANM: length"),
        (
            "QROT not unit",
            assemble(list({**secs, "QROT": q.tobytes()}.items()), version=2),
            "frame 0 joint 0 is not a unit quaternion",
        ),
        ("QROT length", assemble(list({**secs, "QROT": secs["QROT"][:-2]}.items()), version=2), "section QROT: length"),
        (
            "FSHF length",
            assemble(list({**secs, "FSHF": secs["FSHF"] + b"\0" * 4}.items()), version=2),
            "section FSHF: length",
        ),
    ]


@pytest.mark.parametrize("name,data,message", _v2_corruptions(), ids=[c[0] for c in _v2_corruptions()])
def test_rejects_invalid_version_2_files(name, data, message):
    with pytest.raises(mmdb.MmdbError) as err:
        mmdb.load(data)
    assert message.lower() in str(err.value).lower()


def _entry(data, tag):
    return section_entries(data)[tag]


def _corruptions():
    good = sample_file()
    size = len(good)
    at, off, length = _entry(good, "LPOS")
    secs = sample_sections()
    dup = list(secs.items()) + [("INFO", secs["INFO"])]
    missing = [(t, d) for t, d in secs.items() if t != "VALD"]
    long_lpos = {**secs, "LPOS": secs["LPOS"] + b"\0" * 12}
    long_name = {**secs, "SKEL": struct.pack("<I", 10_000) + secs["SKEL"][4:]}
    return [
        ("shorter than header", good[:20], "truncated"),
        ("empty", b"", "truncated"),
        ("magic", b"\x89MMDX" + good[5:], "magic"),
        ("version", patch(good, 8, struct.pack("<I", 4)), "unsupported version 4"),
        (
            "version 2 with version 1 sections",
            patch(good, 8, struct.pack("<I", 2)),
            "missing required section(s) PANM, QROT, FSHF",
        ),
        ("truncated", good[:-1], "truncated"),
        ("file size field", patch(good, 16, struct.pack("<Q", size + 16), refix=False), "file size"),
        ("trailing bytes", good + b"\0" * 16, "file size"),
        ("checksum", patch(good, size // 2, bytes([good[size // 2] ^ 0xFF]), refix=False), "checksum"),
        ("section outside", patch(good, at + 8, struct.pack("<Q", size + 16)), "outside the file"),
        ("section length outside", patch(good, at + 16, struct.pack("<Q", size)), "outside the file"),
        ("section before table", patch(good, at + 8, struct.pack("<Q", 32)), "before the end of the section table"),
        ("duplicate", assemble(dup), "duplicate section INFO"),
        ("missing", assemble(missing), "missing required section(s) VALD"),
        ("wrong length", assemble(list(long_lpos.items())), "section LPOS: length"),
        ("string past section", assemble(list(long_name.items())), "runs past the end of the section"),
        ("parent order", sample_file(parents=(-1, 1)), "parent 1"),
        ("second root", sample_file(parents=(-1, -1)), "parent -1"),
        ("clip outside", sample_file(clips=((0, 5),)), "outside [0, 4)"),
        ("clips with a gap", sample_file(clips=((0, 1), (2, 4))), "do not tile"),
        ("clips short of F", sample_file(clips=((0, 3),)), "do not tile"),
        ("tag outside", sample_file(tag_ranges=((2, 9),)), "tag 'walk'"),
        ("tags overlap", sample_file(tag_ranges=((0, 3), (2, 4))), "overlaps"),
        ("groups do not tile", sample_file(first_dim=1), "tile [0, 3)"),
    ]


@pytest.mark.parametrize("name,data,message", _corruptions(), ids=[c[0] for c in _corruptions()])
def test_rejects_invalid_files(name, data, message):
    with pytest.raises(mmdb.MmdbError) as err:
        mmdb.load(data)
    assert message.lower() in str(err.value).lower()
    assert isinstance(err.value, ValueError)
