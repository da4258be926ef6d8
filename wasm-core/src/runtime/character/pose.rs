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
    /// The inertialized pose's velocities, held for the next transition's source
    /// ([`Pose::hold_velocities`]): derived when a transition or a saved state needs them, not
    /// every update (only those read them).
    velocities: Vec<Vec3>,
    angular_velocities: Vec<Vec3>,
    /// Whether `velocities` are the current pose's (until the next `play`), and whether that
    /// `play` applied the inertialization's offsets.
    held: bool,
    inertialized: bool,
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
        // A writer holds them first (`Character::save_state`); read, they are the sender's.
        if v.reading() {
            self.held = true;
        }
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
            held: false,
            inertialized: false,
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

    /// Derives the velocities of the pose the last `play` wrote — `frame`'s, inertialized as
    /// it was — and holds them until the next `play` (a second call keeps the first's: after a
    /// switch of databases they are the old database's). A frame beyond `db` holds zeros.
    pub fn hold_velocities(&mut self, db: &Database, frame: usize) {
        if self.held {
            return;
        }
        self.held = true;
        if frame >= db.num_frames {
            self.velocities.fill(Vec3::ZERO);
            self.angular_velocities.fill(Vec3::ZERO);
            return;
        }
        db.frame_velocities(frame, &mut self.frame_velocities, &mut self.frame_angular_velocities);
        let (lv, lw) = (&self.frame_velocities[1..], &self.frame_angular_velocities[1..]);
        if self.inertialized {
            self.inertializer.velocities(lv, lw, &mut self.velocities[1..], &mut self.angular_velocities[1..]);
        } else {
            self.velocities[1..].copy_from_slice(lv);
            self.angular_velocities[1..].copy_from_slice(lw);
        }
    }

    /// A jump from `from` (the frame the last `play` wrote) to `frame`: the offsets take what is
    /// output now (joint 0, the root, is the root motion's business); without `inertialize`, a
    /// hard cut.
    pub fn transition(&mut self, db: &Database, from: usize, frame: usize, inertialize: bool) {
        if inertialize {
            self.hold_velocities(db, from);
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

    /// Writes `frame`'s pose, inertialized over `dt` (its velocities only when asked for:
    /// [`Pose::hold_velocities`]).
    pub fn play(&mut self, db: &Database, frame: usize, inertialize: bool, halflife: f32, dt: f32) {
        let (lp, lr) = frame_pose(db, frame);
        if inertialize {
            self.inertializer.update(
                &lp[1..],
                &lr[1..],
                halflife,
                dt,
                &mut self.positions[1..],
                &mut self.rotations[1..],
            );
        } else {
            self.positions[1..].copy_from_slice(&lp[1..]);
            self.rotations[1..].copy_from_slice(&lr[1..]);
        }
        (self.held, self.inertialized) = (false, inertialize);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::database::{Clip, Skeleton};

    /// One clip of 10 frames at 60 fps, two joints; the child's local position at frame `f` is
    /// `child(f)`.
    fn database(child: impl Fn(usize) -> Vec3) -> Database {
        let n = 10;
        Database {
            skeleton: Skeleton {
                names: vec!["root".into(), "child".into()],
                parents: vec![-1, 0],
                offsets: vec![Vec3::ZERO, Vec3::X],
                sites: vec![],
                mirror: vec![],
            },
            fps: 60.0,
            num_frames: n,
            clips: vec![Clip {
                name: "c".into(),
                source: "c".into(),
                start: 0,
                end: n as u32,
                mirrored: false,
                source_fps: 60.0,
                source_start: 0,
                scale: 1.0,
                root_scale: 1.0,
            }],
            tags: vec![],
            local_positions: (0..n).flat_map(|f| [Vec3::ZERO, child(f)]).collect(),
            local_rotations: vec![Quat::IDENTITY; 2 * n],
            contacts: vec![0; 2 * n],
            groups: vec![],
            feature_mean: vec![],
            feature_scale: vec![],
            features: vec![],
            valid: vec![1; n],
            part: None,
            velocities: Default::default(),
        }
    }

    /// A switch of databases: the transition's source moves as the old database's frame did,
    /// not as the same frame of the new one.
    #[test]
    fn held_velocities_are_the_database_played() {
        let moving = database(|f| Vec3::new(1.0 + f as f32 / 60.0, 0.0, 0.0)); // 1 m/s
        let still = database(|_| Vec3::new(2.0, 0.0, 0.0));
        let mut pose = Pose::new(2);
        pose.play(&moving, 4, true, 0.1, 1.0 / 60.0);
        let mut switched = pose.clone();
        switched.hold_velocities(&moving, 4);
        switched.hold_velocities(&still, 4); // kept: the first call's
        assert!((switched.velocities[1] - Vec3::X).length() < 1e-4, "{}", switched.velocities[1]);
        switched.transition(&still, 4, 4, true);
        // Source 1 m/s, target still: the offset carries the whole velocity, and the position.
        let offset = switched.inertializer.offset_velocities()[0];
        assert!((offset - Vec3::X).length() < 1e-4, "{offset}");
        assert!(
            (switched.inertializer.offset_positions()[0] - Vec3::new(-(2.0 - 1.0 - 4.0 / 60.0), 0.0, 0.0)).length()
                < 1e-5
        );
        // Without the switch the source is the frame's own velocity in the database given.
        pose.transition(&still, 4, 4, true);
        assert!(pose.inertializer.offset_velocities()[0].length() < 1e-6);
        // A play releases what was held.
        switched.play(&still, 5, true, 0.1, 1.0 / 60.0);
        assert!(!switched.held);
    }
}
