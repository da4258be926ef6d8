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
import sys
import time
from dataclasses import dataclass, replace

import numpy as np
import torch
from torch import nn

from . import data
from .evaluate import class_table, evaluate, held_out_sequences, stats, with_absent, DEVICE_SETS
from .features import relative_yaw_of_output, yaw_slot
from .geometry import wrap_angle
from .predictors import OnnxModel, sequence_features, yaw_error_deg
from .simulate import TRAIN_AUGMENT
from .train import PUBLIC_MODEL, TrainConfig, simulate_epoch


class GruNet(nn.Module):
    def __init__(self, mean: np.ndarray, std: np.ndarray, hidden: int = 48):
        super().__init__()
        std = np.where(np.asarray(std) > 1e-4, std, 1.0)
        self.register_buffer("mean", torch.as_tensor(mean, dtype=torch.float32))
        self.register_buffer("inv_std", torch.as_tensor(1.0 / std, dtype=torch.float32))
        self.hidden = hidden
        self.inp = nn.Linear(36, hidden)
        self.gru = nn.GRU(hidden, hidden, batch_first=True)
        self.out = nn.Linear(hidden, 6)

    def forward(self, x: torch.Tensor, h: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """x (B, T, 36) raw features, h (1, B, H) or None (zeros) → (B, T, 6), h (1, B, H)."""
        z = torch.relu(self.inp((x - self.mean) * self.inv_std))
        y, h = self.gru(z, h)
        return self.out(y), h


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


def train_gru(cfg: GruConfig, clips, log=print) -> GruNet:
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(1)
    rng = np.random.default_rng(cfg.seed)
    sim_cfg = replace(TrainConfig(), r=cfg.window, augment=TRAIN_AUGMENT)
    ep = simulate_epoch(clips, rng, sim_cfg)
    net = GruNet(ep.feats.mean(0), ep.feats.std(0), cfg.hidden)
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
            starts = order[b * cfg.batch:(b + 1) * cfg.batch]
            idx = starts[:, None] + np.arange(cfg.window)
            x = torch.from_numpy(ep.feats[idx])
            target = torch.from_numpy(yaw_slot(ep.body_yaw[idx] - ep.hmd_yaw[idx]).astype(np.float32))
            out, _ = net(x)
            out, target = out[:, cfg.burn_in:], target[:, cfg.burn_in:]
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
        log(f"  epoch {epoch + 1:3d}/{cfg.epochs}  loss {np.mean(losses):.5f}  yaw error {np.mean(errs):5.2f}°  "
            f"({nb} batches, {time.perf_counter() - t0:.0f} s)")
    return net.eval()


def run_gru(net: GruNet, feats: np.ndarray, hmd_yaw: np.ndarray, chunk: int = 512) -> np.ndarray:
    """Body yaw (B, T) from a zero state at frame 0, frame by frame in effect (the GRU is causal)."""
    B, T, _ = feats.shape
    body = np.zeros((B, T))
    h = None
    with torch.no_grad():
        for t0 in range(0, T, chunk):
            out, h = net(torch.from_numpy(feats[:, t0:t0 + chunk]), h)
            phi, ok = relative_yaw_of_output(out.numpy())
            body[:, t0:t0 + chunk] = hmd_yaw[:, t0:t0 + chunk] + np.where(ok, phi, 0.0)
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
    ap.add_argument("--save", help="write the weights (.pt) here")
    args = ap.parse_args(argv)
    if hasattr(sys.stdout, "reconfigure"):
        sys.stdout.reconfigure(line_buffering=True)
    cfg = GruConfig(hidden=args.hidden, window=args.window, epochs=args.epochs, max_batches_per_epoch=args.max_batches, seed=args.seed)
    clips = data.load_subjects(TrainConfig().subjects, mirrored=None)
    print(f"GRU {cfg}")
    net = train_gru(cfg, clips)
    if args.save:
        torch.save(net.state_dict(), args.save)
    score(net, data.load_subjects(data.TEST_SUBJECTS, mirrored=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
