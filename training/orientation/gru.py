"""A recurrent body-orientation model (GRU), trained and scored against the MLP on the held-out
people — issue 14's "try recurrent": can a memory of the last second or two (the gait's sway,
which way the hips travelled, where the head kept returning) do what the MLP's fed-back yaw
does not?

    python -m orientation.gru [--hidden 48] [--window 180] [--epochs 12] [--max-batches 500]

Model: the 36 tracker features (`features.py`, normalized) → Linear(H) + ReLU → GRU(H) →
Linear(6), the same 6D output in the HMD-yaw frame. No previous-yaw slot: the hidden state is
the memory. Trained on windows of `window` frames from a zero state, the loss on every frame
after the first `burn_in` (a running session has long left its start). Scored exactly like
`evaluate.py` (every frame after the first second of each held-out take, from a zero state at
the take's start, at 72/90/120 Hz, with look-around), per motion class, beside the committed
MLP and HMD-forward on the same frames.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict, dataclass, replace

import numpy as np
import torch
from torch import nn

from . import data
from .evaluate import DEVICE_SETS, GRU_MODEL, class_table, evaluate, held_out_sequences, stats, with_absent
from .features import TRACKER_INPUTS, relative_yaw_of_output, yaw_slot
from .fixtures import build_gru_fixture
from .geometry import wrap_angle
from .model import export_onnx
from .predictors import OnnxModel, OnnxRecurrentModel, sequence_features, yaw_error_deg
from .simulate import TRAIN_AUGMENT
from .train import MODELS_DIR, PUBLIC_MODEL, TrainConfig, quiet_exporter, simulate_epoch

GRU_FIXTURE = data.TRAINING / "fixtures" / "orientation_gru_parity.json"


class GruNet(nn.Module):
    def __init__(self, mean: np.ndarray, std: np.ndarray, hidden: int = 48):
        super().__init__()
        std = np.where(np.asarray(std) > 1e-4, std, 1.0)
        self.register_buffer("mean", torch.as_tensor(mean, dtype=torch.float32))
        self.register_buffer("inv_std", torch.as_tensor(1.0 / std, dtype=torch.float32))
        self.hidden = hidden
        self.inp = nn.Linear(TRACKER_INPUTS, hidden)
        self.gru = nn.GRU(hidden, hidden, batch_first=True)
        self.out = nn.Linear(hidden, 6)

    def forward(self, x: torch.Tensor, h: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """x (B, T, 36) raw features, h (1, B, H) or None (zeros) → (B, T, 6), h (1, B, H)."""
        z = torch.relu(self.inp((x - self.mean) * self.inv_std))
        y, h = self.gru(z, h)
        return self.out(y), h


class GruStep(nn.Module):
    """One frame of a `GruNet`, for export and the browser: (features (B, 36), state (B, H)) →
    (6D (B, 6), next state (B, H)). The GRU cell written out (PyTorch's gate order r, z, n) so
    the ONNX graph is plain matrix products any runtime runs."""

    def __init__(self, net: GruNet):
        super().__init__()
        self.net = net

    def forward(self, x: torch.Tensor, h: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        n, g = self.net, self.net.gru
        H = n.hidden
        z = torch.relu(n.inp((x - n.mean) * n.inv_std))
        gi = z @ g.weight_ih_l0.T + g.bias_ih_l0
        gh = h @ g.weight_hh_l0.T + g.bias_hh_l0
        r = torch.sigmoid(gi[:, :H] + gh[:, :H])
        u = torch.sigmoid(gi[:, H : 2 * H] + gh[:, H : 2 * H])
        c = torch.tanh(gi[:, 2 * H :] + r * gh[:, 2 * H :])
        h2 = (1 - u) * c + u * h
        return n.out(h2), h2


@dataclass
class GruConfig:
    hidden: int = 48
    window: int = 180
    burn_in: int = 30
    epochs: int = 12
    batch: int = 32
    lr: float = 1e-3
    weight_decay: float = 0.01
    lr_decay: float = 0.9
    seed: int = 7
    max_batches_per_epoch: int = 500
    absent_prob: float = TRAIN_AUGMENT.absent_prob


def train_gru(cfg: GruConfig, clips, log=print) -> GruNet:
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(1)
    rng = np.random.default_rng(cfg.seed)
    sim_cfg = replace(TrainConfig(), r=cfg.window, augment=replace(TRAIN_AUGMENT, absent_prob=cfg.absent_prob))
    ep = simulate_epoch(clips, rng, sim_cfg)
    # The recurrent model takes the tracker inputs only (the first 36 of a frame's features).
    net = GruNet(ep.feats[:, :TRACKER_INPUTS].mean(0), ep.feats[:, :TRACKER_INPUTS].std(0), cfg.hidden)
    opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.ExponentialLR(opt, gamma=cfg.lr_decay)
    t0 = time.perf_counter()
    for epoch in range(cfg.epochs):
        if epoch > 0:
            ep = simulate_epoch(clips, rng, sim_cfg)
        order = rng.permutation(ep.starts)
        nb = min(len(order) // cfg.batch, cfg.max_batches_per_epoch)
        losses, errs = [], []
        for b in range(nb):
            starts = order[b * cfg.batch : (b + 1) * cfg.batch]
            idx = starts[:, None] + np.arange(cfg.window)
            x = torch.from_numpy(ep.feats[idx, :TRACKER_INPUTS])
            target = torch.from_numpy(yaw_slot(ep.body_yaw[idx] - ep.hmd_yaw[idx]).astype(np.float32))
            out, _ = net(x)
            out, target = out[:, cfg.burn_in :], target[:, cfg.burn_in :]
            loss = torch.mean((out - target) ** 2)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            nn.utils.clip_grad_norm_(net.parameters(), 1.0)
            opt.step()
            losses.append(loss.item())
            with torch.no_grad():
                e = torch.atan2(-out[..., 2], out[..., 0]) - torch.atan2(-target[..., 2], target[..., 0])
                errs.append(np.degrees(np.abs(wrap_angle(e.numpy()))).mean())
        sched.step()
        log(
            f"  epoch {epoch + 1:3d}/{cfg.epochs}  loss {np.mean(losses):.5f}  yaw error {np.mean(errs):5.2f}°  "
            f"({nb} batches, {time.perf_counter() - t0:.0f} s)"
        )
    return net.eval()


def run_gru(net: GruNet, feats: np.ndarray, hmd_yaw: np.ndarray, chunk: int = 512) -> np.ndarray:
    """Body yaw (B, T) from a zero state at frame 0, frame by frame in effect (the GRU is causal)."""
    B, T, _ = feats.shape
    body = np.zeros((B, T))
    h = None
    with torch.no_grad():
        for t0 in range(0, T, chunk):
            out, h = net(torch.from_numpy(np.ascontiguousarray(feats[:, t0 : t0 + chunk, :TRACKER_INPUTS])), h)
            phi, ok = relative_yaw_of_output(out.numpy())
            body[:, t0 : t0 + chunk] = hmd_yaw[:, t0 : t0 + chunk] + np.where(ok, phi, 0.0)
    return body


def score(net: GruNet, clips, log=print) -> None:
    seqs = held_out_sequences(True, clips=clips, log=log)
    mlp = {"MLP (committed)": OnnxModel(PUBLIC_MODEL)}
    results, arrays = evaluate(seqs, mlp)
    feats, hmd, _ = sequence_features(seqs)
    arrays["preds"]["GRU"] = run_gru(net, feats, hmd)
    results["GRU"] = stats(yaw_error_deg(arrays["preds"]["GRU"], arrays["truth"]), arrays["times"], arrays["lengths"])
    for name in ("GRU", "MLP (committed)", "HMD forward"):
        r = results[name]
        log(f"{name}: mean {r.mean:.1f}°, median {r.median:.1f}°, p95 {r.p95:.1f}°")
    log(class_table(arrays, ["GRU", "MLP (committed)", "HMD forward"]))
    for set_name, absent in DEVICE_SETS.items():
        if not absent:
            continue
        s2 = [with_absent(q, absent) for q in seqs]
        f2, h2, _ = sequence_features(s2)
        e = yaw_error_deg(run_gru(net, f2, h2), arrays["truth"])
        r = stats(e, arrays["times"], arrays["lengths"])
        log(f"GRU, {set_name}: mean {r.mean:.1f}°, p95 {r.p95:.1f}°")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--hidden", type=int, default=48)
    ap.add_argument("--window", type=int, default=180)
    ap.add_argument("--epochs", type=int, default=12)
    ap.add_argument("--max-batches", type=int, default=500)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--absent", type=float, default=GruConfig.absent_prob, help="Augment.absent_prob per controller")
    ap.add_argument("--save", help="write the weights (.pt) here")
    ap.add_argument("--load", help="score (and export) these weights (.pt) instead of training")
    ap.add_argument(
        "--export",
        action="store_true",
        help=f"write {GRU_MODEL.relative_to(data.REPO)}, its config in training/models "
        "and its parity fixture (the committed model: the defaults)",
    )
    args = ap.parse_args(argv)
    if hasattr(sys.stdout, "reconfigure"):
        sys.stdout.reconfigure(line_buffering=True)
    quiet_exporter()
    cfg = GruConfig(
        hidden=args.hidden,
        window=args.window,
        epochs=args.epochs,
        max_batches_per_epoch=args.max_batches,
        seed=args.seed,
        absent_prob=args.absent,
    )
    print(f"GRU {cfg}")
    if args.load:
        net = GruNet(np.zeros(36), np.ones(36), cfg.hidden)  # the normalization is in the weights
        net.load_state_dict(torch.load(args.load))
        net.eval()
    else:
        net = train_gru(cfg, data.load_subjects(TrainConfig().subjects, mirrored=None))
    if args.save:
        torch.save(net.state_dict(), args.save)
    if args.export:
        export(net, cfg)
    score(net, data.load_subjects(data.TEST_SUBJECTS, mirrored=False))
    return 0


def export(net: GruNet, cfg: GruConfig) -> None:
    """The browser's file (features and state in, 6D and the next state out), checked against
    PyTorch over a sequence, its config beside the other models, and its parity fixture."""
    step = GruStep(net).eval()
    meta = {
        "model": "gru",
        "hidden": str(cfg.hidden),
        "window": str(cfg.window),
        "seed": str(cfg.seed),
        "train_subjects": " ".join(data.subject_name(*s) for s in TrainConfig().subjects),
    }
    export_onnx(step, GRU_MODEL, meta, state_size=cfg.hidden)
    onnx_model = OnnxRecurrentModel(GRU_MODEL)
    x = np.random.default_rng(1).normal(0, 1, (50, 4, 36)).astype(np.float32)
    h_t, h_o, worst = torch.zeros(4, cfg.hidden), np.zeros((4, cfg.hidden), np.float32), 0.0
    with torch.no_grad():
        seq_out, _ = net(torch.from_numpy(x.transpose(1, 0, 2)))
        for t in range(50):
            o_t, h_t = step(torch.from_numpy(x[t]), h_t)
            o_o, h_o = onnx_model(x[t], h_o)
            worst = max(
                worst, float(np.abs(o_o - o_t.numpy()).max()), float(np.abs(o_t.numpy() - seq_out[:, t].numpy()).max())
            )
    assert worst < 1e-4, f"exported GRU differs from PyTorch by {worst}"
    print(
        f"wrote {GRU_MODEL.relative_to(data.REPO)} ({GRU_MODEL.stat().st_size / 1024:.1f} KiB; |ONNX − PyTorch| ≤ {worst:.1e})"
    )
    MODELS_DIR.mkdir(parents=True, exist_ok=True)
    (MODELS_DIR / "orientation_gru.json").write_text(json.dumps({"config": asdict(cfg)}, indent=1) + "\n")
    fixture = build_gru_fixture(GRU_MODEL, step)
    GRU_FIXTURE.write_text(json.dumps(fixture) + "\n")
    print(f"wrote {GRU_FIXTURE.relative_to(data.REPO)}")


if __name__ == "__main__":
    sys.exit(main())
