"""Reader for the `.mmdb` motion database format, versions 2 and 1 (numpy only).

Written from `docs/mmdb-format.md` alone, without looking at the Rust writer, so that the
tests comparing it with files the Rust CLI writes check the *document* as much as the code:
if the two disagree, either the writer or the document is wrong.

Everything the document's "Validation a reader must do" section lists is checked; a bad file
raises `MmdbError` (a `ValueError`) whose message names the section and field at fault.

Quaternions are `(x, y, z, w)` as in the file. `quat_mul` / `quat_rotate` are implemented
here (vectorized over any leading axes) rather than imported, to keep this module a
self-contained second implementation.
"""

from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass, field

import numpy as np

MAGIC = b"\x89MMDB\r\n\x1a"
VERSIONS = (1, 2, 3)
HEADER_SIZE = 32
ENTRY_SIZE = 24
ALIGNMENT = 16

REQUIRED_SECTIONS = {
    1: ("INFO", "SKEL", "CLIP", "TAGS", "LPOS", "LROT", "LVEL", "LAVL", "CONT", "FDSC", "FNRM", "FEAT", "VALD"),
    2: ("INFO", "SKEL", "CLIP", "TAGS", "PANM", "QROT", "CONT", "FDSC", "FNRM", "FSHF", "VALD"),
    3: ("INFO", "SKEL", "CLIP", "TAGS", "PANM", "QROT", "CONT", "FDSC", "FNRM", "VALD"),
}
ROTATION_SCALE = 32767.0
# A decoded QROT value whose squared length is off by more than this (relative) is corruption.
QROT_NORM_TOLERANCE = 1e-3

KIND_POSITION, KIND_VELOCITY, KIND_DIRECTION = 0, 1, 2
AXES_XYZ, AXES_XZ = 0, 1


class MmdbError(ValueError):
    """The bytes are not a valid `.mmdb` file this reader reads; the message says why."""


@dataclass
class Clip:
    name: str
    source: str
    start: int
    end: int  # exclusive
    mirrored: bool
    source_fps: float
    scale: float
    root_scale: float
    source_start: int = 0  # first source frame; version 1 does not store it


@dataclass
class FeatureGroup:
    name: str
    kind: int  # KIND_POSITION / KIND_VELOCITY / KIND_DIRECTION
    trajectory: bool
    axes: int  # AXES_XYZ / AXES_XZ
    joint: int
    direction: np.ndarray  # (3,) float32, meaningful for KIND_DIRECTION only
    offsets: list[int]
    weight: float
    first_dim: int
    num_dims: int


@dataclass
class Database:
    version: int
    fps: float
    num_frames: int
    flags: int
    joint_names: list[str]
    parents: np.ndarray  # (J,) int32, parents[0] == -1
    rest_offsets: np.ndarray  # (J, 3) float32
    sites: dict[str, tuple[int, np.ndarray]]  # name -> (joint or -1, (3,) offset)
    clips: list[Clip]
    tags: dict[str, list[tuple[int, int]]]
    local_positions: np.ndarray  # (F, J, 3) float32
    local_rotations: np.ndarray  # (F, J, 4) float32, (x, y, z, w)
    local_velocities: np.ndarray  # (F, J, 3) float32
    local_angular_velocities: np.ndarray  # (F, J, 3) float32
    contacts: np.ndarray  # (F, 2) bool, [:, 0] left, [:, 1] right
    feature_groups: list[FeatureGroup]
    feature_mean: np.ndarray  # (D,) float32
    feature_scale: np.ndarray  # (D,) float32
    features: np.ndarray  # (F, D) float32, normalized
    valid: np.ndarray  # (F,) bool
    extra_sections: dict[str, bytes] = field(default_factory=dict)  # unknown tags, kept raw

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def num_features(self) -> int:
        return int(self.features.shape[1])


class _Cursor:
    """Sequential little-endian reads inside one section, with bounds checks that name it."""

    def __init__(self, data: bytes, section: str):
        self.data, self.section, self.pos = data, section, 0

    def _take(self, n: int, what: str) -> bytes:
        if self.pos + n > len(self.data):
            raise MmdbError(
                f"section {self.section}: {what} runs past the end of the section "
                f"(needs {n} bytes at offset {self.pos}, section is {len(self.data)} bytes)"
            )
        out = self.data[self.pos : self.pos + n]
        self.pos += n
        return out

    def u8(self, what: str) -> int:
        return self._take(1, what)[0]

    def u32(self, what: str) -> int:
        return struct.unpack("<I", self._take(4, what))[0]

    def i32(self, what: str) -> int:
        return struct.unpack("<i", self._take(4, what))[0]

    def f32(self, what: str) -> float:
        return struct.unpack("<f", self._take(4, what))[0]

    def f64(self, what: str) -> float:
        return struct.unpack("<d", self._take(8, what))[0]

    def vec3(self, what: str) -> np.ndarray:
        return np.frombuffer(self._take(12, what), dtype="<f4").astype(np.float32)

    def string(self, what: str) -> str:
        n = self.u32(f"{what} length")
        raw = self._take(n, what)
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError as e:
            raise MmdbError(f"section {self.section}: {what} is not valid UTF-8 ({e})") from None

    def finish(self) -> None:
        """Trailing bytes mean writer and reader disagree on the layout: reject them."""
        if self.pos != len(self.data):
            raise MmdbError(
                f"section {self.section}: {len(self.data) - self.pos} unexpected trailing bytes "
                f"(parsed {self.pos} of {len(self.data)})"
            )


def _read_bytes(path_or_bytes) -> bytes:
    if isinstance(path_or_bytes, (bytes, bytearray, memoryview)):
        return bytes(path_or_bytes)
    with open(os.fspath(path_or_bytes), "rb") as f:
        return f.read()


def _check_header(data: bytes) -> tuple[int, int]:
    """Check magic, version, file_size and checksum; return the version and section count."""
    if len(data) < HEADER_SIZE:
        raise MmdbError(f"truncated: file is {len(data)} bytes, shorter than the {HEADER_SIZE}-byte header")
    if data[:8] != MAGIC:
        raise MmdbError(f"header: bad magic {data[:8]!r}, expected {MAGIC!r} (not an .mmdb file)")
    version, section_count, file_size, checksum, _reserved = struct.unpack_from("<IIQII", data, 8)
    if version not in VERSIONS:
        raise MmdbError(
            f"header: unsupported version {version} (this reader reads versions "
            f"{', '.join(map(str, VERSIONS))}); rebuild the database with `mmdb build`"
        )
    if file_size != len(data):
        state = "truncated" if len(data) < file_size else "has trailing bytes"
        raise MmdbError(
            f"header: file size mismatch: header file_size is {file_size} bytes but the file is "
            f"{len(data)} bytes (file {state})"
        )
    actual = zlib.crc32(memoryview(data)[HEADER_SIZE:]) & 0xFFFFFFFF
    if actual != checksum:
        raise MmdbError(
            f"header: checksum mismatch: stored CRC-32 {checksum:#010x}, computed {actual:#010x} (file corrupted)"
        )
    return version, section_count


def _read_section_table(data: bytes, section_count: int, version: int) -> dict[str, bytes]:
    table_end = HEADER_SIZE + ENTRY_SIZE * section_count
    if table_end > len(data):
        raise MmdbError(f"section table: {section_count} entries need {table_end} bytes, file is {len(data)}")
    sections: dict[str, bytes] = {}
    for i in range(section_count):
        raw_tag, _reserved, offset, length = struct.unpack_from("<4sIQQ", data, HEADER_SIZE + ENTRY_SIZE * i)
        tag = raw_tag.decode("ascii", errors="replace")
        where = f"section table entry {i} ({tag!r})"
        if offset < table_end:
            raise MmdbError(f"{where}: offset {offset} is before the end of the section table ({table_end})")
        if offset + length > len(data):
            raise MmdbError(f"{where}: data [{offset}, {offset + length}) lies outside the file ({len(data)} bytes)")
        if offset % ALIGNMENT:
            raise MmdbError(f"{where}: offset {offset} is not a multiple of {ALIGNMENT}")
        if tag in sections:
            raise MmdbError(f"{where}: duplicate section {tag}")
        sections[tag] = data[offset : offset + length]
    missing = [t for t in REQUIRED_SECTIONS[version] if t not in sections]
    if missing:
        raise MmdbError(f"section table: missing required section(s) {', '.join(missing)}")
    return sections


def _array(sections: dict[str, bytes], tag: str, dtype: str, shape: tuple[int, ...]) -> np.ndarray:
    """A fixed-size section as a (copied, native) array, after checking its byte length."""
    itemsize = np.dtype(dtype).itemsize
    expected = int(np.prod(shape, dtype=np.int64)) * itemsize
    data = sections[tag]
    if len(data) != expected:
        raise MmdbError(
            f"section {tag}: length {len(data)} bytes does not match INFO, which implies "
            f"{' x '.join(map(str, shape))} x {itemsize} = {expected} bytes"
        )
    return np.frombuffer(data, dtype=dtype).reshape(shape).astype(np.dtype(dtype).newbyteorder("="))


def _check_flags(tag: str, arr: np.ndarray) -> np.ndarray:
    if arr.size and arr.max() > 1:
        raise MmdbError(f"section {tag}: values must be 0 or 1, found {int(arr.max())}")
    return arr.astype(bool)


def _check_ranges(what: str, ranges: list[tuple[int, int]], num_frames: int) -> None:
    """Ranges must be non-empty, sorted, disjoint and inside [0, F)."""
    prev_end = 0
    for start, end in ranges:
        if not (start < end <= num_frames):
            raise MmdbError(f"{what}: range [{start}, {end}) is empty or outside [0, {num_frames})")
        if start < prev_end:
            raise MmdbError(f"{what}: range [{start}, {end}) is unsorted or overlaps the previous one")
        prev_end = end


def load(path_or_bytes) -> Database:
    """Read and validate a `.mmdb` file given as a path or as its bytes."""
    data = _read_bytes(path_or_bytes)
    version, section_count = _check_header(data)
    sections = _read_section_table(data, section_count, version)

    info = sections["INFO"]
    if len(info) != 32:
        raise MmdbError(f"section INFO: length {len(info)} bytes, expected 32")
    F, J, fps, D, num_clips, num_tags, G, flags = struct.unpack("<IIfIIIII", info)
    if not (np.isfinite(fps) and fps > 0):
        raise MmdbError(f"section INFO: fps must be positive and finite, got {fps}")
    if flags & ~1:
        raise MmdbError(f"section INFO: unknown flag bits set in flags {flags:#x}")

    # SKEL
    cur = _Cursor(sections["SKEL"], "SKEL")
    names, parents, offsets = [], [], []
    for j in range(J):
        names.append(cur.string(f"joint {j} name"))
        parent = cur.i32(f"joint {j} parent")
        if (j == 0 and parent != -1) or (j > 0 and not 0 <= parent < j):
            raise MmdbError(
                f"section SKEL: joint {j} ({names[-1]!r}) has parent {parent}; parents must come "
                f"first (0 <= parent < index), and only joint 0 has parent -1"
            )
        parents.append(parent)
        offsets.append(cur.vec3(f"joint {j} rest offset"))
    sites = {}
    for s in range(cur.u32("site count")):
        name = cur.string(f"site {s} name")
        joint = cur.i32(f"site {s} joint")
        if not -1 <= joint < J:
            raise MmdbError(f"section SKEL: site {name!r} refers to joint {joint}, outside [-1, {J})")
        sites[name] = (joint, cur.vec3(f"site {s} offset"))
    cur.finish()

    # CLIP
    cur = _Cursor(sections["CLIP"], "CLIP")
    count = cur.u32("clip count")
    if count != num_clips:
        raise MmdbError(f"section CLIP: count {count} differs from INFO num_clips {num_clips}")
    clips = []
    for c in range(count):
        clips.append(
            Clip(
                name=cur.string(f"clip {c} name"),
                source=cur.string(f"clip {c} source"),
                start=cur.u32(f"clip {c} start"),
                end=cur.u32(f"clip {c} end"),
                mirrored=bool(cur.u8(f"clip {c} mirrored")),
                source_fps=cur.f32(f"clip {c} source_fps") if version == 1 else cur.f64(f"clip {c} source_fps"),
                scale=cur.f32(f"clip {c} scale"),
                root_scale=cur.f32(f"clip {c} root_scale"),
                source_start=0 if version == 1 else cur.u32(f"clip {c} source_start"),
            )
        )
    cur.finish()
    _check_ranges("section CLIP", [(c.start, c.end) for c in clips], F)
    if (
        (clips[0].start if clips else 0) != 0
        or (clips[-1].end if clips else 0) != F
        or any(a.end != b.start for a, b in zip(clips, clips[1:]))
    ):
        raise MmdbError(f"section CLIP: clips do not tile [0, {F}) exactly (gap between clips)")
    if len({c.name for c in clips}) != len(clips):
        raise MmdbError("section CLIP: clip names are not unique")
    if bool(flags & 1) != any(c.mirrored for c in clips):
        raise MmdbError("section INFO: flags bit 0 (has mirrored clips) disagrees with the CLIP records")

    # TAGS
    cur = _Cursor(sections["TAGS"], "TAGS")
    count = cur.u32("tag count")
    if count != num_tags:
        raise MmdbError(f"section TAGS: count {count} differs from INFO num_tags {num_tags}")
    tags = {}
    for t in range(count):
        name = cur.string(f"tag {t} name")
        ranges = [
            (cur.u32(f"tag {name!r} start"), cur.u32(f"tag {name!r} end"))
            for _ in range(cur.u32(f"tag {name!r} range count"))
        ]
        _check_ranges(f"section TAGS: tag {name!r}", ranges, F)
        if name in tags:
            raise MmdbError(f"section TAGS: duplicate tag {name!r}")
        tags[name] = ranges
    cur.finish()

    # FDSC
    cur = _Cursor(sections["FDSC"], "FDSC")
    count = cur.u32("group count")
    if count != G:
        raise MmdbError(f"section FDSC: count {count} differs from INFO num_feature_groups {G}")
    groups, next_dim = [], 0
    for g in range(count):
        name = cur.string(f"group {g} name")
        kind, trajectory, axes, _reserved = (
            cur.u8(f"group {name!r} {w}") for w in ("kind", "trajectory", "axes", "reserved")
        )
        joint = cur.i32(f"group {name!r} joint")
        direction = cur.vec3(f"group {name!r} direction")
        offsets_k = [cur.i32(f"group {name!r} offset") for _ in range(cur.u32(f"group {name!r} offset count"))]
        grp = FeatureGroup(
            name,
            kind,
            bool(trajectory),
            axes,
            joint,
            direction,
            offsets_k,
            weight=cur.f32(f"group {name!r} weight"),
            first_dim=cur.u32(f"group {name!r} first_dim"),
            num_dims=cur.u32(f"group {name!r} num_dims"),
        )
        if kind not in (0, 1, 2) or axes not in (0, 1) or not 0 <= joint < J:
            raise MmdbError(f"section FDSC: group {name!r} has kind {kind}, axes {axes}, joint {joint} (invalid)")
        if grp.num_dims != len(offsets_k) * (3 if axes == AXES_XYZ else 2):
            raise MmdbError(f"section FDSC: group {name!r} has {grp.num_dims} dims for {len(offsets_k)} offsets")
        if grp.first_dim != next_dim:
            raise MmdbError(
                f"section FDSC: group {name!r} starts at dim {grp.first_dim}, expected {next_dim} "
                f"(groups must tile [0, {D}))"
            )
        next_dim += grp.num_dims
        groups.append(grp)
    cur.finish()
    if next_dim != D:
        raise MmdbError(f"section FDSC: groups cover [0, {next_dim}), expected to tile [0, {D})")

    fnrm = _array(sections, "FNRM", "<f4", (2, D))
    rest_offsets = np.array(offsets, dtype=np.float32).reshape(J, 3)
    if version == 1:
        local_positions = _array(sections, "LPOS", "<f4", (F, J, 3))
        local_rotations = _array(sections, "LROT", "<f4", (F, J, 4))
        local_velocities = _array(sections, "LVEL", "<f4", (F, J, 3))
        local_angular_velocities = _array(sections, "LAVL", "<f4", (F, J, 3))
        features = _array(sections, "FEAT", "<f4", (F, D))
    else:
        pairs, derived = _read_mirr(sections.get("MIRR"), J, clips) if version >= 3 else (None, [])
        stored = [c for i, c in enumerate(clips) if i not in derived]
        Fs = sum(c.end - c.start for c in stored)
        local_positions, animated = _decode_panm(sections["PANM"], Fs, rest_offsets)
        local_rotations = _decode_qrot(sections["QROT"], Fs, J, version)
        contacts = _check_flags("CONT", _array(sections, "CONT", "u1", (Fs, 2)))
        if derived:
            local_positions, local_rotations, contacts = _expand_mirrors(
                clips, derived, pairs, animated, rest_offsets, local_positions, local_rotations, contacts
            )
        local_velocities, local_angular_velocities = pose_velocities(
            fps, [(c.start, c.end) for c in clips], local_positions, local_rotations
        )
        # Version 3 derives them once the database is assembled (below).
        stored_features = version == 2 or "FSHF" in sections
        features = _decode_fshf(sections["FSHF"], F, D) if stored_features else np.zeros((F, D), np.float32)
    db = Database(
        version=version,
        fps=fps,
        num_frames=F,
        flags=flags,
        joint_names=names,
        parents=np.array(parents, dtype=np.int32),
        rest_offsets=rest_offsets,
        sites=sites,
        clips=clips,
        tags=tags,
        local_positions=local_positions,
        local_rotations=local_rotations,
        local_velocities=local_velocities,
        local_angular_velocities=local_angular_velocities,
        contacts=contacts if version >= 2 else _check_flags("CONT", _array(sections, "CONT", "u1", (F, 2))),
        feature_groups=groups,
        feature_mean=fnrm[0].copy(),
        feature_scale=fnrm[1].copy(),
        features=features,
        valid=_check_flags("VALD", _array(sections, "VALD", "u1", (F,))),
        extra_sections={t: d for t, d in sections.items() if t not in REQUIRED_SECTIONS[version]},
    )
    if version >= 3 and not stored_features:
        raw = pose_features(db)
        db.features = ((raw - db.feature_mean) / db.feature_scale).astype(np.float32)
    return db


# --- version 2 encodings -----------------------------------------------------------------------


def _decode_panm(data: bytes, F: int, rest_offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """PANM: u32 A, A increasing joint indices, f32 F×A×3; other joints at their rest offsets."""
    J = len(rest_offsets)
    if len(data) < 4:
        raise MmdbError("section PANM: shorter than its joint count")
    (A,) = struct.unpack_from("<I", data, 0)
    if A > J:
        raise MmdbError(f"section PANM: {A} animated joints but the skeleton has {J}")
    expected = 4 + 4 * A + 12 * F * A
    if len(data) != expected:
        raise MmdbError(f"section PANM: length {len(data)} bytes, {A} animated joints over {F} frames need {expected}")
    joints = np.frombuffer(data, dtype="<u4", count=A, offset=4).astype(np.int64)
    if A and (joints[-1] >= J or np.any(np.diff(joints) <= 0)):
        raise MmdbError(f"section PANM: joint indices {joints.tolist()[:8]} must increase and be below {J}")
    out = np.broadcast_to(rest_offsets, (F, J, 3)).copy()
    out[:, joints] = np.frombuffer(data, dtype="<f4", offset=4 + 4 * A).reshape(F, A, 3)
    animated = np.zeros(J, dtype=bool)
    animated[joints] = True
    return out, animated


def _read_mirr(data: bytes | None, J: int, clips: list) -> tuple[np.ndarray | None, list[int]]:
    """MIRR (version 3): J u32 mirror map (each joint's opposite, paired back), u32 count, then
    the ascending indices of the clips derived by mirroring the clip before them."""
    if data is None:
        return None, []
    cur = _Cursor(data, "MIRR")
    pairs = np.array([cur.u32("mirror map") for _ in range(J)], dtype=np.int64)
    if np.any(pairs >= J) or np.any(pairs[pairs] != np.arange(J)):
        raise MmdbError("section MIRR: the mirror map does not pair every joint back")
    derived = [cur.u32("derived clip") for _ in range(cur.u32("derived clip count"))]
    cur.finish()
    for k, i in enumerate(derived):
        ok = 1 <= i < len(clips) and (k == 0 or i > derived[k - 1] + 1)
        ok = ok and clips[i].mirrored and not clips[i - 1].mirrored
        if not ok or clips[i].end - clips[i].start != clips[i - 1].end - clips[i - 1].start:
            raise MmdbError(f"section MIRR: clip {i} cannot be derived from the clip before it")
    return pairs, derived


def _expand_mirrors(clips, derived, pairs, animated, rest, positions, rotations, contacts):
    """The stored frames with each derived clip put in its place: the clip before it mirrored
    across the YZ plane (rotation (x, 0-y, 0-z, w) and, for PANM's joints, position (0-x, y, z)
    of the opposite joint; the others at rest), contacts swapped."""
    F = clips[-1].end
    J = len(pairs)
    p = np.zeros((F, J, 3), np.float32)
    q = np.zeros((F, J, 4), np.float32)
    c = np.zeros((F, 2), np.uint8)
    nxt = 0
    for i, clip in enumerate(clips):
        s, e = clip.start, clip.end
        if i in derived:
            a = clips[i - 1].start
            src_p, src_q = p[a : a + e - s][:, pairs], q[a : a + e - s][:, pairs]
            q[s:e] = src_q * np.array([1, -1, -1, 1], np.float32)
            q[s:e, :, 1:3] += np.float32(0.0)  # -0 → +0, as the format states
            mp = src_p * np.array([-1, 1, 1], np.float32)
            mp[..., 0] += np.float32(0.0)
            p[s:e] = np.where(animated[None, :, None], mp, rest[None])
            c[s:e] = c[a : a + e - s][:, ::-1]
        else:
            n = e - s
            p[s:e], q[s:e], c[s:e] = positions[nxt : nxt + n], rotations[nxt : nxt + n], contacts[nxt : nxt + n]
            nxt += n
    return p, q, c


def _decode_qrot(data: bytes, F: int, J: int, version: int = 2) -> np.ndarray:
    """QROT: i16, joint-major then component then frame. Version 2: deltas along frames
    (wrapping). Version 3: zigzag codes in a low-byte and a high-byte plane of the miss of
    `2·c[f-1] - c[f-2]` (wrapping)."""
    if len(data) != F * J * 8:
        raise MmdbError(f"section QROT: length {len(data)} bytes, {F} frames x {J} joints need {F * J * 8}")
    if version >= 3:
        planes = np.frombuffer(data, dtype=np.uint8).reshape(2, -1).astype(np.int64)
        code = planes[0] | (planes[1] << 8)
        residual = np.where(code & 1, -(code >> 1) - 1, code >> 1).reshape(J, 4, F)
        # c[f] = r[f] + 2c[f-1] - c[f-2]: the residuals summed twice (mod 2^16).
        c = np.cumsum(np.cumsum(residual, axis=2), axis=2)
    else:
        # Wrapping i16 prefix sums: accumulate in int64, then reduce mod 2^16.
        c = np.cumsum(np.frombuffer(data, dtype="<i2").reshape(J, 4, F).astype(np.int64), axis=2)
    c = ((c + 32768) % 65536 - 32768).astype(np.float32)
    q = np.ascontiguousarray(c.transpose(2, 0, 1))  # (F, J, 4)
    norm2 = np.einsum("fjc,fjc->fj", q.astype(np.float64), q.astype(np.float64)) / ROTATION_SCALE**2
    bad = np.argwhere(np.abs(norm2 - 1.0) > QROT_NORM_TOLERANCE)
    if len(bad):
        f, j = bad[0]
        raise MmdbError(f"section QROT: frame {f} joint {j} is not a unit quaternion ({q[f, j].tolist()} / 32767)")
    return (q / np.sqrt(np.einsum("fjc,fjc->fj", q, q))[..., None]).astype(np.float32)


def _decode_fshf(data: bytes, F: int, D: int) -> np.ndarray:
    """FSHF: 4 byte planes of the dimension-major values."""
    n = F * D
    if len(data) != 4 * n:
        raise MmdbError(f"section FSHF: length {len(data)} bytes, {F} frames x {D} dims need {4 * n}")
    planes = np.frombuffer(data, dtype=np.uint8).reshape(4, n)
    values = np.ascontiguousarray(planes.T).view("<f4").reshape(D, F)
    return np.ascontiguousarray(values.T).astype(np.float32)


def scaled_axis(q: np.ndarray) -> np.ndarray:
    """Rotation vectors (axis x angle, the short way: q negated when w < 0) of unit quaternions."""
    q = np.where(q[..., 3:] < 0, -q, q)
    v, w = q[..., :3], q[..., 3]
    s = np.linalg.norm(v, axis=-1)
    angle_over_s = np.where(s > 1e-12, 2.0 * np.arctan2(s, w) / np.maximum(s, 1e-300), 2.0)
    return v * angle_over_s[..., None]


def pose_velocities(fps: float, clips: list[tuple[int, int]], positions: np.ndarray, rotations: np.ndarray):
    """Version 2's derived velocities: per clip, central differences (one-sided at the ends,
    zero in a one-frame clip), `(p[b] - p[a]) / h` and `scaled_axis(q[b]·q[a]⁻¹) / h`, with
    `a = max(f-1, start)`, `b = min(f+1, end-1)`, `h = (b - a) / fps`; f64, stored as f32."""
    lin = np.zeros(positions.shape, dtype=np.float64)
    ang = np.zeros(positions.shape, dtype=np.float64)
    p, q = positions.astype(np.float64), rotations.astype(np.float64)
    for start, end in clips:
        if end - start < 2:
            continue
        f = np.arange(start, end)
        a, b = np.maximum(f - 1, start), np.minimum(f + 1, end - 1)
        inv_h = (fps / (b - a))[:, None, None]
        lin[f] = (p[b] - p[a]) * inv_h
        qa_inv = q[a] * np.array([-1.0, -1.0, -1.0, 1.0])
        ang[f] = scaled_axis(quat_mul(q[b], qa_inv)) * inv_h
    return lin.astype(np.float32), ang.astype(np.float32)


def pose_features(db: Database) -> np.ndarray:
    """Version 3's derived raw features (F, D), before normalization: per clip, for frame `i`
    and offset `k` of a group, frame `t = clamp(i + k)` to the clip, in the character space of
    frame `i` (root position `r`, yaw `R`): position `R⁻¹(p_t − r)`, velocity `R⁻¹(p_{t+1} −
    p_{t−1})·fps/2` (one-sided at the clip's ends), direction `R⁻¹·rot_t·axis`; f64, stored
    as f32. An independent reading of docs/mmdb-format.md, not the Rust code."""
    F, D = db.num_frames, db.num_features
    out = np.zeros((F, D), dtype=np.float32)
    pos, rot = _fk(db.parents, db.local_positions, db.local_rotations, character_space=False)
    for c in db.clips:
        f = np.arange(c.start, c.end)
        root_p, root_q = pos[f, 0], rot[f, 0]
        inv = root_q * np.array([-1.0, -1.0, -1.0, 1.0])
        for g in db.feature_groups:
            axis = np.asarray(g.direction, dtype=np.float64)

            site = np.zeros(3) if g.kind == KIND_DIRECTION else axis

            def point(t, joint=g.joint, site=site):
                return pos[t, joint] + quat_rotate(rot[t, joint], np.broadcast_to(site, (len(t), 3)))

            for k, o in enumerate(g.offsets):
                t = np.clip(f + o, c.start, c.end - 1)
                if g.kind == KIND_POSITION:
                    v = quat_rotate(inv, point(t) - root_p)
                elif g.kind == KIND_VELOCITY:
                    a, b = np.maximum(t - 1, c.start), np.minimum(t + 1, c.end - 1)
                    h = np.where(b > a, (b - a) / db.fps, 1.0)[:, None]
                    v = quat_rotate(inv, np.where((b > a)[:, None], (point(b) - point(a)) / h, 0.0))
                else:
                    v = quat_rotate(inv, quat_rotate(rot[t, g.joint], np.broadcast_to(axis, (len(t), 3))))
                dims = [0, 1, 2] if g.axes == AXES_XYZ else [0, 2]
                d = g.first_dim + k * len(dims)
                out[f, d : d + len(dims)] = v[:, dims]
    return out


# --- quaternions (x, y, z, w), vectorized over leading axes ------------------------------------


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a·b (apply b first, then a)."""
    ax, ay, az, aw = np.moveaxis(np.asarray(a), -1, 0)
    bx, by, bz, bw = np.moveaxis(np.asarray(b), -1, 0)
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v by unit quaternions q: v + 2w(u×v) + 2u×(u×v), u = q.xyz."""
    q, v = np.asarray(q), np.asarray(v)
    u, w = q[..., :3], q[..., 3:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _fk(parents: np.ndarray, lpos: np.ndarray, lrot: np.ndarray, character_space: bool):
    """FK over (N, J, .) local transforms, in float64, exactly as the format document states."""
    lpos, lrot = lpos.astype(np.float64), lrot.astype(np.float64)
    pos, rot = np.empty_like(lpos), np.empty_like(lrot)
    if character_space:
        pos[:, 0], rot[:, 0] = 0.0, (0.0, 0.0, 0.0, 1.0)
    else:
        pos[:, 0], rot[:, 0] = lpos[:, 0], lrot[:, 0]
    for j in range(1, len(parents)):
        p = parents[j]
        rot[:, j] = quat_mul(rot[:, p], lrot[:, j])
        pos[:, j] = pos[:, p] + quat_rotate(rot[:, p], lpos[:, j])
    return pos, rot


def world_transforms_all(db: Database, character_space: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """World (or character-space) positions (F, J, 3) and rotations (F, J, 4) of every frame.

    rot[j] = rot[p]·LROT[j], pos[j] = pos[p] + rot[p]·LPOS[j], from pos[0] = LPOS[0],
    rot[0] = LROT[0]. With `character_space`, joint 0's transform is replaced by the identity
    (the space every feature is expressed in).
    """
    return _fk(db.parents, db.local_positions, db.local_rotations, character_space)


def world_transforms(db: Database, frame: int, character_space: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """World (or character-space) positions (J, 3) and rotations (J, 4) of one frame."""
    if not 0 <= frame < db.num_frames:
        raise IndexError(f"frame {frame} outside [0, {db.num_frames})")
    sl = slice(frame, frame + 1)
    pos, rot = _fk(db.parents, db.local_positions[sl], db.local_rotations[sl], character_space)
    return pos[0], rot[0]


def world_positions(db: Database) -> np.ndarray:
    """World joint positions of every frame, (F, J, 3) float64."""
    return world_transforms_all(db)[0]
