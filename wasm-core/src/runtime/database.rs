//! The motion database: skeleton, one pose per frame (SoA arrays), contacts, clips, tags and
//! the normalized feature matrix (docs/method.md §1–2). Built by [`crate::builder`], stored by
//! [`crate::format`], searched by [`crate::search`].

use crate::kinematics::local_to_model;
use glam::{DQuat, DVec3, Quat, Vec3};

/// The joint hierarchy. Joint 0 is the virtual root; parents precede children.
#[derive(Clone, Debug, PartialEq)]
pub struct Skeleton {
    pub names: Vec<String>,
    /// Parent index per joint, `-1` for joint 0.
    pub parents: Vec<i32>,
    /// Rest position of each joint in its parent's space (rest rotations are the identity).
    pub offsets: Vec<Vec3>,
    /// Named points on the body, one per [`crate::roles::Role`] in [`crate::roles::Role::ALL`]
    /// order (`hips`, `left_toe`, …; joint −1 where the skeleton has no such part).
    pub sites: Vec<Site>,
    /// The opposite-side joint of each joint (itself for centre joints): how a mirrored clip is
    /// made from its original ([`crate::mirror::mirror_pose`]). Empty where unknown (a
    /// database read from a version-1 or -2 file): its mirrored clips are stored whole.
    pub mirror: Vec<usize>,
}

/// A point rigidly attached to a joint.
#[derive(Clone, Debug, PartialEq)]
pub struct Site {
    pub name: String,
    /// Joint index, `-1` when the skeleton has no such part.
    pub joint: i32,
    /// Offset in the joint's space.
    pub offset: Vec3,
}

impl Skeleton {
    pub fn num_joints(&self) -> usize {
        self.names.len()
    }

    /// Index of the joint with this exact name.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// The site with this name, if its part was found.
    pub fn site(&self, name: &str) -> Option<&Site> {
        self.sites.iter().find(|s| s.name == name && s.joint >= 0)
    }

    /// The joint of the site with this name, if its part was found on a joint below the root.
    pub fn site_joint(&self, name: &str) -> Option<usize> {
        self.site(name).filter(|s| s.joint > 0).map(|s| s.joint as usize)
    }
}

/// A contiguous range of frames from one source take.
#[derive(Clone, Debug, PartialEq)]
pub struct Clip {
    pub name: String,
    pub source: String,
    /// First frame (inclusive).
    pub start: u32,
    /// End frame (exclusive).
    pub end: u32,
    pub mirrored: bool,
    /// The source's frame rate (frames per second, `1 / Frame Time`, snapped to the whole
    /// number when within 0.01 of it): database frame `start + k` was sampled at source frame
    /// `source_start + k · source_fps / fps` (linear / slerp between source frames).
    pub source_fps: f64,
    /// The source frame the clip's first frame was sampled at (a configured frame range starts
    /// past 0). Version-1 files do not store it and read as 0. A time-reversed copy (named
    /// `… (reversed)`) keeps its forward clip's value and runs the mapping backward: its frame
    /// `start + k` is the forward clip's `start + (n − 1 − k)`.
    pub source_start: u32,
    /// Metres per source unit.
    pub scale: f32,
    /// Root-motion scale from bone-length normalization (1 for the reference skeleton).
    pub root_scale: f32,
}

/// A named set of frame ranges (`walk`, `run`, `idle`…), usable as a search mask.
#[derive(Clone, Debug, PartialEq)]
pub struct Tag {
    pub name: String,
    /// `[start, end)` frame ranges, sorted and disjoint.
    pub ranges: Vec<(u32, u32)>,
}

/// What a feature group measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FeatureKind {
    Position = 0,
    Velocity = 1,
    Direction = 2,
}

/// Which components of a 3D quantity a feature keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axes {
    Xyz = 0,
    /// Ground plane (x, z): trajectory features.
    Xz = 1,
}

impl Axes {
    pub fn num_dims(self) -> usize {
        match self {
            Axes::Xyz => 3,
            Axes::Xz => 2,
        }
    }
}

/// One group of feature dimensions sharing a normalization scale and a weight.
#[derive(Clone, Debug, PartialEq)]
pub struct FeatureGroup {
    pub name: String,
    pub kind: FeatureKind,
    /// Trajectory groups are scaled by β_r at search time, pose groups by β_q.
    pub is_trajectory: bool,
    pub axes: Axes,
    pub joint: usize,
    /// Axis in joint space for [`FeatureKind::Direction`].
    pub axis: Vec3,
    /// Frame offsets relative to the current frame.
    pub offsets: Vec<i32>,
    pub weight: f32,
    pub first_dim: usize,
    pub num_dims: usize,
}

/// A built motion database. All per-frame arrays are frame-major and flat so they can be
/// viewed from JS without copying.
#[derive(Clone, Debug, PartialEq)]
pub struct Database {
    pub skeleton: Skeleton,
    pub fps: f32,
    pub num_frames: usize,
    pub clips: Vec<Clip>,
    pub tags: Vec<Tag>,
    /// `F×J` local positions (joint 0: world position of the virtual root).
    pub local_positions: Vec<Vec3>,
    /// `F×J` local rotations (joint 0: world yaw of the virtual root).
    pub local_rotations: Vec<Quat>,
    /// `F×J` local linear and angular velocities, derived from the poses by
    /// [`Database::compute_velocities`] (not stored in `.mmdb` version 2).
    pub local_velocities: Vec<Vec3>,
    pub local_angular_velocities: Vec<Vec3>,
    /// `F×2` foot contacts (left, right), 0 or 1.
    pub contacts: Vec<u8>,
    pub groups: Vec<FeatureGroup>,
    /// `D` per-dimension mean and scale: stored = (raw − mean) / scale.
    pub feature_mean: Vec<f32>,
    pub feature_scale: Vec<f32>,
    /// `F×D` normalized features, derived from the poses ([`Database::compute_features`]; stored
    /// in `.mmdb` versions 1 and 2).
    pub features: Vec<f32>,
    /// `F` 1 where a search may land.
    pub valid: Vec<u8>,
    /// Set when this database is the first part of a larger one (its `PART` section).
    pub part: Option<Part>,
}

/// A database that is the first part of a larger one, the *whole*: its frames are the whole's
/// `ranges`, in order, with everything per frame (pose, contacts, features, validity) and the
/// feature normalization copied from the whole (docs/mmdb-format.md, `PART`). A page draws its
/// first frame after the part's bytes and moves its characters to the whole when it arrives:
/// the frame playing is the same frame there, so nothing on screen changes at the swap.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// The whole's file name, in the same folder as the part (a plain name: no `/`, `\`, `..`).
    pub whole: String,
    /// The whole's frame count and its file's CRC-32 (header `checksum`): which file it is.
    pub whole_frames: u32,
    pub whole_checksum: u32,
    /// `[start, end)` frame ranges of the whole, ascending and disjoint; each is one clip of
    /// the whole and of the part.
    pub ranges: Vec<(u32, u32)>,
}

impl Part {
    /// The whole's frame for this part's `frame` (`None` past the part's end).
    pub fn whole_frame(&self, frame: usize) -> Option<usize> {
        let mut f = frame;
        for &(s, e) in &self.ranges {
            let n = (e - s) as usize;
            if f < n {
                return Some(s as usize + f);
            }
            f -= n;
        }
        None
    }

    /// Whether `name` may name a whole: a plain file name, so a part never points elsewhere.
    pub fn is_plain_name(name: &str) -> bool {
        !name.is_empty()
            && name.len() <= 255
            && name != "."
            && name != ".."
            && !name.contains(['/', '\\', '\0', '?', '#', ':'])
    }
}

impl Database {
    pub fn num_joints(&self) -> usize {
        self.skeleton.num_joints()
    }

    pub fn num_features(&self) -> usize {
        self.feature_mean.len()
    }

    pub fn duration(&self) -> f32 {
        self.num_frames as f32 / self.fps
    }

    /// Index of the clip containing `frame` (the last clip for a frame past the end; 0 without
    /// clips, which the loader never lets through).
    pub fn clip_at(&self, frame: usize) -> usize {
        self.clips.partition_point(|c| c.end as usize <= frame).min(self.clips.len().saturating_sub(1))
    }

    /// Normalized feature vector of `frame`.
    pub fn feature(&self, frame: usize) -> &[f32] {
        let d = self.num_features();
        &self.features[frame * d..(frame + 1) * d]
    }

    /// Frames carrying `tag` as a per-frame mask, or `None` if there is no such tag.
    pub fn tag_mask(&self, tag: &str) -> Option<Vec<bool>> {
        let tag = self.tags.iter().find(|t| t.name == tag)?;
        let mut mask = vec![false; self.num_frames];
        for &(s, e) in &tag.ranges {
            mask[s as usize..e as usize].fill(true);
        }
        Some(mask)
    }

    /// Fills the local velocities from the local poses: central differences within each clip,
    /// one-sided at its first and last frame (docs/method.md §3), in f64 from the stored f32
    /// values: `v[f] = (p[b] − p[a]) · fps / (b − a)`, `ω[f] = axis·angle(q[b] · q[a]⁻¹) · fps /
    /// (b − a)` with `a = max(f − 1, start)`, `b = min(f + 1, end − 1)`. One function for the
    /// builder and the `.mmdb` reader, so a stored and a derived velocity cannot disagree.
    /// A one-frame clip has zero velocities.
    pub fn compute_velocities(&mut self) {
        (self.local_velocities, self.local_angular_velocities) =
            pose_velocities(self.num_joints(), self.fps, &self.clips, &self.local_positions, &self.local_rotations);
    }

    /// Derives the normalized feature matrix from the poses with the stored normalization
    /// (`.mmdb` version 3 does not store it).
    pub fn compute_features(&mut self) {
        self.features = self.derived_features();
    }

    /// The normalized features the poses give ([`crate::pose_features`], the builder's recipe,
    /// with this database's normalization): what [`Database::compute_features`] stores.
    pub fn derived_features(&self) -> Vec<f32> {
        let mut features = crate::pose_features::pose_features(
            &self.skeleton.parents,
            self.fps,
            &self.clips,
            &self.groups,
            self.num_features(),
            &self.local_positions,
            &self.local_rotations,
        );
        crate::pose_features::apply_normalization(&mut features, &self.feature_mean, &self.feature_scale);
        features
    }

    /// World positions and rotations of every joint at `frame` (the one FK,
    /// [`crate::kinematics::local_to_model`]), written into the caller's buffers (no allocation).
    ///
    /// # Panics
    /// If the buffers are shorter than the joint count or `frame` is out of range.
    pub fn forward_kinematics(&self, frame: usize, positions: &mut [Vec3], rotations: &mut [Quat]) {
        let j = self.num_joints();
        let r = frame * j..(frame + 1) * j;
        local_to_model(
            &self.skeleton.parents,
            0..j,
            None,
            &self.local_positions[r.clone()],
            &self.local_rotations[r],
            positions,
            rotations,
        );
    }

    /// World positions of every joint in the rest pose (identity rotations, the skeleton's
    /// offsets) with the virtual root at the origin: what retargeting aligns to.
    pub fn rest_positions(&self) -> Vec<Vec3> {
        let j = self.num_joints();
        let (mut p, mut r) = (vec![Vec3::ZERO; j], vec![Quat::IDENTITY; j]);
        let identity = vec![Quat::IDENTITY; j];
        local_to_model(&self.skeleton.parents, 0..j, None, &self.skeleton.offsets, &identity, &mut p, &mut r);
        p
    }

    /// The head joint's height in the rest pose above its lowest joint (database units): the
    /// skeleton's standing eye height. `None` without a head role.
    pub fn rest_head_height(&self) -> Option<f32> {
        let head = self.skeleton.site_joint("head")?;
        let rest = self.rest_positions();
        let floor = rest.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
        Some(rest[head].y - floor)
    }

    /// Median height above the floor of the toe sites in frames where that foot is in contact
    /// (m); `None` without toe sites or contacts. The foot lock plants toes at this height, and
    /// retargeting maps it onto the avatar's standing toe height, so feet touch the floor
    /// whatever the skeletons' foot geometry.
    pub fn toe_height_in_contact(&self) -> Option<f32> {
        let sites = [self.skeleton.site("left_toe")?, self.skeleton.site("right_toe")?];
        let j = self.num_joints();
        let (mut positions, mut rotations) = (vec![Vec3::ZERO; j], vec![Quat::IDENTITY; j]);
        let mut heights = Vec::new();
        // Every 4th frame is plenty for a median and keeps this cheap in the browser.
        for frame in (0..self.num_frames).step_by(4) {
            let contacts = &self.contacts[2 * frame..2 * frame + 2];
            if contacts == [0, 0] {
                continue;
            }
            self.forward_kinematics(frame, &mut positions, &mut rotations);
            for (side, site) in sites.iter().enumerate() {
                if contacts[side] != 0 {
                    let k = site.joint as usize;
                    heights.push((positions[k] + rotations[k] * site.offset).y);
                }
            }
        }
        if heights.is_empty() {
            return None;
        }
        let mid = heights.len() / 2;
        Some(*heights.select_nth_unstable_by(mid, f32::total_cmp).1)
    }
}

/// The velocities [`Database::compute_velocities`] describes, of `F×J` poses cut into `clips`.
pub fn pose_velocities(
    joints: usize,
    fps: f32,
    clips: &[Clip],
    positions: &[Vec3],
    rotations: &[Quat],
) -> (Vec<Vec3>, Vec<Vec3>) {
    let n = positions.len().min(rotations.len());
    let (mut velocities, mut angular) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
    let fps = fps as f64;
    for clip in clips {
        let (start, end) = (clip.start as usize, (clip.end as usize).min(n / joints.max(1)));
        for f in start..end {
            let (a, b) = (f.saturating_sub(1).max(start), (f + 1).min(end - 1));
            if a >= b {
                continue;
            }
            let inv_h = fps / (b - a) as f64;
            for k in 0..joints {
                let (pa, pb) = (positions[a * joints + k].as_dvec3(), positions[b * joints + k].as_dvec3());
                let (qa, qb) = (rotations[a * joints + k].as_dquat(), rotations[b * joints + k].as_dquat());
                velocities[f * joints + k] = ((pb - pa) * inv_h).as_vec3();
                angular[f * joints + k] = (scaled_axis(qb * qa.conjugate()) * inv_h).as_vec3();
            }
        }
    }
    (velocities, angular)
}

/// Rotation vector (axis × angle) of a unit quaternion, taking the short way. Same value as
/// `to_scaled_axis` but without `atan2` for the small rotations between nearby frames:
/// angle = 2·atan(x), x = |v|/w, by its Taylor series when x < 0.1 (truncation error
/// < x¹²/13 < 1e-13 relative, far below f32 storage precision).
pub fn scaled_axis(q: DQuat) -> DVec3 {
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
        let series =
            1.0 - x2 * (1.0 / 3.0 - x2 * (1.0 / 5.0 - x2 * (1.0 / 7.0 - x2 * (1.0 / 9.0 - x2 * (1.0 / 11.0)))));
        v * (2.0 * inv_w * series)
    } else {
        v * (2.0 * s.atan2(q.w) / s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
