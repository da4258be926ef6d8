"""The VR replay numbers natively (`npm run eval -- --replay`, or `python -m orientation.replay`):
each recording of `public/recordings/` (`make_recordings.py`) replayed through the runtime's
tracked drive by the `mmdb replay` CLI, the body yaw coming from the orientation network run on
the recording's trackers here (`predictors.run_network`, the page's feedback loop).

Per recording: user↔avatar root distance against the mocap truth, the share of frames the root
sits clamped at α, foot skating (the runtime's contact-flag measure and, for comparison with
numbers published before it, the legacy toe-height one), the runtime update time, and the body
yaw error of the network and of HMD-forward, overall and per motion class. The page's own bench
(`npm run bench -- --vr`) adds rendering, retargeting, arm IK and the network's run in the browser.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from . import data
from .features import frame_features
from .geometry import hmd_yaw, rotate_y, wrap_angle
from .motion_classes import CLASSES
from .predictors import OnnxModel, load_model, page_yaw, run_network, run_recurrent

RECORDINGS = data.REPO / "public" / "recordings"
VR_DATABASE = data.REPO / "public" / "databases" / "vr.mmdb"
MODEL = data.PUBLIC_MODEL
GRU_MODEL = data.GRU_MODEL


def load(path: Path) -> dict:
    rec = json.loads(path.read_text())
    n = rec["frames"]
    rec["_pos"] = np.asarray(rec["position"], dtype=np.float64).reshape(n, 3, 3)
    rec["_rot"] = np.asarray(rec["rotation"], dtype=np.float64).reshape(n, 3, 4)
    t = np.asarray(rec["time"], dtype=np.float64)
    rec["_dt"] = np.diff(t, prepend=t[0] - 1.0 / rec["meta"].get("rate", 72.0))
    return rec


def network_drive(model, rec: dict, recurrent=None) -> tuple[np.ndarray, np.ndarray]:
    """The page's body yaw for a recording whose controllers stay tracked — the network's, or
    with the recurrent model the mean of both once it has warmed up (`network-yaw.ts`) — and
    where the network puts the hips: (T, 2) room metres from the head centre on the floor (its
    second output turned out of the HMD-yaw frame; NaN from a model without it)."""
    feats, yaw = frame_features(rec["_pos"], rec["_rot"], rec["_dt"])
    x = feats[None].astype(np.float32)
    hips = np.full((1, len(yaw), 2), np.nan)
    body = run_network(model, x, yaw[None], hips=hips)[0]
    world = rotate_y(np.stack([hips[0, :, 0], np.zeros(len(yaw)), hips[0, :, 1]], axis=1), yaw)[:, [0, 2]]
    if recurrent is not None:
        body = page_yaw(body[None], run_recurrent(recurrent, x, yaw[None]), rec["_dt"][None])[0]
    return body, world


def replay(
    db: Path,
    rec_path: Path,
    yaw: np.ndarray | str,
    alpha: float,
    cli: Path = data.MMDB_BIN,
    settings: str | None = None,
    hips: np.ndarray | None = None,
) -> dict:
    """One `mmdb replay` run: the body yaw per frame (or `truth` / `hmd`) and, when given, where
    the network puts the hips (T, 2) (the root's target; NaN rows: the head centre)."""
    with tempfile.TemporaryDirectory() as tmp:
        if isinstance(yaw, str):
            source = yaw
        else:
            source = str(Path(tmp) / "yaw.json")
            Path(source).write_text(json.dumps([float(v) for v in yaw]))
        cmd = [str(cli), "replay", str(db), str(rec_path), "--alpha", str(alpha), "--yaw", source, "--json"]
        if hips is not None and np.isfinite(hips).any():
            offsets = Path(tmp) / "hips.json"
            offsets.write_text(
                json.dumps([[float(x), float(z)] if np.isfinite([x, z]).all() else None for x, z in hips])
            )
            cmd += ["--hips", str(offsets)]
        if settings:
            cmd += ["--settings", settings]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        raise data.DataError(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    return json.loads(proc.stdout)


def yaw_errors(pred: np.ndarray, rec: dict) -> dict:
    truth = np.asarray(rec["truth"]["bodyYaw"])
    err = np.degrees(np.abs(wrap_angle(pred - truth)))
    t = np.asarray(rec["time"]) - rec["time"][0]
    scored = t >= 1.0  # the warm-up second, as in the evaluation
    out = {"mean": float(err[scored].mean()), "frames": int(scored.sum())}
    classes = np.asarray(rec["truth"].get("motionClass", [-1] * len(truth)))
    for i, c in enumerate(CLASSES):
        m = scored & (classes == i)
        if m.any():
            out[c] = float(err[m].mean())
    return out


def run(
    recordings: list[Path], db: Path, alpha: float, model_path: Path, settings: str | None = None, log=print
) -> list[dict]:
    model = OnnxModel(model_path)
    # The committed network is run as the page runs it: with the recurrent model beside it.
    recurrent = load_model(GRU_MODEL) if Path(model_path) == MODEL and GRU_MODEL.is_file() else None
    rows = []
    for path in recordings:
        rec = load(path)
        yaw, hips = network_drive(model, rec, recurrent)
        row = {"recording": path.stem, "heldIn": rec["meta"].get("heldIn"), "seconds": rec["time"][-1] - rec["time"][0]}
        row["network"] = replay(db, path, yaw, alpha, settings=settings, hips=hips)
        row["hmd"] = replay(db, path, "hmd", alpha, settings=settings)
        if "truth" in rec:
            row["yaw_network"] = yaw_errors(yaw, rec)
            row["yaw_hmd"] = yaw_errors(hmd_yaw(rec["_rot"][:, 0]), rec)
        rows.append(row)
        log(f"  {path.stem}: done")
    return rows


def table(rows: list[dict]) -> str:
    out = [
        "| recording | s | root distance cm mean / p95 (HMD-forward yaw) | clamped | skating cm/s (legacy toe-height) | corrective steps/s | "
        "update ms median / p95 | yaw error ° network · HMD forward | network per class °  |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        n, h = r["network"], r["hmd"]
        d = n["root_distance"]
        dh = h["root_distance"]
        classes = ", ".join(f"{c} {r['yaw_network'][c]:.1f}" for c in CLASSES if c in r.get("yaw_network", {}))
        out.append(
            f"| {r['recording']}{'' if not r['heldIn'] else ' (held in)'} | {r['seconds']:.1f} | "
            f"{100 * d['mean']:.1f} / {100 * d['p95']:.1f} ({100 * dh['mean']:.1f}) | {100 * n['clamped_share']:.0f}% | "
            f"{n['skating']:.1f} ({n['skating_toe_height']:.1f}) | {n['steps_per_second']:.2f} | {n['update_ms']['median']:.4f} / {n['update_ms']['p95']:.4f} | "
            f"{r['yaw_network']['mean']:.1f} · {r['yaw_hmd']['mean']:.1f} | {classes} |"
        )
    held_out = [r for r in rows if not r["heldIn"]]
    if held_out:
        w = np.array([r["network"]["frames"] for r in held_out], dtype=float)
        mean = lambda key: float(np.average([key(r) for r in held_out], weights=w))  # noqa: E731
        out.append(
            f"\nheld-out recordings (frame-weighted): root distance {100 * mean(lambda r: r['network']['root_distance']['mean']):.1f} cm, "
            f"skating {mean(lambda r: r['network']['skating']):.1f} cm/s (legacy {mean(lambda r: r['network']['skating_toe_height']):.1f}), "
            f"{mean(lambda r: r['network']['steps_per_second']):.2f} corrective steps/s, "
            f"update median {np.median([r['network']['update_ms']['median'] for r in held_out]):.4f} ms (native), "
            f"yaw error network {mean(lambda r: r['yaw_network']['mean']):.1f}° vs HMD forward {mean(lambda r: r['yaw_hmd']['mean']):.1f}°"
        )
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dir", type=Path, default=RECORDINGS)
    ap.add_argument("--db", type=Path, default=VR_DATABASE)
    ap.add_argument("--alpha", type=float, default=0.3)
    ap.add_argument("--model", type=Path, default=MODEL)
    ap.add_argument("--settings", help="runtime settings JSON patched onto the VR settings")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    names = json.loads((args.dir / "index.json").read_text())
    rows = run([args.dir / n for n in names], args.db, args.alpha, args.model, args.settings)
    print(f"\nVR replays on {args.db.name}, α = {args.alpha} m (native runtime; network yaw from {args.model.name}):\n")
    print(table(rows))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
