"""Shared paths and the Rust CLI fixture.

`training/` and `training/tests/` go on sys.path so tests import `mmdb`, `bvh_reference` and
the helper modules by name, whatever directory pytest is started from.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
TRAINING = TESTS.parent
REPO = TRAINING.parent
for p in (TRAINING, TESTS):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

MMDB_BIN = REPO / "wasm-core" / "target" / "opt" / "mmdb"
# shared/ sits beside the repo on developer machines and in CI; MMDB_MOCAP_DIR overrides.
MOCAP = Path(os.environ.get("MMDB_MOCAP_DIR", REPO.parent / "shared" / "mocap"))


@pytest.fixture(scope="session")
def mocap() -> Path:
    if not (MOCAP / "cmu-asf").is_dir():
        pytest.fail(f"mocap data not found at {MOCAP} (set MMDB_MOCAP_DIR)")
    return MOCAP


@pytest.fixture(scope="session")
def mmdb_cli():
    """Run the Rust CLI: `mmdb_cli("build", ...)` -> CompletedProcess (text, never raises).

    Skipped only when the binary has not been built; CI builds it before running pytest.
    """
    if not MMDB_BIN.is_file():
        pytest.skip(f"Rust CLI not built: {MMDB_BIN} does not exist (cargo build --profile opt --bin mmdb)")

    def run(*args, timeout: float = 120.0) -> subprocess.CompletedProcess:
        return subprocess.run([str(MMDB_BIN), *map(str, args)], capture_output=True, text=True, timeout=timeout)

    return run


@pytest.fixture(scope="session")
def build_db(mmdb_cli):
    """`build_db(out, *args)`: run `mmdb build ... -o out`, fail with its stderr if it fails."""

    def build(out, *args) -> Path:
        proc = mmdb_cli("build", *args, "-o", out)
        if proc.returncode != 0:
            pytest.fail(f"mmdb build {' '.join(map(str, args))} failed ({proc.returncode}):\n{proc.stderr}")
        return Path(out)

    return build
