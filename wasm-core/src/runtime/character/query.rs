//! The search query (docs/method.md §3): the pose part copied from the frame playing, the
//! trajectory part from the drive's prediction, expressed in the character's root space and
//! normalized like the database's features.

use super::drive::Drive;
use crate::controller::{ControllerSettings, Simulation};
use crate::database::{Axes, Database, FeatureKind};
use crate::persist::{Persist, Visitor};
use glam::{Quat, Vec3};

/// Where a trajectory feature dimension comes from.
#[derive(Clone, Copy, Debug)]
struct TrajectorySlot {
    first_dim: usize,
    kind: FeatureKind,
    axes: Axes,
    axis: Vec3,
    /// Index into the prediction times.
    time: usize,
}

/// The query buffer and the prediction it is built from; allocated once per character.
#[derive(Clone, Debug)]
pub struct Query {
    /// Normalized features of the last query.
    pub values: Vec<f32>,
    /// First dimension of each 3-axis velocity feature on the hips (or the root): the pose
    /// part's body velocity, which [`Query::add_drag`] corrects.
    body_velocity_dims: Vec<usize>,
    slots: Vec<TrajectorySlot>,
    /// Prediction times (s) of the trajectory features.
    pub times: Vec<f32>,
    /// The predicted trajectory at the last search (world space).
    pub predicted_positions: Vec<Vec3>,
    pub predicted_rotations: Vec<Quat>,
}

/// The last query (a database switch searches with its pose part) and the prediction shown.
impl Persist for Query {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.values.persist(v, "query");
        self.predicted_positions.persist(v, "predicted positions");
        self.predicted_rotations.persist(v, "predicted rotations");
    }
}

impl Query {
    pub fn new(db: &Database) -> Query {
        let mut times: Vec<f32> = Vec::new();
        let mut slots = Vec::new();
        for g in db.groups.iter().filter(|g| g.is_trajectory) {
            for (k, &offset) in g.offsets.iter().enumerate() {
                // Past offsets would need a history of the simulation; they are taken from the
                // database frame like pose features (documented limitation).
                if offset <= 0 {
                    continue;
                }
                let t = offset as f32 / db.fps;
                let time = times.iter().position(|&x| x == t).unwrap_or_else(|| {
                    times.push(t);
                    times.len() - 1
                });
                slots.push(TrajectorySlot {
                    first_dim: g.first_dim + k * g.axes.num_dims(),
                    kind: g.kind,
                    axes: g.axes,
                    axis: g.axis,
                    time,
                });
            }
        }
        let hips = db.skeleton.site("hips").map_or(-1, |s| s.joint);
        let body_velocity_dims = db
            .groups
            .iter()
            .filter(|g| {
                !g.is_trajectory
                    && g.kind == FeatureKind::Velocity
                    && g.axes == Axes::Xyz
                    && (g.joint as i32 == hips || g.joint == 0)
                    && g.offsets == [0]
            })
            .map(|g| g.first_dim)
            .collect();
        Query {
            values: vec![0.0; db.num_features()],
            body_velocity_dims,
            predicted_positions: vec![Vec3::ZERO; times.len()],
            predicted_rotations: vec![Quat::IDENTITY; times.len()],
            slots,
            times,
        }
    }

    /// Fills the trajectory part from the drive's prediction, relative to the root at
    /// `(root_position, root_rotation)`, normalized with `db`'s mean and scale. The pose part
    /// must already be in `values` (see [`Query::set_pose`]).
    pub fn set_trajectory(
        &mut self,
        db: &Database,
        drive: &Drive,
        simulation: &Simulation,
        settings: &ControllerSettings,
        root_position: Vec3,
        root_rotation: Quat,
    ) {
        drive.predict(simulation, settings, &self.times, &mut self.predicted_positions, &mut self.predicted_rotations);
        let inv = root_rotation.inverse();
        for slot in &self.slots {
            let v = match slot.kind {
                FeatureKind::Position => inv * (self.predicted_positions[slot.time] - root_position),
                FeatureKind::Direction => inv * (self.predicted_rotations[slot.time] * slot.axis),
                // The simulation has one velocity; use it for any velocity-at-offset feature.
                FeatureKind::Velocity => inv * simulation.velocity,
            };
            let d = slot.first_dim;
            match slot.axes {
                Axes::Xyz => self.values[d..d + 3].copy_from_slice(&[v.x, v.y, v.z]),
                Axes::Xz => self.values[d..d + 2].copy_from_slice(&[v.x, v.z]),
            }
            for k in d..d + slot.axes.num_dims() {
                self.values[k] = (self.values[k] - db.feature_mean[k]) / db.feature_scale[k];
            }
        }
    }

    /// The pose part: the (normalized) features of the frame playing, all of them (the
    /// trajectory part is overwritten by [`Query::set_trajectory`]).
    pub fn set_pose(&mut self, features: &[f32]) {
        self.values.copy_from_slice(features);
    }

    /// Adds the root's drag (`drag_velocity`, world: what adjustment and clamping move it by,
    /// see `RootMotion::drag_velocity`) to the pose part's hips velocity, expressed in the
    /// character's root space at `root_rotation`.
    ///
    /// Why: the pose part says what the character *is doing*; copied from the frame playing it
    /// says "standing" while the clamp drags a standing character after a walking user (VR) or
    /// sideways (strafing without side-steps), and the search keeps returning standing frames
    /// whose planted feet then slide. With the drag the query describes the motion actually
    /// shown, so frames that really move that way win (docs/runtime.md, "Dragged roots").
    pub fn add_drag(&mut self, db: &Database, drag_velocity: Vec3, root_rotation: Quat) {
        let v = root_rotation.inverse() * drag_velocity;
        for &d in &self.body_velocity_dims {
            for (k, x) in [v.x, v.y, v.z].into_iter().enumerate() {
                self.values[d + k] += x / db.feature_scale[d + k];
            }
        }
    }
}
