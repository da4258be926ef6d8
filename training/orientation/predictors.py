"""Body-yaw predictors run frame by frame as at run time: the network in its feedback loop, and
the two baselines it is compared with (HMD-forward, dead-zone).

`run_network` is the reference for `web/src/orientation/orientation-model.ts`: per frame,
1. features of the current poses (`features.py`);
2. previous slot = 6D of (previous body yaw − current HMD yaw); after a reset: HMD forward (φ = 0);
3. run the model; φ = atan2(−out[2], out[0]); if the output is not finite or degenerate
   (|(out[0], out[2])| ≤ 1e-6), keep the previous body yaw (or the HMD yaw after a reset);
4. body yaw = HMD yaw + φ, fed back at the next frame.
A previous body yaw that is not finite (however it got there) counts as a reset: the slot gets
φ⁻ = 0 and the fallback is the HMD yaw, so the loop never keeps a NaN.
It runs many sequences side by side (one batch row each) to evaluate quickly.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .features import (
    FRAME_COLUMNS,
    FRAME_INPUTS,
    NUM_INPUTS,
    PREV,
    TRACKER_INPUTS,
    frame_features,
    relative_yaw_of_output,
    yaw_slot,
)
from .geometry import wrap_angle
from .simulate import TrackerSequence

DEAD_ZONE = np.radians(25.0)


class OnnxModel:
    """The exported model through onnxruntime (CPU, one thread): f(x (B, inputs)) -> (B, 8), the
    6D then the hips (as `TorchModel`; (B, 6) for a model from before the hips); `inputs` 54, or 42
    for a model from before the context."""

    def __init__(self, path):
        import onnxruntime as ort

        opts = ort.SessionOptions()
        opts.intra_op_num_threads = 1
        opts.inter_op_num_threads = 1
        self.session = ort.InferenceSession(str(path), sess_options=opts, providers=["CPUExecutionProvider"])
        self.input = self.session.get_inputs()[0].name
        self.inputs = int(self.session.get_inputs()[0].shape[1])

    def __call__(self, x: np.ndarray) -> np.ndarray:
        outs = self.session.run(None, {self.input: np.ascontiguousarray(x, dtype=np.float32)})
        return np.concatenate(outs, axis=1)


class OnnxRecurrentModel:
    """A recurrent model file (`gru.GruStep`): f(x (B, 36), h (B, H)) -> ((B, 6), (B, H))."""

    recurrent = True

    def __init__(self, path):
        import onnxruntime as ort

        opts = ort.SessionOptions()
        opts.intra_op_num_threads = 1
        opts.inter_op_num_threads = 1
        self.session = ort.InferenceSession(str(path), sess_options=opts, providers=["CPUExecutionProvider"])
        self.inputs = [i.name for i in self.session.get_inputs()]
        self.state_size = int(self.session.get_inputs()[1].shape[1])

    def __call__(self, x: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        out, h2 = self.session.run(
            None,
            {
                self.inputs[0]: np.ascontiguousarray(x, dtype=np.float32),
                self.inputs[1]: np.ascontiguousarray(h, dtype=np.float32),
            },
        )
        return out, h2


def load_model(path):
    """The model file at `path`: feed-back (1 input) or recurrent (features and state)."""
    import onnx

    inputs = onnx.load(str(path), load_external_data=False).graph.input
    return OnnxRecurrentModel(path) if len(inputs) == 2 else OnnxModel(path)


class TorchModel:
    def __init__(self, net):
        import torch

        self.net, self.torch = net.eval(), torch
        self.inputs = net.inputs

    def __call__(self, x: np.ndarray) -> np.ndarray:
        with self.torch.no_grad():
            return self.net(self.torch.as_tensor(np.asarray(x, dtype=np.float32))).numpy()


def sequence_features(seqs: list[TrackerSequence]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Padded frame features (B, T, 48) float32 (`features.frame_features`; a recurrent model
    takes the first 36), HMD yaw (B, T), lengths (B,)."""
    lengths = np.array([s.num_frames for s in seqs])
    T = int(lengths.max())
    feats = np.zeros((len(seqs), T, FRAME_INPUTS), dtype=np.float32)
    yaw = np.zeros((len(seqs), T))
    for b, s in enumerate(seqs):
        f, y = frame_features(s.pos, s.rot, s.dt)
        feats[b, : len(f)], yaw[b, : len(f)] = f, y
    return feats, yaw, lengths


def run_network(
    model: Callable[[np.ndarray], np.ndarray],
    feats: np.ndarray,
    hmd_yaw: np.ndarray,
    inject: dict[int, tuple[np.ndarray, np.ndarray]] | None = None,
    finite: np.ndarray | None = None,
    inject_yaw: dict[int, tuple[np.ndarray, np.ndarray]] | None = None,
    hips: np.ndarray | None = None,
) -> np.ndarray:
    """Body yaw (B, T) predicted in the feedback loop from a reset at frame 0; a (B, T, 2) `hips`
    receives the second output (`features.hips_target`; NaN from a model without it).

    `inject` maps a frame to (rows, values (len(rows), 6)) written into those rows' previous
    slot instead of the fed-back prediction (garbage for the robustness tests); `inject_yaw`
    maps a frame to (rows, values (len(rows),)) replacing those rows' previous body yaw itself
    (NaN, ±inf: a corrupted state). If `finite` is a (B, T) bool array, it receives whether each
    raw network output was finite."""
    B, T, _ = feats.shape
    inputs = getattr(model, "inputs", NUM_INPUTS)
    x = np.zeros((B, inputs), dtype=np.float32)
    cols = FRAME_COLUMNS[: inputs - 6]  # where the frame features go (the first 36 for a 42-input model)
    body = np.zeros((B, T))
    prev_world = None
    for t in range(T):
        if inject_yaw is not None and t in inject_yaw and prev_world is not None:
            rows, values = inject_yaw[t]
            prev_world = prev_world.copy()
            prev_world[rows] = values
        x[:, cols] = feats[:, t, : len(cols)]
        known = np.zeros(B, dtype=bool) if prev_world is None else np.isfinite(prev_world)
        previous = np.where(known, prev_world if prev_world is not None else 0.0, hmd_yaw[:, t])
        x[:, PREV] = yaw_slot(previous - hmd_yaw[:, t])
        if inject is not None and t in inject:
            rows, values = inject[t]
            x[rows, PREV] = values
        out = model(x)
        if finite is not None:
            finite[:, t] = np.isfinite(out).all(axis=1)
        if hips is not None:
            hips[:, t] = out[:, 6:8] if out.shape[1] >= 8 else np.nan
        phi, ok = relative_yaw_of_output(out)
        body[:, t] = np.where(ok, hmd_yaw[:, t] + phi, previous)
        prev_world = body[:, t]
    return body


def run_recurrent(model, feats: np.ndarray, hmd_yaw: np.ndarray) -> np.ndarray:
    """Body yaw (B, T) of a recurrent model from a zero state at frame 0 — the reference for the
    recurrent path of `orientation-model.ts`: per frame, run (inputs 0..35, state); φ as for the
    feed-back network; a non-finite or degenerate output keeps the previous body yaw (the HMD yaw
    at the start) and a non-finite state starts again from zeros, so a NaN never stays."""
    B, T, _ = feats.shape
    h = np.zeros((B, model.state_size), dtype=np.float32)
    body = np.zeros((B, T))
    previous = hmd_yaw[:, 0].copy()
    for t in range(T):
        out, h = model(feats[:, t, :TRACKER_INPUTS], h)
        h = np.where(np.isfinite(h).all(axis=1, keepdims=True), h, 0.0).astype(np.float32)
        phi, ok = relative_yaw_of_output(out)
        previous = np.where(ok, hmd_yaw[:, t] + phi, previous)
        body[:, t] = previous
    return body


RECURRENT_WARMUP = 1.5  # s of input after a reset before the recurrent model's yaw is used (network-yaw.ts)
BLEND_RATE = 2.0  # per second: how fast the recurrent model's weight moves to its target


def page_yaw(main: np.ndarray, recurrent: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """The VR page's body yaw (B, T) (`network-yaw.ts`): the recurrent model's weight targets ½
    (the mean on the circle of both models) whatever devices are tracked, 0 until the recurrent
    model has had `RECURRENT_WARMUP` s of input (summed dt, the first frame's included), and
    moves there at `BLEND_RATE` a second; where the weighted vectors cancel, the main model's
    yaw."""
    age = np.cumsum(dt, axis=1)
    w = np.zeros(main.shape[0])
    out = np.empty_like(main)
    for t in range(main.shape[1]):
        target = np.where(age[:, t] < RECURRENT_WARMUP, 0.0, 0.5)
        step = BLEND_RATE * np.maximum(dt[:, t], 0.0)
        w = w + np.clip(target - w, -step, step)
        s = (1 - w) * np.sin(main[:, t]) + w * np.sin(recurrent[:, t])
        c = (1 - w) * np.cos(main[:, t]) + w * np.cos(recurrent[:, t])
        mixed = np.where(np.hypot(s, c) > 1e-6, np.arctan2(s, c), main[:, t])
        out[:, t] = np.where(w == 0, main[:, t], mixed)
    return out


def hmd_forward(hmd_yaw: np.ndarray) -> np.ndarray:
    """Baseline: the body faces where the head looks."""
    return hmd_yaw.copy()


def dead_zone(
    hmd_yaw: np.ndarray,
    dt: np.ndarray,
    threshold: float = DEAD_ZONE,
    halflife: float = 0.15,
    settle: float = np.radians(2.0),
) -> np.ndarray:
    """Baseline used by many VR apps: the body keeps its yaw until the head is more than
    `threshold` off; then it turns toward the head (exponential, `halflife` seconds) until
    within `settle`, and waits again. hmd_yaw (B, T), dt (B, T)."""
    B, T = hmd_yaw.shape
    body = np.zeros((B, T))
    b = hmd_yaw[:, 0].copy()
    turning = np.zeros(B, dtype=bool)
    for t in range(T):
        off = wrap_angle(hmd_yaw[:, t] - b)
        turning = np.where(turning, np.abs(off) > settle, np.abs(off) > threshold)
        k = 1.0 - np.exp(-np.log(2.0) * dt[:, t] / halflife)
        b = np.where(turning, b + k * off, b)
        body[:, t] = b
    return body


def yaw_error_deg(pred: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.degrees(np.abs(wrap_angle(pred - truth)))
