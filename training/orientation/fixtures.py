"""Recorded inputs and PyTorch outputs of the committed model, for the runtime parity tests.

`training/fixtures/orientation_parity.json` (rewritten by `npm run train`, or
`python -m orientation.fixtures`) holds
- `rows`: 48 raw 54-float inputs (held-out frames with true, perturbed and garbage previous
  slots) and the PyTorch outputs for them;
- `sequence`: 150 frames of simulated raw tracker poses (a held-out take at 90 Hz with
  look-around, one dropped frame and one 0.3 s pause), with the inputs the Python reference
  (`FeatureBuilder` + the feedback loop of `predictors.py`) built each frame, the PyTorch
  outputs and the body yaw — what `features.ts` and `orientation-model.ts` must reproduce.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from . import data
from .features import (
    NUM_INPUTS,
    PREV,
    TRACKER_INPUTS,
    FeatureBuilder,
    FRAME_COLUMNS,
    frame_features,
    relative_yaw_of_output,
    yaw_slot,
)
from .model import net_from_state
from .predictors import TorchModel
from .simulate import EVAL_AUGMENT, simulate

FIXTURE = data.TRAINING / "fixtures" / "orientation_parity.json"
SEED = 4242


def _floats(a) -> list:
    return np.asarray(a, dtype=np.float64).round(12).tolist()


def fixture_sequence(rng: np.random.Generator, clips, n: int = 150):
    """A held-out take at 90 Hz with look-around: its first `n` frames, one dropped frame, one
    0.3 s pause (velocities restart from zero) and some quaternions negated (WebXR may give q
    or −q: the features must not care)."""
    clip = next(c for c in clips if c.name == "cmu_08_03")
    seq = simulate(clip, rng, EVAL_AUGMENT, fps=90.0)
    dt = seq.dt[:n].copy()
    dt[40] = 2.0 / 90.0
    dt[100] = 0.3
    pos, rot = seq.pos[:n], seq.rot[:n].copy()
    rot[::7] *= -1.0
    return seq, dt, pos, rot


def build_fixture(onnx_path: Path, weights: Path) -> dict:
    model = TorchModel(net_from_state(dict(np.load(weights))))
    rng = np.random.default_rng(SEED)
    clips = data.load_subjects(data.TEST_SUBJECTS, mirrored=False, log=lambda *_: None)
    seq, dt, pos, rot = fixture_sequence(rng, clips)
    n = len(dt)

    fb = FeatureBuilder()
    inputs, outputs, body, hmd = [], [], [], []
    prev = None
    for t in range(n):
        x = fb.update(pos[t], rot[t], dt[t])
        fb.set_previous(0.0 if prev is None else prev - fb.hmd_yaw)
        out = model(x[None])[0]
        phi, ok = relative_yaw_of_output(out)
        prev = (fb.hmd_yaw + float(phi)) if ok else (fb.hmd_yaw if prev is None else prev)
        inputs.append(x.copy())
        outputs.append(out)
        body.append(prev)
        hmd.append(fb.hmd_yaw)

    # Independent rows: held-out frames with various previous slots, some of them garbage.
    other = simulate(next(c for c in clips if c.name.startswith("cmu_03_")), rng, EVAL_AUGMENT, fps=72.0)
    f, y = frame_features(other.pos, other.rot, other.dt)
    idx = rng.choice(np.arange(1, len(f)), 48, replace=False)
    rows = np.zeros((48, NUM_INPUTS), dtype=np.float32)
    rows[:, FRAME_COLUMNS] = f[idx]
    rows[:, PREV] = yaw_slot(other.body_yaw[idx - 1] - y[idx] + rng.normal(0, 0.3, 48))
    rows[-8:, PREV] = rng.normal(0, 50.0, (8, 6))  # garbage in the previous slot
    row_out = model(rows)
    return {
        "model": str(onnx_path.relative_to(data.REPO)),
        "model_sha256": hashlib.sha256(onnx_path.read_bytes()).hexdigest(),
        "rows": {"inputs": _floats(rows), "outputs": _floats(row_out)},
        "sequence": {
            "name": seq.name,
            "fps": seq.fps,
            "dt": np.asarray(dt, dtype=np.float64).tolist(),  # exact: the windows compare summed times
            "positions": _floats(pos.reshape(n, 9)),
            "quaternions": _floats(rot.reshape(n, 12)),
            "inputs": _floats(np.array(inputs)),
            "outputs": _floats(np.array(outputs)),
            "body_yaw": _floats(body),
            "hmd_yaw": _floats(hmd),
        },
    }


def build_gru_fixture(onnx_path: Path, step) -> dict:
    """The recurrent model's parity fixture: the same sequence, with the 36 inputs, the outputs
    and the body yaw of the Python reference loop (`predictors.run_recurrent`), run in PyTorch
    (`step`: a `gru.GruStep`)."""
    import torch

    rng = np.random.default_rng(SEED)
    clips = data.load_subjects(data.TEST_SUBJECTS, mirrored=False, log=lambda *_: None)
    seq, dt, pos, rot = fixture_sequence(rng, clips)
    fb = FeatureBuilder()
    h = torch.zeros(1, step.net.hidden)
    inputs, outputs, body, hmd = [], [], [], []
    prev = None
    for t in range(len(dt)):
        x = fb.update(pos[t], rot[t], dt[t])[:TRACKER_INPUTS].astype(np.float32)
        with torch.no_grad():
            out, h = step(torch.from_numpy(x[None]), h)
        out = out.numpy()[0]
        phi, ok = relative_yaw_of_output(out)
        prev = (fb.hmd_yaw + float(phi)) if ok else (fb.hmd_yaw if prev is None else prev)
        inputs.append(x)
        outputs.append(out)
        body.append(prev)
        hmd.append(fb.hmd_yaw)
    return {
        "model": str(onnx_path.relative_to(data.REPO)),
        "model_sha256": hashlib.sha256(onnx_path.read_bytes()).hexdigest(),
        "sequence": {
            "name": seq.name,
            "fps": seq.fps,
            "dt": np.asarray(dt, dtype=np.float64).tolist(),  # exact: the windows compare summed times
            "positions": _floats(pos.reshape(len(dt), 9)),
            "quaternions": _floats(rot.reshape(len(dt), 12)),
            "inputs": _floats(np.array(inputs)),
            "outputs": _floats(np.array(outputs)),
            "body_yaw": _floats(body),
            "hmd_yaw": _floats(hmd),
        },
    }


def write_fixtures(onnx_path: Path, weights: Path, out: Path = FIXTURE) -> Path:
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(build_fixture(onnx_path, weights)) + "\n")
    print(f"wrote {out.relative_to(data.REPO)}")
    return out


if __name__ == "__main__":
    write_fixtures(data.PUBLIC_MODEL, data.MODELS_DIR / "orientation_main.npz")
    sys.exit(0)
