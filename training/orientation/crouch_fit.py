"""Where a VR user's head drop goes — knees or waist — measured on the mocap
(`python -m orientation.crouch_fit`; docs/vr.md, "Crouching and bending over").

The runtime's rule (`wasm-core/src/runtime/character/crouch.rs`, `split`) turns a head drop d below the
standing height and the headset's pitch into a hips drop and a torso bend. This scores it against
the mocap's truth: every original take of the orientation network's subjects (every 4th frame),
the headset placed as the network's simulation places it (`data.load_clips`, calibrated from the
walk). Per subject, standing is the 90th percentile of head and hips height, and the torso's
standing angle is its median on frames within 3 cm of standing height. The torso angle is that of
hips → head from vertical; its bend is how far it exceeds the standing angle.

The rule's two free constants, the pitch where bending starts and the gain, are fitted here on
the training subjects only (`data.TRAIN_SUBJECTS`) and scored on the held-out ones.
"""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass

import numpy as np

import mmdb

from . import data
from .geometry import quat_mul, quat_rotate

CROUCH_RS = data.REPO / "wasm-core" / "src" / "runtime" / "character" / "crouch.rs"
FRAME_STEP = 4


def rust_constants() -> dict[str, float]:
    """The rule's constants as `crouch.rs` defines them (degrees turned into radians)."""
    src = CROUCH_RS.read_text()
    out = {}
    for name in ("CROUCH_DEADBAND", "BEND_START_PITCH", "BEND_GAIN", "MAX_BEND"):
        m = re.search(rf"pub const {name}: f32 = (-?[0-9.]+)( \* std::f32::consts::PI / 180.0)?;", src)
        if not m:
            raise data.DataError(f"{CROUCH_RS}: no constant {name}")
        out[name] = float(m.group(1)) * (np.pi / 180.0 if m.group(2) else 1.0)
    return out


@dataclass
class Frames:
    subject: np.ndarray  # (n,) subject names
    held_out: np.ndarray  # (n,) bool
    head_drop: np.ndarray  # (n,) m below standing
    hips_drop: np.ndarray  # (n,) m below standing (truth)
    pitch: np.ndarray  # (n,) headset pitch, rad (negative: down)
    bend: np.ndarray  # (n,) torso bend beyond standing, rad (truth, ≥ 0)
    torso: np.ndarray  # (n,) the subject's standing hips → head distance, m


def load_frames(log=print) -> Frames:
    cols: dict[str, list] = {k: [] for k in Frames.__dataclass_fields__}
    for folder, s in data.TRAIN_SUBJECTS + data.TEST_SUBJECTS:
        path = data.ensure_database(folder, s, log=log)
        db = mmdb.load(path)
        site = {k: j for k, (j, _) in db.sites.items()}
        pos, rot = mmdb.world_transforms_all(db)
        rig = data.load_clips(path, data.subject_name(folder, s), mirrored=False)[0].rig
        takes = [slice(c.start, c.end) for c in db.clips if not c.mirrored]
        head = np.concatenate([pos[t, site["head"]] for t in takes])[::FRAME_STEP]
        hips = np.concatenate([pos[t, site["hips"]] for t in takes])[::FRAME_STEP]
        q = np.concatenate([rot[t, site["head"]] for t in takes])[::FRAME_STEP].astype(np.float64)
        view = quat_rotate(
            quat_mul(q, np.broadcast_to(rig.hmd_align, q.shape)), np.broadcast_to([0.0, 0.0, -1.0], head.shape)
        )
        d = np.percentile(head[:, 1], 90) - head[:, 1]
        torso = hips - head
        length = np.linalg.norm(torso, axis=1)
        angle = np.arccos(np.clip(-torso[:, 1] / length, -1.0, 1.0))
        standing = np.abs(d) < 0.03
        n = len(d)
        cols["subject"].append(np.full(n, data.subject_name(folder, s)))
        cols["held_out"].append(np.full(n, (folder, s) in data.TEST_SUBJECTS))
        cols["head_drop"].append(d)
        cols["hips_drop"].append(np.percentile(hips[:, 1], 90) - hips[:, 1])
        cols["pitch"].append(np.arcsin(np.clip(view[:, 1], -1.0, 1.0)))
        cols["bend"].append(np.maximum(angle - np.median(angle[standing]), 0.0))
        cols["torso"].append(np.full(n, np.median(length[standing])))
    return Frames(**{k: np.concatenate(v) for k, v in cols.items()})


def split(head_drop, pitch, torso, start_pitch, gain, deadband, max_bend, bend=True):
    """`crouch.rs`'s `split`, vectorized (`bend=False`: the hips take everything, as before it)."""
    d = np.maximum(head_drop, 0.0)
    e = np.where(d < 2 * deadband, d * d / (4 * deadband), d - deadband)
    most = np.clip(gain * (start_pitch - pitch), 0.0, max_bend) if bend else np.zeros_like(d)
    spine = np.minimum(np.maximum(e - deadband, 0.0), torso * (1.0 - np.cos(most)))
    return e - spine, np.arccos(np.clip(1.0 - spine / torso, -1.0, 1.0))


def score(f: Frames, **rule) -> dict[str, float]:
    """Mean errors (hips drop in m, bend in rad) on held-out and training frames: all of them,
    and those whose head is more than 5 cm down."""
    hips, bend = split(f.head_drop, f.pitch, f.torso, **rule)
    low = f.head_drop > 0.05
    out = {}
    for side, mask in (("held_out", f.held_out), ("training", ~f.held_out)):
        out[f"{side}_hips_low"] = float(np.abs(hips - f.hips_drop)[mask & low].mean())
        out[f"{side}_bend"] = float(np.abs(bend - f.bend)[mask].mean())
        out[f"{side}_bend_low"] = float(np.abs(bend - f.bend)[mask & low].mean())
    upright = np.abs(f.head_drop) < 0.06
    out["upright_bend_p95"] = float(np.percentile(bend[upright], 95))
    return out


def fit(f: Frames, deadband: float, max_bend: float) -> tuple[float, float]:
    """The start pitch and gain that best predict the training subjects' hips drop."""
    best = None
    for start in np.radians(np.arange(0.0, -41.0, -5.0)):
        for gain in (0.5, 0.75, 1.0, 1.5, 2.0, 3.0):
            e = score(f, start_pitch=start, gain=gain, deadband=deadband, max_bend=max_bend)["training_hips_low"]
            if best is None or e < best[0]:
                best = (e, start, gain)
    return best[1], best[2]


def main(argv=None) -> int:
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args(argv)
    c = rust_constants()
    f = load_frames()
    base = dict(deadband=c["CROUCH_DEADBAND"], max_bend=c["MAX_BEND"])
    start, gain = fit(f, **base)
    print(
        f"{len(f.head_drop)} frames ({f.held_out.sum()} held out); {(f.head_drop > 0.05).sum()} with the head > 5 cm down"
    )
    print(
        f"fitted on the training subjects: bending starts at {np.degrees(start):.0f}°, gain {gain} "
        f"(crouch.rs: {np.degrees(c['BEND_START_PITCH']):.0f}°, {c['BEND_GAIN']})\n"
    )
    print(
        "| rule | hips drop error, head > 5 cm down: held-out / training | torso bend error: held-out all / > 5 cm down | bend p95 near standing |"
    )
    print("|---|---|---|---|")
    for name, rule in (
        ("hips take the whole drop (before)", dict(start_pitch=0.0, gain=0.0, bend=False)),
        ("crouch.rs", dict(start_pitch=c["BEND_START_PITCH"], gain=c["BEND_GAIN"])),
    ):
        s = score(f, **rule, **base)
        print(
            f"| {name} | {100 * s['held_out_hips_low']:.1f} / {100 * s['training_hips_low']:.1f} cm | "
            f"{np.degrees(s['held_out_bend']):.1f}° / {np.degrees(s['held_out_bend_low']):.1f}° | {np.degrees(s['upright_bend_p95']):.1f}° |"
        )
    print("\nper held-out subject, hips drop error with the head > 5 cm down (before → crouch.rs):")
    for subject in np.unique(f.subject[f.held_out]):
        m = (f.subject == subject) & (f.head_drop > 0.05)
        if not m.any():
            continue
        before, _ = split(f.head_drop[m], f.pitch[m], f.torso[m], 0.0, 0.0, bend=False, **base)
        after, _ = split(f.head_drop[m], f.pitch[m], f.torso[m], c["BEND_START_PITCH"], c["BEND_GAIN"], **base)
        print(
            f"  {subject}: {m.sum()} frames, {100 * np.abs(before - f.hips_drop[m]).mean():.1f} → {100 * np.abs(after - f.hips_drop[m]).mean():.1f} cm"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
