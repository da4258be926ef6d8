"""A tiny test-side `.mmdb` writer and byte-patching helpers.

The writer makes a minimal valid file (4 frames, VirtualRoot + Hips) so the reader's
validation can be tested without the Rust CLI, one defect at a time. The patch helpers are
shared with the CLI tests, which corrupt real files the same way for both readers.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

MAGIC = b"\x89MMDB\r\n\x1a"


def string(s: str) -> bytes:
    raw = s.encode()
    return struct.pack("<I", len(raw)) + raw


def f32s(*values) -> bytes:
    return np.asarray(values, dtype="<f4").tobytes()


def assemble(sections: list[tuple[str, bytes]], version: int = 1) -> bytes:
    """Header + table + 16-aligned section data, checksum filled in."""
    table_end = 32 + 24 * len(sections)
    table, body, offset = b"", b"", (table_end + 15) // 16 * 16
    for tag, data in sections:
        table += struct.pack("<4sIQQ", tag.encode(), 0, offset, len(data))
        padded = data + b"\0" * (-len(data) % 16)
        body += padded
        offset += len(padded)
    payload = table + b"\0" * ((table_end + 15) // 16 * 16 - table_end) + body
    size = 32 + len(payload)
    header = MAGIC + struct.pack("<IIQII", version, len(sections), size, zlib.crc32(payload), 0)
    return header + payload


def refix_checksum(data: bytes) -> bytes:
    """Recompute the header CRC so that a deliberate corruption is caught by its own check."""
    return data[:24] + struct.pack("<I", zlib.crc32(data[32:])) + data[28:]


def patch(data: bytes, offset: int, new: bytes, refix: bool = True) -> bytes:
    out = data[:offset] + new + data[offset + len(new) :]
    return refix_checksum(out) if refix else out


def section_entries(data: bytes) -> dict[str, tuple[int, int, int]]:
    """tag -> (table entry byte offset, data offset, data length)."""
    count = struct.unpack_from("<I", data, 12)[0]
    out = {}
    for i in range(count):
        at = 32 + 24 * i
        tag, _, off, length = struct.unpack_from("<4sIQQ", data, at)
        out[tag.decode()] = (at, off, length)
    return out


F, J, D = 4, 2, 3
YAW = np.radians([0.0, 30.0, 60.0, 90.0])  # VirtualRoot yaw per frame


def sample_sections(parents=(-1, 0), clips=((0, 4),), tag_ranges=((0, 4),), first_dim: int = 0) -> dict[str, bytes]:
    """A valid database unless the arguments say otherwise."""
    root_rot = np.stack([np.zeros(F), np.sin(YAW / 2), np.zeros(F), np.cos(YAW / 2)], axis=1)
    lpos = np.zeros((F, J, 3))
    lpos[:, 0] = [[f * 0.1, 0.0, 1.0] for f in range(F)]
    lpos[:, 1] = [0.0, 0.9, 0.5]
    lrot = np.zeros((F, J, 4))
    lrot[:, 0], lrot[:, 1] = root_rot, [0.0, 0.0, 0.0, 1.0]
    skel = b"".join(
        string(n) + struct.pack("<i", p) + f32s(*o)
        for n, p, o in zip(("VirtualRoot", "Hips"), parents, ((0, 0, 0), (0, 0.9, 0)))
    )
    skel += struct.pack("<I", 2) + string("hips") + struct.pack("<i", 1) + f32s(0, 0, 0)
    skel += string("left_toe") + struct.pack("<i", -1) + f32s(0, 0, 0)
    clip = struct.pack("<I", len(clips)) + b"".join(
        string(f"walk{i}") + string("walk.bvh") + struct.pack("<IIB", s, e, 0) + f32s(120, 1, 1)
        for i, (s, e) in enumerate(clips)
    )
    tags = (
        struct.pack("<I", 1)
        + string("walk")
        + struct.pack("<I", len(tag_ranges))
        + b"".join(struct.pack("<II", s, e) for s, e in tag_ranges)
    )
    fdsc = struct.pack("<I", 1) + string("hips_position") + bytes([0, 0, 0, 0])
    fdsc += struct.pack("<i", 1) + f32s(0, 0, 1) + struct.pack("<Ii", 1, 0) + f32s(1.0)
    fdsc += struct.pack("<II", first_dim, D)
    return {
        "INFO": struct.pack("<IIfIIIII", F, J, 30.0, D, len(clips), 1, 1, 0),
        "SKEL": skel,
        "CLIP": clip,
        "TAGS": tags,
        "LPOS": f32s(*lpos.ravel()),
        "LROT": f32s(*lrot.ravel()),
        "LVEL": f32s(*np.arange(F * J * 3)),
        "LAVL": f32s(*-np.arange(F * J * 3)),
        "CONT": bytes([1, 0, 1, 1, 0, 1, 0, 0]),
        "FDSC": fdsc,
        "FNRM": f32s(0.5, 0.5, 0.5, 2, 2, 2),
        "FEAT": f32s(*np.linspace(-1, 1, F * D)),
        "VALD": bytes([1, 1, 0, 0]),
    }


def sample_file(**kwargs) -> bytes:
    return assemble(list(sample_sections(**kwargs).items()))


def encode_panm(lpos: np.ndarray, rest: np.ndarray) -> bytes:
    """PANM from docs/mmdb-format.md: the joints whose position ever differs from the rest offset."""
    animated = [j for j in range(lpos.shape[1]) if np.any(lpos[:, j].astype("<f4") != rest[j].astype("<f4"))]
    return (
        struct.pack("<I", len(animated))
        + struct.pack(f"<{len(animated)}I", *animated)
        + lpos[:, animated].astype("<f4").tobytes()
    )


def encode_qrot(lrot: np.ndarray) -> bytes:
    """QROT: round(x * 32767), joint-major / component / frame, wrapping deltas along frames."""
    c = np.clip(np.round(lrot.astype(np.float32) * np.float32(32767)), -32767, 32767).astype(np.int64)
    planar = c.transpose(1, 2, 0)  # (J, 4, F)
    deltas = np.diff(planar, axis=2, prepend=0)
    return (((deltas + 32768) % 65536) - 32768).astype("<i2").tobytes()


def encode_fshf(features: np.ndarray) -> bytes:
    """FSHF: 4 byte planes of the dimension-major f32 values."""
    raw = np.ascontiguousarray(features.astype("<f4").T).view(np.uint8).reshape(-1, 4)
    return np.ascontiguousarray(raw.T).tobytes()


def sample_sections_v2(clips=((0, 4),)) -> dict[str, bytes]:
    """The version-2 twin of `sample_sections()`: same poses and features, v2 encodings."""
    v1 = sample_sections(clips=clips)
    lpos = np.frombuffer(v1["LPOS"], "<f4").reshape(F, J, 3)
    lrot = np.frombuffer(v1["LROT"], "<f4").reshape(F, J, 4)
    rest = np.array([[0, 0, 0], [0, 0.9, 0]], dtype=np.float32)
    clip = struct.pack("<I", len(clips)) + b"".join(
        string(f"walk{i}")
        + string("walk.bvh")
        + struct.pack("<IIB", s, e, 0)
        + struct.pack("<d", 120.0)
        + f32s(1, 1)
        + struct.pack("<I", 7 * i)
        for i, (s, e) in enumerate(clips)
    )
    out = {k: v for k, v in v1.items() if k not in ("LPOS", "LROT", "LVEL", "LAVL", "FEAT")}
    out.update(
        CLIP=clip,
        PANM=encode_panm(lpos, rest),
        QROT=encode_qrot(lrot),
        FSHF=encode_fshf(np.frombuffer(v1["FEAT"], "<f4").reshape(F, D)),
    )
    order = ("INFO", "SKEL", "CLIP", "TAGS", "PANM", "QROT", "CONT", "FDSC", "FNRM", "FSHF", "VALD")
    return {k: out[k] for k in order}


def sample_file_v2(**kwargs) -> bytes:
    return assemble(list(sample_sections_v2(**kwargs).items()), version=2)
