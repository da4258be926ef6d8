//! Building a [`Database`] from BVH takes (docs/method.md §1–2), stage by stage:
//! 1. [`skeleton`]: the reference take's roles (names checked against topology and geometry,
//!    `crate::roles`) and skeleton; [`sample`] gives the poses they are measured on;
//! 2. [`take`]: per take, unit scale and up axis measured on its motion, frame range, then
//!    resampling to the database rate — with bone lengths normalized onto the reference
//!    skeleton, or, for another skeleton topology, [`retarget`]ed onto it;
//! 3. [`repair`]: 1–3-frame rotation glitches of the capture bridged;
//! 4. [`reverse`]: optional time-reversed copies of each take;
//! 5. [`clip`]: world transforms, the virtual root ([`root`]), local rows, [`contacts`]; a
//!    mirrored copy is its original's rows mirrored (`crate::mirror`);
//! 6. clips and tags assembled here; rotations quantized as `.mmdb` stores them, then what a
//!    loader derives from the rows — features (`crate::pose_features`); velocities are derived
//!    when a frame is played (`Database::frame_velocities`) — and [`features`]: normalization and validity.
//!
//! All arithmetic is f64 until the arrays are stored as f32, so the database's forward
//! kinematics reproduces the source within ~1e-6 m.

mod clip;
mod contacts;
mod features;
mod poses;
mod repair;
pub mod retarget;
mod reverse;
mod root;
mod rows;
mod sample;
mod skeleton;
mod tags;
mod take;

use crate::bvh::Bvh;
use crate::config::BuildConfig;
use crate::database::{Clip, Database, Tag};
use crate::error::{Error, Result};
use crate::format::codec;
use crate::roles::Role;
use clip::{ClipBuilder, Scratch};
use glam::{Quat, Vec3};
use poses::Poses;
use retarget::{RetargetReport, Retargeter, Rig};
use rows::{Accumulator, Rows};
use skeleton::{same_topology, Reference};
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
    /// Takes of another skeleton retargeted onto the reference one: (source name, report).
    pub retargeted: Vec<(String, RetargetReport)>,
    /// What the build was estimated to need before it started (checked against
    /// [`crate::limits::MAX_BUILD_BYTES`]).
    pub footprint: crate::limits::BuildFootprint,
}

impl BuildOutput {
    /// One line per retargeted take: leg ratio and end-effector errors.
    pub fn retarget_notes(&self) -> Vec<String> {
        self.retargeted
            .iter()
            .map(|(name, r)| {
                let missing = if r.unmapped.is_empty() { String::new() } else { format!("; at rest (no source joint): {}", r.unmapped.join(", ")) };
                format!(
                    "{name}: retargeted onto the reference skeleton (legs ×{:.3}, hips {:+.1} cm); error vs the scaled source, mean / max: ankles {:.1} / {:.1} cm, toes {:.1} / {:.1} cm, hands {:.1} / {:.1} cm, head {:.1} / {:.1} cm{missing}",
                    r.leg_ratio,
                    100.0 * r.floor_shift,
                    100.0 * r.feet.mean,
                    100.0 * r.feet.max,
                    100.0 * r.toes.mean,
                    100.0 * r.toes.max,
                    100.0 * r.hands.mean,
                    100.0 * r.hands.max,
                    100.0 * r.head.mean,
                    100.0 * r.head.max
                )
            })
            .collect()
    }
}

/// Name of joint 0 in every database.
pub const VIRTUAL_ROOT: &str = "VirtualRoot";

fn base_name(path: &str) -> &str {
    path.rsplit(['/', '\\']).next().unwrap_or(path)
}

/// One clip to build: a take, mirrored and/or reversed.
#[derive(Clone, Copy)]
struct Plan {
    take: usize,
    mirrored: bool,
    reversed: bool,
    start: usize,
    frames: usize,
}

/// Builds one database from `sources` (at least one) as `config` says.
///
/// Everything that could make the result unusable is checked before the arrays are allocated
/// (`crate::limits`): the frame count and size, the feature dimensions, the memory the build
/// will need ([`crate::limits::BuildFootprint`]), how far each take reaches once scaled. At the
/// end the database's values go through the loader's own checks
/// ([`crate::format::check_database`]), so a database `build` returns always loads.
///
/// # Errors
/// No sources, a skeleton that is not a humanoid (the message says which part is missing),
/// roles that cannot be found, a bad feature or clip spec, no take long enough to build from,
/// or a limit above exceeded (the message has the number and the limit).
pub fn build(config: &BuildConfig, sources: &[Source]) -> Result<BuildOutput> {
    if sources.is_empty() {
        return Err(Error::config("no BVH files to build from"));
    }
    config.validate()?;
    let mut warnings = Vec::new();
    let reference_index = match &config.reference {
        Some(r) => sources
            .iter()
            .position(|s| crate::config::source_matches(r, base_name(&s.name)))
            .ok_or_else(|| Error::config(format!("reference '{r}' is not one of the source files")))?,
        None => 0,
    };
    let ref_source = &sources[reference_index];
    let reference = Reference::new(config, ref_source, Take::frame_range(ref_source, config)?, true)?;
    // Each take's own skeleton when it is not the reference's topology (then retargeted).
    let mut foreign: Vec<Option<Reference>> = Vec::with_capacity(sources.len());
    for s in sources {
        foreign.push(if same_topology(ref_source, s) {
            None
        } else {
            Some(Reference::new(config, s, Take::frame_range(s, config)?, false)?)
        });
    }
    let rig_of = |t: usize| foreign[t].as_ref().unwrap_or(&reference);

    // Per-take unit scale and axis conversion, then the reference's rest skeleton (metres, Y up).
    let takes: Vec<Take> = sources
        .iter()
        .enumerate()
        .map(|(t, s)| Take::new(s, config, &rig_of(t).roles, &mut warnings))
        .collect::<Result<_>>()?;
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
    crate::limits::check_feature_dims(num_dims).map_err(|m| Error::config(format!("features: {m}")))?;
    let fps = config.fps;
    // Every take's row count is known before any work, so the output arrays are allocated
    // once and split into per-clip slices.
    let mut plans = Vec::new();
    let mut num_frames = 0usize;
    let mut short = Vec::new();
    for (t, take) in takes.iter().enumerate() {
        let n = take.num_out(fps).ok_or_else(|| {
            Error::config(format!(
                "{}: {} frames at {} fps resample to more than {} frames at {fps} fps",
                sources[t].name,
                take.frames.1 - take.frames.0,
                take.source_fps,
                crate::limits::MAX_FRAMES
            ))
        })?;
        if n < 2 {
            warnings.push(format!("{}: skipped, {n} frame(s) at {fps} fps (2 needed)", sources[t].name));
            short.push(format!("{} ({n})", sources[t].name));
            continue;
        }
        for reversed in [false, true].into_iter().take(if take.reverse { 2 } else { 1 }) {
            for mirrored in [false, true].into_iter().take(if take.mirror { 2 } else { 1 }) {
                plans.push(Plan { take: t, mirrored, reversed, start: num_frames, frames: n });
                num_frames = num_frames.saturating_add(n);
            }
        }
    }
    if num_frames == 0 {
        return Err(Error::config(format!(
            "no frames to build from: every take is shorter than 2 frames at {fps} fps: {}",
            short.join(", ")
        )));
    }
    let nd = reference.num_joints() + 1;
    // Refuse before allocating: the output is num_frames × (joints, dims) and must fit (on
    // wasm32 too, where usize is 32 bits).
    crate::limits::check_database_size(num_frames, nd, num_dims).map_err(Error::config)?;
    // Root motion of a take with other leg lengths is scaled by the leg ratio (a take of another
    // skeleton: its own legs); a take whose legs have no length (a degenerate rest pose) or
    // differ more than `MAX_ROOT_SCALE`-fold cannot be compared: its root motion stays as is.
    let mut root_scales = Vec::with_capacity(takes.len());
    let max_root_scale = crate::limits::MAX_ROOT_SCALE as f64;
    for (t, take) in takes.iter().enumerate() {
        let leg = rig_of(t).leg_length(&take.offsets);
        let scale = ref_leg / leg;
        root_scales.push(if t == reference_index {
            1.0
        } else if scale.is_finite() && (1.0 / max_root_scale..=max_root_scale).contains(&scale) && leg > 1e-6 {
            scale
        } else {
            warnings.push(format!(
                "{}: legs of length {leg:.3} m in the rest pose; root motion not rescaled to the reference",
                sources[t].name
            ));
            1.0
        });
    }
    for (t, take) in takes.iter().enumerate() {
        take.check_reach(&sources[t].name, root_scales[t])?;
    }
    let footprint = crate::limits::BuildFootprint {
        source_bytes: sources.iter().map(|s| s.bvh.heap_bytes() as u64).sum(),
        frames: num_frames as u64,
        joints: nd as u64,
        dims: num_dims as u64,
        take_frames: plans.iter().map(|p| p.frames as u64).max().unwrap_or(0),
        take_joints: plans
            .iter()
            .map(|p| {
                (reference.num_joints() + foreign[p.take].as_ref().map_or(0, |_| sources[p.take].bvh.joints.len()))
                    as u64
            })
            .max()
            .unwrap_or(0),
        take_copies: takes.iter().map(|t| t.mirror as u64 + t.reverse as u64).max().unwrap_or(0),
        name_bytes: plans.iter().map(|p| 3 * sources[p.take].name.len() as u64 + 64).sum::<u64>()
            + skeleton.names.iter().map(|n| n.len() as u64 + 16).sum::<u64>(),
    };
    footprint.check().map_err(Error::config)?;
    let mut out = Accumulator::new(num_frames, nd).map_err(Error::config)?;
    let clip_builder = ClipBuilder {
        config,
        fps,
        parents: &reference.parents,
        hips: reference.roles[Role::Hips],
        forward_rest: reference.forward_rest(&ref_offsets),
        toe_sites: &toe_sites,
    };
    let target_rig = Rig {
        parents: &reference.parents,
        roles: &reference.roles,
        offsets: &ref_offsets,
        end_sites: &ref_take.end_sites,
    };
    // Retargeted takes stand their planted toes at the reference take's planted toe height.
    let toe_floor = if foreign.iter().any(Option::is_some) {
        let mut poses = Poses::default();
        ref_take.resample(&ref_source.bvh, fps, &ref_offsets, &reference.animated_translation, 1.0, true, &mut poses);
        retarget::toe_floor_of(&poses, &target_rig)
    } else {
        None
    };
    // A take's variants (mirrored, reversed) are one job: they reuse the resampled take.
    let mut jobs: Vec<(usize, Vec<(Plan, Rows)>)> = Vec::new();
    let mut rest_rows = out.rows();
    for &plan in &plans {
        let (rows, tail) = rest_rows.split_at(plan.frames, nd);
        rest_rows = tail;
        match jobs.last_mut() {
            Some((last, list)) if *last == plan.take => list.push((plan, rows)),
            _ => jobs.push((plan.take, vec![(plan, rows)])),
        }
    }
    // Database joints: 0 is the virtual root (animated, its own mirror), then the BVH joints.
    let db_mirror = &skeleton.mirror;
    let db_animated: Vec<bool> = std::iter::once(true).chain(reference.animated_translation.iter().copied()).collect();
    let pool = std::sync::Mutex::new(Vec::<Scratch>::new());
    let job_notes = std::sync::Mutex::new((Vec::<String>::new(), Vec::<(usize, RetargetReport)>::new()));
    crate::parallel::for_each(jobs, |(t, variants)| {
        let mut scratch = pool.lock().unwrap().pop().unwrap_or_default();
        let take = &takes[t];
        let mut locals = std::mem::take(&mut scratch.locals);
        match &foreign[t] {
            Some(own) => {
                let mut source = Poses::default();
                take.resample(&sources[t].bvh, fps, &take.offsets, &own.animated_translation, 1.0, true, &mut source);
                let rig = Rig {
                    parents: &own.parents,
                    roles: &own.roles,
                    offsets: &take.offsets,
                    end_sites: &take.end_sites,
                };
                let report = Retargeter::new(rig, target_rig, root_scales[t]).apply(&source, toe_floor, &mut locals);
                job_notes.lock().unwrap().1.push((t, report));
            }
            None => take.resample(
                &sources[t].bvh,
                fps,
                &ref_offsets,
                &reference.animated_translation,
                root_scales[t],
                t == reference_index,
                &mut locals,
            ),
        }
        let repaired = if config.repair_spikes { repair::repair_spikes(&mut locals) } else { Vec::new() };
        if !repaired.is_empty() {
            let names = &rig_of(t).names;
            let names = if foreign[t].is_some() { &reference.names } else { names };
            let list: Vec<String> =
                repaired.iter().take(5).map(|&(j, f)| format!("{} at frame {f}", names[j])).collect();
            let more = if repaired.len() > 5 { format!(" and {} more", repaired.len() - 5) } else { String::new() };
            job_notes.lock().unwrap().0.push(format!(
                "{}: repaired {} rotation spike(s): {}{more}",
                sources[t].name,
                repaired.len(),
                list.join(", ")
            ));
        }
        let mut reversed = std::mem::take(&mut scratch.reversed);
        // The originals' rows, by `reversed`: a mirrored copy is made from them, exactly
        // (`crate::mirror`), so a `.mmdb` file can carry the pair once.
        let mut originals: Vec<(bool, Rows)> = Vec::new();
        for (plan, mut rows) in variants {
            if plan.mirrored {
                if let Some((_, original)) = originals.iter().find(|(r, _)| *r == plan.reversed) {
                    crate::mirror::mirror_frames(
                        db_mirror,
                        &db_animated,
                        &skeleton.offsets,
                        (original.positions, original.rotations, original.contacts),
                        (rows.positions, rows.rotations, rows.contacts),
                    );
                    continue;
                }
            }
            let base = if plan.reversed {
                reverse::reverse(&locals, &mut reversed);
                &reversed
            } else {
                &locals
            };
            clip_builder.append(base, rows.reborrow(), &mut scratch, take.root_position_window);
            if !plan.mirrored {
                originals.push((plan.reversed, rows));
            }
        }
        (scratch.locals, scratch.reversed) = (locals, reversed);
        pool.lock().unwrap().push(scratch);
    });
    // The working copies go before the velocities are added (the memory estimate's peaks).
    drop(pool);
    let (mut spike_warnings, mut reports) = job_notes.into_inner().unwrap();
    spike_warnings.sort();
    warnings.extend(spike_warnings);
    reports.sort_by_key(|(t, _)| *t);
    let retargeted = reports.into_iter().map(|(t, r)| (sources[t].name.clone(), r)).collect();

    let mut clips = Vec::new();
    let mut tag_ranges: BTreeMap<String, Vec<(u32, u32)>> = BTreeMap::new();
    for plan in &plans {
        let (take, source) = (&takes[plan.take], &sources[plan.take]);
        let (start, num_out) = (plan.start as u32, plan.frames);
        let mut name = take.clip_name.clone();
        if plan.reversed {
            name += " (reversed)";
        }
        if plan.mirrored {
            name += " (mirror)";
        }
        clips.push(Clip {
            name,
            source: base_name(&source.name).to_string(),
            start,
            end: start + num_out as u32,
            mirrored: plan.mirrored,
            source_fps: take.source_fps,
            scale: take.scale as f32,
            root_scale: root_scales[plan.take] as f32,
            // A reversed copy (named "… (reversed)") was sampled over the same source window,
            // backward: its frame `k` is the forward clip's frame `n − 1 − k`.
            source_start: take.frames.0 as u32,
        });
        // Tags: whole clip, then source-frame ranges mapped to database frames (mirrored in
        // time for a reversed copy).
        let to_db = |s: usize| {
            ((s.saturating_sub(take.frames.0)) as f64 * fps / take.source_fps).round().min(num_out as f64) as u32
        };
        let whole = if plan.reversed { take.reverse_tags.as_ref().unwrap_or(&take.tags) } else { &take.tags };
        for tag in whole {
            tag_ranges.entry(tag.clone()).or_default().push((start, start + num_out as u32));
        }
        for r in &take.ranges {
            let (mut s, mut e) = (to_db(r.frames[0]), to_db(r.frames[1]));
            if plan.reversed {
                (s, e) = (num_out as u32 - e, num_out as u32 - s);
            }
            if e > s {
                for tag in &r.tags {
                    tag_ranges.entry(tag.clone()).or_default().push((start + s, start + e));
                }
            }
        }
    }
    ensure_unique_names(&mut clips);
    if config.motion_tags {
        for clip in &clips {
            let (start, n) = (clip.start as usize, (clip.end - clip.start) as usize);
            let ranges = tags::motion_tags(n, fps as f32, |f| {
                (out.positions[(start + f) * nd], out.rotations[(start + f) * nd])
            });
            for (name, ranges) in tags::MOTION_TAGS.iter().zip(ranges).filter(|(_, r)| !r.is_empty()) {
                let list = tag_ranges.entry(name.to_string()).or_default();
                list.extend(ranges.into_iter().map(|(s, e)| (s + clip.start, e + clip.start)));
            }
        }
    }

    // Rotations as the file stores them (16 bits a component), and the features a loader derives
    // from them: a database built here and one read from its file are the same bits.
    let mut local_rotations = out.rotations;
    for q in &mut local_rotations {
        *q = codec::dequantize_rotation(codec::quantize_rotation(*q));
    }
    let mut features = crate::pose_features::pose_features(
        &skeleton.parents,
        fps as f32,
        &clips,
        &groups,
        num_dims,
        &out.positions,
        &local_rotations,
    );
    let (feature_mean, feature_scale) = features::normalize(&mut features, &groups, num_dims);
    let valid = features::validity(&clips, &groups, out.num_frames);
    let tags = tag_ranges.into_iter().map(|(name, ranges)| Tag { name, ranges: coalesce(ranges) }).collect();
    let contact_share = |side: usize| {
        out.contacts.iter().skip(side).step_by(2).filter(|&&c| c != 0).count() as f64 / out.num_frames as f64
    };
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
        local_rotations,
        contacts: out.contacts,
        groups,
        feature_mean,
        feature_scale,
        features,
        valid,
        part: None,
        velocities: Default::default(),
    };
    if let Some(ratio) = config.min_head_height {
        let (excluded, searchable, crouched) = exclude_low_heads(&mut database, ratio as f32);
        if searchable == 0 {
            return Err(Error::config(format!("min_head_height {ratio}: no frame has its head that high (the head role is missing or the data never stands)")));
        }
        warnings.push(format!(
            "min_head_height {ratio}: {excluded} frames with the head lower are not searched ({searchable} are, {crouched} of them the crouch clips' low frames, tagged `{}`)",
            crate::tag_query::CROUCHED_TAG
        ));
    }
    // The loader's own value checks: whatever got past the limits above, `build` never returns
    // a database its loader would refuse.
    crate::format::check_database(&database)
        .map_err(|e| Error::config(format!("the built database would not load: {e}")))?;
    Ok(BuildOutput { database, warnings, retargeted, footprint })
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

/// `min_head_height`: frames whose head is below `ratio` of the rest head height are not
/// searched — except in clips tagged [`crate::tag_query::CROUCH_TAG`] (crouch data), whose low
/// frames stay searchable and are tagged [`crate::tag_query::CROUCHED_TAG`]: the runtime searches
/// them only while its character crouches. Returns (frames excluded, frames searchable, of them
/// crouched).
fn exclude_low_heads(db: &mut Database, ratio: f32) -> (usize, usize, usize) {
    let (Some(head), Some(standing)) = (db.skeleton.site_joint("head"), db.rest_head_height()) else {
        return (0, 0, 0);
    };
    let limit = ratio * standing;
    let j = db.num_joints();
    let (mut p, mut r) = (vec![Vec3::ZERO; j], vec![Quat::IDENTITY; j]);
    let crouch: Vec<(u32, u32)> =
        db.tags.iter().find(|t| t.name == crate::tag_query::CROUCH_TAG).map_or(Vec::new(), |t| t.ranges.clone());
    let mut crouched: Vec<(u32, u32)> = Vec::new();
    let mut excluded = 0;
    for f in 0..db.num_frames {
        if db.valid[f] == 0 {
            continue;
        }
        db.forward_kinematics(f, &mut p, &mut r);
        // The virtual root stands on the floor: world height is height above it.
        if p[head].y < limit {
            let frame = f as u32;
            if crouch.iter().any(|&(s, e)| (s..e).contains(&frame)) {
                match crouched.last_mut() {
                    Some(last) if last.1 == frame => last.1 = frame + 1,
                    _ => crouched.push((frame, frame + 1)),
                }
            } else {
                db.valid[f] = 0;
                excluded += 1;
            }
        }
    }
    let low = crouched.iter().map(|&(s, e)| (e - s) as usize).sum();
    if !crouched.is_empty() {
        db.tags.push(Tag { name: crate::tag_query::CROUCHED_TAG.to_string(), ranges: crouched });
    }
    (excluded, db.valid.iter().filter(|&&v| v != 0).count(), low)
}
