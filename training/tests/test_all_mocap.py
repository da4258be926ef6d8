"""Every shipped BVH file parses with the oracle and builds with the CLI on its own."""

from concurrent.futures import ThreadPoolExecutor
import json
import os

import numpy as np

import bvh_reference
import mmdb


def bvh_files(mocap):
    """Every file the shared manifest lists (it grows: never a fixed count), all present."""
    manifest = json.loads((mocap / "manifest.json").read_text())
    files = sorted(mocap / e["folder"] / e["file"] for e in manifest)
    assert files, f"{mocap}/manifest.json lists no files"
    missing = [f for f in files if not f.is_file()]
    assert not missing, f"listed in manifest.json but missing: {missing[:5]}"
    on_disk = sorted(mocap.glob("*/*.bvh"))
    assert set(on_disk) <= set(files), f"BVH files not in manifest.json: {sorted(set(on_disk) - set(files))[:5]}"
    return files


def test_every_bvh_parses(mocap):
    for path in bvh_files(mocap):
        parsed = bvh_reference.parse(path)
        assert parsed.num_frames > 0 and np.isfinite(parsed.motion).all(), path
        assert parsed.frame_time > 0, path


def test_every_bvh_builds_alone(mocap, mmdb_cli, tmp_path):
    def build(path):
        out = tmp_path / f"{path.parent.name}-{path.stem}.mmdb"
        proc = mmdb_cli("build", path, "-o", out)
        if proc.returncode != 0:
            return f"{path.name}: exit {proc.returncode}: {proc.stderr.strip()}"
        try:
            db = mmdb.load(out)
        except mmdb.MmdbError as e:
            return f"{path.name}: python reader rejects the output: {e}"
        out.unlink()
        return None if db.num_frames > 0 else f"{path.name}: empty database"

    with ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
        failures = [f for f in pool.map(build, bvh_files(mocap)) if f]
    assert not failures, "\n".join(failures)
