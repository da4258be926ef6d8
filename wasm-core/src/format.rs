//! The `.mmdb` binary format, version 1 (specified in `docs/mmdb-format.md`): writing a
//! [`Database`] to bytes and reading it back with every length and offset checked.

use crate::database::{Axes, Clip, Database, FeatureGroup, FeatureKind, Site, Skeleton, Tag};
use crate::error::{Error, Result};
use glam::{Quat, Vec3};

#[cfg(target_endian = "big")]
compile_error!("the .mmdb writer and reader assume a little-endian target");

pub const MAGIC: [u8; 8] = *b"\x89MMDB\r\n\x1a";
pub const VERSION: u32 = 1;
const HEADER_LEN: usize = 32;
const ENTRY_LEN: usize = 24;
const ALIGN: usize = 16;

/// Section tags in the order they are written.
const TAGS: [&[u8; 4]; 13] =
    [b"INFO", b"SKEL", b"CLIP", b"TAGS", b"LPOS", b"LROT", b"LVEL", b"LAVL", b"CONT", b"FDSC", b"FNRM", b"FEAT", b"VALD"];

/// Serializes a database.
pub fn to_bytes(db: &Database) -> Vec<u8> {
    // The big arrays are borrowed as bytes (the format is little-endian like every target we
    // build for, checked above) and copied once, into the output.
    let mut sections: Vec<(&[u8; 4], std::borrow::Cow<[u8]>)> = Vec::with_capacity(TAGS.len());
    for tag in TAGS {
        let data: std::borrow::Cow<[u8]> = match tag {
            b"LPOS" => bytemuck::cast_slice(&db.local_positions).into(),
            b"LROT" => bytemuck::cast_slice(&db.local_rotations).into(),
            b"LVEL" => bytemuck::cast_slice(&db.local_velocities).into(),
            b"LAVL" => bytemuck::cast_slice(&db.local_angular_velocities).into(),
            b"CONT" => db.contacts.as_slice().into(),
            b"FEAT" => bytemuck::cast_slice(&db.features).into(),
            b"VALD" => db.valid.as_slice().into(),
            _ => small_section(db, tag).into(),
        };
        sections.push((tag, data));
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
                put_f32(&mut w, c.source_fps);
                put_f32(&mut w, c.scale);
                put_f32(&mut w, c.root_scale);
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
pub fn from_bytes(bytes: &[u8]) -> Result<Database> {
    if bytes.len() < HEADER_LEN {
        return Err(Error::format(format!("truncated: {} bytes, shorter than the 32-byte header", bytes.len())));
    }
    if bytes[..8] != MAGIC {
        return Err(Error::format("wrong magic bytes: not a .mmdb file"));
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
    if version != VERSION {
        return Err(Error::format(format!("unsupported format version {version} (this reader supports version {VERSION})")));
    }
    let count = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let file_size = u64::from_le_bytes(bytes[16..24].try_into().unwrap());
    if file_size != bytes.len() as u64 {
        return Err(Error::format(format!(
            "file size is {} bytes but the header says {file_size}: the file is truncated or has trailing data",
            bytes.len()
        )));
    }
    let stored_crc = u32::from_le_bytes(bytes[24..28].try_into().unwrap());
    let crc = crc32fast::hash(&bytes[HEADER_LEN..]);
    if crc != stored_crc {
        return Err(Error::format(format!("checksum mismatch (stored {stored_crc:08x}, computed {crc:08x}): the file is corrupt")));
    }
    let table_end = count.checked_mul(ENTRY_LEN).and_then(|n| n.checked_add(HEADER_LEN)).filter(|&n| n <= bytes.len());
    let Some(table_end) = table_end else {
        return Err(Error::format(format!("section table of {count} entries runs past the end of the file")));
    };
    let mut sections: Vec<([u8; 4], &[u8])> = Vec::with_capacity(count);
    for i in 0..count {
        let e = &bytes[HEADER_LEN + i * ENTRY_LEN..HEADER_LEN + (i + 1) * ENTRY_LEN];
        let tag: [u8; 4] = e[..4].try_into().unwrap();
        let name = String::from_utf8_lossy(&tag).into_owned();
        let offset = u64::from_le_bytes(e[8..16].try_into().unwrap());
        let length = u64::from_le_bytes(e[16..24].try_into().unwrap());
        if offset < table_end as u64 || offset.checked_add(length).is_none_or(|end| end > file_size) {
            return Err(Error::format(format!("section {name} (offset {offset}, length {length}) lies outside the file")));
        }
        if sections.iter().any(|(t, _)| *t == tag) {
            return Err(Error::format(format!("section {name} appears twice")));
        }
        sections.push((tag, &bytes[offset as usize..(offset + length) as usize]));
    }
    let section = |tag: &[u8; 4]| -> Result<Reader> {
        sections.iter().find(|(t, _)| t == tag).map(|&(t, data)| Reader { data, pos: 0, tag: t }).ok_or_else(|| {
            Error::format(format!("required section {} is missing", String::from_utf8_lossy(tag)))
        })
    };

    let mut info = section(b"INFO")?;
    let num_frames = info.u32("num_frames")? as usize;
    let num_joints = info.u32("num_joints")? as usize;
    let fps = info.f32("fps")?;
    let num_dims = info.u32("num_feature_dims")? as usize;
    let num_clips = info.u32("num_clips")? as usize;
    let num_tags = info.u32("num_tags")? as usize;
    let num_groups = info.u32("num_feature_groups")? as usize;
    if !(fps > 0.0 && fps.is_finite()) {
        return Err(Error::format(format!("INFO.fps must be a positive number, found {fps}")));
    }
    if num_joints == 0 {
        return Err(Error::format("INFO.num_joints is 0"));
    }

    let mut r = section(b"SKEL")?;
    let mut skeleton = Skeleton { names: Vec::new(), parents: Vec::new(), offsets: Vec::new(), sites: Vec::new() };
    for j in 0..num_joints {
        skeleton.names.push(r.string("joint name")?);
        let parent = r.i32("joint parent")?;
        if (j == 0 && parent != -1) || (j > 0 && !(0..j as i32).contains(&parent)) {
            return Err(Error::format(format!("SKEL: joint {j} has parent {parent}; parents must precede their children and only joint 0 may be -1")));
        }
        skeleton.parents.push(parent);
        skeleton.offsets.push(r.vec3("joint offset")?);
    }
    let num_sites = r.count(16, "site count")?;
    for _ in 0..num_sites {
        let name = r.string("site name")?;
        let joint = r.i32("site joint")?;
        if joint < -1 || joint >= num_joints as i32 {
            return Err(Error::format(format!("SKEL: site '{name}' names joint {joint}, out of range")));
        }
        skeleton.sites.push(Site { name, joint, offset: r.vec3("site offset")? });
    }

    let mut r = section(b"CLIP")?;
    let n = r.count(26, "clip count")?;
    if n != num_clips {
        return Err(Error::format(format!("CLIP holds {n} clips but INFO says {num_clips}")));
    }
    let mut clips = Vec::with_capacity(n);
    let mut next = 0u32;
    for _ in 0..n {
        let clip = Clip {
            name: r.string("clip name")?,
            source: r.string("clip source")?,
            start: r.u32("clip start")?,
            end: r.u32("clip end")?,
            mirrored: r.u8("clip mirrored")? != 0,
            source_fps: r.f32("clip source fps")?,
            scale: r.f32("clip scale")?,
            root_scale: r.f32("clip root scale")?,
        };
        if clip.start != next || clip.end <= clip.start || clip.end as usize > num_frames {
            return Err(Error::format(format!(
                "CLIP '{}' covers frames {}..{}; clips must be non-empty, in order and tile 0..{num_frames}",
                clip.name, clip.start, clip.end
            )));
        }
        next = clip.end;
        clips.push(clip);
    }
    if next as usize != num_frames {
        return Err(Error::format(format!("clips cover frames 0..{next} but the database has {num_frames} frames")));
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
                return Err(Error::format(format!("tag '{name}' has range {s}..{e}: ranges must be sorted, disjoint, within 0..{num_frames}")));
            }
            last = e;
            ranges.push((s, e));
        }
        tags.push(Tag { name, ranges });
    }

    let fj = num_frames.checked_mul(num_joints).ok_or_else(|| Error::format("INFO counts overflow"))?;
    let local_positions = section(b"LPOS")?.vec3s(fj)?;
    let local_rotations: Vec<Quat> = section(b"LROT")?.pods(fj)?;
    let local_velocities = section(b"LVEL")?.vec3s(fj)?;
    let local_angular_velocities = section(b"LAVL")?.vec3s(fj)?;
    let contacts = section(b"CONT")?.bytes(num_frames * 2)?;

    let mut r = section(b"FDSC")?;
    let n = r.count(40, "feature group count")?;
    if n != num_groups {
        return Err(Error::format(format!("FDSC holds {n} groups but INFO says {num_groups}")));
    }
    let mut groups = Vec::with_capacity(n);
    let mut next_dim = 0usize;
    for _ in 0..n {
        let name = r.string("feature name")?;
        let kind = match r.u8("feature kind")? {
            0 => FeatureKind::Position,
            1 => FeatureKind::Velocity,
            2 => FeatureKind::Direction,
            k => return Err(Error::format(format!("FDSC: feature '{name}' has unknown kind {k}"))),
        };
        let is_trajectory = r.u8("feature trajectory flag")? != 0;
        let axes = match r.u8("feature axes")? {
            0 => Axes::Xyz,
            1 => Axes::Xz,
            a => return Err(Error::format(format!("FDSC: feature '{name}' has unknown axes {a}"))),
        };
        r.u8("reserved")?;
        let joint = r.i32("feature joint")?;
        if joint < 0 || joint as usize >= num_joints {
            return Err(Error::format(format!("FDSC: feature '{name}' names joint {joint}, out of range")));
        }
        let axis = r.vec3("feature axis")?;
        let k = r.count(4, "feature offset count")?;
        let offsets = (0..k).map(|_| r.i32("feature offset")).collect::<Result<Vec<_>>>()?;
        let weight = r.f32("feature weight")?;
        let first_dim = r.u32("feature first dim")? as usize;
        let num = r.u32("feature dim count")? as usize;
        if first_dim != next_dim || num != offsets.len() * axes.num_dims() {
            return Err(Error::format(format!("FDSC: feature '{name}' spans dims {first_dim}+{num}; groups must tile 0..{num_dims} in order")));
        }
        next_dim += num;
        groups.push(FeatureGroup { name, kind, is_trajectory, axes, joint: joint as usize, axis, offsets, weight, first_dim, num_dims: num });
    }
    if next_dim != num_dims {
        return Err(Error::format(format!("feature groups cover {next_dim} dims but INFO says {num_dims}")));
    }
    let norm = section(b"FNRM")?.f32s(2 * num_dims)?;
    let features = section(b"FEAT")?.f32s(num_frames * num_dims)?;
    let valid = section(b"VALD")?.bytes(num_frames)?;

    Ok(Database {
        skeleton,
        fps,
        num_frames,
        clips,
        tags,
        local_positions,
        local_rotations,
        local_velocities,
        local_angular_velocities,
        contacts,
        groups,
        feature_mean: norm[..num_dims].to_vec(),
        feature_scale: norm[num_dims..].to_vec(),
        features,
        valid,
    })
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
                String::from_utf8_lossy(&self.tag),
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
    fn u32(&mut self, field: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, field)?.try_into().unwrap()))
    }
    fn i32(&mut self, field: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.take(4, field)?.try_into().unwrap()))
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
        if n.saturating_mul(min_size) > self.data.len() - self.pos {
            return Err(Error::format(format!("{} {field} {n} does not fit in the section", String::from_utf8_lossy(&self.tag))));
        }
        Ok(n)
    }
    fn string(&mut self, field: &str) -> Result<String> {
        let n = self.u32(field)? as usize;
        let bytes = self.take(n, field)?;
        String::from_utf8(bytes.to_vec()).map_err(|_| Error::format(format!("{} {field} is not UTF-8", String::from_utf8_lossy(&self.tag))))
    }
    /// The whole section as exactly `n` bytes (fixed-size arrays must match INFO exactly).
    fn bytes(&mut self, n: usize) -> Result<Vec<u8>> {
        Ok(self.exact(n)?.to_vec())
    }
    fn exact(&self, n: usize) -> Result<&'a [u8]> {
        if self.data.len() != n {
            return Err(Error::format(format!(
                "section {} is {} bytes but INFO implies {n}",
                String::from_utf8_lossy(&self.tag),
                self.data.len()
            )));
        }
        Ok(self.data)
    }
    /// `n` plain-old-data values filling the whole section (copied, so alignment is free).
    fn pods<T: bytemuck::Pod>(&mut self, n: usize) -> Result<Vec<T>> {
        Ok(bytemuck::pod_collect_to_vec(self.exact(n * std::mem::size_of::<T>())?))
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
        Database {
            skeleton: Skeleton {
                names: vec!["VirtualRoot".into(), "Hips".into()],
                parents: vec![-1, 0],
                offsets: vec![Vec3::ZERO, Vec3::Y],
                sites: vec![Site { name: "hips".into(), joint: 1, offset: Vec3::ZERO }],
            },
            fps: 60.0,
            num_frames: 3,
            clips: vec![Clip { name: "a".into(), source: "a.bvh".into(), start: 0, end: 3, mirrored: false, source_fps: 120.0, scale: 1.0, root_scale: 1.0 }],
            tags: vec![Tag { name: "walk".into(), ranges: vec![(0, 2)] }],
            local_positions: (0..6).map(|i| Vec3::splat(i as f32)).collect(),
            local_rotations: vec![Quat::IDENTITY; 6],
            local_velocities: vec![Vec3::X; 6],
            local_angular_velocities: vec![Vec3::Z; 6],
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
            features: vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0],
            valid: vec![1, 1, 0],
        }
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
        assert_eq!(from_bytes(&bytes).unwrap(), db);
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
        b[8] = 2;
        assert!(message(&b).contains("version 2"));
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
        let clip_offset = u64::from_le_bytes(b[HEADER_LEN + 2 * 24 + 8..HEADER_LEN + 2 * 24 + 16].try_into().unwrap()) as usize;
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
}
