"""FK oracle: world joint positions from a database the Rust CLI built must equal those the
independent BVH reader computes from the source file, joint by joint, frame by frame.

Built without mirroring and at rates that divide the source rate, so database frame f is
source frame f·step exactly and no interpolation is involved. Joint 0 (VirtualRoot) is the
database's addition; every BVH joint must appear under its own name.
"""

import numpy as np
import pytest

import bvh_reference
import mmdb
from synthetic_bvh import ORDERS, default_channels, make_bvh

TOLERANCE = 1e-5  # metres, besides the rotations' quantization below
# docs/mmdb-format.md, QROT: each stored rotation is within 2/32767 rad of the original.
ROTATION_ERROR = 2 / 32767


def quantization_bound(db: mmdb.Database, world: np.ndarray) -> np.ndarray:
    """Per frame and joint, how far version 2's rotation quantization may move a world position:
    each ancestor's rotation error (≤ ROTATION_ERROR) turns the joint about that ancestor, by at
    most ROTATION_ERROR × their distance (first order; the terms add)."""
    bound = np.zeros(world.shape[:2])
    for j in range(1, db.num_joints):
        a = db.parents[j]
        while a >= 0:
            bound[:, j] += np.linalg.norm(world[:, j] - world[:, a], axis=-1)
            a = db.parents[a]
    return bound * ROTATION_ERROR * 1.01


MOCAP_CLIPS = (
    "cmu-asf/cmu_16_49.bvh",
    "cmu-asf/cmu_16_54.bvh",
    "cmu-asf/cmu_127_08.bvh",
    "cmu-asf/cmu_03_03.bvh",
    "cmu-daz/cmu_09_03.bvh",
    "cmu-daz/cmu_02_01.bvh",
)


def compare_fk(db: mmdb.Database, bvh_path, step: int, scale: float) -> None:
    names, _, ref = bvh_reference.fk(bvh_path, scale=scale)
    assert db.joint_names[0] == "VirtualRoot"
    missing = [n for n in names if n not in db.joint_names]
    assert not missing, f"BVH joints missing from the database: {missing}"
    index = [db.joint_names.index(n) for n in names]
    expected_frames = (len(ref) - 1) // step + 1
    assert abs(db.num_frames - expected_frames) <= 1, (db.num_frames, expected_frames)
    frames = min(db.num_frames, expected_frames)
    world = mmdb.world_positions(db)[:frames]
    ours = world[:, index]
    theirs = ref[::step][:frames]
    err = np.abs(ours - theirs).max(axis=2)
    allowed = TOLERANCE + quantization_bound(db, world)[:, index]
    f, j = np.unravel_index(np.argmax(err - allowed), err.shape)
    print(f"{bvh_path.name}: worst {err.max() * 1e3:.3f} mm (bound there {allowed.flat[np.argmax(err)] * 1e3:.3f} mm)")
    assert err[f, j] < allowed[f, j], (
        f"{bvh_path}: max |db FK - BVH FK| = {err[f, j]:.3g} m at db frame {f} (source frame "
        f"{f * step}), joint {names[j]!r}: db {ours[f, j]} vs bvh {theirs[f, j]}"
    )


@pytest.mark.parametrize("fps", [120, 60])
@pytest.mark.parametrize("rel", MOCAP_CLIPS)
def test_mocap_fk_matches_bvh_reference(rel, fps, mocap, build_db, tmp_path):
    src = mocap / rel
    db = mmdb.load(build_db(tmp_path / "one.mmdb", src, "--fps", fps, "--no-mirror", "--no-repair"))
    assert len(db.clips) == 1 and not db.clips[0].mirrored
    clip = db.clips[0]
    assert clip.source_fps == pytest.approx(120.0, rel=1e-4)
    expected_scale = 0.01 if rel.startswith("cmu-daz") else 1.0
    assert clip.scale == pytest.approx(expected_scale, rel=1e-6)
    compare_fk(db, src, 120 // fps, clip.scale)


def _build_synthetic(tmp_path, build_db, text: str):
    src = tmp_path / "synthetic.bvh"
    src.write_text(text)
    db = mmdb.load(build_db(tmp_path / "synthetic.mmdb", src, "--fps", 50, "--scale", 1, "--no-mirror", "--no-repair"))
    assert db.clips[0].scale == 1.0
    return src, db


@pytest.mark.parametrize("order", ORDERS)
def test_synthetic_rotation_orders_through_cli(order, build_db, tmp_path):
    """Every joint uses `order`; Spine also has all three position channels."""
    src, db = _build_synthetic(tmp_path, build_db, make_bvh(order, frame_time="0.02", seed=7))
    compare_fk(db, src, 1, 1.0)


def test_synthetic_partial_interleaved_position_channels_through_cli(build_db, tmp_path):
    """A non-root joint with only some position channels, mixed in among its rotations: the
    present components replace the offset's, the rest keep it."""
    chans = default_channels("ZXY")
    chans["LeftLeg"] = ["Xrotation", "Yposition", "Zrotation", "Yrotation"]
    chans["Spine"] = ["Zposition", "Yrotation", "Xposition", "Xrotation", "Zrotation"]
    src, db = _build_synthetic(tmp_path, build_db, make_bvh(channels=chans, frame_time="0.02", seed=3))
    compare_fk(db, src, 1, 1.0)
