//! The `.mmdb` binary format, version 3 (specified in `docs/mmdb-format.md`): writing a
//! [`Database`] to bytes and reading it back (versions 1 and 2 too) with every length, offset
//! and value checked. The encodings of the pose (and, in version 2, feature) arrays are in
//! `codec.rs`; version 3 derives the features from the poses on load.

pub mod codec;

use crate::database::{Axes, Clip, Database, FeatureGroup, FeatureKind, Part, Site, Skeleton, Tag};
use crate::error::{Error, Result};
use crate::limits::{
    check_feature_dims, num, quote, MAX_ABS_STORED, MAX_FEATURE_OFFSET, MAX_FEATURE_SCALE, MAX_FPS, MAX_FRAMES,
    MAX_ROOT_SCALE, MAX_SCALE, MAX_SOURCE_FPS, MIN_FEATURE_SCALE, MIN_FPS, MIN_SCALE, MIN_SOURCE_FPS,
    QUAT_NORM_TOLERANCE,
};
use glam::{Quat, Vec3};
use std::borrow::Cow;

#[cfg(target_endian = "big")]
compile_error!("the .mmdb writer and reader assume a little-endian target");

pub const MAGIC: [u8; 8] = *b"\x89MMDB\r\n\x1a";
/// The version this crate writes. It reads versions 1 (pose arrays as plain f32, velocities
/// and features included) and 2 (features stored, `FSHF`) too.
pub const VERSION: u32 = 3;
const HEADER_LEN: usize = 32;
/// What a bad derived feature is called in messages: the sections it came from.
const DERIVED_FEATURES: &str = "features derived from PANM and QROT";
const ENTRY_LEN: usize = 24;
const ALIGN: usize = 16;

/// Section tags in the order they are written (no feature matrix: derived on load).
const TAGS: [&[u8; 4]; 10] = [b"INFO", b"SKEL", b"CLIP", b"TAGS", b"PANM", b"QROT", b"CONT", b"FDSC", b"FNRM", b"VALD"];

/// Serializes a database.
///
/// Never panics. The writer trusts its input: a `Database` whose arrays disagree with its
/// counts, or whose counts exceed `u32`, is written as is (truncated counts) and then refused
/// by [`from_bytes`] — which is why the builder keeps databases within
/// [`check_database_size`](crate::limits::check_database_size).
pub fn to_bytes(db: &Database) -> Vec<u8> {
    // Mirrored clips that are exactly their originals mirrored are derived on load (`MIRR`):
    // the per-frame arrays hold the other clips' frames only.
    let animated = codec::animated_joints(&db.local_positions, &db.skeleton.offsets);
    let derived = derived_mirrors(db, &animated);
    let j = db.num_joints();
    let stored: Vec<(usize, usize)> = db
        .clips
        .iter()
        .enumerate()
        .filter(|(i, _)| !derived.contains(i))
        .map(|(_, c)| (c.start as usize, c.end as usize))
        .collect();
    // The stored frames' values of a per-frame array (`per_frame` values a frame).
    fn stored_of<'a, T: Clone>(all: &'a [T], per_frame: usize, stored: &[(usize, usize)], whole: bool) -> Cow<'a, [T]> {
        if whole {
            return Cow::Borrowed(all);
        }
        Cow::Owned(stored.iter().flat_map(|&(s, e)| all[s * per_frame..e * per_frame].iter().cloned()).collect())
    }
    let whole = derived.is_empty();
    let positions = stored_of(&db.local_positions, j, &stored, whole);
    let rotations = stored_of(&db.local_rotations, j, &stored, whole);
    let contacts = stored_of(&db.contacts, 2, &stored, whole);
    // The big arrays are borrowed as bytes (the format is little-endian like every target we
    // build for, checked above) and copied once, into the output.
    let mut sections: Vec<(&[u8; 4], Cow<[u8]>)> = Vec::with_capacity(TAGS.len() + 3);
    for tag in TAGS {
        let data: Cow<[u8]> = match tag {
            b"PANM" => codec::encode_positions(&positions, &db.skeleton.offsets, &animated).into(),
            b"QROT" => codec::encode_rotations(&rotations, j).into(),
            b"CONT" => contacts.clone(),
            b"VALD" => db.valid.as_slice().into(),
            _ => small_section(db, tag).into(),
        };
        sections.push((tag, data));
    }
    if crate::mirror::is_mirror_map(&db.skeleton.mirror, j) {
        let mut w = Vec::with_capacity(4 * (j + derived.len() + 1));
        db.skeleton.mirror.iter().for_each(|&k| put_u32(&mut w, k as u32));
        put_u32(&mut w, derived.len() as u32);
        derived.iter().for_each(|&i| put_u32(&mut w, i as u32));
        sections.push((b"MIRR", w.into()));
    }
    if db.part.is_some() {
        sections.push((b"PART", small_section(db, b"PART").into()));
    }
    // The features are derived on load unless that would cost the reader more than its
    // allocation bound allows for a file this size (a skeleton of a few joints with many feature
    // dimensions): then they are stored, as `FSHF`.
    let size = align(HEADER_LEN + ENTRY_LEN * (sections.len() + 1))
        + sections.iter().map(|(_, d)| align(d.len())).sum::<usize>();
    let frames = (db.num_frames, stored.iter().map(|(s, e)| e - s).sum(), longest_clip(&db.clips));
    if check_decoded_size(size, frames, j, db.num_features()).is_err() {
        sections.push((b"FSHF", codec::shuffle_features(&db.features, db.num_features()).into()));
    }

    let mut offset = align(HEADER_LEN + ENTRY_LEN * sections.len());
    let mut table = Vec::with_capacity(ENTRY_LEN * sections.len());
    for (tag, data) in &sections {
        table.extend_from_slice(*tag);
        put_u32(&mut table, 0);
        table.extend_from_slice(&(offset as u64).to_le_bytes());
        table.extend_from_slice(&(data.len() as u64).to_le_bytes());
        offset = align(offset + data.len());
    }
    let file_size = offset;
    let mut out = Vec::with_capacity(file_size);
    out.extend_from_slice(&MAGIC);
    put_u32(&mut out, VERSION);
    put_u32(&mut out, sections.len() as u32);
    out.extend_from_slice(&(file_size as u64).to_le_bytes());
    put_u32(&mut out, 0); // checksum, patched below
    put_u32(&mut out, 0);
    out.extend_from_slice(&table);
    for (_, data) in &sections {
        out.resize(align(out.len()), 0);
        out.extend_from_slice(data);
    }
    out.resize(file_size, 0);
    let crc = crc32fast::hash(&out[HEADER_LEN..]);
    out[24..28].copy_from_slice(&crc.to_le_bytes());
    out
}

/// The clips `MIRR` derives: each mirrored clip right after an original of its length whose
/// rows, mirrored with the skeleton's mirror map ([`crate::mirror::mirror_pose`]; `animated`:
/// `PANM`'s joints), are its rows bit for bit, contacts swapped. Any other mirrored clip (a
/// database without a mirror map, or from a builder that mirrored otherwise) is stored.
fn derived_mirrors(db: &Database, animated: &[u32]) -> Vec<usize> {
    let j = db.num_joints();
    let pairs = &db.skeleton.mirror;
    // The writer never panics: a database whose arrays disagree with its counts is written as
    // it is (and refused by the reader), nothing derived.
    let f = db.num_frames;
    let consistent = db.local_positions.len() == f * j
        && db.local_rotations.len() == f * j
        && db.contacts.len() == 2 * f
        && db.clips.iter().all(|c| c.start <= c.end && c.end as usize <= f);
    if !consistent || !crate::mirror::is_mirror_map(pairs, j) {
        return Vec::new();
    }
    let mut moves = vec![false; j];
    animated.iter().for_each(|&k| moves[k as usize] = true);
    let (mut p, mut q, mut c) = (Vec::new(), Vec::new(), Vec::new());
    let mut derived = Vec::new();
    for i in 1..db.clips.len() {
        let (a, b) = (&db.clips[i - 1], &db.clips[i]);
        let n = b.end.saturating_sub(b.start) as usize;
        if !b.mirrored || a.mirrored || a.end.saturating_sub(a.start) as usize != n {
            continue;
        }
        let (sa, sb) = (a.start as usize, b.start as usize);
        let (pa, pb) = (sa * j, sb * j);
        p.resize(n * j, Vec3::ZERO);
        q.resize(n * j, Quat::IDENTITY);
        c.resize(2 * n, 0);
        crate::mirror::mirror_frames(
            pairs,
            &moves,
            &db.skeleton.offsets,
            (
                &db.local_positions[pa..pa + n * j],
                &db.local_rotations[pa..pa + n * j],
                &db.contacts[2 * sa..2 * (sa + n)],
            ),
            (&mut p, &mut q, &mut c),
        );
        if same_bits(&p, &db.local_positions[pb..pb + n * j])
            && same_bits(&q, &db.local_rotations[pb..pb + n * j])
            && c == db.contacts[2 * sb..2 * (sb + n)]
        {
            derived.push(i);
        }
    }
    derived
}

/// Whether two arrays of floats hold the same bits (`==` takes −0 for +0 and no NaN for itself).
fn same_bits<T: bytemuck::Pod>(a: &[T], b: &[T]) -> bool {
    bytemuck::cast_slice::<T, u32>(a) == bytemuck::cast_slice::<T, u32>(b)
}

/// The sections made of counts, names and small records.
fn small_section(db: &Database, tag: &[u8; 4]) -> Vec<u8> {
    let mut w = Vec::new();
    match tag {
        b"INFO" => {
            put_u32(&mut w, db.num_frames as u32);
            put_u32(&mut w, db.num_joints() as u32);
            put_f32(&mut w, db.fps);
            put_u32(&mut w, db.num_features() as u32);
            put_u32(&mut w, db.clips.len() as u32);
            put_u32(&mut w, db.tags.len() as u32);
            put_u32(&mut w, db.groups.len() as u32);
            put_u32(&mut w, db.clips.iter().any(|c| c.mirrored) as u32);
        }
        b"SKEL" => {
            let s = &db.skeleton;
            for j in 0..s.num_joints() {
                put_str(&mut w, &s.names[j]);
                put_i32(&mut w, s.parents[j]);
                put_vec3(&mut w, s.offsets[j]);
            }
            put_u32(&mut w, s.sites.len() as u32);
            for site in &s.sites {
                put_str(&mut w, &site.name);
                put_i32(&mut w, site.joint);
                put_vec3(&mut w, site.offset);
            }
        }
        b"CLIP" => {
            put_u32(&mut w, db.clips.len() as u32);
            for c in &db.clips {
                put_str(&mut w, &c.name);
                put_str(&mut w, &c.source);
                put_u32(&mut w, c.start);
                put_u32(&mut w, c.end);
                w.push(c.mirrored as u8);
                w.extend_from_slice(&c.source_fps.to_le_bytes());
                put_f32(&mut w, c.scale);
                put_f32(&mut w, c.root_scale);
                put_u32(&mut w, c.source_start);
            }
        }
        b"PART" => {
            if let Some(p) = &db.part {
                put_str(&mut w, &p.whole);
                put_u32(&mut w, p.whole_frames);
                put_u32(&mut w, p.whole_checksum);
                put_u32(&mut w, p.ranges.len() as u32);
                for &(s, e) in &p.ranges {
                    put_u32(&mut w, s);
                    put_u32(&mut w, e);
                }
            }
        }
        b"TAGS" => {
            put_u32(&mut w, db.tags.len() as u32);
            for t in &db.tags {
                put_str(&mut w, &t.name);
                put_u32(&mut w, t.ranges.len() as u32);
                for &(s, e) in &t.ranges {
                    put_u32(&mut w, s);
                    put_u32(&mut w, e);
                }
            }
        }
        b"FDSC" => {
            put_u32(&mut w, db.groups.len() as u32);
            for g in &db.groups {
                put_str(&mut w, &g.name);
                w.extend_from_slice(&[g.kind as u8, g.is_trajectory as u8, g.axes as u8, 0]);
                put_i32(&mut w, g.joint as i32);
                put_vec3(&mut w, g.axis);
                put_u32(&mut w, g.offsets.len() as u32);
                g.offsets.iter().for_each(|&o| put_i32(&mut w, o));
                put_f32(&mut w, g.weight);
                put_u32(&mut w, g.first_dim as u32);
                put_u32(&mut w, g.num_dims as u32);
            }
        }
        b"FNRM" => {
            w.extend_from_slice(bytemuck::cast_slice(&db.feature_mean));
            w.extend_from_slice(bytemuck::cast_slice(&db.feature_scale));
        }
        _ => unreachable!("unknown section {tag:?}"),
    }
    w
}

/// Parses and validates `.mmdb` bytes.
///
/// Checks structure (header, checksum, a section table whose sections lie inside the file,
/// 16-byte aligned, without overlap or duplicates; every count against the bytes that must
/// hold it; records ending exactly at their section's end) and values (every float finite and
/// within ±[`MAX_ABS_STORED`](crate::limits::MAX_ABS_STORED), unit quaternions, fps in
/// [`MIN_FPS`](crate::limits::MIN_FPS)…[`MAX_FPS`](crate::limits::MAX_FPS), sane scales,
/// at least one frame and one feature group, each group at least one dimension, contacts and
/// validity 0 or 1). So a database that loads can be played: nothing in it makes the runtime
/// divide by zero, loop on a huge fps or index out of range. Heap use is at most
/// [`MMDB_ALLOCATION_FACTOR`](crate::limits::MMDB_ALLOCATION_FACTOR) × `bytes.len()` + 64 KiB
/// whatever the counts claim, and no input panics.
///
/// # Errors
/// [`Error::Format`] naming the section and field when any check fails (see "Validation a
/// reader must do" in `docs/mmdb-format.md`).
pub fn from_bytes(bytes: &[u8]) -> Result<Database> {
    if bytes.len() < HEADER_LEN {
        return Err(Error::format(format!("truncated: {} bytes, shorter than the 32-byte header", bytes.len())));
    }
    if bytes[..8] != MAGIC {
        return Err(Error::format("wrong magic bytes: not a .mmdb file"));
    }
    let version = le_u32(&bytes[8..12]);
    if !(1..=VERSION).contains(&version) {
        return Err(Error::format(format!(
            "unsupported format version {version} (this reader reads versions 1 to {VERSION}); rebuild the database with this version's `mmdb build` or page builder"
        )));
    }
    let count = le_u32(&bytes[12..16]) as usize;
    let file_size = u64::from_le_bytes(bytes[16..24].try_into().unwrap());
    if file_size != bytes.len() as u64 {
        return Err(Error::format(format!(
            "file size is {} bytes but the header says {file_size}: the file is truncated or has trailing data",
            bytes.len()
        )));
    }
    let stored_crc = le_u32(&bytes[24..28]);
    let crc = crc32fast::hash(&bytes[HEADER_LEN..]);
    if crc != stored_crc {
        return Err(Error::format(format!(
            "checksum mismatch (stored {stored_crc:08x}, computed {crc:08x}): the file is corrupt"
        )));
    }
    let table_end = count.checked_mul(ENTRY_LEN).and_then(|n| n.checked_add(HEADER_LEN)).filter(|&n| n <= bytes.len());
    let Some(table_end) = table_end else {
        return Err(Error::format(format!("section table of {count} entries runs past the end of the file")));
    };
    // (tag, offset, data); the table is bounded by the file size above.
    let mut sections: Vec<([u8; 4], usize, &[u8])> = Vec::with_capacity(count);
    for i in 0..count {
        let e = &bytes[HEADER_LEN + i * ENTRY_LEN..HEADER_LEN + (i + 1) * ENTRY_LEN];
        let tag: [u8; 4] = e[..4].try_into().unwrap();
        let name = tag_name(&tag);
        let offset = u64::from_le_bytes(e[8..16].try_into().unwrap());
        let length = u64::from_le_bytes(e[16..24].try_into().unwrap());
        if offset < table_end as u64 || offset.checked_add(length).is_none_or(|end| end > file_size) {
            return Err(Error::format(format!(
                "section {name} (offset {offset}, length {length}) lies outside the file"
            )));
        }
        if offset % ALIGN as u64 != 0 {
            return Err(Error::format(format!("section {name} starts at offset {offset}, not a multiple of {ALIGN}")));
        }
        if sections.iter().any(|(t, _, _)| *t == tag) {
            return Err(Error::format(format!("section {name} appears twice")));
        }
        // Both fit in usize: they are at most the length of a slice.
        let (offset, length) = (offset as usize, length as usize);
        sections.push((tag, offset, &bytes[offset..offset + length]));
    }
    // Sections may be stored in any order, but never share bytes: one byte must not be read
    // as two things (a crafted file could otherwise alias, say, FEAT and LROT).
    let mut by_offset: Vec<(usize, usize, [u8; 4])> = sections.iter().map(|&(t, o, d)| (o, o + d.len(), t)).collect();
    by_offset.sort_unstable();
    for w in by_offset.windows(2) {
        if w[0].1 > w[1].0 {
            return Err(Error::format(format!("sections {} and {} overlap", tag_name(&w[0].2), tag_name(&w[1].2))));
        }
    }
    let section = |tag: &[u8; 4]| -> Result<Reader> {
        sections
            .iter()
            .find(|(t, _, _)| t == tag)
            .map(|&(t, _, data)| Reader { data, pos: 0, tag: t })
            .ok_or_else(|| Error::format(format!("required section {} is missing", tag_name(tag))))
    };

    let mut info = section(b"INFO")?;
    let num_frames = info.u32("num_frames")? as usize;
    let num_joints = info.u32("num_joints")? as usize;
    let fps = info.f32("fps")?;
    let num_dims = info.u32("num_feature_dims")? as usize;
    let num_clips = info.u32("num_clips")? as usize;
    let num_tags = info.u32("num_tags")? as usize;
    let num_groups = info.u32("num_feature_groups")? as usize;
    let flags = info.u32("flags")?;
    info.finish()?;
    // The runtime advances fps·dt frames per update: a flipped exponent bit here (1e30 fps)
    // would spin it for ever.
    if !(MIN_FPS as f32..=MAX_FPS as f32).contains(&fps) {
        return Err(Error::format(format!("INFO.fps must be between {MIN_FPS} and {MAX_FPS}, found {}", num(fps))));
    }
    if num_frames == 0 {
        return Err(Error::format("INFO.num_frames is 0: a database needs at least one frame"));
    }
    if num_frames > MAX_FRAMES {
        return Err(Error::format(format!("INFO.num_frames is {num_frames}, more than {MAX_FRAMES}")));
    }
    if num_joints == 0 {
        return Err(Error::format("INFO.num_joints is 0"));
    }
    if num_groups == 0 || num_dims == 0 {
        return Err(Error::format(format!(
            "INFO has {num_groups} feature groups and {num_dims} feature dims: a database needs at least one of each"
        )));
    }
    // A database the search cannot take would load and then fail in every page and tool.
    check_feature_dims(num_dims).map_err(|m| Error::format(format!("INFO: {m}")))?;
    if flags & !1 != 0 {
        return Err(Error::format(format!("INFO.flags is {flags:#x}: only bit 0 (mirrored clips) is defined")));
    }

    let mut r = section(b"SKEL")?;
    // Each joint record is at least 20 bytes: check before reserving.
    r.fits(num_joints, 20, "joint count")?;
    let mut skeleton = Skeleton {
        names: Vec::with_capacity(num_joints),
        parents: Vec::with_capacity(num_joints),
        offsets: Vec::with_capacity(num_joints),
        sites: Vec::new(),
        mirror: Vec::new(),
    };
    for j in 0..num_joints {
        skeleton.names.push(r.string("joint name")?);
        let parent = r.i32("joint parent")?;
        if (j == 0 && parent != -1) || (j > 0 && !(0..j as i32).contains(&parent)) {
            return Err(Error::format(format!(
                "SKEL: joint {j} has parent {parent}; parents must precede their children and only joint 0 may be -1"
            )));
        }
        skeleton.parents.push(parent);
        skeleton.offsets.push(r.vec3("joint offset")?);
    }
    let num_sites = r.count(20, "site count")?;
    skeleton.sites.reserve(num_sites);
    for _ in 0..num_sites {
        let name = r.string("site name")?;
        let joint = r.i32("site joint")?;
        if joint < -1 || joint >= num_joints as i32 {
            return Err(Error::format(format!("SKEL: site '{}' names joint {joint}, out of range", quote(&name))));
        }
        skeleton.sites.push(Site { name, joint, offset: r.vec3("site offset")? });
    }
    r.finish()?;

    // Checked here: version 2 copies the offsets into every frame's pose.
    check_floats("SKEL joint offset", bytemuck::cast_slice(&skeleton.offsets))?;

    let mut r = section(b"CLIP")?;
    let n = r.count(if version == 1 { 29 } else { 37 }, "clip count")?;
    if n != num_clips {
        return Err(Error::format(format!("CLIP holds {n} clips but INFO says {num_clips}")));
    }
    let mut clips: Vec<Clip> = Vec::with_capacity(n);
    let mut next = 0u32;
    for _ in 0..n {
        let clip = Clip {
            name: r.string("clip name")?,
            source: r.string("clip source")?,
            start: r.u32("clip start")?,
            end: r.u32("clip end")?,
            mirrored: r.flag("clip mirrored")?,
            source_fps: if version == 1 { r.f32("clip source fps")? as f64 } else { r.f64("clip source fps")? },
            scale: r.f32("clip scale")?,
            root_scale: r.f32("clip root scale")?,
            source_start: if version == 1 { 0 } else { r.u32("clip source start")? },
        };
        let name = quote(&clip.name);
        if clip.start != next || clip.end <= clip.start || clip.end as usize > num_frames {
            return Err(Error::format(format!(
                "CLIP '{name}' covers frames {}..{}; clips must be non-empty, in order and tile 0..{num_frames}",
                clip.start, clip.end
            )));
        }
        check_clip_values(&clip)?;
        // Names identify clips in the page and the CLI (a linear scan: clips are few and a
        // hash set would allocate per name).
        if clips.iter().any(|c| c.name == clip.name) {
            return Err(Error::format(format!("CLIP: two clips are named '{name}'")));
        }
        next = clip.end;
        clips.push(clip);
    }
    r.finish()?;
    if next as usize != num_frames {
        return Err(Error::format(format!("clips cover frames 0..{next} but the database has {num_frames} frames")));
    }
    if (flags & 1 != 0) != clips.iter().any(|c| c.mirrored) {
        return Err(Error::format("INFO.flags bit 0 disagrees with the clips' mirrored flags"));
    }

    let mut r = section(b"TAGS")?;
    let n = r.count(8, "tag count")?;
    if n != num_tags {
        return Err(Error::format(format!("TAGS holds {n} tags but INFO says {num_tags}")));
    }
    let mut tags = Vec::with_capacity(n);
    for _ in 0..n {
        let name = r.string("tag name")?;
        let k = r.count(8, "tag range count")?;
        let mut ranges = Vec::with_capacity(k);
        let mut last = 0u32;
        for _ in 0..k {
            let (s, e) = (r.u32("tag range start")?, r.u32("tag range end")?);
            if s < last || e <= s || e as usize > num_frames {
                return Err(Error::format(format!(
                    "tag '{}' has range {s}..{e}: ranges must be sorted, disjoint, within 0..{num_frames}",
                    quote(&name)
                )));
            }
            last = e;
            ranges.push((s, e));
        }
        tags.push(Tag { name, ranges });
    }
    r.finish()?;

    let fj = num_frames.checked_mul(num_joints).ok_or_else(|| Error::format("INFO counts overflow"))?;
    // Version 3: the clips `MIRR` derives are not in the per-frame arrays.
    let mirror = match sections.iter().find(|(t, _, _)| t == b"MIRR") {
        Some(&(tag, _, data)) if version >= 3 => {
            Some(read_mirror(&mut Reader { data, pos: 0, tag }, num_joints, &clips)?)
        }
        _ => None,
    };
    let derived: &[usize] = mirror.as_ref().map_or(&[], |(_, d)| d);
    let stored_frames = num_frames - derived.iter().map(|&i| (clips[i].end - clips[i].start) as usize).sum::<usize>();
    // Version 3 stores the features (`FSHF`) only where deriving them would cost more than
    // the allocation bound allows for the file's size.
    let stored_features = version == 2 || sections.iter().any(|(t, _, _)| t == b"FSHF");
    if version >= 3 {
        let dims = if stored_features { 0 } else { num_dims };
        check_decoded_size(bytes.len(), (num_frames, stored_frames, longest_clip(&clips)), num_joints, dims)?;
    }
    // Version 1 stores the pose arrays as plain f32 with velocities (checked, then left: a
    // database derives a frame's velocities from its poses when it plays it); versions 2 and 3
    // encode them (codec.rs) and store no velocities.
    let (local_positions, local_rotations, animated, velocities) = if version == 1 {
        let local_positions = section(b"LPOS")?.vec3s(fj)?;
        let mut local_rotations: Vec<Quat> = section(b"LROT")?.pods(fj)?;
        if let Some(i) = local_rotations.iter().position(|q| !(q.length_squared() - 1.0).abs().le(&QUAT_NORM_TOLERANCE))
        {
            return Err(Error::format(format!(
                "LROT: frame {} joint {} is not a unit quaternion ({})",
                i / num_joints,
                i % num_joints,
                local_rotations[i]
            )));
        }
        // Normalized, as version 2's decoder does: a rotation 10⁻³ off unit loads, and written
        // again (quantized to 1/32767) it must still load (found by the `mmdb` fuzz target).
        local_rotations.iter_mut().for_each(|q| *q = q.normalize());
        let velocities = (section(b"LVEL")?.vec3s(fj)?, section(b"LAVL")?.vec3s(fj)?);
        (local_positions, local_rotations, Vec::new(), Some(velocities))
    } else {
        let (local_positions, animated) =
            codec::decode_positions(section(b"PANM")?.data, stored_frames, &skeleton.offsets).map_err(Error::format)?;
        let local_rotations = codec::decode_rotations(
            section(b"QROT")?.data,
            stored_frames,
            num_joints,
            QUAT_NORM_TOLERANCE,
            version >= 3,
        )
        .map_err(Error::format)?;
        (local_positions, local_rotations, animated, None)
    };
    // Every version stores the stored frames' contacts (before version 3, every frame is stored).
    let contacts =
        section(b"CONT")?.flags(stored_frames.checked_mul(2).ok_or_else(|| Error::format("INFO counts overflow"))?)?;
    let (local_positions, local_rotations, contacts) = match &mirror {
        Some((pairs, derived)) if !derived.is_empty() => expand_mirrors(
            &clips,
            derived,
            pairs,
            &animated,
            &skeleton.offsets,
            (local_positions, local_rotations, contacts),
        ),
        _ => (local_positions, local_rotations, contacts),
    };
    if let Some((pairs, _)) = mirror {
        skeleton.mirror = pairs;
    }

    let mut r = section(b"FDSC")?;
    let n = r.count(40, "feature group count")?;
    if n != num_groups {
        return Err(Error::format(format!("FDSC holds {n} groups but INFO says {num_groups}")));
    }
    let mut groups = Vec::with_capacity(n);
    let mut next_dim = 0usize;
    for _ in 0..n {
        let name = r.string("feature name")?;
        let quoted = quote(&name);
        let kind = match r.u8("feature kind")? {
            0 => FeatureKind::Position,
            1 => FeatureKind::Velocity,
            2 => FeatureKind::Direction,
            k => return Err(Error::format(format!("FDSC: feature '{quoted}' has unknown kind {k}"))),
        };
        let is_trajectory = r.flag("feature trajectory flag")?;
        let axes = match r.u8("feature axes")? {
            0 => Axes::Xyz,
            1 => Axes::Xz,
            a => return Err(Error::format(format!("FDSC: feature '{quoted}' has unknown axes {a}"))),
        };
        r.u8("reserved")?;
        let joint = r.i32("feature joint")?;
        if joint < 0 || joint as usize >= num_joints {
            return Err(Error::format(format!("FDSC: feature '{quoted}' names joint {joint}, out of range")));
        }
        let axis = r.vec3("feature axis")?;
        let k = r.count(4, "feature offset count")?;
        let offsets = (0..k).map(|_| r.i32("feature offset")).collect::<Result<Vec<_>>>()?;
        if offsets.is_empty() {
            return Err(Error::format(format!("FDSC: feature '{quoted}' has no frame offsets (no dimensions)")));
        }
        check_offsets(&quoted, &offsets)?;
        let weight = r.f32("feature weight")?;
        check_weight(&quoted, weight)?;
        let first_dim = r.u32("feature first dim")? as usize;
        let num = r.u32("feature dim count")? as usize;
        if first_dim != next_dim || num != offsets.len() * axes.num_dims() {
            return Err(Error::format(format!(
                "FDSC: feature '{quoted}' spans dims {first_dim}+{num}; groups must tile 0..{num_dims} in order"
            )));
        }
        next_dim += num;
        groups.push(FeatureGroup {
            name,
            kind,
            is_trajectory,
            axes,
            joint: joint as usize,
            axis,
            offsets,
            weight,
            first_dim,
            num_dims: num,
        });
    }
    r.finish()?;
    if next_dim != num_dims {
        return Err(Error::format(format!("feature groups cover {next_dim} dims but INFO says {num_dims}")));
    }
    let mut norm =
        section(b"FNRM")?.f32s(num_dims.checked_mul(2).ok_or_else(|| Error::format("INFO counts overflow"))?)?;
    let feature_scale = norm.split_off(num_dims);
    let feature_mean = norm;
    check_feature_scale(&feature_scale)?;
    let num_values = num_frames.checked_mul(num_dims).ok_or_else(|| Error::format("INFO counts overflow"))?;
    // Version 3 derives them below, from the decoded poses.
    let features = match version {
        1 => section(b"FEAT")?.f32s(num_values)?,
        _ if stored_features => {
            codec::unshuffle_features(section(b"FSHF")?.data, num_frames, num_dims).map_err(Error::format)?
        }
        _ => Vec::new(),
    };
    let valid = section(b"VALD")?.flags(num_frames)?;

    // Every other float, in one place: finite and within ±MAX_ABS_STORED.
    check_floats("SKEL site offset", &skeleton.sites.iter().flat_map(|s| s.offset.to_array()).collect::<Vec<_>>())?;
    check_floats("FDSC feature axis", &groups.iter().flat_map(|g| g.axis.to_array()).collect::<Vec<_>>())?;
    let (positions_tag, features_tag) = match version {
        1 => ("LPOS", "FEAT"),
        _ if stored_features => ("PANM", "FSHF"),
        _ => ("PANM", DERIVED_FEATURES),
    };
    check_floats(positions_tag, bytemuck::cast_slice(&local_positions))?;
    if let Some((v, w)) = &velocities {
        check_floats("LVEL", bytemuck::cast_slice(v))?;
        check_floats("LAVL", bytemuck::cast_slice(w))?;
    }
    check_floats("FNRM mean", &feature_mean)?;
    check_floats(features_tag, &features)?;

    let part = match sections.iter().find(|(t, _, _)| t == b"PART") {
        Some(&(tag, _, data)) => Some(read_part(&mut Reader { data, pos: 0, tag }, num_frames, &clips)?),
        None => None,
    };

    let mut db = Database {
        skeleton,
        fps,
        num_frames,
        clips,
        tags,
        local_positions,
        local_rotations,
        contacts,
        groups,
        feature_mean,
        feature_scale,
        features,
        valid,
        part,
        velocities: Default::default(),
    };
    if !stored_features && version >= 3 {
        db.compute_features();
        check_floats(features_tag, &db.features)?;
    }
    Ok(db)
}

/// The optional `MIRR` section (version 3): the skeleton's mirror map (`J` × u32, each joint's
/// opposite, paired back) and the clips derived by mirroring the clip before them (u32 count,
/// ascending u32 clip indices; each mirrored, after a stored clip of its length).
fn read_mirror(r: &mut Reader, joints: usize, clips: &[Clip]) -> Result<(Vec<usize>, Vec<usize>)> {
    r.fits(joints, 4, "mirror map")?;
    let pairs = (0..joints).map(|_| r.u32("mirror map").map(|k| k as usize)).collect::<Result<Vec<_>>>()?;
    if !crate::mirror::is_mirror_map(&pairs, joints) {
        let j = (0..joints).find(|&j| pairs[j] >= joints || pairs[pairs[j]] != j).unwrap_or(0);
        return Err(Error::format(format!(
            "MIRR: joint {j}'s opposite is {}; each must be a joint whose opposite is it",
            pairs[j]
        )));
    }
    let n = r.count(4, "derived clip count")?;
    let mut derived: Vec<usize> = Vec::with_capacity(n);
    for _ in 0..n {
        let i = r.u32("derived clip")? as usize;
        let fits = i >= 1
            && i < clips.len()
            && derived.last().is_none_or(|&last| i > last + 1)
            && clips[i].mirrored
            && !clips[i - 1].mirrored
            && clips[i].end - clips[i].start == clips[i - 1].end - clips[i - 1].start;
        if !fits {
            return Err(Error::format(format!(
                "MIRR: clip {i} cannot be derived: derived clips are mirrored ones, ascending, each after a stored clip of its length"
            )));
        }
        derived.push(i);
    }
    r.finish()?;
    Ok((pairs, derived))
}

/// The stored frames' poses and contacts with the derived clips' frames put in their places,
/// each the mirror of the clip before it ([`crate::mirror::mirror_pose`]).
fn expand_mirrors(
    clips: &[Clip],
    derived: &[usize],
    pairs: &[usize],
    animated: &[bool],
    rest: &[Vec3],
    (positions, rotations, contacts): (Vec<Vec3>, Vec<Quat>, Vec<u8>),
) -> (Vec<Vec3>, Vec<Quat>, Vec<u8>) {
    let j = pairs.len();
    let frames = clips.last().map_or(0, |c| c.end as usize);
    let (mut p, mut q, mut c) = (vec![Vec3::ZERO; frames * j], vec![Quat::IDENTITY; frames * j], vec![0u8; frames * 2]);
    let mut next = 0usize;
    for (i, clip) in clips.iter().enumerate() {
        let (s, e) = (clip.start as usize, clip.end as usize);
        if derived.contains(&i) {
            // The original (the clip before, already in place) mirrored into this clip's frames.
            let (from, n) = (clips[i - 1].start as usize, e - s);
            let (op, mp) = p.split_at_mut(s * j);
            let (oq, mq) = q.split_at_mut(s * j);
            let (oc, mc) = c.split_at_mut(2 * s);
            crate::mirror::mirror_frames(
                pairs,
                animated,
                rest,
                (&op[from * j..(from + n) * j], &oq[from * j..(from + n) * j], &oc[2 * from..2 * (from + n)]),
                (mp, mq, mc),
            );
        } else {
            let n = e - s;
            p[s * j..e * j].copy_from_slice(&positions[next * j..(next + n) * j]);
            q[s * j..e * j].copy_from_slice(&rotations[next * j..(next + n) * j]);
            c[2 * s..2 * e].copy_from_slice(&contacts[2 * next..2 * (next + n)]);
            next += n;
        }
    }
    (p, q, c)
}

/// Frames in the longest clip.
fn longest_clip(clips: &[Clip]) -> usize {
    clips.iter().map(|c| c.end.saturating_sub(c.start) as usize).max().unwrap_or(0)
}

/// Refuses a version-3 file whose counts would decode to more than
/// [`MMDB_ALLOCATION_FACTOR`](crate::limits::MMDB_ALLOCATION_FACTOR) times its size: the
/// features and mirrored clips it derives are not in its bytes, so its counts are checked
/// against what they will cost: the poses (the stored frames' and, while mirrored clips are
/// expanded, every frame's), velocities, and, with `dims` > 0, features and the f64 world
/// transforms of the longest clip that they are measured on.
fn check_decoded_size(
    file: usize,
    (frames, stored, longest): (usize, usize, usize),
    joints: usize,
    dims: usize,
) -> Result<()> {
    let (frames, stored, longest, joints, dims) =
        (frames as u128, stored as u128, longest as u128, joints as u128, dims as u128);
    let need =
        frames * joints * (12 + 16) + stored * joints * (12 + 16) + frames * (dims * 4 + 3) + longest * joints * 56;
    let bound = (crate::limits::MMDB_ALLOCATION_FACTOR * file) as u128;
    if need > bound {
        return Err(Error::format(format!(
            "INFO: {frames} frames of {joints} joints and {dims} feature dims decode to {:.1} MB, more than {}× the file's {file} bytes",
            need as f64 / 1e6,
            crate::limits::MMDB_ALLOCATION_FACTOR
        )));
    }
    Ok(())
}

/// The optional `PART` section: this database is the first part of the whole it names. Its
/// ranges must be ascending, disjoint, inside the whole, one per clip of the part and as long
/// as that clip (so a part frame maps to exactly one whole frame of the same clip).
fn read_part(r: &mut Reader, num_frames: usize, clips: &[Clip]) -> Result<Part> {
    let whole = r.string("PART whole")?;
    if !Part::is_plain_name(&whole) {
        return Err(Error::format(format!(
            "PART names its whole '{}': it must be a plain file name beside the part",
            crate::limits::quote(&whole)
        )));
    }
    let whole_frames = r.u32("PART whole frames")?;
    let whole_checksum = r.u32("PART whole checksum")?;
    let count = r.count(8, "PART ranges")?;
    let mut ranges = Vec::with_capacity(count);
    for i in 0..count {
        let (s, e) = (r.u32("PART range start")?, r.u32("PART range end")?);
        let after = ranges.last().map_or(0, |&(_, end)| end);
        if s < after || e <= s || e > whole_frames {
            return Err(Error::format(format!(
                "PART range {i} [{s}, {e}) is empty, out of order or outside the whole's {whole_frames} frames"
            )));
        }
        ranges.push((s, e));
    }
    r.finish()?;
    let lengths_match =
        ranges.len() == clips.len() && ranges.iter().zip(clips).all(|(&(s, e), c)| e - s == c.end - c.start);
    if !lengths_match || clips.last().is_none_or(|c| c.end as usize != num_frames) {
        return Err(Error::format(format!(
            "PART has {} ranges for {} clips: it needs one range per clip, as long as the clip",
            ranges.len(),
            clips.len()
        )));
    }
    Ok(Part { whole, whole_frames, whole_checksum, ranges })
}

/// Checks that `loaded` is what writing `original` and reading it back may give: everything
/// equal except the rotations, each within [`codec::MAX_ROTATION_ERROR`] of the original
/// (quantized to 16 bits a component), and what is derived from the poses: the velocities the
/// loaded poses give must be the ones the original's give ([`crate::database::pose_velocities`];
/// linear ones within 1e-4 m/s, angular ones within `2 · MAX_ROTATION_ERROR · fps`), and the features, where
/// the original's are the ones its own poses derive (a built or version-3 database) and its
/// rotations came back unchanged, the same bits. Written and read once more, `loaded` comes back bit for bit (a fixed point: the
/// writer's quantization is stable, [`codec::quantize_rotation`]).
///
/// # Errors
/// The first difference beyond those bounds.
pub fn check_round_trip(original: &Database, loaded: &Database) -> std::result::Result<(), String> {
    let exact = (
        &original.skeleton,
        original.fps,
        original.num_frames,
        &original.clips,
        &original.tags,
        &original.local_positions,
        &original.contacts,
    ) == (
        &loaded.skeleton,
        loaded.fps,
        loaded.num_frames,
        &loaded.clips,
        &loaded.tags,
        &loaded.local_positions,
        &loaded.contacts,
    ) && (&original.groups, &original.feature_mean, &original.feature_scale, &original.valid)
        == (&loaded.groups, &loaded.feature_mean, &loaded.feature_scale, &loaded.valid);
    if !exact {
        return Err("the skeleton, clips, tags, positions, contacts, feature groups or validity changed".into());
    }
    if same_bits(&original.local_rotations, &loaded.local_rotations)
        && !same_bits(&loaded.features, &original.features)
        && same_bits(&original.derived_features(), &original.features)
    {
        return Err("the features changed".into());
    }
    match from_bytes(&to_bytes(loaded)) {
        Ok(again) if again == *loaded => {}
        Ok(_) => return Err("written and read again, the loaded database changed".into()),
        Err(e) => return Err(format!("written again, the loaded database does not load: {e}")),
    }
    if original.local_rotations.len() != loaded.local_rotations.len() {
        return Err("the rotation count changed".into());
    }
    for (i, (a, b)) in original.local_rotations.iter().zip(&loaded.local_rotations).enumerate() {
        if codec::angle(*a, *b) > codec::MAX_ROTATION_ERROR {
            return Err(format!("rotation {i} moved {:e} rad", codec::angle(*a, *b)));
        }
    }
    let velocities = |db: &Database| {
        crate::database::pose_velocities(db.num_joints(), db.fps, &db.clips, &db.local_positions, &db.local_rotations)
    };
    let ((velocities, angular_velocities), (loaded_velocities, loaded_angular)) =
        (velocities(original), velocities(loaded));
    let angular = (2.0 * codec::MAX_ROTATION_ERROR * original.fps as f64) as f32 * 1.01;
    let pairs = [
        (&velocities, &loaded_velocities, 1e-4, "velocity"),
        (&angular_velocities, &loaded_angular, angular, "angular velocity"),
    ];
    for (a, b, bound, what) in pairs {
        if a.len() != b.len() {
            return Err(format!("the {what} count changed"));
        }
        if let Some(i) = a.iter().zip(b.iter()).position(|(x, y)| !((*x - *y).length() <= bound)) {
            return Err(format!("{what} {i} changed from {} to {}", a[i], b[i]));
        }
    }
    Ok(())
}

/// Checks the values of a database in memory the way [`from_bytes`] checks them in a file,
/// with the same messages: what the builder calls before it returns a database, so that it
/// never writes one its own loader refuses (`limits` has every bound). The structure (counts,
/// tiling) is the builder's by construction; these are the values that come from the data.
///
/// # Errors
/// [`Error::Format`] naming the section and field of the first value out of range.
pub fn check_database(db: &Database) -> Result<()> {
    if !(MIN_FPS as f32..=MAX_FPS as f32).contains(&db.fps) {
        return Err(Error::format(format!("INFO.fps must be between {MIN_FPS} and {MAX_FPS}, found {}", num(db.fps))));
    }
    if db.num_frames == 0 || db.num_frames > MAX_FRAMES {
        return Err(Error::format(format!("INFO.num_frames is {}, not 1 to {MAX_FRAMES}", db.num_frames)));
    }
    check_feature_dims(db.num_features()).map_err(|m| Error::format(format!("INFO: {m}")))?;
    check_floats("SKEL joint offset", bytemuck::cast_slice(&db.skeleton.offsets))?;
    for clip in &db.clips {
        check_clip_values(clip)?;
    }
    for g in &db.groups {
        let quoted = quote(&g.name);
        check_offsets(&quoted, &g.offsets)?;
        check_weight(&quoted, g.weight)?;
    }
    check_feature_scale(&db.feature_scale)?;
    check_floats("SKEL site offset", &db.skeleton.sites.iter().flat_map(|s| s.offset.to_array()).collect::<Vec<_>>())?;
    check_floats("FDSC feature axis", &db.groups.iter().flat_map(|g| g.axis.to_array()).collect::<Vec<_>>())?;
    check_floats("PANM", bytemuck::cast_slice(&db.local_positions))?;
    if let Some(i) = db.local_rotations.iter().position(|q| !(q.length_squared() - 1.0).abs().le(&QUAT_NORM_TOLERANCE))
    {
        let j = db.num_joints().max(1);
        return Err(Error::format(format!(
            "QROT: frame {} joint {} is not a unit quaternion ({})",
            i / j,
            i % j,
            db.local_rotations[i]
        )));
    }
    check_floats("FNRM mean", &db.feature_mean)?;
    check_floats(DERIVED_FEATURES, &db.features)?;
    Ok(())
}

fn check_clip_values(clip: &Clip) -> Result<()> {
    let name = quote(&clip.name);
    if !(MIN_SOURCE_FPS..=MAX_SOURCE_FPS).contains(&clip.source_fps) {
        return Err(Error::format(format!(
            "CLIP '{name}': source fps {} is outside {MIN_SOURCE_FPS}..{MAX_SOURCE_FPS}",
            num(clip.source_fps)
        )));
    }
    if !(MIN_SCALE as f32..=MAX_SCALE as f32).contains(&clip.scale) {
        return Err(Error::format(format!(
            "CLIP '{name}': scale {} is outside {}..{}",
            num(clip.scale),
            num(MIN_SCALE),
            num(MAX_SCALE)
        )));
    }
    if !(1.0 / MAX_ROOT_SCALE..=MAX_ROOT_SCALE).contains(&clip.root_scale) {
        return Err(Error::format(format!(
            "CLIP '{name}': root scale {:e} is outside {:e}..{MAX_ROOT_SCALE:e}",
            clip.root_scale,
            1.0 / MAX_ROOT_SCALE
        )));
    }
    Ok(())
}

fn check_offsets(quoted: &str, offsets: &[i32]) -> Result<()> {
    if let Some(o) = offsets.iter().find(|o| o.unsigned_abs() > MAX_FEATURE_OFFSET as u32) {
        return Err(Error::format(format!(
            "FDSC: feature '{quoted}' has frame offset {o}, beyond ±{MAX_FEATURE_OFFSET}"
        )));
    }
    Ok(())
}

fn check_weight(quoted: &str, weight: f32) -> Result<()> {
    if !(1.0 / MAX_STORED_WEIGHT..=MAX_STORED_WEIGHT).contains(&weight) {
        return Err(Error::format(format!(
            "FDSC: feature '{quoted}' has weight {weight:e}, outside {:e}..{MAX_STORED_WEIGHT:e}",
            1.0 / MAX_STORED_WEIGHT
        )));
    }
    Ok(())
}

fn check_feature_scale(feature_scale: &[f32]) -> Result<()> {
    if let Some(d) = feature_scale.iter().position(|s| !(MIN_FEATURE_SCALE..=MAX_FEATURE_SCALE).contains(s)) {
        return Err(Error::format(format!(
            "FNRM: scale of dim {d} is {}, outside {MIN_FEATURE_SCALE:e}..{MAX_FEATURE_SCALE:e} (queries are divided by it)",
            num(feature_scale[d])
        )));
    }
    Ok(())
}

/// Largest feature weight a reader accepts, and the inverse the smallest (the configuration
/// allows [`MIN_WEIGHT`](crate::limits::MIN_WEIGHT)…[`MAX_WEIGHT`](crate::limits::MAX_WEIGHT);
/// files written before that check may have used more).
const MAX_STORED_WEIGHT: f32 = 1e6;

/// Errors on the first value that is not finite or exceeds [`MAX_ABS_STORED`] in magnitude.
/// (A plain loop over the bits: it vectorizes, so the whole database costs ~1 ms.)
fn check_floats(what: &str, values: &[f32]) -> Result<()> {
    let bound = MAX_ABS_STORED.to_bits();
    let bad = values.iter().fold(false, |bad, v| bad | (v.to_bits() & 0x7FFF_FFFF > bound));
    if bad {
        let i = values.iter().position(|v| v.to_bits() & 0x7FFF_FFFF > bound).unwrap_or(0);
        return Err(Error::format(format!(
            "{what}: value {i} is {}, not finite or beyond ±{MAX_ABS_STORED:e}",
            num(values[i])
        )));
    }
    Ok(())
}

fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes(b.try_into().unwrap())
}

/// A section tag for a message (tags of corrupt files may hold any byte).
fn tag_name(tag: &[u8; 4]) -> String {
    quote(&String::from_utf8_lossy(tag))
}

fn align(n: usize) -> usize {
    n.div_ceil(ALIGN) * ALIGN
}

fn put_u32(w: &mut Vec<u8>, v: u32) {
    w.extend_from_slice(&v.to_le_bytes());
}
fn put_i32(w: &mut Vec<u8>, v: i32) {
    w.extend_from_slice(&v.to_le_bytes());
}
fn put_f32(w: &mut Vec<u8>, v: f32) {
    w.extend_from_slice(&v.to_le_bytes());
}
fn put_vec3(w: &mut Vec<u8>, v: Vec3) {
    v.to_array().iter().for_each(|&x| put_f32(w, x));
}
fn put_str(w: &mut Vec<u8>, s: &str) {
    put_u32(w, s.len() as u32);
    w.extend_from_slice(s.as_bytes());
}

/// A bounds-checked cursor over one section.
struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    tag: [u8; 4],
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, field: &str) -> Result<&'a [u8]> {
        if self.data.len() - self.pos < n {
            return Err(Error::format(format!(
                "section {} ends at byte {} while reading {field} ({n} bytes needed)",
                tag_name(&self.tag),
                self.data.len()
            )));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u8(&mut self, field: &str) -> Result<u8> {
        Ok(self.take(1, field)?[0])
    }
    /// A byte that must be 0 or 1.
    fn flag(&mut self, field: &str) -> Result<bool> {
        match self.u8(field)? {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(Error::format(format!("{} {field} is {b}, not 0 or 1", tag_name(&self.tag)))),
        }
    }
    /// Errors unless every byte of the section was read (records end exactly at its end).
    fn finish(&self) -> Result<()> {
        if self.pos != self.data.len() {
            return Err(Error::format(format!(
                "section {} has {} bytes after its last record",
                tag_name(&self.tag),
                self.data.len() - self.pos
            )));
        }
        Ok(())
    }
    /// Errors unless `n` records of at least `min_size` bytes fit in the rest of the section.
    fn fits(&self, n: usize, min_size: usize, field: &str) -> Result<()> {
        if n.saturating_mul(min_size) > self.data.len() - self.pos {
            return Err(Error::format(format!("{} {field} {n} does not fit in the section", tag_name(&self.tag))));
        }
        Ok(())
    }
    fn u32(&mut self, field: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, field)?.try_into().unwrap()))
    }
    fn i32(&mut self, field: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.take(4, field)?.try_into().unwrap()))
    }
    fn f64(&mut self, field: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(8, field)?.try_into().unwrap()))
    }
    fn f32(&mut self, field: &str) -> Result<f32> {
        Ok(f32::from_le_bytes(self.take(4, field)?.try_into().unwrap()))
    }
    fn vec3(&mut self, field: &str) -> Result<Vec3> {
        Ok(Vec3::new(self.f32(field)?, self.f32(field)?, self.f32(field)?))
    }
    /// A count of records each at least `min_size` bytes long, rejected early if the section
    /// cannot hold that many (so a corrupt count never drives a huge allocation).
    fn count(&mut self, min_size: usize, field: &str) -> Result<usize> {
        let n = self.u32(field)? as usize;
        self.fits(n, min_size, field)?;
        Ok(n)
    }
    fn string(&mut self, field: &str) -> Result<String> {
        let n = self.u32(field)? as usize;
        let bytes = self.take(n, field)?;
        String::from_utf8(bytes.to_vec())
            .map_err(|_| Error::format(format!("{} {field} is not UTF-8", tag_name(&self.tag))))
    }
    /// The whole section as exactly `n` bytes, each 0 or 1 (`CONT`, `VALD`).
    fn flags(&mut self, n: usize) -> Result<Vec<u8>> {
        let data = self.exact(n)?;
        if let Some(i) = data.iter().position(|&b| b > 1) {
            return Err(Error::format(format!("section {}: byte {i} is {}, not 0 or 1", tag_name(&self.tag), data[i])));
        }
        Ok(data.to_vec())
    }
    fn exact(&self, n: usize) -> Result<&'a [u8]> {
        if self.data.len() != n {
            return Err(Error::format(format!(
                "section {} is {} bytes but INFO implies {n}",
                tag_name(&self.tag),
                self.data.len()
            )));
        }
        Ok(self.data)
    }
    /// `n` plain-old-data values filling the whole section (copied, so alignment is free).
    fn pods<T: bytemuck::Pod>(&mut self, n: usize) -> Result<Vec<T>> {
        // Checked: on wasm32 `n · size` could wrap and match a short section.
        let len = n
            .checked_mul(std::mem::size_of::<T>())
            .ok_or_else(|| Error::format(format!("{} size overflows", tag_name(&self.tag))))?;
        Ok(bytemuck::pod_collect_to_vec(self.exact(len)?))
    }
    fn f32s(&mut self, n: usize) -> Result<Vec<f32>> {
        self.pods(n)
    }
    fn vec3s(&mut self, n: usize) -> Result<Vec<Vec3>> {
        self.pods(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tiny but complete database: 2 joints, 3 frames, one clip, one tag, one feature group.
    pub(crate) fn tiny() -> Database {
        let mut db = Database {
            skeleton: Skeleton {
                names: vec!["VirtualRoot".into(), "Hips".into()],
                parents: vec![-1, 0],
                offsets: vec![Vec3::ZERO, Vec3::Y],
                sites: vec![Site { name: "hips".into(), joint: 1, offset: Vec3::ZERO }],
                mirror: vec![0, 1],
            },
            fps: 60.0,
            num_frames: 3,
            clips: vec![Clip {
                name: "a".into(),
                source: "a.bvh".into(),
                start: 0,
                end: 3,
                mirrored: false,
                source_fps: 120.0,
                scale: 1.0,
                root_scale: 1.0,
                source_start: 0,
            }],
            tags: vec![Tag { name: "walk".into(), ranges: vec![(0, 2)] }],
            local_positions: (0..6).map(|i| Vec3::splat(i as f32)).collect(),
            local_rotations: vec![Quat::IDENTITY; 6],
            contacts: vec![1, 0, 0, 1, 1, 1],
            groups: vec![FeatureGroup {
                name: "p".into(),
                kind: FeatureKind::Position,
                is_trajectory: true,
                axes: Axes::Xz,
                joint: 0,
                axis: Vec3::Z,
                offsets: vec![1],
                weight: 1.0,
                first_dim: 0,
                num_dims: 2,
            }],
            feature_mean: vec![0.5, 0.25],
            feature_scale: vec![2.0, 2.0],
            features: Vec::new(),
            valid: vec![1, 1, 0],
            part: None,
            velocities: Default::default(),
        };
        db.compute_features();
        db
    }

    /// A clip of `n` frames and its mirrored copy, made as the builder makes it, with one
    /// feature group of `2 · offsets` dims on the hips.
    fn mirrored_pair(n: usize, offsets: usize) -> Database {
        let mut db = tiny();
        let j = 2;
        db.num_frames = 2 * n;
        db.clips[0].end = n as u32;
        let mut mirror = db.clips[0].clone();
        (mirror.name, mirror.start, mirror.end, mirror.mirrored) = ("a (mirror)".into(), n as u32, 2 * n as u32, true);
        db.clips.push(mirror);
        db.tags[0].ranges = vec![(0, 2)];
        db.local_positions = vec![Vec3::ZERO; 2 * n * j];
        db.local_rotations = vec![Quat::IDENTITY; 2 * n * j];
        db.contacts = vec![0; 4 * n];
        for f in 0..n {
            let t = f as f32 / 60.0;
            db.local_positions[f * j] = Vec3::new(t.sin(), 0.0, t);
            db.local_positions[f * j + 1] = Vec3::new(0.1 * t.cos(), 1.0, 0.0);
            db.local_rotations[f * j] = Quat::from_rotation_y(t);
            db.local_rotations[f * j + 1] = Quat::from_rotation_z(0.3 * t.sin());
            db.contacts[2 * f] = (f % 3 == 0) as u8;
            let (original, copy) = db.local_positions.split_at_mut((n + f) * j);
            let (q0, q1) = db.local_rotations.split_at_mut((n + f) * j);
            crate::mirror::mirror_pose(
                &[0, 1],
                &[true, true],
                &db.skeleton.offsets,
                (&original[f * j..(f + 1) * j], &q0[f * j..(f + 1) * j]),
                (&mut copy[..j], &mut q1[..j]),
            );
            let c = crate::mirror::mirror_contacts(&db.contacts[2 * f..2 * f + 2]);
            db.contacts[2 * (n + f)..2 * (n + f) + 2].copy_from_slice(&c);
        }
        for q in &mut db.local_rotations {
            *q = codec::dequantize_rotation(codec::quantize_rotation(*q));
        }
        db.groups[0].joint = 1;
        db.groups[0].offsets = (0..offsets as i32).collect();
        db.groups[0].num_dims = 2 * offsets;
        db.feature_mean = vec![0.0; 2 * offsets];
        db.feature_scale = vec![1.0; 2 * offsets];
        db.valid = vec![1; 2 * n];
        db.compute_features();
        db
    }

    fn sections_of(bytes: &[u8]) -> Vec<[u8; 4]> {
        (0..le_u32(&bytes[12..16]) as usize)
            .map(|i| bytes[HEADER_LEN + i * ENTRY_LEN..HEADER_LEN + i * ENTRY_LEN + 4].try_into().unwrap())
            .collect()
    }

    /// A mirrored clip that is its original mirrored is derived (`MIRR`): the file holds half
    /// the frames and loads to the same database; the features are stored (`FSHF`) only where
    /// deriving them would pass the reader's allocation bound (2 joints, 128 dims).
    #[test]
    fn mirrored_clips_are_derived_and_features_stored_only_when_needed() {
        let db = mirrored_pair(300, 4);
        let bytes = to_bytes(&db);
        let tags = sections_of(&bytes);
        assert!(tags.contains(b"MIRR") && !tags.contains(b"FSHF"), "{tags:?}");
        let unmirrored = Database { skeleton: Skeleton { mirror: Vec::new(), ..db.skeleton.clone() }, ..db.clone() };
        assert!(bytes.len() * 3 < to_bytes(&unmirrored).len() * 2, "{} bytes", bytes.len());
        assert_eq!(from_bytes(&bytes).unwrap(), db);
        let wide = mirrored_pair(300, 64);
        let bytes = to_bytes(&wide);
        assert!(sections_of(&bytes).contains(b"FSHF"));
        assert_eq!(from_bytes(&bytes).unwrap(), wide);
        // A mirror map that does not pair back, or a derived clip that is not a mirrored one
        // right after its original, is refused naming MIRR.
        let at = |b: &[u8]| {
            let i = sections_of(b).iter().position(|t| t == b"MIRR").unwrap();
            u64::from_le_bytes(b[HEADER_LEN + i * ENTRY_LEN + 8..HEADER_LEN + i * ENTRY_LEN + 16].try_into().unwrap())
                as usize
        };
        let good = to_bytes(&db);
        let mut b = good.clone();
        let m = at(&b);
        b[m..m + 4].copy_from_slice(&1u32.to_le_bytes());
        refix(&mut b);
        assert!(message(&b).contains("MIRR: joint 0's opposite is 1"), "{}", message(&b));
        let mut b = good.clone();
        b[m + 12..m + 16].copy_from_slice(&0u32.to_le_bytes());
        refix(&mut b);
        assert!(message(&b).contains("MIRR: clip 0 cannot be derived"), "{}", message(&b));
    }

    fn message(bytes: &[u8]) -> String {
        from_bytes(bytes).unwrap_err().to_string()
    }

    /// Rewrites the checksum so that a deliberate edit is what the reader trips on.
    fn refix(bytes: &mut [u8]) {
        let crc = crc32fast::hash(&bytes[HEADER_LEN..]);
        bytes[24..28].copy_from_slice(&crc.to_le_bytes());
    }

    #[test]
    fn round_trip() {
        let db = tiny();
        let bytes = to_bytes(&db);
        assert_eq!(bytes.len() % 16, 0);
        // The tiny database's rotations are identities, which quantize exactly.
        assert_eq!(from_bytes(&bytes).unwrap(), db);
    }

    /// A first part (`PART`) round-trips; a part whose ranges do not match its clips, leave the
    /// whole or name a path instead of a file beside it is refused, naming `PART`.
    #[test]
    fn a_first_part_round_trips_and_bad_ones_are_refused() {
        let mut db = tiny();
        let part = Part { whole: "w.mmdb".into(), whole_frames: 10, whole_checksum: 7, ranges: vec![(4, 7)] };
        db.part = Some(part.clone());
        let back = from_bytes(&to_bytes(&db)).unwrap();
        assert_eq!(back.part.as_ref(), Some(&part));
        assert_eq!((part.whole_frame(0), part.whole_frame(2), part.whole_frame(3)), (Some(4), Some(6), None));
        for (bad, says) in [
            (Part { ranges: vec![(4, 6)], ..part.clone() }, "one range per clip"),
            (Part { ranges: vec![(8, 11)], ..part.clone() }, "outside the whole's 10 frames"),
            (Part { ranges: vec![(1, 2), (0, 2)], ..part.clone() }, "out of order"),
            (Part { whole: "../w.mmdb".into(), ..part.clone() }, "plain file name"),
            (Part { whole: "https://x/w.mmdb".into(), ..part.clone() }, "plain file name"),
        ] {
            db.part = Some(bad);
            let m = message(&to_bytes(&db));
            assert!(m.contains("PART") && m.contains(says), "{m}");
        }
    }

    #[test]
    fn rejects_corrupt_truncated_and_wrong_version() {
        let bytes = to_bytes(&tiny());
        assert!(message(&bytes[..10]).contains("truncated"));
        assert!(message(&bytes[..bytes.len() - 16]).contains("truncated"));
        let mut b = bytes.clone();
        b[0] = b'X';
        assert!(message(&b).contains("magic"));
        let mut b = bytes.clone();
        b[8] = 4;
        assert!(message(&b).contains("version 4 (this reader reads versions 1 to 3); rebuild"));
        let mut b = bytes.clone();
        let last = b.len() - 20;
        b[last] ^= 0x40;
        assert!(message(&b).contains("checksum"));
        // A section pointing past the end, with a valid checksum.
        let mut b = bytes.clone();
        b[HEADER_LEN + 8..HEADER_LEN + 16].copy_from_slice(&(1u64 << 40).to_le_bytes());
        refix(&mut b);
        assert!(message(&b).contains("outside the file"));
        // A lying count must not allocate: CLIP count = 2^32-1.
        let mut db = tiny();
        db.clips[0].name = "x".repeat(3);
        let mut b = to_bytes(&db);
        let clip_offset =
            u64::from_le_bytes(b[HEADER_LEN + 2 * 24 + 8..HEADER_LEN + 2 * 24 + 16].try_into().unwrap()) as usize;
        b[clip_offset..clip_offset + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        refix(&mut b);
        assert!(message(&b).contains("does not fit"));
    }

    #[test]
    fn rejects_inconsistent_content() {
        let mut db = tiny();
        db.clips[0].end = 2;
        assert!(message(&to_bytes(&db)).contains("clips cover frames 0..2"));
        let mut db = tiny();
        db.skeleton.parents[1] = 1;
        assert!(message(&to_bytes(&db)).contains("parents must precede"));
        let mut db = tiny();
        db.tags[0].ranges = vec![(2, 5)];
        assert!(message(&to_bytes(&db)).contains("tag 'walk'"));
        let mut db = tiny();
        db.contacts.pop();
        assert!(message(&to_bytes(&db)).contains("section CONT is 5 bytes but INFO implies 6"));
    }

    /// Frame 1's root 1e11 m away and a feature scale of 1e-3: every stored value is within
    /// bounds, but the feature derived from them is not (and the builder's check derives the same).
    fn huge_feature(db: &mut Database) {
        db.local_positions[2].x = 1e11;
        db.feature_scale[0] = 1e-3;
        db.compute_features();
    }

    /// Values, not only structure: each of these loaded before (with a valid checksum) and
    /// then froze, trapped or poisoned the runtime.
    #[test]
    fn rejects_insane_values() {
        type Edit = Box<dyn Fn(&mut Database)>;
        let cases: Vec<(&str, Edit, &str)> = vec![
            ("huge fps", Box::new(|db| db.fps = 1e30), "INFO.fps must be between 1 and 1000"),
            ("zero fps", Box::new(|db| db.fps = 0.0), "INFO.fps"),
            ("nan fps", Box::new(|db| db.fps = f32::NAN), "INFO.fps"),
            ("nan position", Box::new(|db| db.local_positions[3].y = f32::NAN), "PANM: value 10 is NaN"),
            (
                "a feature past 1e12 (a far root over a tiny scale)",
                Box::new(huge_feature),
                "features derived from PANM and QROT: value 0 is 9.999999e13",
            ),
            ("zero scale", Box::new(|db| db.feature_scale[1] = 0.0), "FNRM: scale of dim 1 is 0"),
            ("nan clip scale", Box::new(|db| db.clips[0].scale = f32::NAN), "CLIP 'a': scale NaN"),
            (
                "not a unit quaternion",
                Box::new(|db| db.local_rotations[4] = Quat::from_xyzw(0.0, 0.0, 0.0, 0.5)),
                "QROT: frame 2 joint 0 is not a unit quaternion",
            ),
            ("contact byte 2", Box::new(|db| db.contacts[1] = 2), "section CONT: byte 1 is 2"),
            ("huge offset", Box::new(|db| db.groups[0].offsets[0] = i32::MIN), "frame offset -2147483648"),
            ("nan weight", Box::new(|db| db.groups[0].weight = f32::NAN), "weight NaN"),
            ("denormal weight", Box::new(|db| db.groups[0].weight = 1e-40), "weight 1e-40"),
            ("zero root scale", Box::new(|db| db.clips[0].root_scale = 0.0), "root scale 0e0"),
            ("nan site", Box::new(|db| db.skeleton.sites[0].offset.x = f32::NAN), "SKEL site offset"),
            (
                "duplicate clip name",
                Box::new(|db| {
                    db.clips[0].end = 1;
                    let mut c = db.clips[0].clone();
                    (c.start, c.end) = (1, 3);
                    db.clips.push(c);
                }),
                "two clips are named 'a'",
            ),
        ];
        for (what, edit, expected) in cases {
            let mut db = tiny();
            edit(&mut db);
            let m = message(&to_bytes(&db));
            assert!(m.contains(expected), "{what}: {m}");
        }
    }

    /// The builder's last check is the loader's: each value the loader refuses in a file,
    /// `check_database` refuses in memory with the same message (issue 28: the builder wrote
    /// files its own loader refused).
    #[test]
    fn check_database_says_what_the_loader_says() {
        type Edit = Box<dyn Fn(&mut Database)>;
        let edits: Vec<(&str, Edit)> = vec![
            ("huge fps", Box::new(|db| db.fps = 1e30)),
            ("nan position", Box::new(|db| db.local_positions[3].y = f32::NAN)),
            ("huge derived feature", Box::new(huge_feature)),
            ("zero scale", Box::new(|db| db.feature_scale[1] = 0.0)),
            ("huge scale", Box::new(|db| db.feature_scale[0] = 1.34e12)),
            ("nan clip scale", Box::new(|db| db.clips[0].scale = f32::NAN)),
            ("huge offset", Box::new(|db| db.groups[0].offsets[0] = i32::MIN)),
            ("nan weight", Box::new(|db| db.groups[0].weight = f32::NAN)),
            ("root scale 1e4", Box::new(|db| db.clips[0].root_scale = 1e4)),
            ("nan site", Box::new(|db| db.skeleton.sites[0].offset.x = f32::NAN)),
            ("huge mean", Box::new(|db| db.feature_mean[1] = 1e13)),
        ];
        assert!(check_database(&tiny()).is_ok());
        for (what, edit) in edits {
            let mut db = tiny();
            edit(&mut db);
            let loader = message(&to_bytes(&db));
            let builder = format!(
                "invalid .mmdb: {}",
                check_database(&db).map(|_| "accepted".into()).unwrap_or_else(|e| match e {
                    Error::Format(m) => m,
                    other => other.to_string(),
                })
            );
            assert_eq!(builder, loader, "{what}");
        }
        let mut db = tiny();
        db.local_rotations[2] = Quat::from_xyzw(0.0, 0.0, 0.0, 2.0);
        assert!(check_database(&db)
            .unwrap_err()
            .to_string()
            .contains("QROT: frame 1 joint 0 is not a unit quaternion"));
    }

    /// A frame count past 2²⁴ in `INFO` is refused before anything is read (frame indices stay
    /// exact in f32 and u32).
    #[test]
    fn rejects_more_frames_than_the_limit() {
        let mut bytes = to_bytes(&tiny());
        let info = u64::from_le_bytes(bytes[HEADER_LEN + 8..HEADER_LEN + 16].try_into().unwrap()) as usize;
        bytes[info..info + 4].copy_from_slice(&((MAX_FRAMES + 1) as u32).to_le_bytes());
        refix(&mut bytes);
        assert_eq!(message(&bytes), "invalid .mmdb: INFO.num_frames is 16777217, more than 16777216");
    }

    /// At least one frame and one feature group of at least one dimension (inspect and the
    /// runtime index rows by the dimension count).
    #[test]
    fn rejects_empty_databases() {
        let mut db = tiny();
        db.num_frames = 0;
        db.clips.clear();
        db.tags.clear();
        db.local_positions.clear();
        db.local_rotations.clear();
        db.contacts.clear();
        db.features.clear();
        db.valid.clear();
        assert!(message(&to_bytes(&db)).contains("INFO.num_frames is 0"));
        let mut db = tiny();
        db.groups.clear();
        db.feature_mean.clear();
        db.feature_scale.clear();
        db.features.clear();
        assert!(message(&to_bytes(&db)).contains("0 feature groups and 0 feature dims"));
        let mut db = tiny();
        db.groups[0].offsets.clear();
        assert!(message(&to_bytes(&db)).contains("has no frame offsets"));
    }

    /// Sections that share bytes, or are misaligned, are refused even with a valid checksum.
    #[test]
    fn rejects_overlapping_and_misaligned_sections() {
        let bytes = to_bytes(&tiny());
        let entry = |tag: &[u8; 4]| HEADER_LEN + TAGS.iter().position(|t| *t == tag).unwrap() * ENTRY_LEN;
        // Point CONT at the start of QROT: only the overlap check can catch it.
        let mut b = bytes.clone();
        let qrot: [u8; 8] = b[entry(b"QROT") + 8..entry(b"QROT") + 16].try_into().unwrap();
        b[entry(b"CONT") + 8..entry(b"CONT") + 16].copy_from_slice(&qrot);
        refix(&mut b);
        assert!(
            message(&b).contains("sections QROT and CONT overlap")
                || message(&b).contains("sections CONT and QROT overlap"),
            "{}",
            message(&b)
        );
        let mut b = bytes.clone();
        b[entry(b"INFO") + 8] += 4;
        refix(&mut b);
        assert!(message(&b).contains("not a multiple of 16"), "{}", message(&b));
    }

    /// Version 1 (plain f32 poses with stored velocities and features) still loads; written
    /// again it is the current version and decodes to the same database within the
    /// quantization bound, velocities and features derived by the same recipes the builder used.
    #[test]
    fn version_1_still_loads_and_converts() {
        let v1 = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/corpus/mmdb/humanoid.mmdb")).unwrap();
        assert_eq!(le_u32(&v1[8..12]), 1);
        let old = from_bytes(&v1).unwrap();
        let v2 = to_bytes(&old);
        assert_eq!(le_u32(&v2[8..12]), VERSION);
        assert!(v2.len() * 2 < v1.len(), "{} vs {} bytes", v2.len(), v1.len());
        let new = from_bytes(&v2).unwrap();
        assert_eq!(new.local_positions, old.local_positions);
        // Features derived from the quantized poses: within 5e-3 of the stored ones
        // (normalized units; the poses moved by at most 9.2e-5 rad).
        let worst = old.features.iter().zip(&new.features).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        println!("version 1 → {VERSION}: worst feature change {worst:e}");
        assert!(worst < 5e-3, "{worst}");
        assert_eq!(
            (&new.contacts, &new.valid, &new.clips, &new.skeleton),
            (&old.contacts, &old.valid, &old.clips, &old.skeleton)
        );
        for (a, b) in old.local_rotations.iter().zip(&new.local_rotations) {
            assert!(codec::angle(*a, *b) <= codec::MAX_ROTATION_ERROR);
        }
        // The velocities version 1 stored (the f64 builder's) and the ones the converted file's
        // poses give, as a character plays them, agree.
        let stored = |tag: &[u8; 4]| -> Vec<Vec3> {
            let count = le_u32(&v1[12..16]) as usize;
            let e =
                (0..count).map(|i| &v1[HEADER_LEN + i * ENTRY_LEN..][..ENTRY_LEN]).find(|e| &e[..4] == tag).unwrap();
            let at = |r: std::ops::Range<usize>| u64::from_le_bytes(e[r].try_into().unwrap()) as usize;
            let (offset, length) = (at(8..16), at(16..24));
            bytemuck::pod_collect_to_vec(&v1[offset..offset + length])
        };
        let (velocities, angular) = (stored(b"LVEL"), stored(b"LAVL"));
        let j = new.num_joints();
        let (mut v, mut w) = (vec![Vec3::ZERO; j], vec![Vec3::ZERO; j]);
        for f in 0..new.num_frames {
            new.frame_velocities(f, &mut v, &mut w);
            for k in 0..j {
                let (a, b) = ((velocities[f * j + k], v[k]), (angular[f * j + k], w[k]));
                assert!((a.0 - a.1).length() < 1e-4, "{} vs {}", a.0, a.1);
                assert!((b.0 - b.1).length() < 0.01, "{} vs {}", b.0, b.1);
            }
        }
    }
}
