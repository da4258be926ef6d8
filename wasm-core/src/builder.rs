//! Building a [`Database`] from BVH takes (THESIS_NOTES §1–2):
//! unit scale and up axis → resampling → bone lengths normalized onto a reference skeleton →
//! optional mirroring → virtual root (smoothed hips projection and facing) → velocities →
//! foot contacts → features, normalization and validity.
//!
//! All arithmetic is f64 until the arrays are stored as f32, so the database's forward
//! kinematics reproduces the source within ~1e-6 m.

use crate::bvh::{Bvh, Channel};
use crate::config::{AutoScale, BuildConfig, FeatureSpec, Scale, UpAxis};
use crate::database::{Axes, Clip, Database, FeatureGroup, FeatureKind, Site, Skeleton, Tag};
use crate::error::{Error, Result};
use crate::joint_map::{self, ROLES};
use crate::smoothing::savitzky_golay;
use glam::{DQuat, DVec3, Quat, Vec3};
use std::collections::{BTreeMap, HashMap};

/// A parsed source file with the name used in messages, clip names and config matching.
pub struct Source {
    pub name: String,
    pub bvh: Bvh,
}

/// A built database and what the user should know about how it was built.
pub struct BuildOutput {
    pub database: Database,
    pub warnings: Vec<String>,
}

/// Name of joint 0 in every database.
pub const VIRTUAL_ROOT: &str = "VirtualRoot";

/// Builds one database from `sources` (at least one) as `config` says.
pub fn build(config: &BuildConfig, sources: &[Source]) -> Result<BuildOutput> {
    if sources.is_empty() {
        return Err(Error::config("no BVH files to build from"));
    }
    let mut warnings = Vec::new();
    let reference = match &config.reference {
        Some(r) => sources
            .iter()
            .position(|s| crate::config::wildcard_match(r, base_name(&s.name)))
            .ok_or_else(|| Error::config(format!("reference '{r}' is not one of the source files")))?,
        None => 0,
    };
    let ref_bvh = &sources[reference].bvh;
    let names: Vec<String> = ref_bvh.joints.iter().map(|j| j.name.clone()).collect();
    let parents: Vec<Option<usize>> = ref_bvh.joints.iter().map(|j| j.parent).collect();
    for s in sources {
        check_topology(&sources[reference], s)?;
    }
    let roles = joint_map::find_roles(&names, &parents, &config.roles);
    for (role, name) in &config.roles {
        if !ROLES.contains(&role.as_str()) {
            return Err(Error::config(format!("roles: unknown role '{role}' (known: {})", ROLES.join(", "))));
        }
        if !names.contains(name) {
            return Err(Error::config(format!("roles: '{role}' names joint '{name}', which the skeleton does not have")));
        }
    }
    for role in ["hips", "left_upper_leg", "right_upper_leg", "left_foot", "right_foot"] {
        if !roles.contains_key(role) {
            return Err(Error::config(format!(
                "{}: could not find the {} joint by name among [{}]; name it in the config, e.g. \"roles\": {{\"{role}\": \"<joint name>\"}}",
                sources[reference].name,
                role.replace('_', " "),
                names.join(", ")
            )));
        }
    }

    // Per-take unit scale and axis conversion, then the reference's rest skeleton (metres, Y up).
    let takes: Vec<Take> = sources.iter().map(|s| Take::new(s, config, &roles, &mut warnings)).collect::<Result<_>>()?;
    let ref_take = &takes[reference];
    let ref_offsets: Vec<DVec3> = ref_take.offsets.clone();
    let ref_leg = leg_length(&ref_offsets, &parents, &roles);
    let rest = rest_positions(&ref_offsets, &parents);
    // Forward in the hips' rest frame: left-to-right hip axis × up (left = +X when facing +Z).
    let forward_rest =
        (rest[roles["left_upper_leg"]] - rest[roles["right_upper_leg"]]).cross(DVec3::Y).try_normalize().unwrap_or(DVec3::Z);

    let skeleton = database_skeleton(&names, &parents, &ref_offsets, ref_bvh, &roles, ref_take.scale, ref_take.up);
    let toe_sites = [skeleton.site("left_toe").cloned(), skeleton.site("right_toe").cloned()];
    if roles.get("left_toe").is_none() {
        warnings.push("no toe joints found: foot contacts use the feet's end sites (or ankles)".into());
    }
    let pairs: Vec<usize> = names
        .iter()
        .enumerate()
        .map(|(j, n)| joint_map::mirror_name(n).and_then(|m| names.iter().position(|x| *x == m)).unwrap_or(j))
        .collect();
    let animated_translation: Vec<bool> =
        ref_bvh.joints.iter().map(|j| j.channels.iter().any(|c| matches!(c, Channel::PosX | Channel::PosY | Channel::PosZ))).collect();

    let groups = feature_groups(config, &skeleton, &roles)?;
    let num_dims: usize = groups.iter().map(|g| g.num_dims).sum();
    let fps = config.fps;
    // Every take's row count is known before any work, so the output arrays are allocated
    // once and split into disjoint per-clip slices that the takes fill independently (on
    // all cores natively; WASM has one thread). The result is identical either way.
    let mut plans = Vec::new();
    let mut num_frames = 0usize;
    for (t, take) in takes.iter().enumerate() {
        let n = take.num_out(fps);
        if n < 2 {
            warnings.push(format!("{}: skipped, fewer than 2 frames at {fps} fps", sources[t].name));
            continue;
        }
        for mirrored in [false, true].into_iter().take(if take.mirror { 2 } else { 1 }) {
            plans.push((t, mirrored, num_frames, n));
            num_frames += n;
        }
    }
    if num_frames == 0 {
        return Err(Error::config("no frames to build from (every take is shorter than 2 frames)"));
    }
    let nd = names.len() + 1;
    let mut out = Accumulator {
        num_frames,
        positions: vec![Vec3::ZERO; num_frames * nd],
        rotations: vec![Quat::IDENTITY; num_frames * nd],
        velocities: vec![Vec3::ZERO; num_frames * nd],
        angular_velocities: vec![Vec3::ZERO; num_frames * nd],
        contacts: vec![0; num_frames * 2],
        features: vec![0.0; num_frames * num_dims],
        clips: Vec::new(),
    };
    let clip_builder = ClipBuilder {
        config,
        fps,
        parents: &parents,
        hips: roles["hips"],
        forward_rest,
        toe_sites: &toe_sites,
        groups: &groups,
        num_dims,
    };
    let root_scales: Vec<f64> = takes
        .iter()
        .enumerate()
        .map(|(t, take)| if t == reference { 1.0 } else { ref_leg / leg_length(&take.offsets, &parents, &roles) })
        .collect();
    // A take and its mirror are one job (the mirror reuses the resampled take).
    let mut jobs: Vec<(usize, Vec<Rows>)> = Vec::new();
    let mut rest_rows = out.rows();
    for &(t, mirrored, _, n) in &plans {
        let (rows, tail) = rest_rows.split_at(n, nd, num_dims);
        rest_rows = tail;
        match jobs.last_mut() {
            Some((last, list)) if *last == t && mirrored => list.push(rows),
            _ => jobs.push((t, vec![rows])),
        }
    }
    // Scratch buffers are reused across jobs: fresh ones per clip add up to ~100 MB of f64
    // temporaries for the default database, and WASM memory never shrinks once grown.
    let pool = std::sync::Mutex::new(Vec::<Scratch>::new());
    let spike_warnings = std::sync::Mutex::new(Vec::<String>::new());
    crate::parallel::for_each(jobs, |(t, rows)| {
        let mut scratch = pool.lock().unwrap().pop().unwrap_or_default();
        let take = &takes[t];
        let mut locals = std::mem::take(&mut scratch.locals);
        take.resample(&sources[t].bvh, fps, &ref_offsets, &animated_translation, root_scales[t], t == reference, &mut locals);
        let repaired = if config.repair_spikes { repair_spikes(&mut locals, names.len()) } else { Vec::new() };
        if !repaired.is_empty() {
            let list: Vec<String> = repaired.iter().take(5).map(|&(j, f)| format!("{} at frame {f}", names[j])).collect();
            let more = if repaired.len() > 5 { format!(" and {} more", repaired.len() - 5) } else { String::new() };
            spike_warnings.lock().unwrap().push(format!("{}: repaired {} rotation spike(s): {}{more}", sources[t].name, repaired.len(), list.join(", ") ));
        }
        let mut mirrored = std::mem::take(&mut scratch.mirrored);
        for (i, rows) in rows.into_iter().enumerate() {
            if i == 0 {
                clip_builder.append(&locals, names.len(), rows, &mut scratch);
            } else {
                mirror(&locals, &pairs, &animated_translation, &mut mirrored);
                clip_builder.append(&mirrored, names.len(), rows, &mut scratch);
            }
        }
        (scratch.locals, scratch.mirrored) = (locals, mirrored);
        pool.lock().unwrap().push(scratch);
    });
    let mut spike_warnings = spike_warnings.into_inner().unwrap();
    spike_warnings.sort();
    warnings.extend(spike_warnings);
    let mut tag_ranges: BTreeMap<String, Vec<(u32, u32)>> = BTreeMap::new();
    for &(t, mirrored, start, num_out) in &plans {
        let (take, source) = (&takes[t], &sources[t]);
        let start = start as u32;
        let name = if mirrored { format!("{} (mirror)", take.clip_name) } else { take.clip_name.clone() };
        out.clips.push(Clip {
            name,
            source: base_name(&source.name).to_string(),
            start,
            end: start + num_out as u32,
            mirrored,
            source_fps: take.source_fps as f32,
            scale: take.scale as f32,
            root_scale: root_scales[t] as f32,
        });
        // Tags: whole clip, then source-frame ranges mapped to database frames.
        let to_db = |s: usize| start + ((s.saturating_sub(take.frames.0)) as f64 * fps / take.source_fps).round().min(num_out as f64) as u32;
        for tag in &take.tags {
            tag_ranges.entry(tag.clone()).or_default().push((start, start + num_out as u32));
        }
        for r in &take.ranges {
            let (s, e) = (to_db(r.frames[0]), to_db(r.frames[1]));
            if e > s {
                for tag in &r.tags {
                    tag_ranges.entry(tag.clone()).or_default().push((s, e));
                }
            }
        }
    }
    ensure_unique_names(&mut out.clips);

    let (feature_mean, feature_scale) = normalize(&mut out.features, &groups, num_dims);
    let valid = validity(&out.clips, &groups, out.num_frames);
    let tags = tag_ranges.into_iter().map(|(name, ranges)| Tag { name, ranges: coalesce(ranges) }).collect();
    let contact_share = |side: usize| out.contacts.iter().skip(side).step_by(2).filter(|&&c| c != 0).count() as f64 / out.num_frames as f64;
    if contact_share(0) < 0.05 || contact_share(1) < 0.05 {
        warnings.push(format!(
            "feet are in contact only {:.0}% / {:.0}% of frames (left/right): check the scale, the floor height and contact_speed",
            100.0 * contact_share(0),
            100.0 * contact_share(1)
        ));
    }
    Ok(BuildOutput {
        database: Database {
            skeleton,
            fps: fps as f32,
            num_frames: out.num_frames,
            clips: out.clips,
            tags,
            local_positions: out.positions,
            local_rotations: out.rotations,
            local_velocities: out.velocities,
            local_angular_velocities: out.angular_velocities,
            contacts: out.contacts,
            groups,
            feature_mean,
            feature_scale,
            features: out.features,
            valid,
        },
        warnings,
    })
}

fn base_name(path: &str) -> &str {
    path.rsplit(['/', '\\']).next().unwrap_or(path)
}

fn check_topology(reference: &Source, source: &Source) -> Result<()> {
    let (a, b) = (&reference.bvh.joints, &source.bvh.joints);
    let parent_name = |joints: &[crate::bvh::BvhJoint], j: usize| joints[j].parent.map_or("none".to_string(), |p| joints[p].name.clone());
    for j in 0..a.len().max(b.len()) {
        let same = j < a.len() && j < b.len() && a[j].name == b[j].name && parent_name(a, j) == parent_name(b, j);
        if !same {
            let describe = |joints: &[crate::bvh::BvhJoint]| match joints.get(j) {
                Some(x) => format!("'{}' (child of '{}')", x.name, parent_name(joints, j)),
                None => "no joint".into(),
            };
            return Err(Error::config(format!(
                "{}: joint {j} is {} but the reference skeleton {} has {}: all files of one database must share one skeleton topology",
                source.name,
                describe(b),
                reference.name,
                describe(a)
            )));
        }
    }
    Ok(())
}

/// One source take as it will be resampled: units, axes, range and tags resolved.
struct Take {
    clip_name: String,
    scale: f64,
    /// Rotation taking source axes to Y-up (identity for Y-up sources).
    up: DQuat,
    source_fps: f64,
    frames: (usize, usize),
    mirror: bool,
    tags: Vec<String>,
    ranges: Vec<crate::config::RangeSpec>,
    /// Rest offsets in metres, Y up.
    offsets: Vec<DVec3>,
}

impl Take {
    fn new(source: &Source, config: &BuildConfig, roles: &HashMap<&'static str, usize>, warnings: &mut Vec<String>) -> Result<Take> {
        let bvh = &source.bvh;
        let spec = config.clip_spec(&source.name);
        let parents: Vec<Option<usize>> = bvh.joints.iter().map(|j| j.parent).collect();
        let raw_offsets: Vec<DVec3> = bvh.joints.iter().map(|j| j.offset).collect();
        let rest = rest_positions(&raw_offsets, &parents);

        let up = match config.up {
            UpAxis::Y => DQuat::IDENTITY,
            UpAxis::Z => DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2),
            UpAxis::Auto => {
                let hips = rest[roles["hips"]];
                let top = roles.get("head").map_or_else(
                    || rest.iter().copied().max_by(|a, b| (*a - hips).length().total_cmp(&(*b - hips).length())).unwrap(),
                    |&h| rest[h],
                );
                let v = top - hips;
                let up = if v.z.abs() > v.y.abs() && v.z.abs() > v.x.abs() {
                    DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2 * v.z.signum())
                } else if v.x.abs() > v.y.abs() {
                    DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2 * v.x.signum())
                } else {
                    DQuat::IDENTITY
                };
                if up != DQuat::IDENTITY {
                    warnings.push(format!("{}: rest pose is not Y-up; converted to Y-up", source.name));
                }
                up
            }
        };
        // Standing hip height in source units: hips above the lowest point of the rest pose.
        let lowest = rest
            .iter()
            .copied()
            .chain(bvh.joints.iter().enumerate().filter_map(|(j, b)| b.end_site.map(|e| rest[j] + e)))
            .map(|p| (up * p).y)
            .fold(f64::INFINITY, f64::min);
        let hip_height = (up * rest[roles["hips"]]).y - lowest;
        let scale = match spec.and_then(|s| s.scale).unwrap_or(config.scale) {
            Scale::Fixed(s) => s,
            Scale::Auto(AutoScale::Auto) => {
                if hip_height > 0.0 {
                    [1.0, 0.01, 0.001, 0.0254].into_iter().min_by(|a, b| (hip_height * a / 0.95).ln().abs().total_cmp(&(hip_height * b / 0.95).ln().abs())).unwrap()
                } else {
                    1.0
                }
            }
        };
        let metres = hip_height * scale;
        if !(0.4..=1.5).contains(&metres) {
            warnings.push(format!(
                "{}: standing hip height is {metres:.3} m after scale {scale}; that looks implausible for a person — check the unit scale (--scale)",
                source.name
            ));
        }
        // Frame Time is usually printed with few digits (0.00833333): snap to the whole rate.
        let fps = bvh.fps();
        let source_fps = if (fps - fps.round()).abs() < 0.01 { fps.round() } else { fps };
        let frames = match spec.and_then(|s| s.frames) {
            Some([s, e]) => {
                if e > bvh.num_frames {
                    return Err(Error::config(format!("{}: frames [{s}, {e}] but the take has {} frames", source.name, bvh.num_frames)));
                }
                (s, e)
            }
            None => (0, bvh.num_frames),
        };
        let stem = base_name(&source.name).trim_end_matches(".bvh").trim_end_matches(".BVH").to_string();
        let clip_name = if frames == (0, bvh.num_frames) { stem } else { format!("{stem}[{}-{}]", frames.0, frames.1) };
        Ok(Take {
            clip_name,
            scale,
            up,
            source_fps,
            frames,
            mirror: spec.and_then(|s| s.mirror).unwrap_or(config.mirror),
            tags: spec.map(|s| s.tags.clone()).unwrap_or_default(),
            ranges: spec.map(|s| s.ranges.clone()).unwrap_or_default(),
            offsets: raw_offsets.iter().map(|&o| up * o * scale).collect(),
        })
    }

    /// Number of frames after resampling to `fps`.
    fn num_out(&self, fps: f64) -> usize {
        let count = self.frames.1 - self.frames.0;
        if count == 0 {
            0
        } else {
            ((count - 1) as f64 * fps / self.source_fps + 1e-9).floor() as usize + 1
        }
    }

    /// Local transforms (BVH joints, metres, Y up) resampled to `fps`, frame-major. Takes other
    /// than the reference get the reference's bone lengths; their animated translations (root
    /// motion) are scaled by the leg-length ratio so the feet keep their stride.
    #[allow(clippy::too_many_arguments)]
    fn resample(&self, bvh: &Bvh, fps: f64, ref_offsets: &[DVec3], animated: &[bool], root_scale: f64, is_reference: bool, out: &mut Vec<(DVec3, DQuat)>) {
        let num_joints = bvh.joints.len();
        let count = self.frames.1 - self.frames.0;
        let num_out = self.num_out(fps);
        out.clear();
        out.reserve(num_out * num_joints);
        let convert = self.up != DQuat::IDENTITY;
        let sample = |frame: usize, j: usize| {
            let (t, q) = bvh.local_transform(self.frames.0 + frame, j);
            let t = if is_reference || animated[j] { self.up * t * self.scale * if animated[j] { root_scale } else { 1.0 } } else { ref_offsets[j] };
            (t, if convert { self.up * q * self.up.conjugate() } else { q })
        };
        for k in 0..num_out {
            let s = k as f64 * self.source_fps / fps;
            let i = (s + 1e-9).floor() as usize;
            let a = s - i as f64;
            for j in 0..num_joints {
                if a < 1e-6 || i + 1 >= count {
                    out.push(sample(i.min(count - 1), j));
                } else {
                    let (t0, q0) = sample(i, j);
                    let (t1, q1) = sample(i + 1, j);
                    out.push((t0.lerp(t1, a), q0.slerp(q1, a)));
                }
            }
        }
    }
}

/// World rest positions from offsets (rest rotations are the identity).
fn rest_positions(offsets: &[DVec3], parents: &[Option<usize>]) -> Vec<DVec3> {
    let mut rest: Vec<DVec3> = Vec::with_capacity(offsets.len());
    for (j, &o) in offsets.iter().enumerate() {
        rest.push(parents[j].map_or(o, |p| rest[p] + o));
    }
    rest
}

/// Rest length of the legs (upper leg → foot, mean of both sides).
fn leg_length(offsets: &[DVec3], parents: &[Option<usize>], roles: &HashMap<&'static str, usize>) -> f64 {
    let chain = |upper: usize, foot: usize| {
        let (mut j, mut length) = (foot, 0.0);
        while j != upper {
            length += offsets[j].length();
            match parents[j] {
                Some(p) => j = p,
                None => break,
            }
        }
        length
    };
    0.5 * (chain(roles["left_upper_leg"], roles["left_foot"]) + chain(roles["right_upper_leg"], roles["right_foot"]))
}

fn database_skeleton(
    names: &[String],
    parents: &[Option<usize>],
    offsets: &[DVec3],
    bvh: &Bvh,
    roles: &HashMap<&'static str, usize>,
    scale: f64,
    up: DQuat,
) -> Skeleton {
    let mut skeleton = Skeleton {
        names: std::iter::once(VIRTUAL_ROOT.to_string()).chain(names.iter().cloned()).collect(),
        parents: std::iter::once(-1).chain(parents.iter().map(|p| p.map_or(0, |p| p as i32 + 1))).collect(),
        offsets: std::iter::once(Vec3::ZERO).chain(offsets.iter().map(|o| o.as_vec3())).collect(),
        sites: Vec::new(),
    };
    for role in ROLES {
        let (joint, offset) = match roles.get(role) {
            Some(&j) => (j as i32 + 1, Vec3::ZERO),
            // No toe joint (e.g. CMU Daz): the foot's end site is the toe tip.
            None if role.ends_with("_toe") => {
                let foot = roles[&*role.replace("_toe", "_foot")];
                let end = bvh.joints[foot].end_site.map_or(DVec3::ZERO, |e| up * e * scale);
                (foot as i32 + 1, end.as_vec3())
            }
            None => (-1, Vec3::ZERO),
        };
        skeleton.sites.push(Site { name: role.to_string(), joint, offset });
    }
    skeleton
}

/// The mirror image of a take across the YZ plane, left and right joints swapped: positions
/// `(x, y, z) → (−x, y, z)`, rotations `(x, y, z, w) → (x, −y, −z, w)`. Non-animated
/// translations keep the skeleton's own offsets so every clip shares one skeleton.
fn mirror(locals: &[(DVec3, DQuat)], pairs: &[usize], animated: &[bool], out: &mut Vec<(DVec3, DQuat)>) {
    let n = pairs.len();
    out.clear();
    out.reserve(locals.len());
    for frame in locals.chunks_exact(n) {
        for j in 0..n {
            let (t, q) = frame[pairs[j]];
            let t = if animated[j] { DVec3::new(-t.x, t.y, t.z) } else { frame[j].0 };
            out.push((t, DQuat::from_xyzw(q.x, -q.y, -q.z, q.w)));
        }
    }
}

/// Database arrays accumulated clip by clip.
#[derive(Default)]
struct Accumulator {
    num_frames: usize,
    positions: Vec<Vec3>,
    rotations: Vec<Quat>,
    velocities: Vec<Vec3>,
    angular_velocities: Vec<Vec3>,
    contacts: Vec<u8>,
    features: Vec<f32>,
    clips: Vec<Clip>,
}

impl Accumulator {
    fn rows(&mut self) -> Rows<'_> {
        Rows {
            positions: &mut self.positions,
            rotations: &mut self.rotations,
            velocities: &mut self.velocities,
            angular_velocities: &mut self.angular_velocities,
            contacts: &mut self.contacts,
            features: &mut self.features,
        }
    }
}

/// Mutable views of consecutive database frames, written by one clip.
struct Rows<'a> {
    positions: &'a mut [Vec3],
    rotations: &'a mut [Quat],
    velocities: &'a mut [Vec3],
    angular_velocities: &'a mut [Vec3],
    contacts: &'a mut [u8],
    features: &'a mut [f32],
}

impl<'a> Rows<'a> {
    /// The first `frames` frames, and the rest.
    fn split_at(self, frames: usize, joints: usize, dims: usize) -> (Rows<'a>, Rows<'a>) {
        let (p, p2) = self.positions.split_at_mut(frames * joints);
        let (r, r2) = self.rotations.split_at_mut(frames * joints);
        let (v, v2) = self.velocities.split_at_mut(frames * joints);
        let (a, a2) = self.angular_velocities.split_at_mut(frames * joints);
        let (c, c2) = self.contacts.split_at_mut(frames * 2);
        let (f, f2) = self.features.split_at_mut(frames * dims);
        (
            Rows { positions: p, rotations: r, velocities: v, angular_velocities: a, contacts: c, features: f },
            Rows { positions: p2, rotations: r2, velocities: v2, angular_velocities: a2, contacts: c2, features: f2 },
        )
    }
}

/// Per-thread temporaries of [`ClipBuilder::append`] and the resampling, kept between clips.
#[derive(Default)]
struct Scratch {
    locals: Vec<(DVec3, DQuat)>,
    mirrored: Vec<(DVec3, DQuat)>,
    world: Vec<(DVec3, DQuat)>,
    root_xz: Vec<f64>,
    facing: Vec<f64>,
    root: Vec<(DVec3, DQuat)>,
    lp: Vec<DVec3>,
    lr: Vec<DQuat>,
    contacts: Vec<[bool; 2]>,
}

/// Turns one take's local transforms into database rows.
struct ClipBuilder<'a> {
    config: &'a BuildConfig,
    fps: f64,
    parents: &'a [Option<usize>],
    hips: usize,
    forward_rest: DVec3,
    toe_sites: &'a [Option<Site>; 2],
    groups: &'a [FeatureGroup],
    num_dims: usize,
}

impl ClipBuilder<'_> {
    fn append(&self, locals: &[(DVec3, DQuat)], num_bvh_joints: usize, out: Rows, scratch: &mut Scratch) {
        let n = locals.len() / num_bvh_joints;
        let nj = num_bvh_joints;
        let dt = 1.0 / self.fps;

        // World transforms of the source joints.
        let world = &mut scratch.world;
        world.clear();
        for f in 0..n {
            for j in 0..nj {
                let (t, q) = locals[f * nj + j];
                let w = match self.parents[j] {
                    None => (t, q),
                    Some(p) => {
                        let (pt, pq) = world[f * nj + p];
                        (pt + pq * t, pq * q)
                    }
                };
                world.push(w);
            }
        }

        // Virtual root: hips projected on the floor, facing = hips forward projected; both
        // smoothed (Savitzky–Golay, cubic) so the trajectory ignores the hips' sway.
        let (root_xz, facing) = (&mut scratch.root_xz, &mut scratch.facing);
        root_xz.clear();
        facing.clear();
        let mut last = DVec3::Z;
        for f in 0..n {
            let (p, q) = world[f * nj + self.hips];
            root_xz.extend([p.x, p.z]);
            let d = q * self.forward_rest;
            last = DVec3::new(d.x, 0.0, d.z).try_normalize().unwrap_or(last);
            facing.extend([last.x, last.z]);
        }
        let window = |seconds: f64| 2 * (seconds * self.fps / 2.0).round() as usize + 1;
        savitzky_golay(root_xz, 2, window(self.config.root_position_window), 3);
        savitzky_golay(facing, 2, window(self.config.root_facing_window), 3);
        let root = &mut scratch.root;
        root.clear();
        root.extend((0..n).map(|f| {
            let (x, z) = (facing[2 * f], facing[2 * f + 1]);
            let yaw = if x == 0.0 && z == 0.0 { 0.0 } else { x.atan2(z) };
            (DVec3::new(root_xz[2 * f], 0.0, root_xz[2 * f + 1]), DQuat::from_rotation_y(yaw))
        }));
        let (root, world) = (&*root, &*world);

        // Local pose rows: joint 0 = root (world), source root re-expressed under it.
        let nd = nj + 1;
        let (lp, lr) = (&mut scratch.lp, &mut scratch.lr);
        lp.clear();
        lr.clear();
        for f in 0..n {
            let (rp, rq) = root[f];
            lp.push(rp);
            lr.push(rq);
            for j in 0..nj {
                let (t, q) = locals[f * nj + j];
                if self.parents[j].is_none() {
                    let inv = rq.conjugate();
                    lp.push(inv * (t - rp));
                    lr.push(inv * q);
                } else {
                    lp.push(t);
                    lr.push(q);
                }
            }
        }
        // Keep each joint's quaternions in one hemisphere over time so differences and later
        // interpolation take the short way.
        for f in 1..n {
            for j in 0..nd {
                if lr[f * nd + j].dot(lr[(f - 1) * nd + j]) < 0.0 {
                    lr[f * nd + j] = -lr[f * nd + j];
                }
            }
        }
        // Velocities by central differences within the clip (one-sided at its ends).
        let span = |f: usize| (f.saturating_sub(1), (f + 1).min(n - 1));
        for f in 0..n {
            let (a, b) = span(f);
            let inv_h = self.fps / (b - a) as f64;
            for j in 0..nd {
                let i = f * nd + j;
                out.positions[i] = lp[i].as_vec3();
                out.rotations[i] = lr[i].as_quat();
                out.velocities[i] = ((lp[b * nd + j] - lp[a * nd + j]) * inv_h).as_vec3();
                let dq = lr[b * nd + j] * lr[a * nd + j].conjugate();
                out.angular_velocities[i] = (scaled_axis(dq) * inv_h).as_vec3();
            }
        }

        // World position of a database joint (0 = root) or site.
        let point = |f: usize, joint: usize, offset: DVec3| -> DVec3 {
            if joint == 0 {
                root[f].0
            } else {
                let (p, q) = world[f * nj + joint - 1];
                p + q * offset
            }
        };
        let rotation = |f: usize, joint: usize| if joint == 0 { root[f].1 } else { world[f * nj + joint - 1].1 };
        let velocity = |f: usize, joint: usize, offset: DVec3| {
            let (a, b) = span(f);
            (point(b, joint, offset) - point(a, joint, offset)) / ((b - a) as f64 * dt)
        };

        // Contacts: toe speed under a threshold, then a median filter (a majority vote over
        // 2r+1 frames) to remove flicker.
        let radius = (self.config.contact_filter * self.fps).round() as usize;
        let raw = &mut scratch.contacts;
        raw.clear();
        raw.resize(n, [false; 2]);
        for (side, site) in self.toe_sites.iter().enumerate() {
            if let Some(site) = site {
                for (f, r) in raw.iter_mut().enumerate() {
                    r[side] = velocity(f, site.joint as usize, site.offset.as_dvec3()).length() < self.config.contact_speed;
                }
            }
        }
        for f in 0..n {
            let (a, b) = (f.saturating_sub(radius), (f + radius).min(n - 1));
            for side in 0..2 {
                let on = (a..=b).filter(|&g| raw[g][side]).count();
                out.contacts[2 * f + side] = (2 * on > b - a + 1) as u8;
            }
        }

        // Raw features, in the character space of the current frame.
        for (f, row) in out.features.chunks_exact_mut(self.num_dims).enumerate() {
            let (rp, rq) = root[f];
            let inv = rq.conjugate();
            for g in self.groups {
                let offset = g.axis.as_dvec3();
                for (k, &o) in g.offsets.iter().enumerate() {
                    let f2 = (f as i64 + o as i64).clamp(0, n as i64 - 1) as usize;
                    let site_offset = if g.kind == FeatureKind::Direction { DVec3::ZERO } else { offset };
                    let v = match g.kind {
                        FeatureKind::Position => inv * (point(f2, g.joint, site_offset) - rp),
                        FeatureKind::Velocity => inv * velocity(f2, g.joint, site_offset),
                        FeatureKind::Direction => inv * (rotation(f2, g.joint) * offset),
                    };
                    let d = g.first_dim + k * g.axes.num_dims();
                    match g.axes {
                        Axes::Xyz => row[d..d + 3].copy_from_slice(&[v.x as f32, v.y as f32, v.z as f32]),
                        Axes::Xz => row[d..d + 2].copy_from_slice(&[v.x as f32, v.z as f32]),
                    }
                }
            }
        }
    }
}

/// Feature groups from the config, or the default 27-float locomotion set (THESIS_NOTES §2;
/// weights from Holden's reference: feet positions 0.75, velocities 1, trajectory positions
/// 1, directions 1.5). For position/velocity groups `axis` holds the site offset of the joint.
fn feature_groups(config: &BuildConfig, skeleton: &Skeleton, roles: &HashMap<&'static str, usize>) -> Result<Vec<FeatureGroup>> {
    let t = |s: f64| (s * config.fps).round() as i32;
    let horizon = vec![t(1.0 / 3.0), t(2.0 / 3.0), t(1.0)];
    let spec = |name: &str, kind, joint: &str, offsets: Vec<i32>, weight| FeatureSpec {
        name: name.into(),
        kind,
        joint: joint.into(),
        offsets,
        axes: None,
        weight,
        axis: [0.0, 0.0, 1.0],
    };
    let defaults = vec![
        spec("left_foot_position", FeatureKind::Position, "left_foot", vec![0], 0.75),
        spec("right_foot_position", FeatureKind::Position, "right_foot", vec![0], 0.75),
        spec("left_foot_velocity", FeatureKind::Velocity, "left_foot", vec![0], 1.0),
        spec("right_foot_velocity", FeatureKind::Velocity, "right_foot", vec![0], 1.0),
        spec("hips_velocity", FeatureKind::Velocity, "hips", vec![0], 1.0),
        spec("trajectory_position", FeatureKind::Position, "root", horizon.clone(), 1.0),
        spec("trajectory_direction", FeatureKind::Direction, "root", horizon, 1.5),
    ];
    let specs = config.features.as_ref().unwrap_or(&defaults);
    if specs.is_empty() {
        return Err(Error::config("features: at least one feature group is needed"));
    }
    let mut groups = Vec::with_capacity(specs.len());
    let mut first_dim = 0;
    for s in specs {
        let (joint, site_offset) = if s.joint == "root" || s.joint == VIRTUAL_ROOT {
            (0, Vec3::ZERO)
        } else if let Some(site) = skeleton.site(&s.joint) {
            (site.joint as usize, site.offset)
        } else if ROLES.contains(&s.joint.as_str()) && !roles.contains_key(s.joint.as_str()) {
            return Err(Error::config(format!("feature '{}': the skeleton has no {} joint (set it in \"roles\")", s.name, s.joint)));
        } else {
            let j = skeleton.joint_index(&s.joint).ok_or_else(|| {
                Error::config(format!("feature '{}': '{}' is neither a role ({}), 'root', nor a joint name", s.name, s.joint, ROLES.join(", ")))
            })?;
            (j, Vec3::ZERO)
        };
        if s.offsets.is_empty() {
            return Err(Error::config(format!("feature '{}': offsets must not be empty", s.name)));
        }
        if !(s.weight > 0.0 && s.weight.is_finite()) {
            return Err(Error::config(format!("feature '{}': weight must be > 0", s.name)));
        }
        let axes = s.axes.unwrap_or(if joint == 0 { Axes::Xz } else { Axes::Xyz });
        let num_dims = s.offsets.len() * axes.num_dims();
        let axis = if s.kind == FeatureKind::Direction { Vec3::from_array(s.axis) } else { site_offset };
        groups.push(FeatureGroup {
            name: s.name.clone(),
            kind: s.kind,
            is_trajectory: joint == 0,
            axes,
            joint,
            axis,
            offsets: s.offsets.clone(),
            weight: s.weight,
            first_dim,
            num_dims,
        });
        first_dim += num_dims;
    }
    Ok(groups)
}

/// Normalizes features in place per group: subtract the per-dimension mean, divide by the
/// group's mean standard deviation over the weight (THESIS_NOTES §2). Returns (mean, scale).
fn normalize(features: &mut [f32], groups: &[FeatureGroup], num_dims: usize) -> (Vec<f32>, Vec<f32>) {
    let n = (features.len() / num_dims) as f64;
    let mut mean = vec![0.0f64; num_dims];
    let mut var = vec![0.0f64; num_dims];
    for row in features.chunks_exact(num_dims) {
        for (m, &x) in mean.iter_mut().zip(row) {
            *m += x as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n);
    for row in features.chunks_exact(num_dims) {
        for d in 0..num_dims {
            var[d] += (row[d] as f64 - mean[d]).powi(2);
        }
    }
    let mut scale = vec![1.0f32; num_dims];
    for g in groups {
        let dims = g.first_dim..g.first_dim + g.num_dims;
        let std = dims.clone().map(|d| (var[d] / n).sqrt()).sum::<f64>() / g.num_dims as f64;
        // A constant group would divide by zero; leave it unscaled (it never separates frames).
        let s = if std > 1e-8 { std / g.weight as f64 } else { 1.0 / g.weight as f64 };
        scale[dims].fill(s as f32);
    }
    let mean: Vec<f32> = mean.iter().map(|&m| m as f32).collect();
    for row in features.chunks_exact_mut(num_dims) {
        for d in 0..num_dims {
            row[d] = (row[d] - mean[d]) / scale[d];
        }
    }
    (mean, scale)
}

/// Frames whose feature window stays inside their clip.
fn validity(clips: &[Clip], groups: &[FeatureGroup], num_frames: usize) -> Vec<u8> {
    let ahead = groups.iter().flat_map(|g| g.offsets.iter()).copied().max().unwrap_or(0).max(0) as u32;
    let behind = (-groups.iter().flat_map(|g| g.offsets.iter()).copied().min().unwrap_or(0)).max(0) as u32;
    let mut valid = vec![0u8; num_frames];
    for c in clips {
        for f in c.start..c.end {
            valid[f as usize] = (f >= c.start + behind && f + ahead < c.end) as u8;
        }
    }
    valid
}

/// Longest run of glitched frames [`repair_spikes`] bridges.
const MAX_SPIKE_FRAMES: usize = 3;
/// A spike leaves by more than this (rad) …
const SPIKE_DEPARTURE: f64 = 0.5;
/// … and the frames on either side of it agree within this per bridged frame (rad).
const SPIKE_BRIDGE_PER_FRAME: f64 = 0.1;

/// Repairs single- to three-frame rotation glitches of optical mocap (a joint flips to another
/// Euler solution or to the rest pose and back: CMU 16_15 starts with the humerus at rest,
/// 16_16 flips a thumb for two frames). A glitch *leaves and comes back*: the frames on either
/// side agree while the frames between are far from both — which real fast motion never does,
/// as it does not return. Glitched frames are replaced by slerp across them (or by the first
/// good frame at a take's start). Returns the repaired (joint, frame) pairs.
fn repair_spikes(locals: &mut [(DVec3, DQuat)], num_joints: usize) -> Vec<(usize, usize)> {
    let n = locals.len() / num_joints;
    let angle = |a: DQuat, b: DQuat| 2.0 * a.dot(b).abs().min(1.0).acos();
    let mut repaired = Vec::new();
    for j in 0..num_joints {
        let q = |f: usize, l: &[(DVec3, DQuat)]| l[f * num_joints + j].1;
        // A glitched start: frames 0..k far from frame k, which agrees with frame k+1.
        for k in 1..=MAX_SPIKE_FRAMES.min(n.saturating_sub(2)) {
            let good = q(k, locals);
            if angle(good, q(k + 1, locals)) < SPIKE_BRIDGE_PER_FRAME && (0..k).all(|f| angle(q(f, locals), good) > SPIKE_DEPARTURE) {
                for f in 0..k {
                    locals[f * num_joints + j].1 = good;
                    repaired.push((j, f));
                }
                break;
            }
        }
        let mut f = 1;
        while f + 1 < n {
            let before = q(f - 1, locals);
            if angle(q(f, locals), before) > SPIKE_DEPARTURE {
                for len in 1..=MAX_SPIKE_FRAMES {
                    let after_frame = f + len;
                    if after_frame >= n {
                        break;
                    }
                    let after = q(after_frame, locals);
                    let bridged = angle(before, after) < SPIKE_BRIDGE_PER_FRAME * (len + 1) as f64;
                    if bridged && (f..after_frame).all(|g| angle(q(g, locals), before) > SPIKE_DEPARTURE && angle(q(g, locals), after) > SPIKE_DEPARTURE) {
                        for g in f..after_frame {
                            let u = (g + 1 - f) as f64 / (len + 1) as f64;
                            locals[g * num_joints + j].1 = before.slerp(after, u);
                            repaired.push((j, g));
                        }
                        f = after_frame;
                        break;
                    }
                }
            }
            f += 1;
        }
    }
    repaired
}

/// Rotation vector (axis × angle) of a unit quaternion, taking the short way. Same value as
/// `to_scaled_axis` but without `atan2` for the small rotations between nearby frames:
/// angle = 2·atan(x), x = |v|/w, by its Taylor series when x < 0.1 (truncation error
/// < x¹²/13 < 1e-13 relative, far below f32 storage precision).
fn scaled_axis(q: DQuat) -> DVec3 {
    let q = if q.w < 0.0 { -q } else { q };
    let v = DVec3::new(q.x, q.y, q.z);
    let s = v.length();
    if s < 1e-12 {
        return 2.0 * v;
    }
    let inv_w = 1.0 / q.w;
    let x = s * inv_w;
    if x < 0.1 {
        let x2 = x * x;
        // 2·atan(x)/s = (2/w)·atan(x)/x
        let series = 1.0 - x2 * (1.0 / 3.0 - x2 * (1.0 / 5.0 - x2 * (1.0 / 7.0 - x2 * (1.0 / 9.0 - x2 * (1.0 / 11.0)))));
        v * (2.0 * inv_w * series)
    } else {
        v * (2.0 * s.atan2(q.w) / s)
    }
}

fn coalesce(mut ranges: Vec<(u32, u32)>) -> Vec<(u32, u32)> {
    ranges.sort_unstable();
    let mut out: Vec<(u32, u32)> = Vec::with_capacity(ranges.len());
    for (s, e) in ranges {
        match out.last_mut() {
            Some(last) if s <= last.1 => last.1 = last.1.max(e),
            _ => out.push((s, e)),
        }
    }
    out
}

fn ensure_unique_names(clips: &mut [Clip]) {
    let mut seen: HashMap<String, usize> = HashMap::new();
    for c in clips.iter_mut() {
        let n = seen.entry(c.name.clone()).or_insert(0);
        *n += 1;
        if *n > 1 {
            c.name = format!("{} #{}", c.name, n);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spikes_that_leave_and_return_are_repaired_and_fast_motion_is_not() {
        let q = |a: f64| (DVec3::ZERO, DQuat::from_rotation_z(a));
        // Smooth motion at 0.05 rad/frame, a 2-frame flip at 10, a bad first frame.
        let mut frames: Vec<(DVec3, DQuat)> = (0..30).map(|f| q(0.05 * f as f64)).collect();
        frames[0] = q(2.5);
        frames[10] = q(3.0);
        frames[11] = q(-2.0);
        let repaired = repair_spikes(&mut frames, 1);
        assert_eq!(repaired, vec![(0, 0), (0, 10), (0, 11)]);
        for (f, (_, r)) in frames.iter().enumerate() {
            let expected = DQuat::from_rotation_z(0.05 * if f == 0 { 1.0 } else { f as f64 });
            assert!(r.angle_between(expected) < 1e-6, "frame {f}");
        }
        // A fast, real swing (0.8 rad/frame that does not come back) is left alone.
        let mut swing: Vec<(DVec3, DQuat)> = (0..10).map(|f| q(if f < 5 { 0.0 } else { 0.8 * (f - 4) as f64 })).collect();
        assert!(repair_spikes(&mut swing, 1).is_empty());
    }

    #[test]
    fn scaled_axis_is_exact_for_small_and_large_rotations() {
        for angle in [0.0, 1e-9, 1e-4, 0.05, 0.19, 0.21, 1.0, 3.0, 6.0] {
            for axis in [DVec3::X, DVec3::new(1.0, -2.0, 0.5).normalize()] {
                let q = DQuat::from_axis_angle(axis, angle);
                // The short way round: angles past π come back as 2π − angle about −axis.
                let short = if angle > std::f64::consts::PI { angle - std::f64::consts::TAU } else { angle };
                let expected = axis * short;
                assert!((scaled_axis(q) - expected).length() < 1e-12, "angle {angle}");
                assert!((scaled_axis(-q) - expected).length() < 1e-12, "angle {angle}, negated");
            }
        }
    }
}
