//! One motion-matched character (docs/method.md §3–7). Each [`Character::update`], in order:
//! 1. **drive** ([`drive`]): input, a path or a tracked user moves the simulated character;
//! 2. **search scheduling** ([`schedule`]): on a timer, a sharp change or a clip end, the
//!    [`query`] is searched and a jump is inertialized;
//! 3. **root motion** ([`root`]): the database plays at its own rate, moving the root, which is
//!    then kept with the simulated character (adjustment, clamping);
//! 4. **pose** ([`pose`]): the frame playing, inertialized, and its world transforms (the one FK);
//! 5. **legs** ([`legs`]): foot lock and hips drop by leg IK, the torso bend ([`crouch`]),
//!    touched-up subtrees re-run by FK.
//!
//! Every buffer is allocated by [`Character::new`]: `update` allocates nothing.

pub mod crouch;
pub mod drive;
pub mod legs;
pub mod pose;
pub mod query;
pub mod root;
pub mod schedule;
pub mod settings;
mod state;

pub use drive::Tracked;
pub use schedule::CharacterStats;
pub use settings::CharacterSettings;

use crate::controller::{Input, Path, Simulation, MAX_PATH_COORDINATE};
use crate::database::{Database, Part};
use crate::search::SearchIndex;
use crate::skating::SkatingMeter;
use drive::{Drive, Mode};
use glam::{Quat, Vec3};
use legs::Legs;
use pose::Pose;
use query::Query;
use root::RootMotion;
use schedule::{Outcome, Schedule};

/// Smoothing of the avatar's head offset from its root in tracked mode (s): the head sways a few
/// cm with every step, which the user's own head already does.
pub const HEAD_OFFSET_HALFLIFE: f32 = 0.2;

/// Longest step one update simulates (s). A longer gap (a background tab, a paused debugger, a
/// garbage `dt`) is not played out frame by frame: the character searches afresh from where it
/// stands, so an update never runs away.
pub const MAX_DT: f32 = 0.25;

/// Most database frames one update plays (a safety net under [`MAX_DT`] and the playback speed).
pub(crate) const MAX_FRAMES_PER_UPDATE: u32 = 64;

/// Fastest ground velocity taken from a tracked user (m/s): beyond it a sample is garbage.
const MAX_TRACKED_SPEED: f32 = 50.0;

/// Where the character last was in a good (finite) state: where it goes back to.
#[derive(Clone, Copy, Debug)]
struct LastGood {
    position: Vec3,
    rotation: Quat,
    simulation: Simulation,
}

/// A character playing one database.
///
/// Every entry point is total: inputs that are not finite (or absurd) are refused and the last
/// good value is used, counted in [`CharacterStats::rejected_inputs`]; a character that reaches a
/// non-finite state anyway goes back to its last good state within the same update
/// ([`CharacterStats::recoveries`]). Preconditions on the database (≥ 1 frame and clip, the
/// same feature layout across a switch) are what the `.mmdb` loader guarantees.
#[derive(Clone)]
pub struct Character {
    pub settings: CharacterSettings,
    pub simulation: Simulation,
    pub stats: CharacterStats,
    /// Current database frame, and the fraction of a frame accumulated toward the next one.
    frame: usize,
    frame_fraction: f32,
    drive: Drive,
    schedule: Schedule,
    query: Query,
    root: RootMotion,
    pose: Pose,
    legs: Legs,
    skating: SkatingMeter,
    /// Head joint, and its smoothed floor offset from the root in the root's frame.
    head: Option<usize>,
    head_offset: Vec3,
    /// The last good input and tracked sample: what a refused one is replaced by.
    input: Input,
    tracked: Tracked,
    last_good: LastGood,
}

/// Where a new character starts: the first searchable frame tagged `idle` of its preferred
/// style (what a visitor sees first is a person standing calmly, not the first frame of a run),
/// else the first searchable `idle` frame, else the first searchable frame.
pub fn start_frame(db: &Database, settings: &CharacterSettings) -> usize {
    let tag = |name: &str| db.tags.iter().find(|t| t.name == name);
    let within = |ranges: &[(u32, u32)], f: usize| ranges.iter().any(|&(s, e)| (s as usize..e as usize).contains(&f));
    let style =
        db.tags.iter().find(|t| t.name.strip_prefix(crate::tag_query::STYLE_PREFIX) == Some(settings.style.as_str()));
    let searchable = |f: usize| f < db.num_frames && db.valid[f] != 0;
    if let Some(idle) = tag("idle") {
        let frames = || idle.ranges.iter().flat_map(|&(s, e)| s as usize..e as usize).filter(|&f| searchable(f));
        if let Some(f) = frames().find(|&f| style.is_none_or(|t| within(&t.ranges, f))).or_else(|| frames().next()) {
            return f;
        }
    }
    db.valid.iter().position(|&v| v != 0).unwrap_or(0)
}

impl Character {
    /// A character standing at the origin facing +Z, playing from [`start_frame`]: standing
    /// still in its style where the database has that.
    pub fn new(db: &Database, settings: CharacterSettings) -> Character {
        let frame = start_frame(db, &settings);
        let mut c = Character {
            settings,
            simulation: Simulation::default(),
            stats: CharacterStats::default(),
            frame,
            frame_fraction: 0.0,
            drive: Drive::default(),
            schedule: Schedule::new(),
            query: Query::new(db),
            root: RootMotion::default(),
            pose: Pose::new(db.num_joints()),
            legs: Legs::new(db),
            skating: SkatingMeter::default(),
            head: db.skeleton.site_joint("head"),
            head_offset: Vec3::ZERO,
            input: Input::default(),
            tracked: Tracked::default(),
            last_good: LastGood { position: Vec3::ZERO, rotation: Quat::IDENTITY, simulation: Simulation::default() },
        };
        c.pose.play(db, frame, c.settings.inertialize, c.settings.inertialization_halflife, 0.0);
        c.pose.set_root(c.root.position, c.root.rotation);
        c.reset_feet(db);
        c
    }

    /// Unlocks both feet and restarts their velocity estimate from the current pose.
    fn reset_feet(&mut self, db: &Database) {
        self.pose.reset_output(&db.skeleton.parents);
        self.legs.reset(&self.pose);
        self.skating.reset();
    }

    /// Places the character (and its simulated twin) at a world position and yaw. A position
    /// that is not finite or beyond ±1e5 m, or a rotation that is not a finite unit quaternion,
    /// is refused (the character stays; counted).
    pub fn teleport(&mut self, db: &Database, position: Vec3, rotation: Quat) {
        if !(position.x.abs() <= MAX_PATH_COORDINATE
            && position.z.abs() <= MAX_PATH_COORDINATE
            && rotation.is_finite()
            && (rotation.length() - 1.0).abs() < 1e-3)
        {
            self.stats.rejected_inputs += 1;
            return;
        }
        let rotation = rotation.normalize();
        self.root.position = Vec3::new(position.x, 0.0, position.z);
        self.root.rotation = rotation;
        self.root.drag_velocity = Vec3::ZERO;
        self.simulation = Simulation { position: self.root.position, rotation, ..Simulation::default() };
        self.schedule.force = true;
        self.pose.set_root(self.root.position, self.root.rotation);
        self.reset_feet(db);
    }

    /// Places the character like [`Self::teleport`] and plays `frame` from there, with no blend,
    /// its simulated twin moving and turning as that frame does. A late joiner's copy of a
    /// walking person starts walking where the person's snapshot says (its frame, root and
    /// yaw) instead of from rest, which left it up to 60 cm behind for over a second. A frame
    /// out of range, or a refused position, leaves it a plain teleport (or none).
    pub fn teleport_playing(&mut self, db: &Database, frame: usize, position: Vec3, rotation: Quat) {
        let refused = self.stats.rejected_inputs;
        self.teleport(db, position, rotation);
        if self.stats.rejected_inputs != refused || frame >= db.num_frames {
            return;
        }
        self.frame = frame;
        self.pose.play(db, frame, false, self.settings.inertialization_halflife, 0.0);
        self.root.start_at(db, frame);
        self.pose.set_root(self.root.position, self.root.rotation);
        self.simulation.velocity = Vec3::new(self.root.velocity.x, 0.0, self.root.velocity.z);
        self.simulation.angular_velocity = Vec3::new(0.0, self.root.angular_velocity.y, 0.0);
        self.reset_feet(db);
    }

    /// Height of a planted toe on this database's floor (m): foot locks plant toes there
    /// (with `foot_lock_floor`). Usually `db.toe_height_in_contact()`, computed once per
    /// database and shared by its characters.
    pub fn set_toe_floor(&mut self, height: Option<f32>) {
        self.legs.toe_floor = height;
    }

    /// Lowers the hips `drop` metres below the animation, the legs bending by IK so that the
    /// feet stay where the animation (or the foot lock) puts them: crouching for a VR user
    /// whose head is lower than calibrated, with any database (docs/method.md §9's fallback to
    /// crouch databases). Clamped to [0, 60% of the hip height].
    pub fn set_hips_drop(&mut self, drop: f32) {
        self.legs.hips_drop = if drop.is_finite() { drop.max(0.0) } else { 0.0 };
    }

    /// Bends the torso forward `bend` rad (clamped to [0, [`crouch::MAX_BEND`]]), shared by the
    /// spine joints, about the root's lateral axis: bending over for a VR user. In tracked mode
    /// the root's target moves back by as much as the bend moves the head forward. A skeleton
    /// without spine roles does not bend.
    pub fn set_torso_bend(&mut self, bend: f32) {
        self.legs.bend = if bend.is_finite() { bend.clamp(0.0, crouch::MAX_BEND) } else { 0.0 };
    }

    /// A tracked head `head_drop` m below its standing height with the headset pitched `pitch`
    /// rad (negative: down): the hips drop and the torso bend by [`crouch::split`], for this
    /// skeleton's torso. Returns the split (what a shared room sends).
    pub fn set_crouch(&mut self, head_drop: f32, pitch: f32) -> crouch::Crouch {
        let c = crouch::split(head_drop, pitch, self.legs.torso);
        self.set_hips_drop(c.hips_drop);
        self.set_torso_bend(c.bend);
        c
    }

    /// Follow `path` from its start (or `None` to return to input control).
    pub fn set_path(&mut self, path: Option<Path>) {
        if path.is_none() && matches!(self.drive.mode, Mode::Input) {
            return; // already on input: nothing changes, no search is due
        }
        self.drive.mode = match path {
            Some(path) => Mode::Path { path, time: 0.0 },
            None => Mode::Input,
        };
        self.schedule.force = true;
    }

    /// Follow a tracked user (VR) from now on: call every frame with the raw head floor
    /// position, ground velocity and body yaw (docs/method.md §9). The velocity and yaw are
    /// spring-smoothed here. Back to input control with [`Self::set_path`]`(None)`.
    ///
    /// A component that is not finite (or a position beyond ±1e5 m) keeps its last good value;
    /// a ground speed beyond 50 m/s is clamped (both counted).
    pub fn set_tracked(&mut self, tracked: Tracked) {
        // Only the ground components matter (docs/method.md §9); a garbage height is ignored.
        let mut t = Tracked {
            position: Vec3::new(tracked.position.x, 0.0, tracked.position.z),
            velocity: Vec3::new(tracked.velocity.x, 0.0, tracked.velocity.z),
            yaw: tracked.yaw,
            body: tracked.body,
        };
        let last = self.tracked;
        if !(t.position.x.abs() <= MAX_PATH_COORDINATE && t.position.z.abs() <= MAX_PATH_COORDINATE) {
            t.position = last.position;
            self.stats.rejected_inputs += 1;
        }
        if !(t.velocity.x.is_finite() && t.velocity.z.is_finite()) {
            t.velocity = last.velocity;
            self.stats.rejected_inputs += 1;
        } else if t.velocity.length() > MAX_TRACKED_SPEED {
            t.velocity = t.velocity.normalize() * MAX_TRACKED_SPEED;
            self.stats.rejected_inputs += 1;
        }
        if !t.yaw.is_finite() {
            t.yaw = last.yaw;
            self.stats.rejected_inputs += 1;
        }
        self.tracked = t;
        let tracked = t;
        if !matches!(self.drive.mode, Mode::Tracked(_)) {
            // Start from the user, not from wherever the simulation was.
            self.simulation.velocity = tracked.velocity;
            self.simulation.acceleration = Vec3::ZERO;
            self.schedule.force = true;
            if let Some(head) = self.head {
                let w = self.pose.world_positions[head] - self.root.position;
                self.head_offset = self.root.rotation.inverse() * Vec3::new(w.x, 0.0, w.z);
            }
        }
        self.drive.mode = Mode::Tracked(tracked);
    }

    /// Restrict searches to frames where `mask` is true (e.g. a tag), or lift it with `None`.
    ///
    /// # Errors
    /// A mask whose length is not the database's frame count (nothing changes).
    pub fn set_mask(&mut self, db: &Database, mask: Option<Vec<bool>>) -> Result<(), String> {
        if let Some(m) = &mask {
            if m.len() != db.num_frames {
                return Err(format!("a search mask needs {} frames, got {}", db.num_frames, m.len()));
            }
        }
        self.schedule.mask = mask;
        self.schedule.force = true;
        Ok(())
    }

    /// Forces a search at the next update.
    pub fn request_search(&mut self) {
        self.schedule.force = true;
    }

    /// Prepares a switch away from `from` (the database used so far) to another one with the
    /// same skeleton and feature layout, passed to the next [`Self::update`]: that update
    /// searches the new database from the current pose, and the jump is inertialized like any
    /// other transition (VR: crouch ↔ stand by head height). A search mask belongs to a
    /// database, so it is lifted (set a new one with [`Self::set_mask`] after the switch).
    ///
    /// `from` must be the database the character was playing; with another one the pose part of
    /// the next query is left as it was.
    pub fn switch_database(&mut self, from: &Database) {
        // The transition's source is the pose playing in `from`.
        self.pose.hold_velocities(from, self.frame);
        if self.frame < from.num_frames && from.num_features() == self.query.values.len() {
            self.query.set_pose(from.feature(self.frame));
        }
        self.schedule.mask = None;
        self.schedule.switching = true;
        self.schedule.force = true;
    }

    /// Moves the character from a first part of a database (`part`, its `PART`) to the whole:
    /// it plays the same frame there, with every other state kept, so nothing it shows changes
    /// (the pose, root and contacts of a part frame are the whole frame's). Its next searches
    /// see the whole database. A search mask, made for the part's frames, is lifted.
    pub fn enter_whole(&mut self, part: &Part) {
        // Both map: the frame playing and the one last left are frames of the part.
        self.frame = part.whole_frame(self.frame).unwrap_or(self.frame);
        self.schedule.enter_whole(part);
    }

    pub fn frame(&self) -> usize {
        self.frame
    }
    /// The hips drop (m) and torso bend (rad) asked for ([`Self::set_crouch`] or set directly).
    pub fn crouch(&self) -> crouch::Crouch {
        crouch::Crouch { hips_drop: self.legs.hips_drop, bend: self.legs.bend }
    }
    /// The simulated character's position and facing (where the user wants the avatar).
    pub fn simulation_transform(&self) -> (Vec3, Quat) {
        (self.simulation.position, self.simulation.rotation)
    }
    pub fn root_position(&self) -> Vec3 {
        self.root.position
    }
    pub fn root_rotation(&self) -> Quat {
        self.root.rotation
    }
    /// How fast adjustment and clamping drag the root (world, m/s, smoothed): what the
    /// database motion does not cover.
    pub fn drag_velocity(&self) -> Vec3 {
        self.root.drag_velocity
    }
    /// Joint 0: root world transform; others: local transforms (inertialized, hips dropped).
    pub fn pose_positions(&self) -> &[Vec3] {
        &self.pose.positions
    }
    /// The shown local rotations: inertialized, with foot-lock IK on the legs.
    pub fn pose_rotations(&self) -> &[Quat] {
        &self.pose.output_rotations
    }
    /// World positions of every joint of the shown pose.
    pub fn world_positions(&self) -> &[Vec3] {
        &self.pose.world_positions
    }
    /// World rotations of every joint of the shown pose.
    pub fn world_rotations(&self) -> &[Quat] {
        &self.pose.world_rotations
    }
    /// The toe points (left, right) of the shown pose, world.
    pub fn toes(&self) -> [Vec3; 2] {
        self.legs.toes
    }
    /// Whether each foot (left, right) is locked to the floor now.
    pub fn foot_locked(&self) -> [bool; 2] {
        self.legs.locked()
    }
    /// Whether each foot (left, right) is stepping back under a dragged body (a foot lock's
    /// drift release, `ik::FootLock`).
    pub fn foot_stepping(&self) -> [bool; 2] {
        self.legs.stepping()
    }
    /// Whether each foot (left, right) is in the air on such a step: while one is, the other
    /// keeps its lock (`legs`).
    pub fn foot_airborne(&self) -> [bool; 2] {
        self.legs.airborne()
    }
    /// Foot contacts of the current frame (left, right).
    pub fn contacts(&self) -> [u8; 2] {
        self.pose.contacts
    }
    /// The last query (normalized features) and the predicted trajectory (world space).
    pub fn query(&self) -> &[f32] {
        &self.query.values
    }
    pub fn predicted_positions(&self) -> &[Vec3] {
        &self.query.predicted_positions
    }
    pub fn predicted_rotations(&self) -> &[Quat] {
        &self.query.predicted_rotations
    }
    /// Sliding of the shown pose's planted toes since the last teleport ([`SkatingMeter`]).
    pub fn skating(&self) -> &SkatingMeter {
        &self.skating
    }

    /// Advances the character by `dt` seconds of real time under `input` (ignored unless the
    /// drive is input). `db` must be the database the character was created for, or another
    /// with the same skeleton and features (call [`Self::switch_database`] before switching).
    ///
    /// `index` must be built from `db`.
    ///
    /// `dt` that is not a number or negative counts as 0; beyond [`MAX_DT`] the gap is not
    /// simulated (a fresh search); an input that is not finite is replaced by the last good one.
    pub fn update(&mut self, db: &Database, index: &SearchIndex, input: &Input, dt: f32) {
        let dt = if dt >= 0.0 {
            dt
        } else {
            self.stats.rejected_inputs += 1; // NaN or negative
            0.0
        };
        let dt = if dt > MAX_DT {
            self.stats.gaps += 1;
            self.schedule.force = true;
            MAX_DT
        } else {
            dt
        };
        if input.direction.is_finite() && input.facing.is_finite() {
            self.input = *input;
        } else {
            self.stats.rejected_inputs += 1;
        }
        if self.frame >= db.num_frames {
            // Another database than the character's, shorter: start over in it.
            self.frame = db.valid.iter().position(|&v| v != 0).unwrap_or(0);
            self.schedule.force = true;
        }
        self.legs.undo_drop(&mut self.pose);
        if self.legs.update_crouched() {
            self.schedule.force = true;
        }
        self.update_head_offset(dt);
        let s = &self.settings;
        let thresholds = (s.velocity_change_threshold, s.rotation_change_threshold);
        let input = self.input;
        if self.drive.update(&mut self.simulation, &s.controller, thresholds, &input, dt) {
            self.schedule.force = true;
        }

        if self.schedule.is_due(db, self.frame, &self.settings) {
            self.search(db, index);
        }

        // Play the database at its own rate, whatever the render rate.
        self.frame_fraction += dt * self.settings.playback_speed * db.fps;
        if !self.frame_fraction.is_finite() {
            self.frame_fraction = 0.0;
        }
        let mut played = 0;
        while self.frame_fraction >= 1.0 {
            if played == MAX_FRAMES_PER_UPDATE {
                // More frames than any sane rate makes in one update: search afresh instead.
                self.frame_fraction = 0.0;
                self.schedule.force = true;
                break;
            }
            played += 1;
            self.frame_fraction -= 1.0;
            let clip_end = db.clips[db.clip_at(self.frame)].end as usize;
            let next = if self.frame + 1 < clip_end { self.frame + 1 } else { self.frame };
            self.root.step(db, self.frame, next, self.settings.inertialization_halflife);
            self.frame = next;
            self.schedule.count_frame();
        }
        let s = &self.settings;
        self.pose.play(db, self.frame, s.inertialize, s.inertialization_halflife, dt);
        self.root.keep_with(&self.simulation, s, dt);
        self.pose.set_root(self.root.position, self.root.rotation);
        self.pose.reset_output(&db.skeleton.parents);
        self.legs.follow = match &self.drive.mode {
            Mode::Tracked(t) if t.body => Some((t.position, t.yaw)),
            _ => None,
        };
        self.legs.apply(db, &mut self.pose, &self.settings, self.root.rotation, dt);
        if self.is_finite() {
            self.last_good =
                LastGood { position: self.root.position, rotation: self.root.rotation, simulation: self.simulation };
            self.skating.update(self.legs.toes, self.pose.contacts, self.legs.toe_floor);
        } else {
            self.recover(db);
        }
    }

    /// Whether the root, the simulated character and the whole shown pose are finite.
    fn is_finite(&self) -> bool {
        let sim = &self.simulation;
        self.root.position.is_finite()
            && self.root.rotation.is_finite()
            && self.root.velocity.is_finite()
            && sim.position.is_finite()
            && sim.velocity.is_finite()
            && sim.acceleration.is_finite()
            && sim.rotation.is_finite()
            && sim.angular_velocity.is_finite()
            && crate::lanes::all_finite(bytemuck::cast_slice(&self.pose.world_positions))
            && crate::lanes::all_finite(bytemuck::cast_slice(&self.pose.world_rotations))
    }

    /// Back to the last good state, this update: root and simulated character where they last
    /// were, no inertialization offsets, the frame playing shown as it is, feet unlocked, a
    /// fresh search next.
    fn recover(&mut self, db: &Database) {
        self.stats.recoveries += 1;
        let good = self.last_good;
        self.root = RootMotion::default();
        self.root.position = good.position;
        self.root.rotation = good.rotation;
        self.simulation = good.simulation;
        self.drive.settle(&self.simulation);
        // The head offset is measured on the shown pose: start it again from the replayed one.
        self.head_offset = Vec3::ZERO;
        self.drive.head_offset = Vec3::ZERO;
        self.frame_fraction = 0.0;
        self.pose.cut();
        self.legs.undo_drop(&mut self.pose);
        self.legs.reset_follow();
        self.legs.hips_drop = 0.0;
        self.legs.bend = 0.0;
        self.legs.bend_shift = Vec3::ZERO;
        self.pose.play(db, self.frame, false, self.settings.inertialization_halflife, 0.0);
        self.pose.set_root(self.root.position, self.root.rotation);
        self.reset_feet(db);
        self.schedule.force = true;
    }

    /// Tracked mode: the shown head's floor offset from the root (last frame's pose), smoothed in
    /// the root's frame, handed to the drive in world space — with `tracked_head_offset`, else
    /// only what the torso bend moved the head. With body tracking the sample is the hips' own
    /// floor point: no offset at all.
    fn update_head_offset(&mut self, dt: f32) {
        let bend_shift = match self.drive.mode {
            Mode::Tracked(Tracked { body: true, .. }) => {
                self.drive.head_offset = Vec3::ZERO;
                return;
            }
            Mode::Tracked(_) => self.legs.bend_shift,
            _ => Vec3::ZERO,
        };
        let (Some(head), true, Mode::Tracked(_)) = (self.head, self.settings.tracked_head_offset, &self.drive.mode)
        else {
            self.drive.head_offset = bend_shift;
            return;
        };
        let world = self.pose.world_positions[head] - self.root.position;
        let local = self.root.rotation.inverse() * Vec3::new(world.x, 0.0, world.z);
        self.head_offset += (local - self.head_offset) * (1.0 - (-dt / HEAD_OFFSET_HALFLIFE).exp2());
        let w = self.root.rotation * self.head_offset;
        self.drive.head_offset = Vec3::new(w.x, 0.0, w.z);
    }

    fn search(&mut self, db: &Database, index: &SearchIndex) {
        if self.query.values.len() != db.num_features() || index.num_dims() != db.num_features() {
            // Another feature layout than the character was made for: nothing to compare with.
            self.schedule.force = false;
            self.stats.rejected_inputs += 1;
            return;
        }
        // Pose part: the current frame's own features (captured from the old database when
        // switching); trajectory part: the drive's prediction.
        if !self.schedule.switching {
            self.query.set_pose(db.feature(self.frame));
        }
        if self.settings.query_drag {
            self.query.add_drag(db, self.root.drag_velocity, self.root.rotation);
        }
        self.query.set_trajectory(
            db,
            &self.drive,
            &self.simulation,
            &self.settings.controller,
            self.root.position,
            self.root.rotation,
        );
        let speed = self.settings.idle_exclude_speed;
        let moving = speed > 0.0 && self.simulation.velocity.length() > speed && !self.schedule.switching;
        let tags = Schedule::tag_query(db, &self.settings, moving, self.legs.crouched);
        if let Outcome::Jump(frame) =
            self.schedule.search(index, &self.settings, self.frame, &self.query, &mut self.stats, tags)
        {
            self.transition(db, frame);
        }
    }

    /// Jumps to `frame`, inertializing from what is being output now.
    fn transition(&mut self, db: &Database, frame: usize) {
        self.stats.transitions += 1;
        let inertialize = self.settings.inertialize;
        self.pose.transition(db, self.frame, frame, inertialize);
        self.root.transition(db, frame, inertialize);
        self.frame = frame;
    }
}
