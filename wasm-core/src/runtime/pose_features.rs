//! The feature values of a database's frames, derived from its poses (docs/method.md §2,
//! docs/mmdb-format.md "Features (not stored)"): the builder and the `.mmdb` reader compute
//! them with this one recipe, so a file need not carry the feature matrix (1.9 of the default
//! database's 4.6 MB brotli) and a first part's frames score exactly as the whole's.
//!
//! Everything is f64 until the values are stored as f32: f64 arithmetic without fused
//! multiply-adds rounds the same on every target, so a page (WASM) derives the same bits as
//! the native CLI from the same file.

use crate::database::{Axes, Clip, FeatureGroup, FeatureKind};
use crate::kinematics::local_to_model;
use glam::{DQuat, DVec3, Quat, Vec3};

/// Raw (unnormalized) features of every frame of a clip, in the character space of each
/// frame, into `out` (`num_frames × num_dims`). Offsets past the clip's ends are clamped.
fn raw_features(clip: &ClipWorld, groups: &[FeatureGroup], num_dims: usize, out: &mut [f32]) {
    let n = clip.num_frames();
    for (f, row) in out.chunks_exact_mut(num_dims).enumerate() {
        let (rp, rq) = clip.root(f);
        let inv = rq.conjugate();
        for g in groups {
            let offset = g.axis.as_dvec3();
            for (k, &o) in g.offsets.iter().enumerate() {
                let f2 = (f as i64 + o as i64).clamp(0, n as i64 - 1) as usize;
                let site_offset = if g.kind == FeatureKind::Direction { DVec3::ZERO } else { offset };
                let v = match g.kind {
                    FeatureKind::Position => inv * (clip.point(f2, g.joint, site_offset) - rp),
                    FeatureKind::Velocity => inv * clip.velocity(f2, g.joint, site_offset),
                    FeatureKind::Direction => inv * (clip.rotation(f2, g.joint) * offset),
                };
                let d = g.first_dim + k * g.axes.num_dims();
                match g.axes {
                    Axes::Xyz => row[d..d + 3].copy_from_slice(&[v.x as f32, v.y as f32, v.z as f32]),
                    Axes::Xz => row[d..d + 2].copy_from_slice(&[v.x as f32, v.z as f32]),
                }
            }
        }
    }
}

/// World transforms of joints `0..m` of one clip's frames (`n × m`, frame-major).
struct ClipWorld<'a> {
    positions: &'a [DVec3],
    rotations: &'a [DQuat],
    m: usize,
    dt: f64,
}

impl ClipWorld<'_> {
    fn num_frames(&self) -> usize {
        self.positions.len() / self.m
    }
    fn root(&self, f: usize) -> (DVec3, DQuat) {
        (self.positions[f * self.m], self.rotations[f * self.m])
    }
    /// World position of `offset` in `joint`'s space.
    fn point(&self, f: usize, joint: usize, offset: DVec3) -> DVec3 {
        self.positions[f * self.m + joint] + self.rotations[f * self.m + joint] * offset
    }
    fn rotation(&self, f: usize, joint: usize) -> DQuat {
        self.rotations[f * self.m + joint]
    }
    /// Velocity of [`ClipWorld::point`] by central differences (one-sided at the clip's ends,
    /// zero for a one-frame clip).
    fn velocity(&self, f: usize, joint: usize, offset: DVec3) -> DVec3 {
        let (a, b) = (f.saturating_sub(1), (f + 1).min(self.num_frames() - 1));
        if a >= b {
            return DVec3::ZERO;
        }
        (self.point(b, joint, offset) - self.point(a, joint, offset)) / ((b - a) as f64 * self.dt)
    }
}

/// Raw features (`F × D`) of `F × J` local poses cut into `clips`, each clip on its own
/// (offsets clamped to it, velocities differenced within it). Forward kinematics covers only
/// the joints up to the highest one a group measures (the one FK, in f64).
#[allow(clippy::too_many_arguments)]
pub fn pose_features(
    parents: &[i32],
    fps: f32,
    clips: &[Clip],
    groups: &[FeatureGroup],
    num_dims: usize,
    positions: &[Vec3],
    rotations: &[Quat],
) -> Vec<f32> {
    let joints = parents.len().max(1);
    let frames = positions.len().min(rotations.len()) / joints;
    let mut out = vec![0.0f32; frames * num_dims];
    let m = groups.iter().map(|g| g.joint + 1).max().unwrap_or(1).min(joints);
    let longest = clips.iter().map(|c| c.end.saturating_sub(c.start) as usize).max().unwrap_or(0);
    let (mut world_p, mut world_q) = (vec![DVec3::ZERO; longest * m], vec![DQuat::IDENTITY; longest * m]);
    let (mut local_p, mut local_q) = (vec![DVec3::ZERO; m], vec![DQuat::IDENTITY; m]);
    for clip in clips {
        let (start, end) = (clip.start as usize, (clip.end as usize).min(frames));
        if start >= end {
            continue;
        }
        let n = end - start;
        for f in 0..n {
            let row = (start + f) * joints;
            for k in 0..m {
                local_p[k] = positions[row + k].as_dvec3();
                local_q[k] = rotations[row + k].as_dquat();
            }
            let w = f * m..(f + 1) * m;
            local_to_model(parents, 0..m, None, &local_p, &local_q, &mut world_p[w.clone()], &mut world_q[w]);
        }
        let world = ClipWorld { positions: &world_p[..n * m], rotations: &world_q[..n * m], m, dt: 1.0 / fps as f64 };
        raw_features(&world, groups, num_dims, &mut out[start * num_dims..end * num_dims]);
    }
    out
}

/// `(x − mean) / scale` per dimension, in place: a raw feature row becomes a stored one
/// (docs/method.md §2; the builder's normalization computes `mean` and `scale`).
pub fn apply_normalization(features: &mut [f32], mean: &[f32], scale: &[f32]) {
    let d = mean.len().min(scale.len()).max(1);
    for row in features.chunks_exact_mut(d) {
        for ((x, &m), &s) in row.iter_mut().zip(mean).zip(scale) {
            *x = (*x - m) / s;
        }
    }
}
