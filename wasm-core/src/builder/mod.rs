//! Building a [`Database`] from BVH takes (docs/method.md §1–2), stage by stage:
//! 1. [`skeleton`]: the reference take's roles and skeleton; every take shares its topology;
//! 2. [`take`]: per take, unit scale, up axis, frame range, then resampling to the database
//!    rate with bone lengths normalized onto the reference skeleton;
//! 3. [`repair`]: 1–3-frame rotation glitches of the capture bridged;
//! 4. [`mirror`]: optional mirrored copy of each take;
//! 5. [`clip`]: world transforms, the virtual root ([`root`]), local rows and velocities,
//!    [`contacts`], raw features;
//! 6. [`features`]: normalization and validity; clips and tags assembled here.
//!
//! All arithmetic is f64 until the arrays are stored as f32, so the database's forward
//! kinematics reproduces the source within ~1e-6 m.

mod clip;
mod contacts;
mod features;
mod mirror;
mod poses;
mod repair;
mod root;
mod rows;
mod skeleton;
mod take;

use crate::bvh::Bvh;
use crate::config::BuildConfig;
use crate::database::{Clip, Database, Tag};
use crate::error::{Error, Result};
use crate::roles::Role;
use clip::{ClipBuilder, Scratch};
use rows::{Accumulator, Rows};
use skeleton::{check_topology, Reference};
use std::collections::{BTreeMap, HashMap};
use take::Take;

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

fn base_name(path: &str) -> &str {
    path.rsplit(['/', '\\']).next().unwrap_or(path)
}

/// Builds one database from `sources` (at least one) as `config` says.
///
/// # Errors
/// No sources, a source whose skeleton differs from the reference's, roles that cannot be
/// found, a bad feature or clip spec, or no take long enough to build from.
pub fn build(config: &BuildConfig, sources: &[Source]) -> Result<BuildOutput> {
    if sources.is_empty() {
        return Err(Error::config("no BVH files to build from"));
    }
    config.validate()?;
    let mut warnings = Vec::new();
    let reference_index = match &config.reference {
        Some(r) => sources
            .iter()
            .position(|s| crate::config::wildcard_match(r, base_name(&s.name)))
            .ok_or_else(|| Error::config(format!("reference '{r}' is not one of the source files")))?,
        None => 0,
    };
    let ref_source = &sources[reference_index];
    for s in sources {
        check_topology(ref_source, s)?;
    }
    let reference = Reference::new(config, ref_source)?;

    // Per-take unit scale and axis conversion, then the reference's rest skeleton (metres, Y up).
    let takes: Vec<Take> = sources.iter().map(|s| Take::new(s, config, &reference, &mut warnings)).collect::<Result<_>>()?;
    let ref_take = &takes[reference_index];
    let ref_offsets = ref_take.offsets.clone();
    let ref_leg = reference.leg_length(&ref_offsets);
    let skeleton = reference.database_skeleton(&ref_offsets, &ref_source.bvh, ref_take.scale, ref_take.up);
    let toe_sites = [skeleton.site("left_toe").cloned(), skeleton.site("right_toe").cloned()];
    if !reference.roles.contains(Role::LeftToe) {
        warnings.push("no toe joints found: foot contacts use the feet's end sites (or ankles)".into());
    }

    let groups = features::feature_groups(config, &skeleton)?;
    let num_dims: usize = groups.iter().map(|g| g.num_dims).sum();
    let fps = config.fps;
    // Every take's row count is known before any work, so the output arrays are allocated
    // once and split into per-clip slices.
    let mut plans = Vec::new();
    let mut num_frames = 0usize;
    let mut short = Vec::new();
    for (t, take) in takes.iter().enumerate() {
        let n = take.num_out(fps).ok_or_else(|| {
            Error::config(format!("{}: {} frames at {} fps resample to more than {} frames at {fps} fps", sources[t].name, take.frames.1 - take.frames.0, take.source_fps, crate::limits::MAX_FRAMES))
        })?;
        if n < 2 {
            warnings.push(format!("{}: skipped, {n} frame(s) at {fps} fps (2 needed)", sources[t].name));
            short.push(format!("{} ({n})", sources[t].name));
            continue;
        }
        for mirrored in [false, true].into_iter().take(if take.mirror { 2 } else { 1 }) {
            plans.push((t, mirrored, num_frames, n));
            num_frames = num_frames.saturating_add(n);
        }
    }
    if num_frames == 0 {
        return Err(Error::config(format!("no frames to build from: every take is shorter than 2 frames at {fps} fps: {}", short.join(", "))));
    }
    let nd = reference.num_joints() + 1;
    // Refuse before allocating: the output is num_frames × (joints, dims) and must fit (on
    // wasm32 too, where usize is 32 bits).
    crate::limits::check_database_size(num_frames, nd, num_dims).map_err(Error::config)?;
    let mut out = Accumulator::new(num_frames, nd, num_dims);
    let clip_builder = ClipBuilder {
        config,
        fps,
        parents: &reference.parents,
        hips: reference.roles[Role::Hips],
        forward_rest: reference.forward_rest(&ref_offsets),
        toe_sites: &toe_sites,
        groups: &groups,
        num_dims,
    };
    // Root motion of a take with other leg lengths is scaled by the leg ratio; a take whose legs
    // have no length (a degenerate rest pose) cannot be compared: its root motion stays as is.
    let mut root_scales = Vec::with_capacity(takes.len());
    for (t, take) in takes.iter().enumerate() {
        let leg = reference.leg_length(&take.offsets);
        let scale = ref_leg / leg;
        root_scales.push(if t == reference_index {
            1.0
        } else if scale.is_finite() && scale > 0.0 && leg > 1e-6 {
            scale
        } else {
            warnings.push(format!("{}: legs of length {leg:.3} m in the rest pose; root motion not rescaled to the reference", sources[t].name));
            1.0
        });
    }
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
    let pool = std::sync::Mutex::new(Vec::<Scratch>::new());
    let spike_warnings = std::sync::Mutex::new(Vec::<String>::new());
    crate::parallel::for_each(jobs, |(t, rows)| {
        let mut scratch = pool.lock().unwrap().pop().unwrap_or_default();
        let take = &takes[t];
        let mut locals = std::mem::take(&mut scratch.locals);
        take.resample(&sources[t].bvh, fps, &ref_offsets, &reference.animated_translation, root_scales[t], t == reference_index, &mut locals);
        let repaired = if config.repair_spikes { repair::repair_spikes(&mut locals) } else { Vec::new() };
        if !repaired.is_empty() {
            let list: Vec<String> = repaired.iter().take(5).map(|&(j, f)| format!("{} at frame {f}", reference.names[j])).collect();
            let more = if repaired.len() > 5 { format!(" and {} more", repaired.len() - 5) } else { String::new() };
            spike_warnings.lock().unwrap().push(format!("{}: repaired {} rotation spike(s): {}{more}", sources[t].name, repaired.len(), list.join(", ")));
        }
        let mut mirrored = std::mem::take(&mut scratch.mirrored);
        for (i, rows) in rows.into_iter().enumerate() {
            if i == 0 {
                clip_builder.append(&locals, rows, &mut scratch);
            } else {
                mirror::mirror(&locals, &reference.pairs, &reference.animated_translation, &mut mirrored);
                clip_builder.append(&mirrored, rows, &mut scratch);
            }
        }
        (scratch.locals, scratch.mirrored) = (locals, mirrored);
        pool.lock().unwrap().push(scratch);
    });
    let mut spike_warnings = spike_warnings.into_inner().unwrap();
    spike_warnings.sort();
    warnings.extend(spike_warnings);

    let mut clips = Vec::new();
    let mut tag_ranges: BTreeMap<String, Vec<(u32, u32)>> = BTreeMap::new();
    for &(t, mirrored, start, num_out) in &plans {
        let (take, source) = (&takes[t], &sources[t]);
        let start = start as u32;
        let name = if mirrored { format!("{} (mirror)", take.clip_name) } else { take.clip_name.clone() };
        clips.push(Clip {
            name,
            source: base_name(&source.name).to_string(),
            start,
            end: start + num_out as u32,
            mirrored,
            source_fps: take.source_fps,
            scale: take.scale as f32,
            root_scale: root_scales[t] as f32,
            source_start: take.frames.0 as u32,
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
    ensure_unique_names(&mut clips);

    let (feature_mean, feature_scale) = features::normalize(&mut out.features, &groups, num_dims);
    let valid = features::validity(&clips, &groups, out.num_frames);
    let tags = tag_ranges.into_iter().map(|(name, ranges)| Tag { name, ranges: coalesce(ranges) }).collect();
    let contact_share = |side: usize| out.contacts.iter().skip(side).step_by(2).filter(|&&c| c != 0).count() as f64 / out.num_frames as f64;
    if contact_share(0) < 0.05 || contact_share(1) < 0.05 {
        warnings.push(format!(
            "feet are in contact only {:.0}% / {:.0}% of frames (left/right): check the scale, the floor height and contact_speed",
            100.0 * contact_share(0),
            100.0 * contact_share(1)
        ));
    }
    let mut database = Database {
        skeleton,
        fps: fps as f32,
        num_frames: out.num_frames,
        clips,
        tags,
        local_positions: out.positions,
        local_rotations: out.rotations,
        local_velocities: Vec::new(),
        local_angular_velocities: Vec::new(),
        contacts: out.contacts,
        groups,
        feature_mean,
        feature_scale,
        features: out.features,
        valid,
    };
    database.compute_velocities();
    Ok(BuildOutput { database, warnings })
}

/// Sorted, merged `[start, end)` ranges.
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

/// Clip names made unique with a ` #2`, ` #3`… suffix.
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
