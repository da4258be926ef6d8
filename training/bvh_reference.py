"""A small, deliberately independent BVH parser and forward kinematics, used as a test oracle.

It shares nothing with the Rust importer (different language, rotation *matrices* instead of
quaternions, its own parser), so agreement between the two is evidence that both are right.

Conventions (the project's chosen reading of BVH, stated here because BVH itself is vague):

- The file is whitespace-tokenized, so tabs, CRLF line endings and odd indentation are fine.
- HIERARCHY: `ROOT`/`JOINT name { OFFSET x y z  CHANNELS n ch... ...children }`. `End Site`
  blocks only carry an OFFSET and are *not* joints (they are skipped).
- Any joint may have any subset of `Xposition Yposition Zposition Xrotation Yrotation
  Zrotation`, in any order.
- Rotations are in **degrees**. A joint's local rotation is the product of the per-axis
  rotation matrices in the order the channels are listed: for `Zrotation Xrotation Yrotation`,
  `R = Rz · Rx · Ry` (column vectors, first-listed is outermost).
- Position channels **replace** the matching component of the joint's OFFSET; components with
  no channel keep the OFFSET value. (For the usual root with all three, the offset is unused.)
- FK: `world_rot[j] = world_rot[parent] @ R_j`,
  `world_pos[j] = world_pos[parent] + world_rot[parent] @ t_j` (root: parent = identity at the
  origin). All translations, offsets and position channels alike, are multiplied by `scale`.
- MOTION: `Frames: N`, `Frame Time: t`, then N*C numbers (C = total channel count) in
  hierarchy order; line breaks inside the numbers do not matter.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

AXES = {"X": 0, "Y": 1, "Z": 2}
CHANNEL_NAMES = {f"{a}{kind}" for a in "XYZ" for kind in ("position", "rotation")}


class BvhError(ValueError):
    """The text is not a BVH file this parser understands; the message says where."""


@dataclass
class Bvh:
    names: list[str]
    parents: np.ndarray  # (J,) int, -1 for the root
    offsets: np.ndarray  # (J, 3) float64, in file units
    channels: list[list[str]]  # per joint, in file order
    frame_time: float
    motion: np.ndarray  # (frames, total channels) float64, in file order

    @property
    def num_frames(self) -> int:
        return self.motion.shape[0]


class _Tokens:
    def __init__(self, tokens: list[str]):
        self.tokens, self.i = tokens, 0

    def next(self, what: str) -> str:
        if self.i >= len(self.tokens):
            raise BvhError(f"unexpected end of file while reading {what}")
        self.i += 1
        return self.tokens[self.i - 1]

    def expect(self, word: str) -> None:
        got = self.next(repr(word))
        if got != word:
            raise BvhError(f"expected {word!r}, found {got!r} (token {self.i})")

    def floats(self, n: int, what: str) -> list[float]:
        try:
            return [float(self.next(what)) for _ in range(n)]
        except ValueError as e:
            raise BvhError(f"bad number in {what}: {e}") from None


def _parse_joint(tok: _Tokens, name: str, parent: int, bvh: dict) -> None:
    index = len(bvh["names"])
    bvh["names"].append(name)
    bvh["parents"].append(parent)
    bvh["channels"].append([])
    bvh["offsets"].append([0.0, 0.0, 0.0])
    tok.expect("{")
    while True:
        word = tok.next(f"the body of joint {name!r}")
        if word == "}":
            return
        if word == "OFFSET":
            bvh["offsets"][index] = tok.floats(3, f"OFFSET of {name!r}")
        elif word == "CHANNELS":
            count = int(tok.next(f"CHANNELS count of {name!r}"))
            chans = [tok.next(f"CHANNELS of {name!r}") for _ in range(count)]
            bad = [c for c in chans if c not in CHANNEL_NAMES]
            if bad:
                raise BvhError(f"joint {name!r}: unknown channel(s) {bad}")
            bvh["channels"][index] = chans
        elif word == "JOINT":
            _parse_joint(tok, tok.next("joint name"), index, bvh)
        elif word == "End":
            tok.expect("Site")
            tok.expect("{")
            tok.expect("OFFSET")
            tok.floats(3, f"End Site OFFSET under {name!r}")
            tok.expect("}")
        else:
            raise BvhError(f"unexpected {word!r} in joint {name!r}")


def parse_text(text: str) -> Bvh:
    """Parse BVH text (see the module docstring for the accepted syntax)."""
    head, sep, motion = text.partition("MOTION")
    if not sep:
        raise BvhError("no MOTION section")
    tok = _Tokens(head.split())
    tok.expect("HIERARCHY")
    tok.expect("ROOT")
    bvh = {"names": [], "parents": [], "channels": [], "offsets": []}
    _parse_joint(tok, tok.next("root name"), -1, bvh)
    if tok.i != len(tok.tokens):
        raise BvhError(f"unexpected {tok.tokens[tok.i]!r} after the root joint")

    words = motion.split()
    if words[:1] != ["Frames:"] or words[2:4] != ["Frame", "Time:"]:
        raise BvhError("MOTION must start with 'Frames: N' and 'Frame Time: t'")
    frames, frame_time = int(words[1]), float(words[4])
    num_channels = sum(len(c) for c in bvh["channels"])
    values = words[5:]
    if len(values) != frames * num_channels:
        raise BvhError(f"MOTION has {len(values)} numbers, expected {frames} frames x {num_channels} channels")
    try:
        data = np.array(values, dtype=np.float64).reshape(frames, num_channels)
    except ValueError as e:
        raise BvhError(f"bad number in MOTION: {e}") from None
    return Bvh(
        bvh["names"],
        np.array(bvh["parents"]),
        np.array(bvh["offsets"], dtype=np.float64),
        bvh["channels"],
        frame_time,
        data,
    )


def parse(path: str | os.PathLike) -> Bvh:
    with open(path, "r", encoding="utf-8", errors="replace") as f:
        return parse_text(f.read())


def axis_rotation(axis: int, degrees: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) about one coordinate axis, right-handed, angles in degrees."""
    a = np.radians(np.asarray(degrees, dtype=np.float64))
    c, s = np.cos(a), np.sin(a)
    m = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]  # the plane the axis rotates: x->(y,z), y->(z,x), z->(x,y)
    m[..., axis, axis] = 1.0
    m[..., i, i], m[..., i, j] = c, -s
    m[..., j, i], m[..., j, j] = s, c
    return m


def local_transforms(bvh: Bvh, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame local translations (F, J, 3) and rotation matrices (F, J, 3, 3)."""
    F, J = bvh.num_frames, len(bvh.names)
    trans = np.broadcast_to(bvh.offsets, (F, J, 3)).copy()
    rots = np.broadcast_to(np.eye(3), (F, J, 3, 3)).copy()
    column = 0
    for j, chans in enumerate(bvh.channels):
        for ch in chans:
            values, axis = bvh.motion[:, column], AXES[ch[0]]
            if ch.endswith("position"):
                trans[:, j, axis] = values
            else:
                rots[:, j] = rots[:, j] @ axis_rotation(axis, values)
            column += 1
    return trans * scale, rots


def fk_bvh(bvh: Bvh, scale: float = 1.0) -> np.ndarray:
    """World joint positions (F, J, 3) float64 of a parsed file."""
    trans, rots = local_transforms(bvh, scale)
    pos, rot = np.empty_like(trans), np.empty_like(rots)
    for j, p in enumerate(bvh.parents):
        if p < 0:
            pos[:, j], rot[:, j] = trans[:, j], rots[:, j]
        else:
            rot[:, j] = rot[:, p] @ rots[:, j]
            pos[:, j] = pos[:, p] + np.einsum("fab,fb->fa", rot[:, p], trans[:, j])
    return pos


def fk(path: str | os.PathLike, scale: float = 1.0) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(joint names, parents, world positions (frames, J, 3) float64) of a BVH file."""
    bvh = parse(path)
    return bvh.names, bvh.parents, fk_bvh(bvh, scale)
