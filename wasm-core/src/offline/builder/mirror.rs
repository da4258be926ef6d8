//! Mirroring (docs/method.md §1): the mirror image of a take across the character's sagittal
//! (YZ) plane with left and right joints swapped doubles the data for free.

use super::poses::Poses;
use glam::{DQuat, DVec3};

/// `out` = `poses` mirrored: positions `(x, y, z) → (−x, y, z)`, rotations
/// `(x, y, z, w) → (x, −y, −z, w)`, each joint taking its pair's (`pairs[j]`, itself for centre
/// joints) transform. Non-animated translations keep the skeleton's own offsets so every clip
/// shares one skeleton.
pub fn mirror(poses: &Poses, pairs: &[usize], animated: &[bool], out: &mut Poses) {
    let n = pairs.len();
    out.reset(n, poses.num_frames());
    for f in 0..poses.num_frames() {
        for j in 0..n {
            let (t, q) = poses.at(f, pairs[j]);
            let t = if animated[j] { DVec3::new(-t.x, t.y, t.z) } else { poses.at(f, j).0 };
            out.push(t, DQuat::from_xyzw(q.x, -q.y, -q.z, q.w));
        }
    }
}
