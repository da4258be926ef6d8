//! One source take as it will be resampled: unit scale and up axis measured on its motion, frame
//! range, rate, mirroring, reversal and tags resolved from the config (docs/database.md); then
//! its local transforms resampled to the database rate.

use super::poses::Poses;
use super::sample::{median, sample_poses};
use super::{base_name, Source};
use crate::bvh::Bvh;
use crate::config::{AutoScale, BuildConfig, RangeSpec, Scale, UpAxis};
use crate::error::{Error, Result};
use crate::roles::{Role, Roles, ShapePose};
use glam::{DQuat, DVec3};

pub struct Take {
    pub clip_name: String,
    pub scale: f64,
    /// Rotation taking source axes to Y-up (identity for Y-up sources).
    pub up: DQuat,
    pub source_fps: f64,
    /// Source frames `[start, end)`.
    pub frames: (usize, usize),
    pub mirror: bool,
    /// Add a time-reversed copy (`super::reverse`).
    pub reverse: bool,
    pub tags: Vec<String>,
    /// Whole-clip tags of the reversed copy (default: `tags`).
    pub reverse_tags: Option<Vec<String>>,
    pub ranges: Vec<RangeSpec>,
    /// Virtual-root smoothing window (s): the clip's own or the configuration's.
    pub root_position_window: f64,
    /// Rest offsets in metres, Y up.
    pub offsets: Vec<DVec3>,
    /// End-site offsets in metres, Y up.
    pub end_sites: Vec<Option<DVec3>>,
    /// How far the take's joints can be from the origin in source units, at most: every
    /// offset, position channel and end site, summed along each joint chain (see
    /// [`crate::limits::MAX_REACH`]).
    pub reach: f64,
}

impl Take {
    /// The source frame range `[start, end)` configured for a source (default: the whole take).
    ///
    /// # Errors
    /// A configured frame range beyond the take.
    pub fn frame_range(source: &Source, config: &BuildConfig) -> Result<(usize, usize)> {
        let bvh = &source.bvh;
        let configured =
            config.clip_spec(&source.name).and_then(|s| s.frames).or_else(|| config.frame_cuts_of(&source.name));
        match configured {
            Some([s, e]) => {
                if e > bvh.num_frames || e <= s {
                    return Err(Error::config(format!(
                        "{}: frames [{s}, {e}] but the take has {} frames",
                        source.name, bvh.num_frames
                    )));
                }
                Ok((s, e))
            }
            None => Ok((0, bvh.num_frames)),
        }
    }

    /// Resolves a take: its frame range, up axis and unit scale measured on its own motion
    /// (`roles` are its skeleton's), rate, mirroring and tags.
    ///
    /// # Errors
    /// A configured frame range beyond the take.
    pub fn new(source: &Source, config: &BuildConfig, roles: &Roles, warnings: &mut Vec<String>) -> Result<Take> {
        let bvh = &source.bvh;
        let spec = config.clip_spec(&source.name);
        let frames = Take::frame_range(source, config)?;
        let raw_offsets: Vec<DVec3> = bvh.joints.iter().map(|j| j.offset).collect();

        // Up and units from the motion: in any frame a person's head is above the hips and the
        // hips above the feet, whatever the rest pose (Unity humanoids: legs up) or axes.
        let poses = sample_poses(bvh, frames, 32);
        let feet: Vec<usize> = [Role::LeftFoot, Role::RightFoot, Role::LeftToe, Role::RightToe]
            .into_iter()
            .filter_map(|r| roles.get(r))
            .collect();
        let hips = roles[Role::Hips];
        let mut up_sum = DVec3::ZERO;
        for pose in &poses {
            let low = feet.iter().map(|&f| pose.joints[f]).sum::<DVec3>() / feet.len().max(1) as f64;
            up_sum += match roles.get(Role::Head) {
                Some(h) => {
                    (pose.joints[h] - pose.joints[hips]).normalize_or_zero()
                        + (pose.joints[hips] - low).normalize_or_zero()
                }
                None => (pose.joints[hips] - low).normalize_or_zero(),
            };
        }
        let half_pi = std::f64::consts::FRAC_PI_2;
        let detected = {
            let v = up_sum;
            if v.z.abs() > v.y.abs() && v.z.abs() > v.x.abs() {
                DQuat::from_rotation_x(-half_pi * v.z.signum())
            } else if v.x.abs() > v.y.abs() {
                DQuat::from_rotation_z(half_pi * v.x.signum())
            } else if v.y < 0.0 {
                DQuat::from_rotation_z(std::f64::consts::PI)
            } else {
                DQuat::IDENTITY
            }
        };
        let up = match config.up {
            UpAxis::Y => DQuat::IDENTITY,
            UpAxis::Z => DQuat::from_rotation_x(-half_pi),
            UpAxis::X => DQuat::from_rotation_z(half_pi),
            UpAxis::Auto => {
                if detected != DQuat::IDENTITY {
                    let axis = if up_sum.z.abs() > up_sum.y.abs() && up_sum.z.abs() > up_sum.x.abs() {
                        if up_sum.z > 0.0 {
                            "Z"
                        } else {
                            "-Z"
                        }
                    } else if up_sum.x.abs() > up_sum.y.abs() {
                        if up_sum.x > 0.0 {
                            "X"
                        } else {
                            "-X"
                        }
                    } else {
                        "-Y"
                    };
                    warnings.push(format!("{}: the motion is {axis}-up; rotated to Y-up", source.name));
                }
                detected
            }
        };
        // Standing hip height in source units: the hips above the lowest foot point (joints and
        // end sites), median over the sampled frames.
        let height = |pose: &ShapePose| {
            let lowest = feet
                .iter()
                .flat_map(|&f| [Some(pose.joints[f]), pose.ends[f]])
                .flatten()
                .map(|p| (up * p).y)
                .fold(f64::INFINITY, f64::min);
            (up * pose.joints[hips]).y - lowest
        };
        let hip_height = median(poses.iter().map(height).filter(|h| h.is_finite()).collect());
        let scale = match spec.and_then(|s| s.scale).unwrap_or(config.scale) {
            Scale::Fixed(s) => s,
            Scale::Auto(AutoScale::Auto) => {
                if hip_height > 0.0 {
                    [1.0, 0.01, 0.001, 0.0254]
                        .into_iter()
                        .min_by(|a, b| {
                            (hip_height * a / 0.95).ln().abs().total_cmp(&(hip_height * b / 0.95).ln().abs())
                        })
                        .unwrap()
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
        let stem = clip_stem(base_name(&source.name));
        let clip_name = if frames == (0, bvh.num_frames) { stem } else { format!("{stem}[{}-{}]", frames.0, frames.1) };
        Ok(Take {
            clip_name,
            scale,
            up,
            source_fps,
            frames,
            mirror: spec.and_then(|s| s.mirror).unwrap_or(config.mirror),
            reverse: spec.and_then(|s| s.reverse).unwrap_or(config.reverse),
            // The style is a whole-clip tag of every copy (mirrored, reversed).
            tags: spec
                .map(|s| s.tags.clone())
                .unwrap_or_default()
                .into_iter()
                .chain(config.style_tag(&source.name))
                .collect(),
            reverse_tags: spec
                .and_then(|s| s.reverse_tags.clone())
                .map(|t| t.into_iter().chain(config.style_tag(&source.name)).collect()),
            ranges: spec.map(|s| s.ranges.clone()).unwrap_or_default(),
            root_position_window: spec.and_then(|s| s.root_position_window).unwrap_or(config.root_position_window),
            offsets: raw_offsets.iter().map(|&o| up * o * scale).collect(),
            end_sites: bvh.joints.iter().map(|j| j.end_site.map(|e| up * e * scale)).collect(),
            reach: reach(bvh, frames),
        })
    }

    /// Refuses a take whose joints can reach beyond [`crate::limits::MAX_REACH`] metres once
    /// scaled (by its unit scale and, when its root motion is rescaled, by `root_scale`):
    /// its velocities at the database rate would overflow the feature scale the loader accepts.
    ///
    /// # Errors
    /// The reach, the scale and what to check.
    pub fn check_reach(&self, name: &str, root_scale: f64) -> Result<()> {
        let metres = self.reach * self.scale * root_scale.max(1.0);
        if !(metres <= crate::limits::MAX_REACH) {
            return Err(Error::config(format!(
                "{name}: its values times the unit scale {} reach {} m from the origin; at most {} m — check the unit scale (--scale)",
                crate::limits::num(self.scale),
                crate::limits::num(metres),
                crate::limits::num(crate::limits::MAX_REACH)
            )));
        }
        Ok(())
    }

    /// Number of frames after resampling to `fps`, or `None` past [`crate::limits::MAX_FRAMES`]
    /// (a 1 fps take resampled to 1,000 fps grows 1,000-fold).
    pub fn num_out(&self, fps: f64) -> Option<usize> {
        crate::limits::resampled_frames(self.frames.1 - self.frames.0, self.source_fps, fps)
    }

    /// Local transforms (BVH joints, metres, Y up) resampled to `fps` (linear / slerp between
    /// source frames). Takes other than the reference get the reference's bone lengths; their
    /// animated translations (root motion) are scaled by the leg-length ratio `root_scale` so
    /// the feet keep their stride.
    #[allow(clippy::too_many_arguments)]
    pub fn resample(
        &self,
        bvh: &Bvh,
        fps: f64,
        ref_offsets: &[DVec3],
        animated: &[bool],
        root_scale: f64,
        is_reference: bool,
        out: &mut Poses,
    ) {
        let num_joints = bvh.joints.len();
        let count = self.frames.1 - self.frames.0;
        // build() refused takes past the frame limit before calling this.
        let num_out = self.num_out(fps).unwrap_or(0);
        out.reset(num_joints, num_out);
        let convert = self.up != DQuat::IDENTITY;
        let sample = |frame: usize, j: usize| {
            let (t, q) = bvh.local_transform(self.frames.0 + frame, j);
            let t = if is_reference || animated[j] {
                self.up * t * self.scale * if animated[j] { root_scale } else { 1.0 }
            } else {
                ref_offsets[j]
            };
            (t, if convert { self.up * q * self.up.conjugate() } else { q })
        };
        for k in 0..num_out {
            let s = k as f64 * self.source_fps / fps;
            let i = (s + 1e-9).floor() as usize;
            let a = s - i as f64;
            for j in 0..num_joints {
                let (t, q) = if a < 1e-6 || i + 1 >= count {
                    sample(i.min(count - 1), j)
                } else {
                    let (t0, q0) = sample(i, j);
                    let (t1, q1) = sample(i + 1, j);
                    (t0.lerp(t1, a), q0.slerp(q1, a))
                };
                out.push(t, q);
            }
        }
    }
}

/// The farthest any joint (or end site) of `bvh` can be from the origin over `frames`, in
/// source units: per joint the largest offset or position-channel component (√3 × that bounds
/// the translation), summed along the chain from the root.
fn reach(bvh: &Bvh, frames: (usize, usize)) -> f64 {
    let mut own: Vec<f64> = bvh.joints.iter().map(|j| j.offset.abs().max_element()).collect();
    for (k, j) in bvh.joints.iter().enumerate() {
        for (c, channel) in j.channels.iter().enumerate() {
            if matches!(channel, crate::bvh::Channel::PosX | crate::bvh::Channel::PosY | crate::bvh::Channel::PosZ) {
                let at = j.first_channel + c;
                let largest = (frames.0..frames.1.min(bvh.num_frames))
                    .map(|f| bvh.values[f * bvh.num_channels + at].abs())
                    .fold(0.0, f64::max);
                own[k] = own[k].max(largest);
            }
        }
    }
    let mut chain = vec![0.0f64; bvh.joints.len()];
    let mut farthest = 0.0f64;
    for (k, j) in bvh.joints.iter().enumerate() {
        chain[k] = j.parent.map_or(0.0, |p| chain[p]) + 3f64.sqrt() * own[k];
        let site = j.end_site.map_or(0.0, |e| e.length());
        farthest = farthest.max(chain[k] + site);
    }
    farthest
}

/// A source's clip name: its file name without the extension, and for one clip of a glTF file
/// (`walks.glb#Walk`) the clip's name after a `#` (`walks#Walk`).
fn clip_stem(name: &str) -> String {
    let (file, clip) = crate::config::split_clip(name);
    let stem = match file.rsplit_once('.') {
        Some((stem, ext)) if ["bvh", "glb", "gltf", "vrma"].contains(&ext.to_ascii_lowercase().as_str()) => stem,
        _ => file,
    };
    match clip {
        Some(clip) => format!("{stem}#{clip}"),
        None => stem.to_string(),
    }
}
