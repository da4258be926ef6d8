//! Poses sampled from a take's motion, in file units and axes: what the roles, the up axis and
//! the unit scale are measured on. The rest pose (the BVH offsets with identity rotations) may be
//! anything — exporters write Unity humanoids with the legs pointing up, Z-up rigs lying down —
//! but a person in the motion stands on their feet with the head above the hips.

use crate::bvh::Bvh;
use crate::kinematics::local_to_model;
use crate::roles::ShapePose;
use glam::{DQuat, DVec3};

/// Up to `count` poses evenly spread over source frames `[start, end)` (model space, file units,
/// file axes), with every joint's end-site point.
pub fn sample_poses(bvh: &Bvh, frames: (usize, usize), count: usize) -> Vec<ShapePose> {
    let n = bvh.joints.len();
    let parents: Vec<i32> = bvh.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i32)).collect();
    let (start, end) = (frames.0.min(bvh.num_frames), frames.1.min(bvh.num_frames));
    if end <= start || n == 0 {
        return Vec::new();
    }
    let count = count.clamp(1, end - start);
    let (mut lp, mut lr) = (vec![DVec3::ZERO; n], vec![DQuat::IDENTITY; n]);
    let (mut wp, mut wr) = (vec![DVec3::ZERO; n], vec![DQuat::IDENTITY; n]);
    (0..count)
        .map(|k| {
            // Frame centres of `count` equal parts of the range.
            let f = start + ((2 * k + 1) * (end - start)) / (2 * count);
            for j in 0..n {
                (lp[j], lr[j]) = bvh.local_transform(f, j);
            }
            local_to_model(&parents, 0..n, None, &lp, &lr, &mut wp, &mut wr);
            let ends = bvh.joints.iter().enumerate().map(|(j, b)| b.end_site.map(|e| wp[j] + wr[j] * e)).collect();
            ShapePose { joints: wp.clone(), ends }
        })
        .collect()
}

/// The median of `values` (NaN when empty).
pub fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}
