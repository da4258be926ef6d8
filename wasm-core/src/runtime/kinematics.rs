//! Forward kinematics: local joint transforms → model-space transforms. The one FK of the
//! crate — the database viewer, the builder (in f64), the character's world pose and its leg
//! touch-ups, and the retargeter all call [`local_to_model`].
//!
//! Like ozz-animation's `LocalToModelJob`, it updates a *range* of joints whose parents outside
//! the range are already current: after the foot lock bends a leg, only that leg's subtree is
//! recomputed ([`subtree_range`]).
//!
//! Method (docs/method.md §1): for a joint `j` with parent `p`,
//! `rot[j] = rot[p] · local_rot[j]` and `pos[j] = pos[p] + rot[p] · local_pos[j]`;
//! a joint without a parent takes `root ∘ local` (the root transform, if any, then its local).

use std::ops::{Add, Mul, Range};

/// Model transforms of `joints` from their local transforms.
///
/// - `parents[j]`: index of `j`'s parent, negative for none. Every parent must precede its
///   children (`parents[j] < j`), as in every skeleton this crate builds or loads.
/// - `root`: the transform of the space parentless joints are expressed in (`None`: model space
///   itself).
/// - Joints of `joints` read their parents' model transforms from the output arrays, so parents
///   before `joints.start` must already be current there.
///
/// Works for `f32` ([`glam::Vec3`]/[`glam::Quat`]) and `f64` ([`glam::DVec3`]/[`glam::DQuat`]).
/// Allocates nothing.
///
/// # Panics
/// If `joints` reaches past any of the slices, or a parent index is not below its child's.
pub fn local_to_model<V, Q>(
    parents: &[i32],
    joints: Range<usize>,
    root: Option<(V, Q)>,
    local_positions: &[V],
    local_rotations: &[Q],
    model_positions: &mut [V],
    model_rotations: &mut [Q],
) where
    V: Copy + Add<Output = V>,
    Q: Copy + Mul<Q, Output = Q> + Mul<V, Output = V>,
{
    // Slices cut to the range up front: the loop's own indexing then needs no bounds checks
    // (the full pose's FK runs every update).
    let end = joints.end;
    let (parents, local_positions, local_rotations) =
        (&parents[..end], &local_positions[..end], &local_rotations[..end]);
    let (model_positions, model_rotations) = (&mut model_positions[..end], &mut model_rotations[..end]);
    for j in joints {
        let (p, q) = (local_positions[j], local_rotations[j]);
        let parent = parents[j];
        (model_positions[j], model_rotations[j]) = if parent < 0 {
            match root {
                Some((rp, rq)) => (rp + rq * p, rq * q),
                None => (p, q),
            }
        } else {
            let k = parent as usize;
            assert!(k < j, "joint {j}'s parent {k} does not precede it");
            let (pp, pq) = (model_positions[k], model_rotations[k]);
            (pp + pq * p, pq * q)
        };
    }
}

/// The smallest joint range that holds `joint` and all its descendants: `joint..last + 1`. In a
/// depth-first skeleton (every BVH) the range holds nothing else; otherwise it may also hold
/// joints that are not descendants, which [`local_to_model`] recomputes to the same values.
///
/// # Panics
/// If `joint` is out of range.
pub fn subtree_range(parents: &[i32], joint: usize) -> Range<usize> {
    assert!(joint < parents.len(), "joint {joint} out of range 0..{}", parents.len());
    let mut inside = vec![false; parents.len()];
    inside[joint] = true;
    let mut last = joint;
    for k in joint + 1..parents.len() {
        let p = parents[k];
        if p >= joint as i32 && inside[p as usize] {
            inside[k] = true;
            last = k;
        }
    }
    joint..last + 1
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DQuat, DVec3, Quat, Vec3};

    #[test]
    fn chains_rotations_and_offsets() {
        // root → a → b, each turned 90° about Y, offsets along +Z.
        let parents = [-1, 0, 1];
        let q = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let lp = [Vec3::new(1.0, 0.0, 0.0), Vec3::Z, Vec3::Z];
        let lr = [q; 3];
        let (mut p, mut r) = ([Vec3::ZERO; 3], [Quat::IDENTITY; 3]);
        local_to_model(&parents, 0..3, None, &lp, &lr, &mut p, &mut r);
        assert!((p[1] - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6);
        assert!((p[2] - Vec3::new(2.0, 0.0, -1.0)).length() < 1e-6);
        assert!(r[2].dot(Quat::from_rotation_y(3.0 * std::f32::consts::FRAC_PI_2)).abs() > 1.0 - 1e-6);
    }

    #[test]
    fn a_partial_range_equals_the_full_pass() {
        let parents = [-1, 0, 1, 2, 1, 4];
        let lp: Vec<DVec3> = (0..6).map(|j| DVec3::new(j as f64, 1.0, 0.5)).collect();
        let lr: Vec<DQuat> = (0..6).map(|j| DQuat::from_rotation_x(0.3 * j as f64)).collect();
        let root = Some((DVec3::new(0.0, 0.0, 2.0), DQuat::from_rotation_y(0.7)));
        let (mut p, mut r) = (vec![DVec3::ZERO; 6], vec![DQuat::IDENTITY; 6]);
        local_to_model(&parents, 0..6, root, &lp, &lr, &mut p, &mut r);
        let (full_p, full_r) = (p.clone(), r.clone());
        // Change joint 4's rotation, recompute only its subtree.
        let mut lr2 = lr.clone();
        lr2[4] = DQuat::from_rotation_z(1.0);
        assert_eq!(subtree_range(&parents, 4), 4..6);
        local_to_model(&parents, subtree_range(&parents, 4), root, &lp, &lr2, &mut p, &mut r);
        let (mut q, mut s) = (vec![DVec3::ZERO; 6], vec![DQuat::IDENTITY; 6]);
        local_to_model(&parents, 0..6, root, &lp, &lr2, &mut q, &mut s);
        assert_eq!(p, q);
        assert_eq!(r, s);
        assert_eq!(&p[..4], &full_p[..4]);
        assert_eq!(&r[..4], &full_r[..4]);
    }

    #[test]
    fn subtree_ranges() {
        let parents = [-1, 0, 1, 2, 1, 4, 0];
        assert_eq!(subtree_range(&parents, 0), 0..7);
        assert_eq!(subtree_range(&parents, 1), 1..6);
        assert_eq!(subtree_range(&parents, 2), 2..4);
        assert_eq!(subtree_range(&parents, 6), 6..7);
        // Breadth-first order: the range spans the interleaved non-descendant.
        let bfs = [-1, 0, 0, 1, 2, 1];
        assert_eq!(subtree_range(&bfs, 1), 1..6);
    }
}
