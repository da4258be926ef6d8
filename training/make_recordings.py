"""Synthetic VR tracker recordings from held-in mocap, for replays, tests and `npm run bench -- --vr`.

Each recording is one CMU take of a subject the orientation network was trained on (held in:
`orientation.data.TRAIN_SUBJECTS`), turned into headset and controller poses by the colleague's
tracker simulation (`orientation.simulate`, the evaluation augmentation: real speed, 72 Hz,
tracker noise, looking around up to ±60°), written in the VR page's recording format
(docs/vr-recording.md, JSON version 1) plus the ground truth per frame in `truth`: the mocap
body (virtual-root) yaw and the root's floor position. Everything is shifted so the user starts
at the origin of the room.

They are derived from the mocap, so they are not committed: `node scripts/setup.mjs test` (and
`npm run bench -- --vr` when they are missing) writes them to public/recordings/.

    training/.venv/bin/python training/make_recordings.py [--out public/recordings] [--force]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

import mmdb
from orientation.data import TRAIN_SUBJECTS, ensure_database, load_clips
from orientation.simulate import EVAL_AUGMENT, simulate

REPO = Path(__file__).resolve().parent.parent
OUT = REPO / "public" / "recordings"
FPS = 72.0
SEED = 6

# (recording name, folder, subject, take, what it shows)
RECORDINGS = (
    ("walk", "cmu-asf", "16", "cmu_16_32", "walk straight, 4.8 s"),
    ("turn", "cmu-asf", "16", "cmu_16_17", "walk with a 90° left turn, 4.3 s"),
    ("run", "cmu-asf", "127", "cmu_127_04", "walk to run, 3.7 s"),
)


def _root_floor(db: mmdb.Database, start: int, end: int, times: np.ndarray) -> np.ndarray:
    """Joint 0 (the virtual root: hips on the floor) x, z at `times` (s from the clip start)."""
    root = db.local_positions[start:end, 0].astype(np.float64)
    f = np.clip(times * db.fps, 0.0, end - start - 1.0)
    i0 = np.minimum(np.floor(f).astype(int), end - start - 2)
    a = (f - i0)[:, None]
    p = root[i0] + a * (root[i0 + 1] - root[i0])
    return p[:, [0, 2]]


def make(name: str, folder: str, subject: str, take: str, note: str, seed: int) -> dict:
    if (folder, subject) not in TRAIN_SUBJECTS:
        raise SystemExit(f"{folder} {subject} is not a training subject: recordings must be held-in")
    path = ensure_database(folder, subject)
    clips = [c for c in load_clips(path, f"{folder}_{subject}", mirrored=False) if take in c.name]
    if len(clips) != 1:
        raise SystemExit(f"{path}: expected one un-mirrored clip named like {take}, found {[c.name for c in clips]}")
    clip = clips[0]
    db = mmdb.load(path)
    dbclip = next(c for c in db.clips if not c.mirrored and c.name == clip.name)
    aug = EVAL_AUGMENT.__class__(**{**EVAL_AUGMENT.__dict__, "global_yaw": False})
    seq = simulate(clip, np.random.default_rng(seed), aug, fps=FPS)
    t = np.cumsum(seq.dt) - seq.dt[0]  # speed 1: the clip's own clock
    root = _root_floor(db, dbclip.start, dbclip.end, t)
    origin = root[0].copy()
    pos = seq.pos.copy()
    pos[:, :, 0] -= origin[0]
    pos[:, :, 2] -= origin[1]
    root -= origin
    n = seq.num_frames
    eye = float(np.percentile(pos[:, 0, 1], 90))
    r = lambda a, d: [round(float(v), d) for v in np.asarray(a).ravel()]  # noqa: E731
    return {
        "format": "mm-vr-recording",
        "version": 1,
        "trackers": ["head", "left", "right"],
        "frames": n,
        "meta": {"source": f"{folder}/{take}.bvh", "subject": f"{folder}_{subject}", "heldIn": True,
                 "description": note, "rate": FPS, "seed": seed, "eyeHeight": round(eye, 4),
                 "lookAround": True, "generator": "training/make_recordings.py"},
        "time": r(t, 6),
        "position": r(pos, 5),
        "rotation": r(seq.rot / np.linalg.norm(seq.rot, axis=-1, keepdims=True), 6),
        "tracked": [1] * (3 * n),
        "truth": {"bodyYaw": r(seq.body_yaw, 5), "root": r(root, 5)},
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--force", action="store_true", help="rewrite existing files")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    index = []
    for k, (name, folder, subject, take, note) in enumerate(RECORDINGS):
        out = args.out / f"{name}.json"
        index.append(out.name)
        if out.exists() and not args.force:
            continue
        rec = make(name, folder, subject, take, note, SEED + k)
        out.write_text(json.dumps(rec, separators=(",", ":")))
        print(f"wrote {out} ({rec['frames']} frames, {rec['frames'] / FPS:.1f} s, {out.stat().st_size // 1024} kB)")
    (args.out / "index.json").write_text(json.dumps(index) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
