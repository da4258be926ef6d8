//! The character's root (joint 0) in the world: moved by the database's root motion as it
//! plays, its velocity jumps at transitions inertialized (docs/method.md §5), then kept with
//! the simulated character by adjustment and clamping (§6).

use super::settings::CharacterSettings;
use crate::controller::Simulation;
use crate::database::Database;
use crate::persist::{Persist, Visitor};
use crate::spring::{decay_spring_damper_exact, quat_abs};
use glam::{Quat, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RootMotion {
    pub position: Vec3,
    pub rotation: Quat,
    pub velocity: Vec3,
    pub angular_velocity: Vec3,
    /// Inertialization offsets of the root's velocity and yaw rate (world space), and their rates.
    velocity_offset: Vec3,
    velocity_offset_rate: Vec3,
    angular_offset: Vec3,
    angular_offset_rate: Vec3,
    /// Velocity the root gets from adjustment and clamping (not from the database), world,
    /// smoothed over [`DRAG_HALFLIFE`]: how fast the character is being dragged.
    pub drag_velocity: Vec3,
}

/// Smoothing of [`RootMotion::drag_velocity`]: the clamp moves the root in steps of a frame,
/// the adjustment by a decaying spring; a fifth of a second shows the drag, not the steps.
const DRAG_HALFLIFE: f32 = 0.2;

impl Default for RootMotion {
    fn default() -> Self {
        RootMotion {
            position: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            velocity_offset: Vec3::ZERO,
            velocity_offset_rate: Vec3::ZERO,
            angular_offset: Vec3::ZERO,
            angular_offset_rate: Vec3::ZERO,
            drag_velocity: Vec3::ZERO,
        }
    }
}

impl Persist for RootMotion {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.position.persist(v, "root position");
        self.rotation.persist(v, "root rotation");
        self.velocity.persist(v, "root velocity");
        self.angular_velocity.persist(v, "root angular velocity");
        self.velocity_offset.persist(v, "root velocity offset");
        self.velocity_offset_rate.persist(v, "root velocity offset rate");
        self.angular_offset.persist(v, "root angular offset");
        self.angular_offset_rate.persist(v, "root angular offset rate");
        self.drag_velocity.persist(v, "root drag velocity");
    }
}

impl RootMotion {
    /// World velocity and angular velocity of the database root at `frame`, carried into the
    /// character's frame.
    fn motion_at(&self, db: &Database, frame: usize) -> (Vec3, Vec3) {
        let to_world = self.rotation * db.local_rotations[frame * db.num_joints()].inverse();
        let (velocity, angular) = db.joint_velocity(frame, 0);
        (to_world * velocity, to_world * angular)
    }

    /// Starts playing `frame` with no offsets, moving as it moves (a placed copy, not a jump).
    pub fn start_at(&mut self, db: &Database, frame: usize) {
        self.transition(db, frame, false);
        (self.velocity, self.angular_velocity) = self.motion_at(db, frame);
    }

    /// A jump to `frame`: with `inertialize`, the velocity and yaw-rate mismatch becomes an
    /// offset that decays (what is output now already includes the old offset, so the new one
    /// is simply output − target, Bollo's form); else a hard cut.
    pub fn transition(&mut self, db: &Database, frame: usize, inertialize: bool) {
        if inertialize {
            let (velocity, angular) = self.motion_at(db, frame);
            self.velocity_offset = self.velocity - velocity;
            self.angular_offset = self.angular_velocity - angular;
        } else {
            self.velocity_offset = Vec3::ZERO;
            self.angular_offset = Vec3::ZERO;
        }
    }

    /// Plays one database frame from `frame` to `next`: the database root's motion as a delta
    /// in its own frame, applied to ours, plus the decaying offsets.
    pub fn step(&mut self, db: &Database, frame: usize, next: usize, halflife: f32) {
        let j = db.num_joints();
        let (p0, r0) = (db.local_positions[frame * j], db.local_rotations[frame * j]);
        let (p1, r1) = (db.local_positions[next * j], db.local_rotations[next * j]);
        let frame_dt = 1.0 / db.fps;
        let delta_position = self.rotation * (r0.inverse() * (p1 - p0));
        let delta_rotation = r0.inverse() * r1;
        self.position += delta_position + self.velocity_offset * frame_dt;
        self.rotation =
            (Quat::from_scaled_axis(self.angular_offset * frame_dt) * self.rotation * delta_rotation).normalize();
        decay_spring_damper_exact(&mut self.velocity_offset, &mut self.velocity_offset_rate, halflife, frame_dt);
        decay_spring_damper_exact(&mut self.angular_offset, &mut self.angular_offset_rate, halflife, frame_dt);
        let (v, w) = self.motion_at(db, next);
        self.velocity = v + self.velocity_offset;
        self.angular_velocity = w + self.angular_offset;
    }

    /// Adjustment toward the simulated character, then clamping at α (docs/method.md §6).
    pub fn keep_with(&mut self, simulation: &Simulation, s: &CharacterSettings, dt: f32) {
        let before = self.position;
        self.adjust_and_clamp(simulation, s, dt);
        if dt > 0.0 {
            let drag = (self.position - before) / dt;
            self.drag_velocity += (drag - self.drag_velocity) * (1.0 - (-dt / DRAG_HALFLIFE).exp2());
        }
    }

    fn adjust_and_clamp(&mut self, simulation: &Simulation, s: &CharacterSettings, dt: f32) {
        if s.adjustment && dt > 0.0 {
            // Exact exponential approach with the given half-life, capped by the character's
            // own speed so that an idle character is never dragged.
            let target = Vec3::new(simulation.position.x, 0.0, simulation.position.z);
            let mut step = (target - self.position) * (1.0 - (-dt / s.adjustment_position_halflife).exp2());
            let cap = (s.adjustment_max_ratio * self.velocity.length()).max(s.adjustment_min_speed) * dt;
            if step.length() > cap {
                step = step.normalize_or_zero() * cap;
            }
            self.position += step;
            let offset = quat_abs(simulation.rotation * self.rotation.inverse());
            let mut turn = offset.to_scaled_axis() * (1.0 - (-dt / s.adjustment_rotation_halflife).exp2());
            let cap = s.adjustment_max_ratio * self.angular_velocity.length() * dt;
            if turn.length() > cap {
                turn = turn.normalize_or_zero() * cap;
            }
            self.rotation = (Quat::from_scaled_axis(turn) * self.rotation).normalize();
        }
        if s.clamping {
            let target = Vec3::new(simulation.position.x, 0.0, simulation.position.z);
            let offset = self.position - target;
            if offset.length() > s.clamp_distance {
                self.position = target + offset.normalize() * s.clamp_distance;
            }
            // Both rotations are pure yaws: clamp the yaw difference.
            let (axis, angle) = quat_abs(self.rotation * simulation.rotation.inverse()).to_axis_angle();
            if angle > s.clamp_angle {
                self.rotation = (Quat::from_axis_angle(axis, s.clamp_angle) * simulation.rotation).normalize();
            }
        }
    }
}
