"""Leave-one-person-out: the body-yaw network judged on people it never saw (`npm run eval`).

    python -m orientation.lopo                      # every person of the manifest: ~15 min here
    python -m orientation.lopo --people cmu-05,cmu-06,cmu-10 --epochs 1 --max-batches 20  # CI's form
    python -m orientation.lopo --fit                # and the network trained on everybody, on each person

Every person of `../shared/mocap/manifest.json` (its `person` field; the manifest grows, so
nothing here names one) is held out in turn: a network is trained on everybody else with the
shipped recipe (`train.MODELS["main"]`) and scored on that person's original (not mirrored)
takes, simulated at 72, 90 and 120 Hz, with and without the look-around augmentation, per motion
class (`motion_classes.CLASSES`). The held-out figure is the mean over people, each weighted
equally (a person with ten minutes of mocap counts as much as one with five seconds); p95 is
over every scored frame, each person's frames weighted to the same total.

All the folds train at once, as one stacked model (`StackedNets`: K independent networks whose
weights are (K, ...) tensors; Adam is per element, so this is K separate trainings, bit for bit
up to the order of float sums): one simulated epoch serves every fold, each drawing its windows
only from the people it may see. With `--weights`, one extra member sees everybody, and every
member's weights are written (the shipped model itself comes from `npm run train`).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch

from . import data
from .features import FRAME_COLUMNS, HIPS_GAIN, PREV, frame_features, hips_target
from .geometry import wrap_angle
from .model import AveragedNet, OrientationNet
from .motion_classes import CLASSES, with_crouching
from .predictors import TorchModel, hmd_forward, run_network, sequence_features, yaw_error_deg
from .simulate import EVAL_AUGMENT, simulate, without_look_around

# The fixed split's scoring constants: the same frames count, at the same rates, from the same seed.
from .evaluate import EVAL_FPS, EVAL_SEED, WARMUP
from .train import (
    MODELS,
    Epoch,
    TrainConfig,
    add_override_arguments,
    batch_tensors,
    batch_yaw_error_deg,
    epoch_record,
    loss_of,
    normalization,
    with_overrides,
)

CONDITIONS = ("with look-around", "without look-around")
MIN_CLASS_SECONDS = 2.0  # a person's class counts in the class means from this much scored time


# ---------------------------------------------------------------------------------------------
# Clips packed for another machine: positions in 0.1 mm, yaw in µrad, quaternion parts in
# 1/32767, each a running difference (mocap is smooth: small integers that compress ~5×).

_POS, _YAW, _ROT = 1e-4, 1e-6, 1.0 / 32767.0
_FIELDS = (("body_yaw", _YAW), ("root_pos", _POS), ("head_pos", _POS), ("head_rot", _ROT))


def pack_clips(clips, path: Path) -> Path:
    arrays = {}
    for name, unit in _FIELDS:
        q = np.rint(np.concatenate([getattr(c, name) for c in clips]) / unit).astype(np.int64)
        arrays[name] = np.diff(q, axis=0, prepend=np.zeros_like(q[:1])).astype(np.int32)
    for name, unit in (("hand_pos", _POS), ("hand_rot", _ROT)):
        q = np.rint(np.concatenate([getattr(c, name) for c in clips], axis=1) / unit).astype(np.int64)
        arrays[name] = np.diff(q, axis=1, prepend=np.zeros_like(q[:, :1])).astype(np.int32)
    for name in ("hmd_align", "grip_align", "hand_axis"):
        arrays[name] = np.stack([getattr(c.rig, name) for c in clips])
    meta = [
        {
            "name": c.name,
            "subject": c.subject,
            "mirrored": c.mirrored,
            "fps": c.fps,
            "frames": c.num_frames,
            "head": c.rig.head,
            "hands": list(c.rig.hands),
            "upright_head": c.upright_head,
        }
        for c in clips
    ]
    np.savez_compressed(path, meta=np.array(json.dumps(meta)), **arrays)
    return Path(path)


def unpack_clips(path: Path) -> list:
    z = np.load(path)
    meta = json.loads(str(z["meta"]))
    full = {name: np.cumsum(z[name].astype(np.int64), axis=0) * unit for name, unit in _FIELDS}
    full["hand_pos"] = np.cumsum(z["hand_pos"].astype(np.int64), axis=1) * _POS
    full["hand_rot"] = np.cumsum(z["hand_rot"].astype(np.int64), axis=1) * _ROT
    for name in ("head_rot",):
        full[name] /= np.linalg.norm(full[name], axis=-1, keepdims=True)
    full["hand_rot"] /= np.linalg.norm(full["hand_rot"], axis=-1, keepdims=True)
    clips, at = [], 0
    for i, m in enumerate(meta):
        sl = slice(at, at + m["frames"])
        at += m["frames"]
        rig = data.Rig(m["head"], tuple(m["hands"]), z["hmd_align"][i], z["grip_align"][i], z["hand_axis"][i])
        clips.append(
            data.MocapClip(
                name=m["name"],
                subject=m["subject"],
                mirrored=m["mirrored"],
                fps=m["fps"],
                body_yaw=full["body_yaw"][sl],
                root_pos=full["root_pos"][sl],
                head_pos=full["head_pos"][sl],
                head_rot=full["head_rot"][sl],
                hand_pos=full["hand_pos"][:, sl],
                hand_rot=full["hand_rot"][:, sl],
                rig=rig,
                upright_head=m["upright_head"],
            )
        )
    return clips


# ---------------------------------------------------------------------------------------------
# Simulated epochs, shared by every fold, built in parallel with per-clip seeds (the same
# sequences whatever the number of workers).

_CLIPS: list = []  # the clips, set before the workers fork


def _simulate_one(job: tuple[int, int, int, object, int]):
    i, seed, epoch, aug, variant = job
    rng = np.random.default_rng([seed, epoch, i] + ([variant] if variant else []))
    seq = simulate(_CLIPS[i], rng, aug)
    f, y = frame_features(seq.pos, seq.rot, seq.dt)
    return f.astype(np.float32), y, seq.body_yaw, hips_target(seq.pos[:, 0], y, seq.hips).astype(np.float32)


@dataclass
class SharedEpoch:
    epoch: Epoch
    owner: np.ndarray  # (N,) person index of each frame


def simulate_shared(clips, owners: np.ndarray, cfg: TrainConfig, epoch: int, pool) -> SharedEpoch:
    variants = range(cfg.variants_per_clip)
    jobs = [(i, cfg.seed, epoch, cfg.augment, v) for i in range(len(clips)) for v in variants]
    results = pool.map(_simulate_one, jobs, chunksize=4) if pool else list(map(_simulate_one, jobs))
    feats, hmd, body, hips, starts, owner, offset = [], [], [], [], [], [], 0
    for (f, y, b, h), who in zip(results, np.repeat(owners, len(variants))):
        n = len(f)
        if n >= cfg.r + 1:
            starts.append(offset + np.arange(1, n - cfg.r + 1))
        feats.append(f)
        hmd.append(y)
        body.append(b)
        hips.append(h)
        owner.append(np.full(n, who, dtype=np.int32))
        offset += n
    if not starts:
        raise data.DataError(f"no sequence is longer than r + 1 = {cfg.r + 1} frames")
    ep = Epoch(
        np.concatenate(feats), np.concatenate(hmd), np.concatenate(body), np.concatenate(starts), np.concatenate(hips)
    )
    return SharedEpoch(ep, np.concatenate(owner))


def fold_view(shared: SharedEpoch, held_out: int | None) -> Epoch:
    """The epoch as fold `held_out` sees it: windows of everybody else (None: everybody)."""
    ep = shared.epoch
    if held_out is None:
        return ep
    return replace(ep, starts=ep.starts[shared.owner[ep.starts] != held_out])


# ---------------------------------------------------------------------------------------------
# K networks as one.


class StackedNets(torch.nn.Module):
    """K `OrientationNet`s of the same shape, weights stacked: layer l is W (K, out, in), b (K, out)."""

    def __init__(self, nets: list[OrientationNet]):
        super().__init__()
        linear = [[m for m in n.mlp if isinstance(m, torch.nn.Linear)] for n in nets]
        self.weights = torch.nn.ParameterList(
            torch.nn.Parameter(torch.stack([ls[i].weight.detach() for ls in linear])) for i in range(len(linear[0]))
        )
        self.biases = torch.nn.ParameterList(
            torch.nn.Parameter(torch.stack([ls[i].bias.detach() for ls in linear])) for i in range(len(linear[0]))
        )
        self.register_buffer("mean", torch.stack([n.mean for n in nets]))
        self.register_buffer("inv_std", torch.stack([n.inv_std for n in nets]))
        self.hidden, self.outputs = nets[0].hidden, nets[0].outputs

    def member(self, k: int) -> OrientationNet:
        net = OrientationNet(hidden=self.hidden, outputs=self.outputs)
        linear = [m for m in net.mlp if isinstance(m, torch.nn.Linear)]
        with torch.no_grad():
            for layer, w, b in zip(linear, self.weights, self.biases):
                layer.weight.copy_(w[k])
                layer.bias.copy_(b[k])
            net.mean.copy_(self.mean[k])
            net.inv_std.copy_(self.inv_std[k])
        return net.eval()

    def rollout(self, feats: torch.Tensor, dyaw: torch.Tensor, prev0: torch.Tensor, previous: bool = False):
        """`train.fast_rollout` for every member at once: feats (K, B, r, 48), dyaw (K, B, r),
        prev0 (K, B, 2) → last outputs (K, B, 8). The first r − 1 steps run without autograd
        (the fed-back estimates are inputs, as in `fast_rollout`). With `previous`, also the
        step before's estimate as (cos φ, sin φ) (K, B, 1) each, φ in the last frame's HMD frame."""
        w1, b1 = self.weights[0], self.biases[0]
        m, iv = self.mean[:, PREV], self.inv_std[:, PREV]
        cols = torch.as_tensor(FRAME_COLUMNS, device=m.device)
        fixed = torch.tensor([0.0, 0.0, 0.0, 0.0, 1.0, 0.0], device=m.device)
        const = torch.einsum("ki,khi->kh", (fixed - m) * iv, w1[:, :, PREV]) + b1
        wc = (w1[:, :, PREV.start] * iv[:, 0:1])[:, None]  # (K, 1, H)
        ws = (-w1[:, :, PREV.start + 2] * iv[:, 2:3])[:, None]
        x = (feats - self.mean[:, None, None, cols]) * self.inv_std[:, None, None, cols]
        pre = torch.einsum("kbri,khi->kbrh", x, w1[:, :, cols]) + const[:, None, None]
        cd, sd = torch.cos(dyaw), torch.sin(dyaw)
        middle = list(zip(self.weights[1:-1], self.biases[1:-1]))
        w3, b3 = self.weights[-1], self.biases[-1]

        def hidden(h):
            for w, b in middle:
                h = torch.relu(torch.baddbmm(b[:, None], h, w.transpose(1, 2)))
            return h

        c, s = prev0[..., :1], prev0[..., 1:]
        r = feats.shape[2]

        def turn(c, s, t):
            ct, st = cd[:, :, t : t + 1], sd[:, :, t : t + 1]
            return c * ct + s * st, s * ct - c * st

        w3s, b3s = w3[:, [0, 2]].transpose(1, 2), b3[:, None, [0, 2]]
        with torch.no_grad():
            for t in range(r - 1):
                if t > 0:
                    c, s = turn(c, s, t)
                h = torch.relu(pre[:, :, t] + c * wc + s * ws)
                o = torch.baddbmm(b3s, hidden(h), w3s)
                n = torch.rsqrt(o[..., :1] * o[..., :1] + o[..., 1:] * o[..., 1:] + 1e-8)
                c, s = o[..., :1] * n, -o[..., 1:] * n
        if r > 1:
            c, s = turn(c, s, r - 1)
        h = torch.relu(pre[:, :, r - 1] + c * wc + s * ws)
        out = torch.baddbmm(b3[:, None], hidden(h), w3.transpose(1, 2))
        return (out, c, s) if previous else out


def turned_truth(ep: Epoch, starts: np.ndarray, r: int) -> np.ndarray:
    """The body's true change of yaw into the last frame of each window (radians)."""
    last = starts + r - 1
    return wrap_angle(ep.body_yaw[last] - ep.body_yaw[last - 1])


def train_folds(
    clips,
    owners,
    folds: list[int | None],
    cfg: TrainConfig,
    jobs: int = 1,
    log=print,
    device: str = "cpu",
    time_budget: float | None = None,
) -> StackedNets:
    """One network per entry of `folds` (a person index held out, or None: nobody), trained
    together on shared simulated epochs with the recipe `cfg` (on `device`: "cpu" or "cuda")."""
    global _CLIPS
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(1)
    rng = np.random.default_rng(cfg.seed)
    _CLIPS = clips
    pool = multiprocessing.get_context("fork").Pool(jobs) if jobs > 1 else None
    try:
        t0 = time.perf_counter()
        shared = simulate_shared(clips, owners, cfg, 0, pool)
        views = [fold_view(shared, k) for k in folds]
        nets = StackedNets([OrientationNet(*normalization(v), hidden=cfg.hidden) for v in views]).to(device)
        nets.history = []
        opt = torch.optim.AdamW(nets.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
        sched = torch.optim.lr_scheduler.ExponentialLR(opt, gamma=cfg.lr_decay)
        for epoch in range(cfg.epochs):
            if epoch > 0:
                shared = simulate_shared(clips, owners, cfg, epoch, pool)
                views = [fold_view(shared, k) for k in folds]
            orders = [rng.permutation(v.starts) for v in views]
            nb = min(len(o) for o in orders) // cfg.batch
            if cfg.max_batches_per_epoch:
                nb = min(nb, cfg.max_batches_per_epoch)
            losses, errs = [], []
            for b in range(nb):
                parts = [
                    batch_tensors(v, o[b * cfg.batch : (b + 1) * cfg.batch], cfg, rng) for v, o in zip(views, orders)
                ]
                feats, dyaw, prev0, target = (torch.stack(x).to(device) for x in zip(*parts))
                out, c, s = nets.rollout(feats, dyaw, prev0, previous=True)
                # Sum over members of each member's mean: every member's gradient is its own.
                loss = loss_of(out, target, cfg.hips_weight, dims=(1, 2)).sum()
                if cfg.smooth > 0 and cfg.r > 1:
                    # Temporal consistency: the step before's estimate turned by the body's true
                    # change of yaw; the fed-back estimate is an input (no gradient), as above.
                    d = np.stack(
                        [turned_truth(v, o[b * cfg.batch : (b + 1) * cfg.batch], cfg.r) for v, o in zip(views, orders)]
                    )
                    d = torch.from_numpy(d.astype(np.float32)).to(device)[..., None]
                    a = torch.atan2(s, c) + d
                    z = torch.zeros_like(a)
                    smooth = torch.cat([torch.cos(a), z, -torch.sin(a), z, torch.ones_like(a), z], dim=-1)
                    loss = loss + cfg.smooth * ((out[..., :6] - smooth) ** 2).mean(dim=(1, 2)).sum()
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                losses.append(loss.item() / len(folds))
                errs.append(batch_yaw_error_deg(out, target))
            sched.step()
            nets.history.append(epoch_record(epoch, losses, errs, nb, opt, t0))
            log(
                f"  epoch {epoch + 1:3d}/{cfg.epochs}  mean loss {np.mean(losses):.5f}  "
                f"({nb} batches × {len(folds)} folds, {time.perf_counter() - t0:.0f} s)"
            )
            nets.epochs_done = epoch + 1
            if time_budget is not None and time.perf_counter() - t0 > time_budget:
                log(f"  time budget {time_budget:.0f} s reached after {epoch + 1} epochs, stopping")
                break
    finally:
        if pool:
            pool.close()
    return nets.cpu().eval()


# ---------------------------------------------------------------------------------------------
# Scoring one held-out person.


@dataclass
class Scored:
    """Per-frame errors of one person under one condition: the network's and HMD-forward's,
    with each scored frame's class and duration."""

    net: np.ndarray  # (F,) degrees
    hmd: np.ndarray  # (F,)
    classes: np.ndarray  # (F,)
    dt: np.ndarray  # (F,) seconds
    signed: np.ndarray  # (F,) the network's error with its sign (degrees, + = counter-clockwise)
    jerk: np.ndarray  # (F,) |second difference| of the network's yaw, degrees per frame²
    hips: np.ndarray  # (F,) cm from the page's root target (`HIPS_GAIN` of the second output) to the true hips
    under: np.ndarray  # (F,) cm from the head centre (MMVR's root target) to the true hips on the floor


def originals(clips, person: str) -> list:
    """A person's original (not mirrored) clips, the ones scored."""
    return [c for c in clips if c.subject == person and not c.mirrored]


def score_person(net: OrientationNet, clips, aug, fps_list=EVAL_FPS, seed: int = EVAL_SEED) -> Scored:
    """One network on `clips` (their classes with crouching: `run` sets them) simulated with
    `aug` at each of `fps_list`, frame by frame from a reset as at run time."""
    rng = np.random.default_rng(seed)
    seqs = [simulate(c, rng, aug, fps=f) for c in clips for f in fps_list]
    feats, hmd, lengths = sequence_features(seqs)
    hips = np.full(feats.shape[:2] + (2,), np.nan)
    pred = run_network(TorchModel(net), feats, hmd, hips=hips)
    out = {"net": [], "hmd": [], "classes": [], "dt": [], "signed": [], "jerk": [], "hips": [], "under": []}
    for b, s in enumerate(seqs):
        n = s.num_frames
        times = np.cumsum(s.dt) - s.dt[0]
        keep = times >= WARMUP
        out["net"].append(yaw_error_deg(pred[b, :n], s.body_yaw)[keep])
        out["signed"].append(np.degrees(wrap_angle(pred[b, :n] - s.body_yaw))[keep])
        out["hmd"].append(yaw_error_deg(hmd_forward(hmd[b, :n]), s.body_yaw)[keep])
        out["classes"].append(s.classes[keep])
        out["dt"].append(s.dt[keep])
        y = np.unwrap(pred[b, :n])
        out["jerk"].append(np.degrees(np.abs(np.diff(y, 2, prepend=y[:1], append=y[-1:])))[keep])
        truth = hips_target(s.pos[:, 0], hmd[b, :n], s.hips)
        out["hips"].append(100.0 * np.linalg.norm(HIPS_GAIN * hips[b, :n] - truth, axis=1)[keep])
        out["under"].append(100.0 * np.linalg.norm(truth, axis=1)[keep])
    return Scored(*(np.concatenate(out[k]) for k in ("net", "hmd", "classes", "dt", "signed", "jerk", "hips", "under")))


# The device-variation table: one change at a time from the evaluation's devices (with looking
# around, 90 Hz), every fold scored on its own person. Grip angles are about the grip's own
# axes (WebXR gripSpace: x right/out of the back of the hand, y back along the forearm, z out
# of the fist's thumb side reversed), the left grip mirrored.
DEVICE_VARIATIONS = {
    "as evaluated (90 Hz)": {},
    "72 Hz": {"fps": 72.0},
    "120 Hz": {"fps": 120.0},
    **{
        f"grip {a} {'+' if v > 0 else '−'}{abs(v)}°": {"grip_rot": tuple(v if i == j else 0 for j in range(3))}
        for i, a in enumerate("xyz")
        for v in (30, -30)
    },
    "headset pitched +15°": {"hmd_pitch": 15.0},
    "headset pitched −15°": {"hmd_pitch": -15.0},
    "headset 3 cm lower, 3 cm further out": {"hmd_offset": (0.0, -0.03, -0.03)},
    "a 1.5 m person (head at 1.4 m)": {"head_height": (1.4, 1.4)},
    "a 2.0 m person (head at 1.9 m)": {"head_height": (1.9, 1.9)},
    "tracking noise ×4": {"noise_pos": (0.002, 0.002), "noise_rot": (0.4, 0.4)},
    "10 % dropped frames": {"dropped_frame_prob": 0.1},
    "controllers freeze (from a random time)": {"frozen_prob": 1.0},
}
# The rows whose spread the issue bounds: how the controllers are held and the headset worn.
HOLDING_ROWS = [k for k in DEVICE_VARIATIONS if k.startswith(("grip", "headset"))]


def device_variations(nets: list, clips, folds: list[str], log=print) -> dict:
    """Mean error over people (each weighted equally) per row of `DEVICE_VARIATIONS`."""
    out = {}
    for row, change in DEVICE_VARIATIONS.items():
        change = dict(change)
        fps = change.pop("fps", 90.0)
        aug = replace(EVAL_AUGMENT, **change)
        means = []
        for k, person in enumerate(folds):
            held = originals(clips, person)
            means.append(float(score_person(nets[k], held, aug, (fps,)).net.mean()))
        out[row] = float(np.mean(means))
        log(f"  {row}: {out[row]:.1f}°")
    return out


def standing_offsets(scored: dict[str, Scored]) -> dict[str, float]:
    """Per person, the network's mean signed error while standing (degrees): a steady offset."""
    i = CLASSES.index("standing")
    return {p: float(s.signed[s.classes == i].mean()) for p, s in scored.items() if (s.classes == i).sum() > 0}


def summarize(scored: dict[str, Scored]) -> dict:
    """Per person: mean, p95, per-class mean and seconds, for the network and HMD-forward."""
    out = {}
    for person, s in scored.items():
        row = {
            "frames": int(len(s.net)),
            "mean": float(s.net.mean()) if len(s.net) else float("nan"),
            "p95": float(np.percentile(s.net, 95)) if len(s.net) else float("nan"),
            "hmd": float(s.hmd.mean()) if len(s.net) else float("nan"),
            "jerk": float(s.jerk.mean()) if len(s.net) else float("nan"),
            "hips": float(s.hips.mean()) if len(s.net) else float("nan"),
            "under": float(s.under.mean()) if len(s.net) else float("nan"),
            "classes": {},
        }
        for i, c in enumerate(CLASSES):
            m = s.classes == i
            secs = float(s.dt[m].sum())
            if m.any():
                row["classes"][c] = {"seconds": secs, "mean": float(s.net[m].mean()), "hmd": float(s.hmd[m].mean())}
        out[person] = row
    return out


def weighted_p95(scored: dict[str, Scored]) -> float:
    """95th percentile of every scored frame's error, each person's frames weighing 1 in all."""
    v = np.concatenate([s.net for s in scored.values() if len(s.net)])
    w = np.concatenate([np.full(len(s.net), 1.0 / len(s.net)) for s in scored.values() if len(s.net)])
    order = np.argsort(v)
    cw = np.cumsum(w[order])
    return float(v[order][np.searchsorted(cw, 0.95 * cw[-1])])


def totals(per_person: dict, p95: float) -> dict:
    """The held-out figures: means over people (equal weights), per class over the people with
    at least `MIN_CLASS_SECONDS` of it."""
    rows = [r for r in per_person.values() if r["frames"]]
    mean = float(np.mean([r["mean"] for r in rows]))
    hmd = float(np.mean([r["hmd"] for r in rows]))
    jerk = float(np.mean([r["jerk"] for r in rows]))
    hips = float(np.mean([r.get("hips", np.nan) for r in rows]))
    under = float(np.mean([r.get("under", np.nan) for r in rows]))
    classes = {}
    for c in CLASSES:
        have = [r["classes"][c] for r in rows if c in r["classes"] and r["classes"][c]["seconds"] >= MIN_CLASS_SECONDS]
        if have:
            classes[c] = {
                "people": len(have),
                "mean": float(np.mean([h["mean"] for h in have])),
                "hmd": float(np.mean([h["hmd"] for h in have])),
            }
    ratio = mean / hmd if hmd > 0 else float("nan")
    return {
        "mean": mean,
        "p95": p95,
        "hmd": hmd,
        "ratio": ratio,
        "jerk": jerk,
        "hips": hips,
        "under": under,
        "classes": classes,
    }


def table(results: dict) -> str:
    """Markdown: one row per held-out person — mean / p95, then each class's mean (network · HMD
    forward), both conditions; the last rows the means over people."""
    lines = []
    for cond in CONDITIONS:
        per, tot = results[cond]["people"], results[cond]["total"]
        lines += [
            f"**{cond}** (network · HMD forward, degrees)",
            "",
            "| held out | seconds | mean | p95 | " + " | ".join(CLASSES) + " | root target cm · under the head |",
            "|---|---|---|---|" + "---|" * len(CLASSES) + "---|",
        ]
        for person, r in per.items():
            secs = sum(c["seconds"] for c in r["classes"].values())
            cells = [
                f"{r['classes'][c]['mean']:.1f} · {r['classes'][c]['hmd']:.1f}"
                if c in r["classes"] and r["classes"][c]["seconds"] >= MIN_CLASS_SECONDS
                else ""
                for c in CLASSES
            ]
            lines.append(
                f"| {person} | {secs:.0f} | {r['mean']:.1f} · {r['hmd']:.1f} | {r['p95']:.1f} | "
                + " | ".join(cells)
                + f" | {r.get('hips', np.nan):.1f} · {r.get('under', np.nan):.1f} |"
            )
        cells = [
            f"**{tot['classes'][c]['mean']:.1f}** · {tot['classes'][c]['hmd']:.1f}" if c in tot["classes"] else ""
            for c in CLASSES
        ]
        lines.append(
            f"| **mean over {len(per)} people** | | **{tot['mean']:.1f}** · {tot['hmd']:.1f} "
            f"(×{tot['ratio']:.2f}) | **{tot['p95']:.1f}** | "
            + " | ".join(cells)
            + f" | **{tot.get('hips', np.nan):.1f}** · {tot.get('under', np.nan):.1f} |"
        )
        lines.append("")
    return "\n".join(lines)


def device_table(rows: dict[str, float]) -> str:
    """Markdown: mean error over people per device variation, and its change from the first row."""
    base = next(iter(rows.values()))
    lines = ["| devices (with look-around) | mean over people | change |", "|---|---|---|"]
    sign = lambda x: f"{x:+.1f}".replace("-", "−") if round(x, 1) != 0 else "±0.0"  # noqa: E731
    lines += [f"| {k} | {v:.1f}° | {sign(v - base)}° |" for k, v in rows.items()]
    spread = max(abs(rows[k] - base) for k in HOLDING_ROWS)
    lines.append(f"| **largest change, grip and headset rows** | | **{spread:.1f}°** |")
    return "\n".join(lines)


def worse_than_hmd(results: dict, cond: str = "without look-around", margin: float = 0.0) -> list[str]:
    """People and people's classes where the network is worse than HMD-forward."""
    out = []
    for person, r in results[cond]["people"].items():
        if r["mean"] > r["hmd"] + margin:
            out.append(f"{person} overall {r['mean']:.1f}° vs {r['hmd']:.1f}°")
        for c, v in r["classes"].items():
            if v["seconds"] >= MIN_CLASS_SECONDS and v["mean"] > v["hmd"] + margin:
                out.append(f"{person} {c} {v['mean']:.1f}° vs {v['hmd']:.1f}°")
    return out


def run(
    names: list[str] | None = None,
    folds: list[str] | None = None,
    cfg: TrainConfig | None = None,
    jobs: int = 1,
    log=print,
    clips: list | None = None,
    device: str = "cpu",
    weights: Path | None = None,
    time_budget: float | None = None,
    devices: bool = False,
    onnx_dir: Path | None = None,
    fit: bool = False,
) -> dict:
    """Train the folds (and, with `weights` or `fit`, the member that sees everybody) and score
    them. `clips`: already loaded (`unpack_clips`) instead of built from the manifest. `fit`: also
    score the member that saw everybody on each fold's person (`results["fit"]`, with look-around):
    how well the recipe fits people it trained on, beside how it does on people it did not."""
    cfg = cfg or MODELS["main"]
    everyone = list(dict.fromkeys(c.subject for c in clips)) if clips is not None else list(data.people())
    names = names or everyone
    folds = folds or names
    bad = [f for f in folds if f not in names]
    if bad:
        raise data.DataError(f"fold(s) {', '.join(bad)} are not among the people trained on")
    if clips is None:
        clips = data.load_people(names, mirrored=None, log=log)
    else:
        clips = [c for c in clips if c.subject in names]
    owners = np.array([names.index(c.subject) for c in clips])
    for c in clips:  # the scored clips' classes with crouching, once for every score below
        if not c.mirrored and c.subject in folds:
            c._classes = with_crouching(c)
    # Each fold's network is `cfg.members` networks averaged (`model.AveragedNet`), trained side
    # by side: member m of entry p of `base` is stacked member p + m·len(base).
    everybody = weights is not None or fit  # one more network, trained on everybody, last in `base`
    base: list[int | None] = [names.index(f) for f in folds] + ([None] if everybody else [])
    members = base * cfg.members
    log(
        f"{len(names)} people, {len(clips)} clips ({sum(c.seconds for c in clips):.0f} s with mirrors); "
        f"{len(folds)} folds{' + one on everybody' if everybody else ''}, {cfg.epochs} epochs ≤ "
        f"{cfg.max_batches_per_epoch} batches of {cfg.batch}, seed {cfg.seed}, {cfg.members} network(s) averaged"
    )
    nets = train_folds(clips, owners, members, cfg, jobs, log, device, time_budget)

    def fold_net(p: int):
        if cfg.members == 1:
            return nets.member(p)
        return AveragedNet([nets.member(p + m * len(base)) for m in range(cfg.members)]).eval()

    fold_nets = [fold_net(p) for p in range(len(base))]
    if weights:
        from .model import state_to_numpy

        states = {
            f"{k}/{n}": v
            for k, p in enumerate(folds + ["everyone"])
            for n, v in state_to_numpy(fold_nets[k]).items()
            if k < len(base)
        }
        np.savez(weights, folds=np.array(json.dumps(folds + ["everyone"])), **states)
    if onnx_dir:
        # Each fold's network as the page loads one (`vr.html?model=`): the replays of a person's
        # recordings run on the network that never saw them (`npm run bench -- --vr --lopo`).
        from .model import export_onnx

        for k, person in enumerate(folds):
            meta = {"held_out_person": person, "trained_on": ",".join(n for n in names if n != person)}
            export_onnx(fold_nets[k], onnx_dir / f"{person}.onnx", meta)
            log(f"wrote {onnx_dir / f'{person}.onnx'}")
    results = {}
    for look, cond in zip((True, False), CONDITIONS):
        aug = EVAL_AUGMENT if look else without_look_around(EVAL_AUGMENT)
        scored = {}
        for k, person in enumerate(folds):
            held = originals(clips, person)
            scored[person] = score_person(fold_nets[k], held, aug)
        per = summarize(scored)
        results[cond] = {"people": per, "total": totals(per, weighted_p95(scored))}
        if not look:
            results["standing offset"] = standing_offsets(scored)
    if fit:
        results["fit"] = {
            p: float(score_person(fold_nets[len(folds)], originals(clips, p), EVAL_AUGMENT).net.mean()) for p in folds
        }
    if devices:
        results["devices"] = device_variations(fold_nets, clips, folds, log)
    results["recipe"] = {
        "epochs": cfg.epochs,
        "epochs_done": getattr(nets, "epochs_done", 0),
        "batches": cfg.max_batches_per_epoch,
        "batch": cfg.batch,
        "hidden": list(cfg.hidden),
        "members": cfg.members,
        "seed": cfg.seed,
        "people": names,
    }
    return results


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--people", help="comma-separated manifest persons to use (default: everyone)")
    ap.add_argument("--folds", help="comma-separated persons to hold out (default: each of --people)")
    add_override_arguments(ap)
    ap.add_argument("--batch", type=int)
    ap.add_argument("--smooth", type=float, help="TrainConfig.smooth: the temporal-consistency loss's weight")
    ap.add_argument("--lr", type=float)
    ap.add_argument("--devices", action="store_true", help="also the device-variation table")
    ap.add_argument(
        "--augment",
        action="append",
        metavar="FIELD=VALUE",
        help="an experiment: set a training Augment field (a number or comma-separated numbers)",
    )
    ap.add_argument("--time-budget", type=float, help="stop training after the epoch that passes this many seconds")
    ap.add_argument("--jobs", type=int, default=max(1, multiprocessing.cpu_count()), help="simulation workers")
    ap.add_argument("--json", type=Path, help="write the results here")
    ap.add_argument("--pack", type=Path, help="write the people's clips, packed, to this file and stop")
    ap.add_argument("--clips", type=Path, help="read the clips from a --pack file instead of the mocap")
    ap.add_argument("--device", default="cpu", help="train on this torch device (cuda: the folds' rollouts)")
    ap.add_argument("--weights", type=Path, help="also train on everybody; write every member's weights (.npz)")
    ap.add_argument(
        "--fit",
        action="store_true",
        help="also train on everybody and score that network on each person (people it saw): fit against held out",
    )
    ap.add_argument(
        "--onnx", type=Path, help="write each fold's network to this folder as <person>.onnx (the VR bench's --lopo)"
    )
    args = ap.parse_args(argv)
    if hasattr(sys.stdout, "reconfigure"):
        sys.stdout.reconfigure(line_buffering=True)
    cfg = with_overrides(MODELS["main"], args)
    if args.batch:
        cfg = replace(cfg, batch=args.batch)
    if args.smooth is not None:
        cfg = replace(cfg, smooth=args.smooth)
    for a in args.augment or ():
        field, value = a.split("=", 1)
        nums = tuple(float(v) for v in value.split(","))
        cfg = replace(cfg, augment=replace(cfg.augment, **{field: nums if len(nums) > 1 else nums[0]}))
    if args.lr:
        cfg = replace(cfg, lr=args.lr)
    t0 = time.perf_counter()
    split = lambda s: [x for x in s.split(",") if x] if s else None  # noqa: E731
    if args.pack:
        names = split(args.people) or list(data.people())
        pack_clips(data.load_people(names, mirrored=None), args.pack)
        print(f"wrote {args.pack} ({args.pack.stat().st_size / 1e6:.1f} MB)")
        return 0
    clips = unpack_clips(args.clips) if args.clips else None
    results = run(
        split(args.people),
        split(args.folds),
        cfg,
        args.jobs,
        clips=clips,
        device=args.device,
        weights=args.weights,
        time_budget=args.time_budget,
        devices=args.devices,
        onnx_dir=args.onnx,
        fit=args.fit,
    )
    print()
    print(table(results))
    for cond in CONDITIONS:
        t = results[cond]["total"]
        worst = max(t["classes"].items(), key=lambda kv: kv[1]["mean"]) if t["classes"] else ("-", {"mean": 0})
        print(
            f"{cond}: mean {t['mean']:.1f}° over people, p95 {t['p95']:.1f}°, ×{t['ratio']:.2f} HMD forward; "
            f"worst class {worst[0]} {worst[1]['mean']:.1f}°; yaw jerk (mean |Δ²yaw|) {t['jerk']:.2f}°/frame²; "
            f"root target {t['hips']:.1f} cm from the hips (the head centre: {t['under']:.1f} cm)"
        )
    if "devices" in results:
        print()
        print(device_table(results["devices"]))
    offsets = results["standing offset"]
    if offsets:
        worst = max(offsets, key=lambda p: abs(offsets[p]))
        print(
            f"standing still (without look-around), mean signed yaw error: largest {offsets[worst]:+.1f}° ({worst}), "
            f"mean |offset| over people {np.mean(np.abs(list(offsets.values()))):.1f}°"
        )
    if "fit" in results:
        fit, held = results["fit"], results[CONDITIONS[0]]["people"]
        print(
            "fit (with look-around; the network trained on everybody, scored on each person it saw · held out): "
            + ", ".join(f"{p} {fit[p]:.1f} · {held[p]['mean']:.1f}" for p in fit)
            + f"; mean over people {np.mean(list(fit.values())):.1f}° · {np.mean([held[p]['mean'] for p in fit]):.1f}°"
        )
    worse = worse_than_hmd(results)
    print(f"worse than HMD forward without look-around: {'; '.join(worse) if worse else 'nowhere'}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")
    print(f"leave-one-person-out finished in {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
