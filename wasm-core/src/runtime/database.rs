//! The motion database: skeleton, one pose per frame (SoA arrays), contacts, clips, tags and
//! the normalized feature matrix (docs/method.md §1–2). Built by [`crate::builder`], stored by
//! [`crate::format`], searched by [`crate::search`].

use crate::kinematics::local_to_model;
use glam::{DQuat, DVec3, Quat, Vec3};
use std::sync::OnceLock;

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
    /// The velocities derived so far ([`Database::frame_velocities`]); `Velocities::default()`.
    pub velocities: Velocities,
}

/// Frames per block of [`Velocities`]: 32 frames of 32 joints are 24 kB, derived in ~0.03 ms
/// natively the first time a character plays or jumps into one (every frame's of the shipped
/// whole, 1,066 blocks: 27-36 ms, `search::load_time`).
const VELOCITY_BLOCK: usize = 32;

/// The velocities of a database's frames, derived a block at a time when first asked for and kept
/// (each block's linear velocities, then its angular ones, frame-major). Derived from the poses,
/// so it is no part of a database's value: a clone starts empty and any two compare equal. The
/// poses must not change once a velocity was asked for (a builder or test that edits them does
/// so before, or on a clone).
#[derive(Default)]
pub struct Velocities {
    blocks: OnceLock<Box<[Block]>>,
}

/// One block of [`Velocities`], derived once.
type Block = OnceLock<Box<[Vec3]>>;

impl Velocities {
    /// The block holding `frame` and the frame's index in it, derived now if it was not; `None`
    /// for a frame past the count the blocks were laid out for.
    fn block<'a>(&'a self, db: &Database, frame: usize) -> Option<(&'a [Vec3], usize)> {
        if frame >= db.num_frames {
            return None;
        }
        let blocks =
            self.blocks.get_or_init(|| (0..db.num_frames.div_ceil(VELOCITY_BLOCK)).map(|_| OnceLock::new()).collect());
        let b = frame / VELOCITY_BLOCK;
        let block = blocks.get(b)?.get_or_init(|| {
            let (j, start) = (db.num_joints(), b * VELOCITY_BLOCK);
            let n = VELOCITY_BLOCK.min(db.num_frames - start); // start ≤ frame < num_frames
            let mut out = vec![Vec3::ZERO; 2 * n * j].into_boxed_slice();
            let (velocities, angular) = out.split_at_mut(n * j);
            for i in 0..n {
                db.velocities_from_poses(start + i, &mut velocities[i * j..], &mut angular[i * j..]);
            }
            out
        });
        Some((block, frame - b * VELOCITY_BLOCK))
    }
}

impl Clone for Velocities {
    fn clone(&self) -> Velocities {
        Velocities::default()
    }
}

impl PartialEq for Velocities {
    fn eq(&self, _: &Velocities) -> bool {
        true
    }
}

impl std::fmt::Debug for Velocities {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let derived = self.blocks.get().map_or(0, |b| b.iter().filter(|b| b.get().is_some()).count());
        write!(f, "Velocities {{ derived blocks: {derived} }}")
    }
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

    /// Local linear and angular velocities of every joint at `frame` (docs/method.md §3): central
    /// differences within the frame's clip, one-sided at its first and last frame, in f64 from
    /// the stored f32 values: `v[f] = (p[b] − p[a]) · fps / (b − a)`, `ω[f] = axis·angle(q[b] ·
    /// q[a]⁻¹) · fps / (b − a)` with `a = max(f − 1, start)`, `b = min(f + 1, end − 1)`; zero in a
    /// one-frame clip. Derived a block of frames at a time the first time one of them is asked
    /// for, and kept ([`Velocities`]): not on load, where every frame's took a third of it (22 ms
    /// natively for the shipped whole) and 24 bytes a joint a frame (19 MB) before any character
    /// played one. Written into the caller's buffers.
    ///
    /// # Panics
    /// If the buffers are shorter than the joint count or `frame` is out of range.
    pub fn frame_velocities(&self, frame: usize, velocities: &mut [Vec3], angular: &mut [Vec3]) {
        let j = self.num_joints();
        let (velocities, angular) = (&mut velocities[..j], &mut angular[..j]);
        match self.velocities.block(self, frame) {
            Some((block, i)) => {
                let n = block.len() / (2 * j);
                velocities.copy_from_slice(&block[i * j..(i + 1) * j]);
                angular.copy_from_slice(&block[(n + i) * j..(n + i + 1) * j]);
            }
            None => self.velocities_from_poses(frame, velocities, angular),
        }
    }

    /// Joint `joint`'s local velocity and angular velocity at `frame` ([`Database::frame_velocities`]).
    pub fn joint_velocity(&self, frame: usize, joint: usize) -> (Vec3, Vec3) {
        let j = self.num_joints();
        match self.velocities.block(self, frame) {
            Some((block, i)) => {
                let n = block.len() / (2 * j);
                (block[i * j + joint], block[(n + i) * j + joint])
            }
            None => {
                let Some((a, b, inv_h)) = self.difference_frames(frame) else { return (Vec3::ZERO, Vec3::ZERO) };
                let (ia, ib) = (a * j + joint, b * j + joint);
                let (p, q) = (&self.local_positions, &self.local_rotations);
                difference_velocity(p[ia], p[ib], q[ia], q[ib], inv_h)
            }
        }
    }

    /// Derives every frame's velocities now (each block [`Database::frame_velocities`] would
    /// derive when first asked): for whoever counts a character's own allocations apart from
    /// the database's derived data, or wants no first-touch work later.
    pub fn derive_velocities(&self) {
        for frame in (0..self.num_frames).step_by(VELOCITY_BLOCK) {
            self.velocities.block(self, frame);
        }
    }

    /// [`Database::frame_velocities`] from the poses, every joint.
    fn velocities_from_poses(&self, frame: usize, velocities: &mut [Vec3], angular: &mut [Vec3]) {
        let j = self.num_joints();
        let Some((a, b, inv_h)) = self.difference_frames(frame) else {
            velocities[..j].fill(Vec3::ZERO);
            angular[..j].fill(Vec3::ZERO);
            return;
        };
        let (pa, pb) = (&self.local_positions[a * j..(a + 1) * j], &self.local_positions[b * j..(b + 1) * j]);
        let (qa, qb) = (&self.local_rotations[a * j..(a + 1) * j], &self.local_rotations[b * j..(b + 1) * j]);
        for k in 0..j {
            (velocities[k], angular[k]) = difference_velocity(pa[k], pb[k], qa[k], qb[k], inv_h);
        }
    }

    /// The frames `a < b` whose difference is `frame`'s velocity, and `fps / (b − a)`; `None`
    /// in a one-frame clip.
    fn difference_frames(&self, frame: usize) -> Option<(usize, usize, f64)> {
        let clip = self.clips.get(self.clip_at(frame))?;
        let (start, end) = (clip.start as usize, (clip.end as usize).min(self.num_frames));
        difference_frames(frame, start, end, self.fps)
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

/// Every frame's velocities ([`Database::frame_velocities`]) of `F×J` poses cut into `clips`:
/// for the offline tools and checks, which look at all of them at once.
pub fn pose_velocities(
    joints: usize,
    fps: f32,
    clips: &[Clip],
    positions: &[Vec3],
    rotations: &[Quat],
) -> (Vec<Vec3>, Vec<Vec3>) {
    let n = positions.len().min(rotations.len());
    let (mut velocities, mut angular) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
    for clip in clips {
        let (start, end) = (clip.start as usize, (clip.end as usize).min(n / joints.max(1)));
        for f in start..end {
            let Some((a, b, inv_h)) = difference_frames(f, start, end, fps) else { continue };
            for k in 0..joints {
                let (ia, ib) = (a * joints + k, b * joints + k);
                (velocities[f * joints + k], angular[f * joints + k]) =
                    difference_velocity(positions[ia], positions[ib], rotations[ia], rotations[ib], inv_h);
            }
        }
    }
    (velocities, angular)
}

/// The neighbours whose difference is `frame`'s velocity in the clip `[start, end)`.
fn difference_frames(frame: usize, start: usize, end: usize, fps: f32) -> Option<(usize, usize, f64)> {
    let (a, b) = (frame.saturating_sub(1).max(start), (frame + 1).min(end.checked_sub(1)?));
    (a < b).then(|| (a, b, fps as f64 / (b - a) as f64))
}

/// One joint's finite-difference velocity and angular velocity, in f64.
#[inline]
fn difference_velocity(pa: Vec3, pb: Vec3, qa: Quat, qb: Quat, inv_h: f64) -> (Vec3, Vec3) {
    let v = (pb.as_dvec3() - pa.as_dvec3()) * inv_h;
    let w = scaled_axis(qb.as_dquat() * qa.as_dquat().conjugate()) * inv_h;
    (v.as_vec3(), w.as_vec3())
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
