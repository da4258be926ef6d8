"""The Python reader against files the Rust CLI writes: bit-identical round trip, and corrupt
files rejected by both readers with a message that says why."""

import json
import struct

import numpy as np
import pytest

import mmdb
from mmdb_writer import patch, section_entries

ROUND_TRIP_FILES = ("cmu-asf/cmu_16_49.bvh", "cmu-asf/cmu_16_48.bvh")


@pytest.fixture(scope="module")
def built(tmp_path_factory, mocap, build_db):
    """A two-file database with the CLI defaults (fps 60, scale auto, mirroring on)."""
    out = tmp_path_factory.mktemp("cli") / "two.mmdb"
    return build_db(out, *(mocap / f for f in ROUND_TRIP_FILES))


def f32(values) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).astype(np.float32)


def test_round_trip_matches_dump_bit_for_bit(built, mmdb_cli):
    db = mmdb.load(built)
    # Version 3 derives the mirrored clips (MIRR) and the features: this reader does it its own way.
    assert db.version == 3 and "MIRR" in db.extra_sections and "FSHF" not in db.extra_sections
    proc = mmdb_cli("dump", built)
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    F, J, D = db.num_frames, db.num_joints, db.num_features
    assert (d["num_frames"], d["num_joints"], d["num_features"]) == (F, J, D)
    assert np.float32(d["fps"]) == np.float32(db.fps)
    assert d["joint_names"] == db.joint_names
    assert np.array_equal(np.asarray(d["parents"], dtype=np.int32), db.parents)
    # Bit-exact: what the file stores exactly, and the linear velocities both derive from it.
    for key, arr in [
        ("local_positions", db.local_positions),
        ("local_velocities", db.local_velocities),
        ("feature_mean", db.feature_mean),
        ("feature_scale", db.feature_scale),
    ]:
        dumped = f32(d[key])
        assert dumped.size == arr.size, key
        assert np.array_equal(dumped, arr.ravel()), f"{key} differs at {np.flatnonzero(dumped != arr.ravel())[:5]}"
    # The rotations are decoded from the same integers by both; normalizing in f32 may round
    # the last bit differently (glam's summation order is not numpy's), and the angular
    # velocities and the features (version 3: derived, normalized units) derived from them move
    # by about that much times fps, or times a bone length over a feature scale.
    for key, arr, tol in [
        ("local_rotations", db.local_rotations, 2.5e-7),
        ("local_angular_velocities", db.local_angular_velocities, 1e-4),
        ("features", db.features, 1e-4),
    ]:
        dumped = f32(d[key])
        assert dumped.size == arr.size, key
        worst = np.abs(dumped - arr.ravel()).max()
        print(f"{key}: Python vs Rust at most {worst:.2e}")
        assert worst <= tol, f"{key} differs by {worst}"
    assert np.array_equal(np.asarray(d["contacts"], dtype=np.uint8), db.contacts.astype(np.uint8).ravel())
    assert np.array_equal(np.asarray(d["valid"], dtype=np.uint8), db.valid.astype(np.uint8).ravel())
    ours = [
        (
            c.name,
            c.source,
            c.start,
            c.end,
            c.mirrored,
            c.source_fps,
            c.source_start,
            np.float32(c.scale),
            np.float32(c.root_scale),
        )
        for c in db.clips
    ]
    theirs = [
        (
            c["name"],
            c["source"],
            c["start"],
            c["end"],
            bool(c["mirrored"]),
            c["source_fps"],
            c["source_start"],
            np.float32(c["scale"]),
            np.float32(c["root_scale"]),
        )
        for c in d["clips"]
    ]
    assert ours == theirs
    # defaults: 2 sources, each with a mirrored copy
    assert len(db.clips) == 4 and sum(c.mirrored for c in db.clips) == 2 and db.flags & 1
    assert all(c.name.endswith(" (mirror)") == c.mirrored for c in db.clips)
    assert np.isfinite(db.features).all() and db.valid.any()


def test_inspect_runs(built, mmdb_cli):
    text = mmdb_cli("inspect", built)
    assert text.returncode == 0 and text.stdout.strip(), text.stderr
    as_json = mmdb_cli("inspect", built, "--json")
    assert as_json.returncode == 0, as_json.stderr
    json.loads(as_json.stdout)


TRUNCATED = ("truncat", "too short", "shorter", "file size", "file_size", "length")
OUTSIDE = ("outside", "out of bounds", "bounds", "past", "beyond", "exceed", "range")


def corruptions(good: bytes):
    size = len(good)
    first_entry = next(iter(section_entries(good).values()))[0]
    mid = size // 2
    cases = [
        ("flipped byte", patch(good, mid, bytes([good[mid] ^ 0x5A]), refix=False), ("checksum", "crc")),
        ("wrong magic", b"\x89MMDC" + good[5:], ("magic",)),
        ("version 4", patch(good, 8, struct.pack("<I", 4)), ("version",)),
        (
            "file_size field",
            patch(good, 16, struct.pack("<Q", size + 16), refix=False),
            ("file size", "file_size", "size", "length"),
        ),
        ("trailing bytes", good + b"\0" * 16, ("file size", "file_size", "size", "length")),
        ("section outside", patch(good, first_entry + 8, struct.pack("<Q", (size + 31) // 16 * 16)), OUTSIDE),
    ]
    cases += [(f"truncated to {n}", good[:n], TRUNCATED) for n in (0, 10, 31, 32, 100, mid, size - 1)]
    return cases


def test_corrupt_files_are_rejected_by_both_readers(built, mmdb_cli, tmp_path):
    failures = []
    for name, data, words in corruptions(built.read_bytes()):
        try:
            mmdb.load(data)
            failures.append(f"{name}: python accepted it")
        except mmdb.MmdbError as e:
            if not any(w in str(e).lower() for w in words):
                failures.append(f"{name}: python message {str(e)!r} has none of {words}")
        path = tmp_path / "bad.mmdb"
        path.write_bytes(data)
        proc = mmdb_cli("inspect", path)
        err = proc.stderr.lower()
        if proc.returncode == 0:
            failures.append(f"{name}: `mmdb inspect` exited 0")
        elif "panicked" in err or not any(w in err for w in words):
            failures.append(
                f"{name}: `mmdb inspect` exit {proc.returncode}, stderr {proc.stderr.strip()!r} has none of {words}"
            )
    assert not failures, "\n".join(failures)
