//! One take's resampled local transforms → database rows: world transforms by the one FK, the
//! virtual root, local pose rows and foot contacts. (Features come from the finished rows:
//! `crate::pose_features`, as on load.)

use super::contacts::contacts;
use super::poses::Poses;
use super::root::virtual_root;
use super::rows::Rows;
use crate::config::BuildConfig;
use crate::database::Site;
use crate::kinematics::local_to_model;
use glam::{DQuat, DVec3};

/// Per-thread temporaries of [`ClipBuilder::append`] and the resampling, kept between clips:
/// fresh ones per clip add up to ~100 MB of f64 temporaries for the default database, and WASM
/// memory never shrinks once grown.
#[derive(Default)]
pub struct Scratch {
    pub locals: Poses,
    pub reversed: Poses,
    world: Poses,
    root_xz: Vec<f64>,
    facing: Vec<f64>,
    root: Vec<(DVec3, DQuat)>,
    lp: Vec<DVec3>,
    lr: Vec<DQuat>,
    contacts: Vec<[bool; 2]>,
}

/// Turns one take's local transforms into database rows.
pub struct ClipBuilder<'a> {
    pub config: &'a BuildConfig,
    pub fps: f64,
    /// BVH joint parents (negative for the root).
    pub parents: &'a [i32],
    pub hips: usize,
    pub forward_rest: DVec3,
    pub toe_sites: &'a [Option<Site>; 2],
}

/// World geometry of one clip: database joint `j` is BVH joint `j − 1`; joint 0 is the root.
struct Geometry<'a> {
    world: &'a Poses,
    root: &'a [(DVec3, DQuat)],
    /// Seconds per frame.
    dt: f64,
}

impl Geometry<'_> {
    /// World position of `offset` in `joint`'s space.
    fn point(&self, f: usize, joint: usize, offset: DVec3) -> DVec3 {
        if joint == 0 {
            self.root[f].0
        } else {
            let (p, q) = self.world.at(f, joint - 1);
            p + q * offset
        }
    }
    /// Velocity of [`Geometry::point`] by central differences.
    fn velocity(&self, f: usize, joint: usize, offset: DVec3) -> DVec3 {
        let (a, b) = (f.saturating_sub(1), (f + 1).min(self.root.len() - 1));
        (self.point(b, joint, offset) - self.point(a, joint, offset)) / ((b - a) as f64 * self.dt)
    }
}

impl ClipBuilder<'_> {
    /// Appends one clip; `root_window` is its virtual-root smoothing window (s).
    pub fn append(&self, locals: &Poses, out: Rows, scratch: &mut Scratch, root_window: f64) {
        let (n, nj) = (locals.num_frames(), locals.num_joints);

        // World transforms of the source joints.
        let world = &mut scratch.world;
        world.reset(nj, n);
        world.positions.resize(n * nj, DVec3::ZERO);
        world.rotations.resize(n * nj, DQuat::IDENTITY);
        for f in 0..n {
            let r = f * nj..(f + 1) * nj;
            local_to_model(
                self.parents,
                0..nj,
                None,
                &locals.positions[r.clone()],
                &locals.rotations[r.clone()],
                &mut world.positions[r.clone()],
                &mut world.rotations[r],
            );
        }

        let (c, hips) = (self.config, self.hips);
        let world = &scratch.world;
        virtual_root(
            n,
            |f| world.at(f, hips),
            self.forward_rest,
            self.fps,
            root_window,
            c.root_facing_window,
            &mut scratch.root_xz,
            &mut scratch.facing,
            &mut scratch.root,
        );
        let root = &scratch.root;

        // Local pose rows: joint 0 = root (world), source root re-expressed under it.
        let nd = nj + 1;
        let (lp, lr) = (&mut scratch.lp, &mut scratch.lr);
        lp.clear();
        lr.clear();
        // Exact capacities: the build's memory estimate (`limits::BuildFootprint`) counts on
        // them, and a doubling `push` would hold the old and the new buffer at once.
        lp.reserve_exact(n * nd);
        lr.reserve_exact(n * nd);
        for f in 0..n {
            let (rp, rq) = root[f];
            lp.push(rp);
            lr.push(rq);
            for j in 0..nj {
                let (t, q) = locals.at(f, j);
                if self.parents[j] < 0 {
                    let inv = rq.conjugate();
                    lp.push(inv * (t - rp));
                    lr.push(inv * q);
                } else {
                    lp.push(t);
                    lr.push(q);
                }
            }
        }
        // Keep each joint's quaternions in one hemisphere over time so differences and later
        // interpolation take the short way.
        for f in 1..n {
            for j in 0..nd {
                if lr[f * nd + j].dot(lr[(f - 1) * nd + j]) < 0.0 {
                    lr[f * nd + j] = -lr[f * nd + j];
                }
            }
        }
        // (Velocities are derived from these rows, a frame at a time, as a character plays
        // it: `Database::frame_velocities`, the same for a built and a loaded database.)
        let geometry = Geometry { world, root, dt: 1.0 / self.fps };
        for (i, (p, q)) in lp.iter().zip(lr.iter()).enumerate() {
            out.positions[i] = p.as_vec3();
            out.rotations[i] = q.as_quat();
        }

        let toe_speed = |side: usize, f: usize| {
            self.toe_sites[side].as_ref().map(|s| geometry.velocity(f, s.joint as usize, s.offset.as_dvec3()).length())
        };
        let radius = (c.contact_filter * self.fps).round() as usize;
        contacts(n, toe_speed, c.contact_speed, radius, &mut scratch.contacts, out.contacts);
    }
}
