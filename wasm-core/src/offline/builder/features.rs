//! The feature database (docs/method.md §2): which quantities are matched (groups from the
//! config or the default 27-float locomotion set), their normalization, and which frames a
//! search may return. Their values come from the poses (`crate::pose_features`, as on load).

use crate::config::{BuildConfig, FeatureSpec};
use crate::database::{Axes, Clip, FeatureGroup, FeatureKind, Skeleton};
use crate::error::{Error, Result};
use crate::pose_features::apply_normalization;
use crate::roles::Role;
use glam::Vec3;

/// Feature groups from the config, or the default 27-float locomotion set (weights from
/// Holden's reference: feet positions 0.75, velocities 1, trajectory positions 1, directions
/// 1.5). For position/velocity groups `axis` holds the site offset of the joint.
///
/// # Errors
/// An empty feature list, a group on a missing role or unknown joint, empty offsets, or a
/// weight that is not positive.
pub fn feature_groups(config: &BuildConfig, skeleton: &Skeleton) -> Result<Vec<FeatureGroup>> {
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
    let role_list = || Role::ALL.iter().map(|r| r.name()).collect::<Vec<_>>().join(", ");
    let mut groups = Vec::with_capacity(specs.len());
    let mut first_dim = 0;
    for s in specs {
        let (joint, site_offset) = if s.on_root() {
            (0, Vec3::ZERO)
        } else if let Some(site) = skeleton.site(&s.joint) {
            (site.joint as usize, site.offset)
        } else if Role::from_name(&s.joint).is_some() {
            return Err(Error::config(format!(
                "feature '{}': the skeleton has no {} joint (set it in \"roles\")",
                s.name, s.joint
            )));
        } else {
            let j = skeleton.joint_index(&s.joint).ok_or_else(|| {
                Error::config(format!(
                    "feature '{}': '{}' is neither a role ({}), 'root', nor a joint name",
                    s.name,
                    s.joint,
                    role_list()
                ))
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
/// group's mean standard deviation over the weight (docs/method.md §2). Returns (mean, scale).
pub fn normalize(features: &mut [f32], groups: &[FeatureGroup], num_dims: usize) -> (Vec<f32>, Vec<f32>) {
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
    // The loader's own step (`pose_features::apply_normalization`): the same f32 operations, so a
    // file's derived features are these bits.
    apply_normalization(features, &mean, &scale);
    (mean, scale)
}

/// Frames whose feature window stays inside their clip.
pub fn validity(clips: &[Clip], groups: &[FeatureGroup], num_frames: usize) -> Vec<u8> {
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
