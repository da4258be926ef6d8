//! The character's runtime state as bytes ([`crate::persist`]): a shared room's late joiner
//! loads the sender's state into its copy, which from then on computes the sender's own floats
//! from the same inputs (docs/rooms.md, "Late joiners"). Settings, the search mask and the
//! path's points are not state: the receiver has its own (the same, by the room's contract).
//!
//! Layout: a header of five u32 — magic `MMRS`, [`STATE_VERSION`], joints, frames and feature
//! dimensions of the database (a state from another database is refused) — then the fields in
//! the order [`Character`]'s `persist` lists them.

use super::{Character, LastGood, Mode, MAX_FRAMES_PER_UPDATE};
use crate::controller::MAX_PATH_COORDINATE;
use crate::database::Database;
use crate::persist::{Persist, StateReader, StateWriter, Visitor};

const STATE_MAGIC: u32 = u32::from_le_bytes(*b"MMRS");
/// Bumped whenever a field is added, removed or reordered.
pub const STATE_VERSION: u32 = 6;

impl Persist for LastGood {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.position.persist(v, "last good position");
        self.rotation.persist(v, "last good rotation");
        self.simulation.persist(v, "");
    }
}

impl Persist for Character {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.simulation.persist(v, "");
        self.frame.persist(v, "frame");
        self.frame_fraction.persist(v, "frame fraction");
        self.drive.persist(v, "");
        self.schedule.persist(v, "");
        self.query.persist(v, "");
        self.root.persist(v, "");
        self.pose.persist(v, "");
        self.legs.persist(v, "");
        self.head_offset.persist(v, "head offset");
        self.input.persist(v, "");
        self.tracked.persist(v, "");
        self.last_good.persist(v, "");
    }
}

impl Character {
    /// The runtime state as bytes (allocates: call on request, not every frame).
    pub fn save_state(&self, db: &Database) -> Vec<u8> {
        let mut w = StateWriter::default();
        for mut x in
            [STATE_MAGIC, STATE_VERSION, db.num_joints() as u32, db.num_frames as u32, db.num_features() as u32]
        {
            x.persist(&mut w, "");
        }
        let mut state = self.clone();
        state.pose.hold_velocities(db, state.frame);
        state.persist(&mut w, "");
        w.bytes
    }

    /// Continues from a state [`Self::save_state`] wrote on the same database. Untrusted bytes:
    /// everything is read and checked into a copy first, so a refused state (the reason names
    /// the field and byte) leaves the character exactly as it was. A path must be set first
    /// if the state follows one.
    ///
    /// # Errors
    /// Another database or version, short or long bytes, a value not finite or out of range.
    pub fn load_state(&mut self, db: &Database, bytes: &[u8]) -> Result<(), String> {
        let mut r = StateReader::new(bytes);
        let expect = [
            (STATE_MAGIC, "magic"),
            (STATE_VERSION, "version"),
            (db.num_joints() as u32, "joint count"),
            (db.num_frames as u32, "frame count"),
            (db.num_features() as u32, "feature count"),
        ];
        for (want, what) in expect {
            let mut x = 0u32;
            x.persist(&mut r, what);
            if x != want {
                r.fail(format!("runtime state {what} is {x}, expected {want}"));
            }
        }
        let mut next = self.clone();
        next.persist(&mut r, "");
        r.finish()?;
        if next.frame >= db.num_frames {
            return Err(format!(
                "runtime state frame {} is beyond the database's {} frames",
                next.frame, db.num_frames
            ));
        }
        if !next.schedule.left_is_within(db.num_frames) {
            return Err(format!(
                "runtime state's last jump left a frame beyond the database's {} frames",
                db.num_frames
            ));
        }
        if !(0.0..=MAX_FRAMES_PER_UPDATE as f32).contains(&next.frame_fraction) || next.legs.hips_drop < 0.0 {
            return Err("runtime state frame fraction or hips drop out of range".into());
        }
        let far = |p: glam::Vec3| !(p.x.abs() <= MAX_PATH_COORDINATE && p.z.abs() <= MAX_PATH_COORDINATE);
        if far(next.root.position) || far(next.simulation.position) {
            return Err(format!("runtime state root beyond ±{MAX_PATH_COORDINATE} m"));
        }
        if let Mode::Path { time, .. } = next.drive.mode {
            if !(0.0..=86_400.0).contains(&time) {
                return Err(format!("runtime state path time {time} s"));
            }
        }
        next.pose.forward_kinematics(&db.skeleton.parents, 0..db.num_joints());
        *self = next;
        Ok(())
    }
}
