//! The character's pose: the database frame playing, inertialized (docs/method.md §5), and the
//! shown pose — the same with the leg touch-ups — in local and world space. The world pose is
//! what the runtime hands out (no caller needs forward kinematics of its own).

use crate::database::Database;
use crate::inertialize::Inertializer;
use crate::kinematics::local_to_model;
use crate::persist::{Persist, Visitor};
use glam::{Quat, Vec3};

#[derive(Clone, Debug)]
pub struct Pose {
    inertializer: Inertializer,
    /// Inertialized pose: joint 0 holds the root's world transform, the others local
    /// transforms. Transitions start from this, never from the touched-up output (else the
    /// touch-ups would be folded into the offsets and decay away).
    pub positions: Vec<Vec3>,
    pub rotations: Vec<Quat>,
    pub velocities: Vec<Vec3>,
    pub angular_velocities: Vec<Vec3>,
    /// What is shown: the inertialized rotations with the leg IK applied.
    pub output_rotations: Vec<Quat>,
    /// World transforms of the shown pose.
    pub world_positions: Vec<Vec3>,
    pub world_rotations: Vec<Quat>,
    /// Foot contacts of the frame playing (left, right).
    pub contacts: [u8; 2],
    /// Scratch, not state: the velocities of the frame playing or jumped to, derived when it is
    /// ([`Database::frame_velocities`]).
    frame_velocities: Vec<Vec3>,
    frame_angular_velocities: Vec<Vec3>,
}

/// Local positions and rotations of one frame.
fn frame_pose(db: &Database, frame: usize) -> (&[Vec3], &[Quat]) {
    let j = db.num_joints();
    let r = frame * j..(frame + 1) * j;
    (&db.local_positions[r.clone()], &db.local_rotations[r])
}

/// The world transforms are not stored: the reader recomputes them from the rest by the one FK
/// ([`Pose::forward_kinematics`]), so a stored shown pose can never disagree with its locals.
impl Persist for Pose {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.inertializer.persist(v, "");
        self.positions.persist(v, "joint positions");
        self.rotations.persist(v, "joint rotations");
        self.velocities.persist(v, "joint velocities");
        self.angular_velocities.persist(v, "joint angular velocities");
        self.output_rotations.persist(v, "shown joint rotations");
        self.contacts.persist(v, "contacts");
    }
}

impl Pose {
    pub fn new(num_joints: usize) -> Pose {
        let j = num_joints;
        Pose {
            inertializer: Inertializer::new(j - 1),
            positions: vec![Vec3::ZERO; j],
            rotations: vec![Quat::IDENTITY; j],
            velocities: vec![Vec3::ZERO; j],
            angular_velocities: vec![Vec3::ZERO; j],
            output_rotations: vec![Quat::IDENTITY; j],
            world_positions: vec![Vec3::ZERO; j],
            world_rotations: vec![Quat::IDENTITY; j],
            contacts: [0; 2],
            frame_velocities: vec![Vec3::ZERO; j],
            frame_angular_velocities: vec![Vec3::ZERO; j],
        }
    }

    /// Drops every inertialization offset (a hard cut at the next `play`).
    pub fn cut(&mut self) {
        self.inertializer.reset();
    }

    /// A jump to `frame`: the offsets take what is output now (joint 0, the root, is the root
    /// motion's business); without `inertialize`, a hard cut.
    pub fn transition(&mut self, db: &Database, frame: usize, inertialize: bool) {
        if inertialize {
            let j = db.num_joints();
            let (lp, lr) = frame_pose(db, frame);
            db.frame_velocities(frame, &mut self.frame_velocities, &mut self.frame_angular_velocities);
            let (lv, lw) = (&self.frame_velocities, &self.frame_angular_velocities);
            self.inertializer.transition_from_output(
                &self.positions[1..],
                &self.velocities[1..],
                &self.rotations[1..],
                &self.angular_velocities[1..],
                &lp[1..j],
                &lv[1..j],
                &lr[1..j],
                &lw[1..j],
            );
        } else {
            self.inertializer.reset();
        }
    }

    /// Writes `frame`'s pose, inertialized over `dt`, with the root at `(root_position,
    /// root_rotation)`.
    pub fn play(&mut self, db: &Database, frame: usize, inertialize: bool, halflife: f32, dt: f32) {
        let (lp, lr) = frame_pose(db, frame);
        db.frame_velocities(frame, &mut self.frame_velocities, &mut self.frame_angular_velocities);
        let (lv, lw) = (&self.frame_velocities, &self.frame_angular_velocities);
        if inertialize {
            self.inertializer.update(
                &lp[1..],
                &lv[1..],
                &lr[1..],
                &lw[1..],
                halflife,
                dt,
                &mut self.positions[1..],
                &mut self.velocities[1..],
                &mut self.rotations[1..],
                &mut self.angular_velocities[1..],
            );
        } else {
            self.positions[1..].copy_from_slice(&lp[1..]);
            self.rotations[1..].copy_from_slice(&lr[1..]);
            self.velocities[1..].copy_from_slice(&lv[1..]);
            self.angular_velocities[1..].copy_from_slice(&lw[1..]);
        }
        self.contacts = [db.contacts[2 * frame], db.contacts[2 * frame + 1]];
    }

    /// Places the root (joint 0).
    pub fn set_root(&mut self, position: Vec3, rotation: Quat) {
        self.positions[0] = position;
        self.rotations[0] = rotation;
    }

    /// The shown pose starts as the inertialized one; its world transforms by the one FK.
    pub fn reset_output(&mut self, parents: &[i32]) {
        self.output_rotations.copy_from_slice(&self.rotations);
        self.forward_kinematics(parents, 0..parents.len());
    }

    /// World transforms of the shown pose for `joints` (their parents outside the range must be
    /// current): after a touch-up of a limb, only its subtree.
    pub fn forward_kinematics(&mut self, parents: &[i32], joints: std::ops::Range<usize>) {
        local_to_model(
            parents,
            joints,
            None,
            &self.positions,
            &self.output_rotations,
            &mut self.world_positions,
            &mut self.world_rotations,
        );
    }
}
