"""Synthetic VR tracker recordings from mocap, for replays, tests and `npm run bench -- --vr`.

Two sets:
- **held-in** (`walk`, `turn`, `run`): CMU takes of subjects the orientation network was trained
  on (`orientation.data.TRAIN_SUBJECTS`) — the e2e replay test uses `walk`;
- **held-out** (`backward`, `sidestep`, `turn-in-place`, `gesture`, `moving-about`,
  `walk-69`): people (100STYLE: a style) the network never saw (`orientation.data.TEST_SUBJECTS`),
  and takes that are not in the VR database (`databases/vr.json`) either — the replay numbers
  of issue 14 are measured on these. A window of each take is chosen where the named motion
  classes (`orientation.motion_classes`) fill most of it.

`body-moving-about` also carries the body joints a body-tracking headset reports (WebXR Body
Tracking: the hips, hip joints and shoulders, from the mocap skeleton's joints; docs/vr-recording.md
`body`), so a replay and the body-tracking e2e drive the avatar from the tracked hips. The others
stand for headsets without body tracking.

Each take becomes headset and controller poses by the tracker simulation
(`orientation.simulate`, the evaluation augmentation: real speed, 72 Hz, tracker noise, looking
around up to ±60°), written in the VR page's recording format (docs/vr-recording.md, JSON
version 1) plus the ground truth per frame in `truth`: the mocap body (virtual-root) yaw, the
root's floor position and the motion class. Everything is shifted so the user starts at the
origin of the room.

They are derived from the mocap, so they are not committed: `node scripts/setup.mjs test` (and
`npm run bench -- --vr` when they are missing) writes them to public/recordings/.

    training/.venv/bin/python training/make_recordings.py [--out public/recordings] [--force]
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
from pathlib import Path

import numpy as np

import mmdb
from orientation.data import TEST_SUBJECTS, TRAIN_SUBJECTS, MocapClip, ensure_database, load_clips
from orientation.motion_classes import CLASSES
from orientation.simulate import EVAL_AUGMENT, simulate

REPO = Path(__file__).resolve().parent.parent
OUT = REPO / "public" / "recordings"
FPS = 72.0
SEED = 6

# (recording name, folder, subject, take, what it shows, held in?, window seconds (None: the
# whole take), the motion classes the window should hold)
RECORDINGS = (
    ("walk", "cmu-asf", "16", "cmu_16_32", "walk straight, 4.8 s", True, None, ()),
    ("turn", "cmu-asf", "16", "cmu_16_17", "walk with a 90° left turn, 4.3 s", True, None, ()),
    ("run", "cmu-asf", "127", "cmu_127_04", "walk to run, 3.7 s", True, None, ()),
    (
        "backward",
        "100style",
        "Akimbo",
        "Akimbo_TR1",
        "walking backward and turning, hands on hips",
        False,
        12.0,
        ("backward",),
    ),
    (
        "sidestep",
        "100style",
        "Akimbo",
        "Akimbo_TR1",
        "side-steps left and right, hands on hips",
        False,
        12.0,
        ("sideways",),
    ),
    ("turn-in-place", "cmu-asf", "69", "cmu_69_16", "a stepping turn of 153° on the spot, 2.8 s", False, None, ()),
    (
        "gesture",
        "cmu-asf",
        "14",
        "cmu_14_26",
        "directing traffic, waving, pointing, a few steps",
        False,
        20.0,
        ("gesturing", "standing"),
    ),
    (
        "moving-about",
        "cmu-asf",
        "14",
        "cmu_14_18",
        "laughing while stepping about: forward, back, sideways",
        False,
        20.0,
        ("forward", "backward", "sideways"),
    ),
    ("walk-69", "cmu-asf", "69", "cmu_69_01", "a forward walk, 3.9 s", False, None, ()),
    (
        "body-moving-about",
        "cmu-asf",
        "14",
        "cmu_14_18",
        "body tracked: stepping about, forward, back, sideways",
        False,
        8.0,
        ("forward", "backward", "sideways"),
    ),
)

# Recordings that carry the tracked body, and the WebXR body joints they carry with the mocap
# skeleton role each is read from (the page's `BODY_JOINTS`, web/src/vr/tracker-sample.ts).
BODY_RECORDINGS = ("body-moving-about",)
BODY_JOINTS = (
    ("hips", "hips"),
    ("left-upper-leg", "left_upper_leg"),
    ("right-upper-leg", "right_upper_leg"),
    ("left-arm-upper", "left_upper_arm"),
    ("right-arm-upper", "right_upper_arm"),
)


def window(clip: MocapClip, seconds: float | None, classes: tuple[str, ...]) -> tuple[int, int]:
    """Frames [start, end) of the `seconds`-long window of `clip` holding most frames of
    `classes` (the whole clip when `seconds` is None or longer than it)."""
    n = clip.num_frames
    length = n if seconds is None else min(n, int(round(seconds * clip.fps)))
    if length >= n or not classes:
        return 0, length
    wanted = np.isin(clip.classes, [CLASSES.index(c) for c in classes]).astype(float)
    counts = np.convolve(wanted, np.ones(length), mode="valid")  # counts[s] = frames s..s+length
    s = int(np.argmax(counts))
    return s, s + length


def _at_times(values: np.ndarray, fps: float, times: np.ndarray) -> np.ndarray:
    """Per-frame `values` (frames, …) linearly interpolated at `times` (s from the first frame)."""
    n = len(values)
    f = np.clip(times * fps, 0.0, n - 1.0)
    i0 = np.minimum(np.floor(f).astype(int), n - 2)
    a = (f - i0).reshape((-1,) + (1,) * (values.ndim - 1))
    return values[i0] + a * (values[i0 + 1] - values[i0])


def _root_floor(db: mmdb.Database, start: int, end: int, times: np.ndarray) -> np.ndarray:
    """Joint 0 (the virtual root: hips on the floor) x, z at `times` (s from the clip start)."""
    return _at_times(db.local_positions[start:end, 0].astype(np.float64), db.fps, times)[:, [0, 2]]


def _body(db: mmdb.Database, start: int, end: int, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The `BODY_JOINTS` of frames [start, end) at `times`: world positions (n, J, 3) and
    rotations (n, J, 4) — the mocap joints' own frames, on the near hemisphere, nlerped."""
    joints = [db.sites[site][0] for _, site in BODY_JOINTS]
    pos, rot = mmdb.world_transforms_all(db)
    pos, rot = pos[start:end, joints], rot[start:end, joints].astype(np.float64)
    for k in range(1, len(rot)):
        flip = np.sum(rot[k] * rot[k - 1], axis=-1) < 0
        rot[k, flip] *= -1
    q = _at_times(rot, db.fps, times)
    return _at_times(pos.astype(np.float64), db.fps, times), q / np.linalg.norm(q, axis=-1, keepdims=True)


def _cut(clip: MocapClip, s: int, e: int) -> MocapClip:
    """Frames [s, e) of a clip (its motion classes kept: computed on the whole take)."""
    classes = clip.classes[s:e]
    out = MocapClip(
        name=clip.name,
        subject=clip.subject,
        mirrored=clip.mirrored,
        fps=clip.fps,
        body_yaw=clip.body_yaw[s:e],
        root_pos=clip.root_pos[s:e],
        head_pos=clip.head_pos[s:e],
        head_rot=clip.head_rot[s:e],
        hand_pos=clip.hand_pos[:, s:e],
        hand_rot=clip.hand_rot[:, s:e],
        rig=clip.rig,
    )
    out._classes = classes
    return out


@functools.cache
def _subject(folder: str, subject: str) -> tuple[Path, list[MocapClip], mmdb.Database]:
    """A subject's database, its clips and the database read: once per subject (several
    recordings share one; the clips' forward kinematics over the whole database was most of
    the time)."""
    path = ensure_database(folder, subject)
    return path, load_clips(path, f"{folder}_{subject}", mirrored=False), mmdb.load(path)


def make(
    name: str,
    folder: str,
    subject: str,
    take: str,
    note: str,
    held_in: bool,
    seconds: float | None,
    classes: tuple[str, ...],
    seed: int,
) -> dict:
    if held_in != ((folder, subject) in TRAIN_SUBJECTS) or (not held_in and (folder, subject) not in TEST_SUBJECTS):
        raise SystemExit(f"{folder} {subject}: recording {name} must be {'held in' if held_in else 'held out'}")
    path, subject_clips, db = _subject(folder, subject)
    clips = [c for c in subject_clips if c.name.startswith(take)]
    if len(clips) != 1:
        raise SystemExit(f"{path}: expected one un-mirrored clip named like {take}, found {[c.name for c in clips]}")
    whole = clips[0]
    s, e = window(whole, seconds, classes)
    clip = _cut(whole, s, e)
    dbclip = next(c for c in db.clips if not c.mirrored and c.name == whole.name)
    aug = EVAL_AUGMENT.__class__(**{**EVAL_AUGMENT.__dict__, "global_yaw": False})
    seq = simulate(clip, np.random.default_rng(seed), aug, fps=FPS)
    t = np.cumsum(seq.dt) - seq.dt[0]  # speed 1: the clip's own clock
    root = _root_floor(db, dbclip.start + s, dbclip.start + e, t)
    body = _body(db, dbclip.start + s, dbclip.start + e, t) if name in BODY_RECORDINGS else None
    origin = root[0].copy()
    pos = seq.pos.copy()
    pos[:, :, 0] -= origin[0]
    pos[:, :, 2] -= origin[1]
    root -= origin
    n = seq.num_frames
    eye = float(np.percentile(pos[:, 0, 1], 90))
    r = lambda a, d: [round(float(v), d) for v in np.asarray(a).ravel()]  # noqa: E731
    extra = {}
    if body is not None:
        bpos = body[0].copy()
        bpos[:, :, 0] -= origin[0]
        bpos[:, :, 2] -= origin[1]
        extra["body"] = {
            "joints": [name for name, _ in BODY_JOINTS],
            "position": r(bpos, 5),
            "rotation": r(body[1], 6),
            "tracked": [1] * (n * len(BODY_JOINTS)),
        }
    return {
        "format": "mm-vr-recording",
        "version": 1,
        "trackers": ["head", "left", "right"],
        "frames": n,
        "meta": {
            "source": f"{folder}/{whole.name}",
            "subject": f"{folder}_{subject}",
            "heldIn": held_in,
            "window": f"{s / whole.fps:.2f}-{e / whole.fps:.2f} s",
            "description": note,
            "rate": FPS,
            "seed": seed,
            "eyeHeight": round(eye, 4),
            "lookAround": True,
            "bodyTracking": body is not None,
            "generator": "training/make_recordings.py",
        },
        "time": r(t, 6),
        "position": r(pos, 5),
        "rotation": r(seq.rot / np.linalg.norm(seq.rot, axis=-1, keepdims=True), 6),
        "tracked": [1] * (3 * n),
        "truth": {"bodyYaw": r(seq.body_yaw, 5), "root": r(root, 5), "motionClass": [int(c) for c in seq.classes]},
        **extra,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--force", action="store_true", help="rewrite existing files")
    ap.add_argument(
        "--seed",
        type=int,
        default=SEED,
        help="simulation seed (another draw of the devices' noise, offsets and looking around: the benches' spread)",
    )
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    index = []
    for k, (name, folder, subject, take, note, held_in, seconds, classes) in enumerate(RECORDINGS):
        out = args.out / f"{name}.json"
        index.append(out.name)
        if out.exists() and not args.force:
            continue
        rec = make(name, folder, subject, take, note, held_in, seconds, classes, args.seed + k)
        out.write_text(json.dumps(rec, separators=(",", ":")))
        print(f"wrote {out} ({rec['frames']} frames, {rec['frames'] / FPS:.1f} s, {out.stat().st_size // 1024} kB)")
    (args.out / "index.json").write_text(json.dumps(index) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
