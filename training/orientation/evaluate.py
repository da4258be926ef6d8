"""Evaluate body-yaw predictors on the held-out subjects (`npm run eval`).

    python -m orientation.evaluate [--quick] [--no-plots]

Data: every original (not mirrored) take of the held-out subjects (`data.TEST_SUBJECTS`),
simulated at 72, 90 and 120 Hz at the real speed, with tracker noise and random device
offsets, once with the look-around augmentation (head yaw up to ±60° off the body) and once
without. Each predictor runs frame by frame from a reset at the start of the take, as at run
time; errors are |body yaw − true yaw| in degrees over every frame after the first second
(`WARMUP`: every predictor starts from "HMD forward"; a running session has long left it).

Predictors: the committed network (r = 50), the network trained with r = 1, the r = 50
network trained without look-around, HMD-forward, and the dead-zone heuristic (the body turns
toward the head once the head is more than 25° off). Writes docs/orientation-error-time.png
and docs/orientation-error-hist.png and prints the README table.

Device sets: the same look-around sequences with one or both controllers absent, each replaced
by the pose the VR page gives an absent controller (`TrackerState`'s hanging hand at the side of
the head's heading: `simulate.hanging_pose`, the page's defaults) — the inputs the network sees live with
the headset alone or one controller. The network is not retrained per set.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from . import data
from .motion_classes import CLASSES
from .predictors import (
    dead_zone,
    hmd_forward,
    load_model,
    page_yaw,
    run_network,
    run_recurrent,
    sequence_features,
    yaw_error_deg,
)
from .simulate import EVAL_AUGMENT, TrackerSequence, hanging_pose, simulate, without_look_around
from .train import MODELS_DIR, PUBLIC_MODEL

WARMUP = 1.0  # s
EVAL_FPS = (72.0, 90.0, 120.0)
EVAL_SEED = 20220
DOCS = data.REPO / "docs"

# Device set -> trackers absent (1 left, 2 right).
DEVICE_SETS = {"two controllers": (), "left controller only": (2,), "headset only": (1, 2)}


def with_absent(seq: TrackerSequence, absent: tuple[int, ...]) -> TrackerSequence:
    """`seq` with the controllers `absent` replaced by the page's hanging pose."""
    if not absent:
        return seq
    pos, rot = seq.pos.copy(), seq.rot.copy()
    for t in absent:
        pos[:, t], rot[:, t] = hanging_pose(seq.pos[:, 0], seq.rot[:, 0], t)
    return replace(seq, pos=pos, rot=rot)


GRU_MODEL = data.GRU_MODEL
PREDICTORS_MAIN = "network r=50"
PREDICTORS = {
    "network r=50": PUBLIC_MODEL,
    "GRU (the one-controller and headset-only model)": GRU_MODEL,
    "network r=1": MODELS_DIR / "orientation_r1.onnx",
    "network r=50, trained without look-around": MODELS_DIR / "orientation_nolook.onnx",
}
BASELINES = ("HMD forward", "dead zone 25°")
# What the VR page does (web/src/vr/network-yaw.ts): the mean of the two models' yaws, whatever
# devices are tracked.
PAGE = "VR page (network ⊕ GRU)"


def held_out_sequences(
    look_around: bool, seed: int = EVAL_SEED, fps_list=EVAL_FPS, clips=None, log=print
) -> list[TrackerSequence]:
    clips = data.load_subjects(data.TEST_SUBJECTS, mirrored=False, log=log) if clips is None else clips
    aug = EVAL_AUGMENT if look_around else without_look_around(EVAL_AUGMENT)
    rng = np.random.default_rng(seed)
    return [simulate(c, rng, aug, fps=f) for c in clips for f in fps_list]


@dataclass
class Result:
    errors: np.ndarray  # (B, T) degrees, NaN where padded or in the warm-up
    mean: float
    median: float
    p95: float


def scored(times: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The frames that count: inside each sequence, after the first `WARMUP` seconds."""
    T = times.shape[1]
    return (np.arange(T)[None, :] < lengths[:, None]) & (times >= WARMUP)


def stats(err: np.ndarray, times: np.ndarray, lengths: np.ndarray, where: np.ndarray | None = None) -> Result:
    mask = scored(times, lengths)
    if where is not None:
        mask &= where
    e = np.where(mask, err, np.nan)
    v = e[mask]
    if v.size == 0:
        return Result(e, float("nan"), float("nan"), float("nan"))
    return Result(e, float(v.mean()), float(np.median(v)), float(np.percentile(v, 95)))


def evaluate(seqs: list[TrackerSequence], models: dict[str, object]) -> tuple[dict[str, Result], dict]:
    """Errors of every predictor (name -> Result) on the sequences; also the padded arrays. With
    the committed network and the recurrent model among `models`, also the VR page's mean of
    the two (`PAGE`)."""
    feats, hmd, lengths = sequence_features(seqs)
    B, T = hmd.shape
    truth = np.zeros((B, T))
    dt = np.full((B, T), 1.0 / 90)
    times = np.zeros((B, T))
    classes = np.full((B, T), -2)
    for b, s in enumerate(seqs):
        n = s.num_frames
        truth[b, :n], dt[b, :n] = s.body_yaw, s.dt
        times[b, :n] = np.cumsum(s.dt) - s.dt[0]
        if s.classes is not None:
            classes[b, :n] = s.classes
    preds = {
        name: (run_recurrent if getattr(m, 'recurrent', False) else run_network)(m, feats, hmd)
        for name, m in models.items()
    }
    main, recurrent = PREDICTORS_MAIN, next((n for n, m in models.items() if getattr(m, "recurrent", False)), None)
    if main in preds and recurrent:
        preds[PAGE] = page_yaw(preds[main], preds[recurrent], dt)
    preds["HMD forward"] = hmd_forward(hmd)
    preds["dead zone 25°"] = dead_zone(hmd, dt)
    out = {name: stats(yaw_error_deg(p, truth), times, lengths) for name, p in preds.items()}
    return out, {"times": times, "lengths": lengths, "truth": truth, "hmd": hmd, "preds": preds, "classes": classes}


def per_class(arrays: dict, names: list[str]) -> dict[str, dict[str, Result]]:
    """Errors of the predictors `names` per motion class (`motion_classes.CLASSES`)."""
    out = {}
    for name in names:
        err = yaw_error_deg(arrays["preds"][name], arrays["truth"])
        out[name] = {
            c: stats(err, arrays["times"], arrays["lengths"], arrays["classes"] == i) for i, c in enumerate(CLASSES)
        }
    return out


def class_table(arrays: dict, names: list[str]) -> str:
    """Markdown: mean / p95 per motion class and the seconds scored in each."""
    res = per_class(arrays, names)
    mask = scored(arrays["times"], arrays["lengths"])
    dt = np.diff(arrays["times"], axis=1, prepend=0.0)
    secs = [float(dt[mask & (arrays["classes"] == i)].sum()) for i in range(len(CLASSES))]
    rows = [
        "| predictor | " + " | ".join(f"{c} ({s:.0f} s)" for c, s in zip(CLASSES, secs)) + " |",
        "|---|" + "---|" * len(CLASSES),
    ]
    for n in names:
        rows.append(f"| {n} | " + " | ".join(f"{res[n][c].mean:.1f}° / {res[n][c].p95:.1f}°" for c in CLASSES) + " |")
    return "\n".join(rows)


def table(results: dict[str, dict[str, Result]]) -> str:
    conds = list(results)
    names = list(next(iter(results.values())))
    head = "| predictor | " + " | ".join(f"{c}: mean / median / p95" for c in conds) + " |"
    rows = [head, "|---|" + "---|" * len(conds)]
    for n in names:
        cells = [f"{r[n].mean:.1f}° / {r[n].median:.1f}° / {r[n].p95:.1f}°" for r in results.values()]
        rows.append(f"| {n} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def per_subject(results: dict[str, dict[str, Result]], seqs: dict[str, list]) -> str:
    """Mean error per held-out subject (markdown table), every predictor, both conditions."""
    subjects = [data.subject_name(*s) for s in data.TEST_SUBJECTS]
    conds = list(results)
    names = list(next(iter(results.values())))
    rows = [
        "| predictor | " + " | ".join(f"{c}: {s}" for c in conds for s in subjects) + " |",
        "|---|" + "---|" * (len(conds) * len(subjects)),
    ]
    for n in names:
        cells = []
        for c in conds:
            for subj in subjects:
                idx = [i for i, q in enumerate(seqs[c]) if q.subject == subj]
                cells.append(f"{np.nanmean(results[c][n].errors[idx]):.1f}°")
        rows.append(f"| {n} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def plots(results: dict[str, dict[str, Result]], arrays: dict[str, dict], seqs: dict[str, list]) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cond = "with look-around"
    res, arr = results[cond], arrays[cond]
    colors = {
        "network r=50": "#1f77b4",
        "network r=1": "#ff7f0e",
        "network r=50, trained without look-around": "#9467bd",
        "GRU (the one-controller and headset-only model)": "#17becf",
        PAGE: "#000000",
        "HMD forward": "#d62728",
        "dead zone 25°": "#2ca02c",
    }
    written = []

    # 1. One long held-out take: per-frame error of each predictor, and the head's look-around.
    lengths = arr["lengths"]
    b = int(np.argmax(lengths))
    s = seqs[cond][b]
    t = arr["times"][b, : lengths[b]]
    fig, (ax0, ax1) = plt.subplots(2, 1, figsize=(10, 6), sharex=True, gridspec_kw={"height_ratios": [1, 2]})
    ax0.plot(t, np.degrees(s.look_yaw), color="gray")
    ax0.set_ylabel("head yaw added\nby look-around (°)")
    ax0.set_title(f"Held-out take {s.name}: body-yaw error over time")
    for name, r in res.items():
        e = np.where(np.isnan(r.errors[b, : lengths[b]]), np.nan, r.errors[b, : lengths[b]])
        raw = np.degrees(
            np.abs(
                ((arr["preds"][name][b, : lengths[b]] - arr["truth"][b, : lengths[b]]) + np.pi) % (2 * np.pi) - np.pi
            )
        )
        ax1.plot(t, raw, label=f"{name} (mean {np.nanmean(e):.1f}°)", color=colors.get(name), lw=1)
    ax1.axvspan(0, WARMUP, color="0.9", label="warm-up (not scored)")
    ax1.set_xlabel("time (s)")
    ax1.set_ylabel("|yaw error| (°)")
    ax1.set_ylim(0, 90)
    ax1.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    p = DOCS / "orientation-error-time.png"
    fig.savefig(p, dpi=90)
    plt.close(fig)
    written.append(p)

    # 2. Histogram of the errors over all held-out frames (with look-around).
    fig, ax = plt.subplots(figsize=(8, 4.5))
    bins = np.linspace(0, 90, 46)
    for name, r in res.items():
        v = r.errors[~np.isnan(r.errors)]
        ax.hist(
            np.clip(v, 0, 90),
            bins=bins,
            histtype="step",
            lw=1.5,
            density=True,
            color=colors.get(name),
            label=f"{name}: mean {r.mean:.1f}°, p95 {r.p95:.1f}°",
        )
    ax.set_xlabel("|body yaw error| (°), errors above 90° in the last bin")
    ax.set_ylabel("share of frames (density)")
    ax.set_title("Held-out subjects, with look-around")
    ax.legend(fontsize=8)
    fig.tight_layout()
    p = DOCS / "orientation-error-hist.png"
    fig.savefig(p, dpi=90)
    plt.close(fig)
    written.append(p)
    return written


def run(quick: bool = False, make_plots: bool = True, models: dict[str, Path] | None = None, log=print):
    models = PREDICTORS if models is None else models
    missing = [str(p) for p in models.values() if not Path(p).is_file()]
    if missing:
        raise data.DataError(f"model(s) missing: {', '.join(missing)} (run `npm run train`)")
    loaded = {name: load_model(p) for name, p in models.items()}
    clips = data.load_subjects(data.TEST_SUBJECTS, mirrored=False, log=log)
    if quick:
        clips = clips[::4]
    results, arrays, seqs = {}, {}, {}
    for look in (True, False):
        cond = "with look-around" if look else "without look-around"
        seqs[cond] = held_out_sequences(look, clips=clips, log=log)
        results[cond], arrays[cond] = evaluate(seqs[cond], loaded)
    frames = int(sum((arrays[c]["times"] >= WARMUP).sum() for c in arrays))
    log(
        f"held-out subjects {', '.join(data.subject_name(*s) for s in data.TEST_SUBJECTS)}: "
        f"{len(clips)} takes × {len(EVAL_FPS)} frame rates × 2 conditions, {frames} scored frames"
    )
    written = plots(results, arrays, seqs) if make_plots else []
    nets = [PAGE] * (PAGE in arrays["with look-around"]["preds"]) + [n for n in loaded] + ["HMD forward"]
    # Per device set: the feed-back network, the GRU and the page's mean of both.
    per_set = {n: m for n, m in loaded.items() if n == next(iter(loaded)) or getattr(m, "recurrent", False)}
    sets = {
        name: evaluate([with_absent(q, absent) for q in seqs["with look-around"]], per_set)[0]
        for name, absent in DEVICE_SETS.items()
    }
    return results, written, per_subject(results, seqs), class_table(arrays["with look-around"], nets), sets


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Evaluate the body-orientation predictors on held-out subjects")
    ap.add_argument("--quick", action="store_true", help="a quarter of the takes")
    ap.add_argument("--no-plots", action="store_true")
    ap.add_argument("--json", type=Path, help="also write the numbers here")
    ap.add_argument(
        "--model",
        action="append",
        metavar="NAME=PATH",
        help="evaluate these ONNX models instead of the committed ones (repeatable)",
    )
    ap.add_argument(
        "--chromium",
        action=argparse.BooleanOptionalAction,
        default=Path("/usr/bin/chromium").exists(),
        help="also time the model in headless Chromium (default: when /usr/bin/chromium exists)",
    )
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    models = None
    if args.model:
        models = dict(m.split("=", 1) for m in args.model)
    results, written, subjects, classes, sets = run(args.quick, not args.no_plots and models is None, models)
    print("\nmean / median / p95 |body yaw error| over all scored frames:\n")
    print(table(results))
    print("\nmean / p95 per motion class (with look-around):\n")
    print(classes)
    print("\nmean per held-out subject:\n")
    print(subjects)
    print("\nper device set (with look-around; an absent controller as the VR page shows it):\n")
    print(table(sets))
    print()
    for p in written:
        print(f"wrote {p.relative_to(data.REPO)}")
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    c: {n: {"mean": r.mean, "median": r.median, "p95": r.p95} for n, r in res.items()}
                    for c, res in results.items()
                },
                indent=1,
            )
        )
    print(f"evaluation finished in {time.perf_counter() - t0:.0f} s")
    if args.chromium:
        # Inference time in the browser (and parity there): headless Chromium via playwright-core.
        bench = data.TRAINING / "bench_chromium.mjs"
        proc = subprocess.run(["node", str(bench)], cwd=data.REPO, capture_output=True, text=True, timeout=600)
        lines = (proc.stdout + proc.stderr).strip().splitlines()
        print(lines[-1] if lines else f"bench_chromium.mjs printed nothing (exit {proc.returncode})")
        if proc.returncode != 0:
            return proc.returncode
    return 0


if __name__ == "__main__":
    sys.exit(main())
