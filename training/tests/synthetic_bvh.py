"""Small synthetic BVH files for the FK tests: a Mixamo-named legged skeleton in metres.

The names (Hips, LeftUpLeg, ..., Head) let the Rust builder find hips and feet, so the same
files work for `bvh_reference` alone and through `mmdb build --scale 1`. Angles are large
(tens of degrees on every axis) and vary per frame so that any mistake in rotation order,
sign or composition shows up as centimetres, not rounding noise.
"""

from __future__ import annotations

import numpy as np

ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")

# name, parent, offset (m), end-site offset or None
SKELETON = [
    ("Hips", None, (0.0, 0.9, 0.0), None),
    ("Spine", "Hips", (0.0, 0.1, 0.0), None),
    ("Head", "Spine", (0.0, 0.5, 0.02), (0.0, 0.2, 0.0)),
    ("LeftUpLeg", "Hips", (0.1, -0.05, 0.0), None),
    ("LeftLeg", "LeftUpLeg", (0.0, -0.42, 0.0), None),
    ("LeftFoot", "LeftLeg", (0.0, -0.42, -0.02), None),
    ("LeftToeBase", "LeftFoot", (0.0, -0.06, 0.12), (0.0, 0.0, 0.05)),
    ("RightUpLeg", "Hips", (-0.1, -0.05, 0.0), None),
    ("RightLeg", "RightUpLeg", (0.0, -0.42, 0.0), None),
    ("RightFoot", "RightLeg", (0.0, -0.42, -0.02), None),
    ("RightToeBase", "RightFoot", (0.0, -0.06, 0.12), (0.0, 0.0, 0.05)),
]


def rotation_channels(order: str) -> list[str]:
    return [f"{axis}rotation" for axis in order]


def default_channels(order: str) -> dict[str, list[str]]:
    """Root: 3 positions + rotations; Spine: 3 positions + rotations (a non-root position
    joint); everyone else rotations only, all in `order`."""
    position = ["Xposition", "Yposition", "Zposition"]
    chans = {name: rotation_channels(order) for name, *_ in SKELETON}
    chans["Hips"] = position + rotation_channels(order)
    chans["Spine"] = position + rotation_channels(order)
    return chans


def channel_values(name: str, channel: str, offset, t: np.ndarray, rng) -> np.ndarray:
    """Values over time for one channel: the root walks forward along +Z with sway; other
    position channels wobble a few cm around the offset; rotations swing by up to ~70 deg."""
    axis = "XYZ".index(channel[0])
    phase, freq = rng.uniform(0, 2 * np.pi), rng.uniform(0.4, 1.5)
    wave = np.sin(2 * np.pi * freq * t + phase)
    if channel.endswith("position"):
        if name == "Hips":
            return [0.05 * wave, 0.9 + 0.03 * wave, 1.3 * t][axis]
        return offset[axis] + 0.04 * wave
    amplitude = 25.0 if name == "Hips" else rng.uniform(30.0, 70.0)
    return amplitude * wave + rng.uniform(-20.0, 20.0)


def make_bvh(
    order: str = "ZXY",
    frames: int = 150,
    frame_time: str = "0.02",
    channels: dict[str, list[str]] | None = None,
    newline: str = "\n",
    indent: str = "  ",
    seed: int = 0,
) -> str:
    """BVH text for SKELETON with the given per-joint channels (default: `default_channels`)."""
    chans = channels or default_channels(order)
    rng = np.random.default_rng(seed)
    t = np.arange(frames) * float(frame_time)
    children = {name: [c for c, p, *_ in SKELETON if p == name] for name, *_ in SKELETON}
    info = {name: (offset, end) for name, _, offset, end in SKELETON}
    lines, columns = ["HIERARCHY"], []

    def fmt(v) -> str:
        return " ".join(repr(float(x)) for x in v)

    def write(name: str, depth: int) -> None:
        pad = indent * depth
        offset, end = info[name]
        lines.append(f"{pad}{'ROOT' if depth == 0 else 'JOINT'} {name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}{indent}OFFSET {fmt(offset)}")
        lines.append(f"{pad}{indent}CHANNELS {len(chans[name])} {' '.join(chans[name])}")
        columns.extend(channel_values(name, ch, offset, t, rng) for ch in chans[name])
        for child in children[name]:
            write(child, depth + 1)
        if end is not None:
            lines.extend(
                [
                    f"{pad}{indent}End Site",
                    f"{pad}{indent}{{",
                    f"{pad}{indent * 2}OFFSET {fmt(end)}",
                    f"{pad}{indent}}}",
                ]
            )
        lines.append(f"{pad}}}")

    write("Hips", 0)
    motion = np.stack(columns, axis=1)
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {frame_time}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in motion]
    return newline.join(lines) + newline
