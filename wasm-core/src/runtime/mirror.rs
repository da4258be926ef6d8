//! Mirroring (docs/method.md §1): a take's mirror image across the character's sagittal (YZ)
//! plane, left and right joints swapped, doubles the data for free. The builder makes each
//! mirrored clip from its original's finished rows with [`mirror_pose`], and the `.mmdb` reader
//! derives a stored file's mirrored clips with the same function (docs/mmdb-format.md, `MIRR`),
//! so a file carries each mirrored pair once.

use glam::{Quat, Vec3};

/// One frame's local pose mirrored: joint `j` takes its opposite joint's (`pairs[j]`, itself for
/// centre joints) rotation `(x, y, z, w) → (x, 0 − y, 0 − z, w)` and, when `animated[j]`, its
/// translation `(x, y, z) → (0 − x, y, z)`; a joint that never moves keeps its rest offset
/// `rest[j]`, so every clip shares one skeleton. Exact: only signs change, so mirroring commutes
/// with the 16-bit quantization (`round(−x) = −round(x)`) and a mirrored clip's stored bits are
/// its original's.
///
/// # Panics
/// If a slice is shorter than `pairs` or a pair index is out of range.
pub fn mirror_pose(
    pairs: &[usize],
    animated: &[bool],
    rest: &[Vec3],
    (positions, rotations): (&[Vec3], &[Quat]),
    (out_positions, out_rotations): (&mut [Vec3], &mut [Quat]),
) {
    // `0 − x`, not `−x`: a zero mirrors to +0 as the quantizer's 0 decodes, so a clip mirrored
    // before quantization and one mirrored after it are the same bits.
    for (j, &k) in pairs.iter().enumerate() {
        let q = rotations[k];
        out_rotations[j] = Quat::from_xyzw(q.x, 0.0 - q.y, 0.0 - q.z, q.w);
        out_positions[j] = if animated[j] {
            let p = positions[k];
            Vec3::new(0.0 - p.x, p.y, p.z)
        } else {
            rest[j]
        };
    }
}

/// A frame's foot contacts mirrored: the left foot's is the right's and the other way round.
pub fn mirror_contacts(contacts: &[u8]) -> [u8; 2] {
    [contacts[1], contacts[0]]
}

/// Consecutive frames mirrored, each by [`mirror_pose`] and [`mirror_contacts`]: `out` gets the
/// mirror of every frame of `from` (`pairs.len()` joints and 2 contacts a frame) — how the
/// builder makes a mirrored clip and the `.mmdb` reader derives one.
///
/// # Panics
/// If `out` holds fewer frames than `from`.
pub fn mirror_frames(
    pairs: &[usize],
    animated: &[bool],
    rest: &[Vec3],
    (positions, rotations, contacts): (&[Vec3], &[Quat], &[u8]),
    (out_positions, out_rotations, out_contacts): (&mut [Vec3], &mut [Quat], &mut [u8]),
) {
    let j = pairs.len();
    for f in 0..contacts.len() / 2 {
        let r = f * j..(f + 1) * j;
        mirror_pose(
            pairs,
            animated,
            rest,
            (&positions[r.clone()], &rotations[r.clone()]),
            (&mut out_positions[r.clone()], &mut out_rotations[r]),
        );
        out_contacts[2 * f..2 * f + 2].copy_from_slice(&mirror_contacts(&contacts[2 * f..2 * f + 2]));
    }
}

/// Whether `pairs` is a mirror map for `joints` joints: one entry per joint, each in range and
/// paired back (`pairs[pairs[j]] = j`).
pub fn is_mirror_map(pairs: &[usize], joints: usize) -> bool {
    pairs.len() == joints && pairs.iter().enumerate().all(|(j, &k)| k < joints && pairs[k] == j)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mirroring twice gives the pose back bit for bit, and a turn to the left becomes one to
    /// the right.
    #[test]
    fn mirroring_twice_is_the_identity() {
        let pairs = [0, 2, 1];
        let animated = [true, false, false];
        let rest = [Vec3::ZERO, Vec3::X, -Vec3::X];
        let p = [Vec3::new(0.3, 1.0, -2.0), Vec3::X, -Vec3::X];
        let q = [Quat::from_rotation_y(0.4), Quat::from_rotation_z(0.2), Quat::from_rotation_x(-0.7)];
        let (mut p1, mut q1, mut p2, mut q2) =
            ([Vec3::ZERO; 3], [Quat::IDENTITY; 3], [Vec3::ZERO; 3], [Quat::IDENTITY; 3]);
        mirror_pose(&pairs, &animated, &rest, (&p, &q), (&mut p1, &mut q1));
        mirror_pose(&pairs, &animated, &rest, (&p1, &q1), (&mut p2, &mut q2));
        assert_eq!((p2, q2), (p, q));
        assert!((q1[0] * Vec3::Z).x < 0.0 && (q[0] * Vec3::Z).x > 0.0);
        assert_eq!(q1[1], Quat::from_xyzw(q[2].x, -q[2].y, -q[2].z, q[2].w));
        assert_eq!(mirror_contacts(&[1, 0]), [0, 1]);
        assert!(is_mirror_map(&pairs, 3) && !is_mirror_map(&[0, 2, 2], 3) && !is_mirror_map(&[0, 1], 3));
    }
}
