"""Mocap subjects, the train/test split by subject, and per-clip world transforms.

The pose data comes only from `.mmdb` files built by the project's own builder (the `mmdb` CLI),
so FK, unit scaling and the virtual root (joint 0: hips on the floor, smoothed yaw facing) are
exactly those the runtime uses; the body's facing, the ground truth here, is joint 0's yaw.

One database per subject, at the source rate (120 fps, no resampling) and mirrored by the
builder (left/right swapped, reflected: the "mirroring" augmentation). A per-subject database
keeps each person's own bone lengths: one database per skeleton would rescale everybody onto
one reference body.
"""

from __future__ import annotations

import json
import os
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import mmdb

from .geometry import quat_conj, quat_from_basis, quat_hemisphere, quat_rotate

TRAINING = Path(__file__).resolve().parent.parent
REPO = TRAINING.parent
DATA_DIR = Path(os.environ.get("ORIENTATION_DATA_DIR", TRAINING / "data"))
MOCAP_DIR = Path(os.environ.get("MMDB_MOCAP_DIR", REPO.parent / "shared" / "mocap"))
MMDB_BIN = Path(os.environ.get("MMDB_BIN", REPO / "wasm-core" / "target" / "opt" / "mmdb"))
# The models the site serves: the feed-back network and the recurrent one (the page averages them).
PUBLIC_MODEL = REPO / "public" / "models" / "orientation.onnx"
GRU_MODEL = REPO / "public" / "models" / "orientation_gru.onnx"
# Side models and the weights the fixtures are made from (not served).
MODELS_DIR = TRAINING / "models"

# (folder, subject): a CMU subject number, or a 100STYLE style (one performer, so a style is the
# unit held out — not a person). Held out, never trained on:
# - cmu-asf 14: everyday actions and gestures, with most of CMU's back-steps and side-steps;
# - cmu-asf 69: forward walks and the turn in place;
# - 100STYLE Akimbo (hands on hips): transitions between forward, backward and side-steps, idle;
# - cmu-asf 03 (walking loops with many full turns, uneven ground), cmu-daz 08 (walks) and 09
#   (runs): both CMU skeletons, both gaits.
# Training: 16 and 127 (walks, runs, turns, side-steps, stops), 02 (bending down, arm activity),
# 91 (slow walks with turnarounds), six cmu-daz walkers, and 100STYLE Angry (backward walking,
# side-steps, forward walking, idle; the same performer as Akimbo, another arm style).
TRAIN_SUBJECTS = (
    ("cmu-asf", "16"),
    ("cmu-asf", "127"),
    ("cmu-asf", "02"),
    ("cmu-asf", "91"),
    ("cmu-daz", "02"),
    ("cmu-daz", "05"),
    ("cmu-daz", "06"),
    ("cmu-daz", "07"),
    ("cmu-daz", "10"),
    ("cmu-daz", "12"),
    ("100style", "Angry"),
)
TEST_SUBJECTS = (
    ("cmu-asf", "14"),
    ("cmu-asf", "69"),
    ("100style", "Akimbo"),
    ("cmu-asf", "03"),
    ("cmu-daz", "08"),
    ("cmu-daz", "09"),
)

SOURCE_FPS = 120.0


class DataError(RuntimeError):
    """Mocap, CLI or database missing or unusable; the message says which and how to fix it."""


def subject_name(folder: str, subject: str) -> str:
    return f"{folder}_{subject}"


def file_pattern(folder: str, subject: str) -> str:
    """The subject's takes: `cmu_<n>_*.bvh`, or `<Style>_*.bvh` in 100STYLE."""
    return f"{subject}_*.bvh" if folder == "100style" else f"cmu_{subject}_*.bvh"


def database_config(folder: str, subject: str, mocap_dir: Path, config_dir: Path) -> dict:
    """The builder config for one subject (all its takes, 120 fps, mirrored, units auto; 100STYLE
    takes cut to the usable windows of its Frame_Cuts.csv)."""
    bvh_dir = mocap_dir / folder
    pattern = file_pattern(folder, subject)
    if not any(bvh_dir.glob(pattern)):
        raise DataError(
            f"no mocap files {bvh_dir / pattern} (is ../shared/mocap beside the repo? MMDB_MOCAP_DIR overrides)"
        )
    rel = os.path.relpath(bvh_dir, config_dir)
    config = {"fps": SOURCE_FPS, "mirror": True, "scale": "auto", "clips": [{"file": f"{rel}/{pattern}"}]}
    if (bvh_dir / "Frame_Cuts.csv").exists():
        config["frame_cuts"] = f"{rel}/Frame_Cuts.csv"
    return config


def ensure_database(
    folder: str, subject: str, data_dir: Path = DATA_DIR, mocap_dir: Path = MOCAP_DIR, cli: Path = MMDB_BIN, log=print
) -> Path:
    """Path of the subject's `.mmdb`, (re)built with the CLI when missing or stale."""
    config = database_config(folder, subject, mocap_dir, data_dir)
    sources = list((mocap_dir / folder).glob(file_pattern(folder, subject)))
    return build_database(subject_name(folder, subject), config, sources, data_dir, cli, log)


def build_database(name: str, config: dict, sources: list[Path], data_dir: Path, cli: Path, log=print) -> Path:
    """`data_dir/<name>.mmdb` built from `config` with the CLI when missing or stale: the config
    text changed, or the CLI binary or a source BVH is newer."""
    data_dir.mkdir(parents=True, exist_ok=True)
    config_path, out = data_dir / f"{name}.json", data_dir / f"{name}.mmdb"
    text = json.dumps(config, indent=1) + "\n"
    if not config_path.exists() or config_path.read_text() != text:
        config_path.write_text(text)
    if not cli.is_file():
        raise DataError(
            f"mmdb CLI not built at {cli} (run `npm run build`, or `cargo build --profile opt --bin mmdb` in wasm-core/)"
        )
    newest = max([config_path.stat().st_mtime, cli.stat().st_mtime] + [p.stat().st_mtime for p in sources])
    if out.exists() and out.stat().st_mtime >= newest:
        return out
    log(
        f"building {out.relative_to(data_dir.parent) if data_dir.parent in out.parents else out} "
        f"from {len(sources)} takes"
    )
    proc = subprocess.run(
        [str(cli), "build", "--config", str(config_path), "-o", str(out)], capture_output=True, text=True, timeout=600
    )
    if proc.returncode != 0:
        raise DataError(f"mmdb build --config {config_path} failed ({proc.returncode}):\n{proc.stderr}")
    return out


def people(mocap_dir: Path = MOCAP_DIR) -> dict[str, dict[str, list[str]]]:
    """Every person of the mocap manifest (its `person` field), in manifest order: person →
    folder → file names. The manifest grows; nothing here names a person."""
    path = mocap_dir / "manifest.json"
    try:
        entries = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise DataError(f"{path}: cannot read the mocap manifest ({e})") from e
    out: dict[str, dict[str, list[str]]] = {}
    for i, e in enumerate(entries):
        missing = [k for k in ("person", "folder", "file") if not isinstance(e.get(k), str) or not e.get(k)]
        if missing:
            raise DataError(f"{path}: entry {i} lacks {', '.join(missing)}")
        out.setdefault(e["person"], {}).setdefault(e["folder"], []).append(e["file"])
    return out


def person_databases(
    person: str,
    folders: dict[str, list[str]],
    data_dir: Path = DATA_DIR,
    mocap_dir: Path = MOCAP_DIR,
    cli: Path = MMDB_BIN,
    log=print,
) -> list[Path]:
    """One `.mmdb` per folder (skeleton) of a person's takes: 120 fps, mirrored, units auto, the
    person's own bone lengths; 100STYLE takes cut to its Frame_Cuts.csv windows."""
    paths = []
    for folder, files in folders.items():
        bvh_dir = mocap_dir / folder
        sources = [bvh_dir / f for f in files]
        absent = [str(p) for p in sources if not p.is_file()]
        if absent:
            raise DataError(f"{mocap_dir / 'manifest.json'}: person {person}: missing file(s) {', '.join(absent[:3])}")
        rel = os.path.relpath(bvh_dir, data_dir)
        config = {"fps": SOURCE_FPS, "mirror": True, "scale": "auto", "clips": [{"file": f"{rel}/{f}"} for f in files]}
        if (bvh_dir / "Frame_Cuts.csv").exists():
            config["frame_cuts"] = f"{rel}/Frame_Cuts.csv"
        paths.append(build_database(f"person_{person}_{folder}", config, sources, data_dir, cli, log))
    return paths


def load_people(names, mirrored: bool | None = None, log=print, **kw) -> list[MocapClip]:
    """Clips of the people `names` (manifest `person` values), `subject` set to the person."""
    everyone = people(kw.get("mocap_dir", MOCAP_DIR))
    unknown = [n for n in names if n not in everyone]
    if unknown:
        raise DataError(f"no person {', '.join(unknown)} in the mocap manifest (known: {', '.join(everyone)})")
    clips = []
    for name in names:
        for path in person_databases(name, everyone[name], log=log, **kw):
            clips += load_clips(path, name, mirrored)
    return clips


@dataclass
class Rig:
    """Where the devices sit on one skeleton, from its rest pose (all rest rotations identity).

    `hmd_align` rotates the WebXR viewer frame (X right, Y up, looking down −Z) into the head
    joint's frame; `grip_align[s]` rotates the WebXR grip frame into hand joint s's frame, with
    the hand as in the rest T-pose holding a controller palm down: −Z (out of the fist on the
    thumb side) forward, +Y back along the forearm, +X out of the back of the right hand /
    the palm of the left hand (WebXR gripSpace, as MDN's XRInputSource.gripSpace describes it).
    `hand_axis[s]` is the unit forearm direction at rest (lower arm → hand), in the hand's frame.
    """

    head: int
    hands: tuple[int, int]  # left, right joint indices
    hmd_align: np.ndarray  # (4,)
    grip_align: np.ndarray  # (2, 4)
    hand_axis: np.ndarray  # (2, 3)


def rig_of(db: mmdb.Database) -> Rig:
    site = {k: j for k, (j, _) in db.sites.items()}
    need = ("head", "left_hand", "right_hand", "left_lower_arm", "right_lower_arm", "left_upper_leg", "right_upper_leg")
    missing = [k for k in need if site.get(k, -1) < 0]
    if missing:
        raise DataError(f"database skeleton lacks the role(s) {missing} needed to place trackers")
    rest = np.zeros((db.num_joints, 3))
    for j in range(1, db.num_joints):
        rest[j] = rest[db.parents[j]] + db.rest_offsets[j]
    up = np.array([0.0, 1.0, 0.0])
    # Facing at rest: (left hip − right hip) × up, the builder's virtual-root rule.
    forward = np.cross(rest[site["left_upper_leg"]] - rest[site["right_upper_leg"]], up)
    forward[1] = 0.0
    forward /= np.linalg.norm(forward)
    back = -forward
    hmd_align = quat_from_basis(np.cross(up, back), up, back)
    grips, axes = [], []
    for side in ("left", "right"):
        a = rest[site[f"{side}_hand"]] - rest[site[f"{side}_lower_arm"]]
        a /= np.linalg.norm(a)
        z = back - np.dot(back, a) * a
        z /= np.linalg.norm(z)
        y = -a
        grips.append(quat_from_basis(np.cross(y, z), y, z))
        axes.append(a)
    return Rig(site["head"], (site["left_hand"], site["right_hand"]), hmd_align, np.array(grips), np.array(axes))


# The headset's pitch, on average, while walking forward: the gaze a few steps ahead.
WALKING_GAZE_PITCH = np.radians(-10.0)
# Forward walking needed to calibrate the headset from the motion (else the rest pose's frame).
MIN_CALIBRATION_SECONDS = 1.0


def calibrate_headset(clips: list["MocapClip"], log=print) -> Rig | None:
    """The rig with `hmd_align` measured from the motion instead of the rest pose, or None when
    the clips hold under `MIN_CALIBRATION_SECONDS` of forward walking.

    A mocap head segment's frame is whatever the capture's calibration made it (CMU's head
    markers sit on a cap): at rest its "forward" is off the face by a constant per skeleton —
    here from −18° (CMU Daz 12) to +42° (CMU 03) in yaw and down to −50° in pitch, where a
    worn headset looks where the face does. Walking forward, people look where they go: the
    viewer's −Z is taken as the mean, in the head's frame, of the direction of travel pitched
    down by `WALKING_GAZE_PITCH`, with no roll (its +Y the mean world up, made orthogonal).
    One rig per database and side (a mirrored clip's head frame is mirrored too).
    """
    from .motion_classes import CLASSES, travel_of

    forward = CLASSES.index("forward")
    views, ups, seconds = [], [], 0.0
    for c in clips:
        _, travel = travel_of(c.root_pos, c.fps)
        walk = c.classes == forward
        if not walk.any():
            continue
        seconds += walk.sum() / c.fps
        g = np.stack(
            [
                np.sin(travel[walk]) * np.cos(WALKING_GAZE_PITCH),
                np.full(walk.sum(), np.sin(WALKING_GAZE_PITCH)),
                np.cos(travel[walk]) * np.cos(WALKING_GAZE_PITCH),
            ],
            axis=-1,
        )
        inv = quat_conj(c.head_rot[walk])
        views.append(quat_rotate(inv, g))
        ups.append(quat_rotate(inv, np.broadcast_to([0.0, 1.0, 0.0], g.shape)))
    if seconds < MIN_CALIBRATION_SECONDS:
        return None
    view = np.concatenate(views).mean(axis=0)
    up = np.concatenate(ups).mean(axis=0)
    y = up - np.dot(up, view) * view / max(np.dot(view, view), 1e-12)
    if not (np.linalg.norm(view) > 0.5 and np.linalg.norm(y) > 0.1):
        log(
            f"{clips[0].subject}: the head turns too much while walking to calibrate the headset; "
            f"the rest pose's frame is kept"
        )
        return None
    z = -view / np.linalg.norm(view)
    y /= np.linalg.norm(y)
    rig = clips[0].rig
    return Rig(rig.head, rig.hands, quat_from_basis(np.cross(y, z), y, z), rig.grip_align, rig.hand_axis)


@dataclass
class MocapClip:
    """World transforms of one clip at the database rate, float64."""

    name: str
    subject: str
    mirrored: bool
    fps: float
    body_yaw: np.ndarray  # (n,) virtual-root yaw, unwrapped
    root_pos: np.ndarray  # (n, 3) virtual-root position (hips on the floor)
    head_pos: np.ndarray  # (n, 3)
    head_rot: np.ndarray  # (n, 4)
    hand_pos: np.ndarray  # (2, n, 3) left, right
    hand_rot: np.ndarray  # (2, n, 4)
    rig: Rig
    # The head's height standing upright (m): the 90th percentile over the database's frames.
    # `classes` leaves crouching out (the VR recordings and the headset calibration predate it);
    # `motion_classes.with_crouching` adds it where a score wants it.
    upright_head: float = 0.0

    @property
    def num_frames(self) -> int:
        return len(self.body_yaw)

    @property
    def classes(self) -> np.ndarray:
        """Motion class per frame (`motion_classes.classify`), computed once."""
        if getattr(self, "_classes", None) is None:
            from .motion_classes import classify

            self._classes = classify(self.root_pos, self.body_yaw, self.hand_pos, self.head_pos, self.fps)
        return self._classes

    @property
    def seconds(self) -> float:
        return (self.num_frames - 1) / self.fps


def load_clips(path: Path, subject: str, mirrored: bool | None = None) -> list[MocapClip]:
    """Clips of one database (`mirrored`: None = all, False = originals only, True = mirrors)."""
    db = mmdb.load(path)
    rig = rig_of(db)
    pos, rot = mmdb.world_transforms_all(db)
    root = db.local_rotations[:, 0].astype(np.float64)
    if np.abs(root[:, [0, 2]]).max() > 1e-4:
        raise DataError(f"{path}: joint 0 is not a pure yaw (not a builder-made virtual root)")
    yaw_all = 2.0 * np.arctan2(root[:, 1], root[:, 3])
    clips = []
    for c in db.clips:
        if mirrored is not None and c.mirrored != mirrored:
            continue
        sl = slice(c.start, c.end)
        clips.append(
            MocapClip(
                name=c.name,
                subject=subject,
                mirrored=c.mirrored,
                fps=float(db.fps),
                body_yaw=np.unwrap(yaw_all[sl]),
                root_pos=db.local_positions[sl, 0].astype(np.float64),
                head_pos=pos[sl, rig.head],
                head_rot=quat_hemisphere(rot[sl, rig.head]),
                hand_pos=np.stack([pos[sl, j] for j in rig.hands]),
                hand_rot=np.stack([quat_hemisphere(rot[sl, j]) for j in rig.hands]),
                rig=rig,
            )
        )
    upright = float(np.percentile(pos[:, rig.head, 1], 90)) if len(pos) else 0.0
    for c in clips:
        c.upright_head = upright
    for side in (False, True):
        group = [c for c in clips if c.mirrored == side]
        calibrated = calibrate_headset(group) if group else None
        for c in group:
            c.rig = calibrated or rig
    return clips


def load_subjects(subjects, mirrored: bool | None = None, log=print, **kw) -> list[MocapClip]:
    """Clips of several subjects, building their databases when needed."""
    clips = []
    for folder, subject in subjects:
        path = ensure_database(folder, subject, log=log, **kw)
        clips += load_clips(path, subject_name(folder, subject), mirrored)
    return clips
