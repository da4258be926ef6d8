//! One motion-matched character (THESIS_NOTES §3–7): each update moves the simulated
//! character from the input, searches the database on a timer / sharp input change / clip
//! end, plays the database at its own rate, inertializes transitions, keeps the root with the
//! simulated character (adjustment and clamping) and writes the pose to preallocated buffers.

use crate::controller::{desired_rotation, desired_velocity, yaw_facing, ChangeDetector, ControllerSettings, Input, Path, Simulation};
use crate::database::{Axes, Database, FeatureKind};
use crate::ik::{knee_bend_direction, leg_ik, FootLock, LegJoints};
use crate::inertialize::Inertializer;
use crate::search::{SearchIndex, SearchMethod, SearchOptions};
use crate::spring::{decay_spring_damper_exact, quat_abs, spring_damper_exact, spring_damper_exact_quat, spring_rotation_predict};
use glam::{Quat, Vec3};

/// Everything a user can tune live (the demo's lil-gui knobs). JSON with the field names
/// below; missing fields keep their defaults, unknown ones are errors.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CharacterSettings {
    pub controller: ControllerSettings,
    /// Database frames between searches (10 at 60 fps).
    pub search_interval: u32,
    /// β_q (pose / quality) and β_r (trajectory / responsiveness).
    pub beta_pose: f32,
    pub beta_trajectory: f32,
    /// Frames around the current one a search may not return.
    pub exclude_radius: usize,
    /// Sharp-change triggers: rate of change of the desired velocity (m/s²) and facing (rad/s).
    pub velocity_change_threshold: f32,
    pub rotation_change_threshold: f32,
    pub inertialize: bool,
    pub inertialization_halflife: f32,
    pub adjustment: bool,
    pub adjustment_position_halflife: f32,
    pub adjustment_rotation_halflife: f32,
    /// Adjustment per frame is capped at this × the character's speed × dt, so a standing
    /// character never slides (THESIS_NOTES §6).
    pub adjustment_max_ratio: f32,
    /// …but never below this speed (m/s), so a standing character is still brought back under
    /// its simulated character (a tracked VR user who stands still must find the avatar under
    /// them, not α away); the foot lock turns the drift into a corrective step. 0 = off.
    pub adjustment_min_speed: f32,
    pub clamping: bool,
    /// α: the root never ends farther than this from the simulated character (m).
    pub clamp_distance: f32,
    /// With `clamping`, the root's yaw stays within this angle (rad) of the simulated
    /// character's: the data has little turning on the spot, and a tracked (VR) user who turns
    /// in place must see the avatar turn with them.
    pub clamp_angle: f32,
    /// Database playback rate multiplier.
    pub playback_speed: f32,
    /// All methods return the same frame; AABB is the fast one, the others are for comparison.
    pub search_method: SearchMethod,
    /// Pin toes in contact to the floor with two-bone leg IK (THESIS_NOTES §7).
    pub foot_lock: bool,
    /// A locked toe unlocks when the animation drifts farther than this (m).
    pub foot_lock_unlock_radius: f32,
    /// Plant locked toes at the floor height (see [`Character::set_toe_floor`]) rather than
    /// wherever they touched down.
    pub foot_lock_floor: bool,
    /// Blend in and out of a lock (exact half-life; Holden's 0.1 s).
    pub foot_lock_halflife: f32,
}

impl Default for CharacterSettings {
    fn default() -> Self {
        CharacterSettings {
            controller: ControllerSettings::default(),
            search_interval: 10,
            beta_pose: 1.0,
            beta_trajectory: 1.0,
            exclude_radius: 20,
            velocity_change_threshold: 50.0,
            rotation_change_threshold: 50.0,
            inertialize: true,
            inertialization_halflife: 0.1,
            adjustment: true,
            adjustment_position_halflife: 0.1,
            adjustment_rotation_halflife: 0.2,
            adjustment_max_ratio: 0.5,
            clamping: true,
            clamp_distance: 0.15,
            clamp_angle: std::f32::consts::FRAC_PI_4,
            playback_speed: 1.0,
            search_method: SearchMethod::Aabb,
            foot_lock: true,
            foot_lock_unlock_radius: 0.2,
            adjustment_min_speed: 0.0,
            foot_lock_floor: true,
            foot_lock_halflife: 0.12,
        }
    }
}

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

/// Counters and the last search, for debug views and the quality harness.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CharacterStats {
    pub searches: u64,
    pub transitions: u64,
    /// Cost of the current frame at the last search, and of the frame it chose.
    pub current_cost: f32,
    pub best_cost: f32,
}

/// A tracked user (VR), as given each frame: raw, the character smooths it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tracked {
    /// The head centre projected on the floor (y ignored), m.
    pub position: Vec3,
    /// The head's ground velocity (y ignored), m/s.
    pub velocity: Vec3,
    /// Predicted body yaw, radians, 0 = facing +Z.
    pub yaw: f32,
}

/// What moves the simulated character.
enum Drive {
    /// Keyboard/gamepad [`Input`] through the velocity and rotation springs.
    Input,
    /// Along a polyline, `time` seconds since its start.
    Path { path: Path, time: f32 },
    /// Along with a tracked user.
    Tracked(Tracked),
}

/// A character playing one database. Owns every buffer it needs: `update` never allocates.
pub struct Character {
    pub settings: CharacterSettings,
    pub simulation: Simulation,
    pub stats: CharacterStats,
    /// Current database frame.
    frame: usize,
    /// Fraction of a database frame accumulated toward the next one.
    frame_fraction: f32,
    frames_since_search: u32,
    force_search: bool,
    /// Set by [`Self::switch_database`]: the next search runs in the new database with the
    /// pose features captured from the old one.
    switching: bool,
    velocity_change: ChangeDetector,
    rotation_change: ChangeDetector,
    desired_velocity: Vec3,
    desired_rotation: Quat,
    drive: Drive,
    /// World transform and motion of the character's root (joint 0).
    root_position: Vec3,
    root_rotation: Quat,
    root_velocity: Vec3,
    root_angular_velocity: Vec3,
    /// Inertialization offsets of the root's velocity and yaw rate (world space).
    root_velocity_offset: Vec3,
    root_velocity_offset_rate: Vec3,
    root_angular_offset: Vec3,
    root_angular_offset_rate: Vec3,
    inertializer: Inertializer,
    /// Inertialized pose: joint 0 holds the root's world transform, the others local
    /// transforms. Transitions start from this, never from the IK-corrected output (else the
    /// corrections would be folded into the offsets and decay away).
    pose_positions: Vec<Vec3>,
    pose_rotations: Vec<Quat>,
    /// What is shown: the inertialized pose with foot-lock IK applied.
    output_rotations: Vec<Quat>,
    world_positions: Vec<Vec3>,
    world_rotations: Vec<Quat>,
    legs: [Option<LegJoints>; 2],
    /// Joints whose world transforms the foot lock needs: the legs and their ancestors, in
    /// parent-first order (FK of just these is a third of the skeleton's).
    leg_chain: Vec<usize>,
    locks: [FootLock; 2],
    /// Height of a planted toe on the floor, if known ([`Database::toe_height_in_contact`]).
    toe_floor: Option<f32>,
    /// How far the hips are lowered below the animation (m), legs bent by IK to keep the feet
    /// planted ([`Self::set_hips_drop`]); the hips joint (the child of the root on the leg chain).
    hips_drop: f32,
    hips: Option<usize>,
    /// The drop applied to `pose_positions` by the last update, undone before the next one:
    /// like the leg IK it is a touch-up of the output, never a state the animation continues.
    applied_drop: f32,
    previous_toes: [Vec3; 2],
    pose_velocities: Vec<Vec3>,
    pose_angular_velocities: Vec<Vec3>,
    contacts: [u8; 2],
    // Query construction.
    query: Vec<f32>,
    mask: Option<Vec<bool>>,
    slots: Vec<TrajectorySlot>,
    times: Vec<f32>,
    predicted_positions: Vec<Vec3>,
    predicted_rotations: Vec<Quat>,
}

impl Character {
    /// A character standing at the origin facing +Z, playing from the first valid frame.
    pub fn new(db: &Database, settings: CharacterSettings) -> Character {
        let j = db.num_joints();
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
                slots.push(TrajectorySlot { first_dim: g.first_dim + k * g.axes.num_dims(), kind: g.kind, axes: g.axes, axis: g.axis, time });
            }
        }
        let frame = db.valid.iter().position(|&v| v != 0).unwrap_or(0);
        let mut c = Character {
            settings,
            simulation: Simulation::default(),
            stats: CharacterStats::default(),
            frame,
            frame_fraction: 0.0,
            frames_since_search: 0,
            force_search: true,
            switching: false,
            velocity_change: ChangeDetector::default(),
            rotation_change: ChangeDetector::default(),
            desired_velocity: Vec3::ZERO,
            desired_rotation: Quat::IDENTITY,
            drive: Drive::Input,
            root_position: Vec3::ZERO,
            root_rotation: Quat::IDENTITY,
            root_velocity: Vec3::ZERO,
            root_angular_velocity: Vec3::ZERO,
            root_velocity_offset: Vec3::ZERO,
            root_velocity_offset_rate: Vec3::ZERO,
            root_angular_offset: Vec3::ZERO,
            root_angular_offset_rate: Vec3::ZERO,
            inertializer: Inertializer::new(j - 1),
            pose_positions: vec![Vec3::ZERO; j],
            pose_rotations: vec![Quat::IDENTITY; j],
            output_rotations: vec![Quat::IDENTITY; j],
            world_positions: vec![Vec3::ZERO; j],
            world_rotations: vec![Quat::IDENTITY; j],
            legs: [LegJoints::from_skeleton(&db.skeleton, "left"), LegJoints::from_skeleton(&db.skeleton, "right")],
            leg_chain: Vec::new(),
            locks: [FootLock::new(); 2],
            toe_floor: None,
            hips_drop: 0.0,
            hips: None,
            applied_drop: 0.0,
            previous_toes: [Vec3::ZERO; 2],
            pose_velocities: vec![Vec3::ZERO; j],
            pose_angular_velocities: vec![Vec3::ZERO; j],
            contacts: [0; 2],
            query: vec![0.0; db.num_features()],
            mask: None,
            predicted_positions: vec![Vec3::ZERO; times.len()],
            predicted_rotations: vec![Quat::IDENTITY; times.len()],
            slots,
            times,
        };
        let mut needed = vec![false; j];
        for leg in c.legs.iter().flatten() {
            let mut k = leg.toe as i32;
            while k >= 0 && !needed[k as usize] {
                needed[k as usize] = true;
                k = db.skeleton.parents[k as usize];
            }
        }
        c.leg_chain = (0..j).filter(|&k| needed[k]).collect();
        c.hips = c.leg_chain.iter().copied().find(|&k| db.skeleton.parents[k] == 0);
        c.write_pose(db, 0.0);
        c.reset_feet(db);
        c
    }

    /// World transforms of the leg chains of the pose being shown (before foot-lock IK).
    fn leg_kinematics(&mut self, db: &Database) {
        for &k in &self.leg_chain {
            let p = db.skeleton.parents[k];
            if p < 0 {
                (self.world_positions[k], self.world_rotations[k]) = (self.pose_positions[k], self.output_rotations[k]);
            } else {
                let p = p as usize;
                self.world_positions[k] = self.world_positions[p] + self.world_rotations[p] * self.pose_positions[k];
                self.world_rotations[k] = self.world_rotations[p] * self.output_rotations[k];
            }
        }
    }

    /// Unlocks both feet and restarts their velocity estimate from the current pose.
    fn reset_feet(&mut self, db: &Database) {
        self.output_rotations.copy_from_slice(&self.pose_rotations);
        self.leg_kinematics(db);
        for side in 0..2 {
            if let Some(leg) = &self.legs[side] {
                let toe = self.world_positions[leg.toe] + self.world_rotations[leg.toe] * leg.toe_offset;
                self.previous_toes[side] = toe;
                self.locks[side].reset(toe, Vec3::ZERO);
            }
        }
    }

    /// Places the character (and its simulated twin) at a world position and yaw.
    pub fn teleport(&mut self, db: &Database, position: Vec3, rotation: Quat) {
        self.root_position = Vec3::new(position.x, 0.0, position.z);
        self.root_rotation = rotation;
        self.simulation = Simulation { position: self.root_position, rotation, ..Simulation::default() };
        self.force_search = true;
        self.pose_positions[0] = self.root_position;
        self.pose_rotations[0] = self.root_rotation;
        self.reset_feet(db);
    }

    /// Height of a planted toe on this database's floor (m): foot locks plant toes there
    /// (with `foot_lock_floor`). Usually `db.toe_height_in_contact()`, computed once per
    /// database and shared by its characters.
    pub fn set_toe_floor(&mut self, height: Option<f32>) {
        self.toe_floor = height;
    }

    /// Lowers the hips `drop` metres below the animation, the legs bending by IK so that the
    /// feet stay where the animation (or the foot lock) puts them: crouching for a VR user
    /// whose head is lower than calibrated, with any database (THESIS_NOTES §9's fallback to
    /// crouch databases). Clamped to [0, 60% of the hip height].
    pub fn set_hips_drop(&mut self, drop: f32) {
        self.hips_drop = if drop.is_finite() { drop.max(0.0) } else { 0.0 };
    }

    /// Follow `path` from its start (or `None` to return to input control).
    pub fn set_path(&mut self, path: Option<Path>) {
        self.drive = match path {
            Some(path) => Drive::Path { path, time: 0.0 },
            None => Drive::Input,
        };
        self.force_search = true;
    }

    /// Follow a tracked user (VR) from now on: call every frame with the raw head floor
    /// position, ground velocity and body yaw (THESIS_NOTES §9). The velocity and yaw are
    /// spring-smoothed here. Back to input control with [`Self::set_path`]`(None)`.
    pub fn set_tracked(&mut self, tracked: Tracked) {
        if !matches!(self.drive, Drive::Tracked(_)) {
            // Start from the user, not from wherever the simulation was.
            self.simulation.velocity = tracked.velocity;
            self.simulation.acceleration = Vec3::ZERO;
            self.force_search = true;
        }
        self.drive = Drive::Tracked(tracked);
    }

    /// Restrict searches to frames where `mask` is true (e.g. a tag), or lift it with `None`.
    ///
    /// # Panics
    /// If the mask's length is not the database's frame count.
    pub fn set_mask(&mut self, db: &Database, mask: Option<Vec<bool>>) {
        assert!(mask.as_ref().is_none_or(|m| m.len() == db.num_frames), "mask length must equal the frame count");
        self.mask = mask;
        self.force_search = true;
    }

    /// Forces a search at the next update.
    pub fn request_search(&mut self) {
        self.force_search = true;
    }

    /// Prepares a switch away from `from` (the database used so far) to another one with the
    /// same skeleton and feature layout, passed to the next [`Self::update`]: that update
    /// searches the new database from the current pose, and the jump is inertialized like any
    /// other transition (VR: crouch ↔ stand by head height). A search mask belongs to a
    /// database, so it is lifted (set a new one with [`Self::set_mask`] after the switch).
    ///
    /// # Panics
    /// If `from` is not the database the character was playing.
    pub fn switch_database(&mut self, from: &Database) {
        self.query.copy_from_slice(from.feature(self.frame));
        self.mask = None;
        self.switching = true;
        self.force_search = true;
    }

    pub fn frame(&self) -> usize {
        self.frame
    }
    /// The simulated character's position and facing (where the user wants the avatar).
    pub fn simulation_transform(&self) -> (Vec3, Quat) {
        (self.simulation.position, self.simulation.rotation)
    }
    pub fn root_position(&self) -> Vec3 {
        self.root_position
    }
    pub fn root_rotation(&self) -> Quat {
        self.root_rotation
    }
    /// Joint 0: root world transform; others: local transforms (inertialized).
    pub fn pose_positions(&self) -> &[Vec3] {
        &self.pose_positions
    }
    /// The shown rotations: inertialized, with foot-lock IK on the legs.
    pub fn pose_rotations(&self) -> &[Quat] {
        &self.output_rotations
    }
    /// Whether each foot (left, right) is locked to the floor now.
    pub fn foot_locked(&self) -> [bool; 2] {
        [self.locks[0].is_locked(), self.locks[1].is_locked()]
    }

    /// Foot contacts of the current frame (left, right).
    pub fn contacts(&self) -> [u8; 2] {
        self.contacts
    }
    /// The last query (normalized features) and the predicted trajectory (world space).
    pub fn query(&self) -> &[f32] {
        &self.query
    }
    pub fn predicted_positions(&self) -> &[Vec3] {
        &self.predicted_positions
    }
    pub fn predicted_rotations(&self) -> &[Quat] {
        &self.predicted_rotations
    }

    /// Advances the character by `dt` seconds of real time under `input` (ignored while
    /// following a path). `db` must be the database the character was created for, or another
    /// with the same skeleton and features (call [`Self::request_search`] after switching).
    ///
    /// `index` must be built from `db`.
    pub fn update(&mut self, db: &Database, index: &SearchIndex, input: &Input, dt: f32) {
        let dt = dt.max(0.0);
        if let (Some(h), true) = (self.hips, self.applied_drop != 0.0) {
            self.pose_positions[h].y += self.applied_drop;
            self.applied_drop = 0.0;
        }
        self.update_simulation(input, dt);

        // Search on a timer, on a sharp input change, or when the clip is about to end.
        let at_clip_end = !self.switching && self.frame + 1 >= db.clips[db.clip_at(self.frame)].end as usize;
        if self.force_search || self.frames_since_search >= self.settings.search_interval || at_clip_end {
            self.search(db, index);
        }

        // Play the database at its own rate, whatever the render rate.
        self.frame_fraction += dt * self.settings.playback_speed * db.fps;
        while self.frame_fraction >= 1.0 {
            self.frame_fraction -= 1.0;
            self.step_frame(db);
        }
        self.write_pose(db, dt);
        self.keep_with_simulation(dt);
        self.lock_feet(db, dt);
    }

    /// Foot lock (THESIS_NOTES §7): each toe in contact is held where the contact began
    /// (blended in and out by [`FootLock`]) and the leg reaches it by two-bone IK.
    fn lock_feet(&mut self, db: &Database, dt: f32) {
        self.output_rotations.copy_from_slice(&self.pose_rotations);
        self.leg_kinematics(db);
        // Toe targets from the pose as animated (before any hips drop).
        let mut targets = [None; 2];
        for side in 0..2 {
            let Some(leg) = &self.legs[side] else { continue };
            let toe = self.world_positions[leg.toe] + self.world_rotations[leg.toe] * leg.toe_offset;
            let velocity = if dt > 0.0 { (toe - self.previous_toes[side]) / dt } else { Vec3::ZERO };
            self.previous_toes[side] = toe;
            if !self.settings.foot_lock {
                self.locks[side].reset(toe, velocity);
                targets[side] = Some((toe, toe));
                continue;
            }
            let contact = self.contacts[side] != 0;
            let s = &self.settings;
            self.locks[side].floor = if s.foot_lock_floor { self.toe_floor } else { None };
            let target = self.locks[side].update(contact, toe, velocity, dt, s.foot_lock_unlock_radius, s.foot_lock_halflife);
            targets[side] = Some((toe, target));
        }
        let dropped = match self.hips {
            Some(h) if self.hips_drop > 0.0 => {
                // The root is a pure yaw, so the hips' local y is world height above the root.
                let drop = self.hips_drop.min(0.6 * self.pose_positions[h].y.max(0.0));
                self.pose_positions[h].y -= drop;
                self.applied_drop = drop;
                self.leg_kinematics(db);
                drop > 0.0
            }
            _ => false,
        };
        let parents = &db.skeleton.parents;
        for side in 0..2 {
            let (Some(leg), Some((toe, target))) = (&self.legs[side], targets[side]) else { continue };
            // Unlocked and blended out: the animation is already right, leave the leg alone.
            if !dropped && (target - toe).length_squared() < 1e-10 {
                continue;
            }
            // Keep the knee in the animation's own bend plane, even a slightly backward
            // (hyperextended) one: a pole on the other side makes the solver turn the leg half
            // a turn about the hip–ankle axis in one frame. Facing only breaks an exact tie.
            let (hip, knee, ankle) = (self.world_positions[leg.upper_leg], self.world_positions[leg.lower_leg], self.world_positions[leg.foot]);
            let bend = knee_bend_direction(hip, knee, ankle);
            let pole = if bend.length_squared() > 1e-8 { bend } else { self.root_rotation * Vec3::Z };
            leg_ik(leg, parents, &self.world_positions, &self.world_rotations, target, pole, 0.0, 1e-4, &mut self.output_rotations);
        }
    }

    fn update_simulation(&mut self, input: &Input, dt: f32) {
        let settings = self.settings.controller;
        let (velocity, rotation) = match &mut self.drive {
            Drive::Input => {
                let v = desired_velocity(input, self.simulation.rotation, &settings);
                (v, desired_rotation(input, v, self.simulation.rotation))
            }
            Drive::Path { path, time } => {
                // The simulated character rides the path exactly; its facing follows the
                // path direction through the rotation spring.
                *time += dt;
                let (p, v) = path.sample(*time);
                self.simulation.position = p;
                self.simulation.velocity = v;
                self.simulation.acceleration = Vec3::ZERO;
                (v, yaw_facing(v).unwrap_or(self.simulation.rotation))
            }
            Drive::Tracked(t) => {
                // The simulated character *is* the user's head on the floor; its velocity is
                // the head's ground velocity, spring-smoothed (§9): the head bobs and sways
                // every step, the trajectory must not.
                self.simulation.position = Vec3::new(t.position.x, 0.0, t.position.z);
                let goal = Vec3::new(t.velocity.x, 0.0, t.velocity.z);
                spring_damper_exact(&mut self.simulation.velocity, &mut self.simulation.acceleration, goal, settings.velocity_halflife, dt);
                (goal, Quat::from_rotation_y(t.yaw))
            }
        };
        let velocity_jump = (velocity - self.desired_velocity).length();
        let rotation_jump = quat_abs(rotation * self.desired_rotation.inverse()).to_scaled_axis().length();
        let sharp_velocity = self.velocity_change.update(velocity_jump, dt, self.settings.velocity_change_threshold);
        let sharp_rotation = self.rotation_change.update(rotation_jump, dt, self.settings.rotation_change_threshold);
        self.force_search |= sharp_velocity || sharp_rotation;
        self.desired_velocity = velocity;
        self.desired_rotation = rotation;
        match self.drive {
            Drive::Input => self.simulation.update(velocity, rotation, &settings, dt),
            // The path or the user sets the position; only the facing is sprung.
            Drive::Path { .. } | Drive::Tracked(_) => {
                let s = &mut self.simulation;
                spring_damper_exact_quat(&mut s.rotation, &mut s.angular_velocity, rotation, settings.rotation_halflife, dt);
            }
        }
    }

    /// Predicts the trajectory and fills the query: pose features copied from the current
    /// frame, trajectory features from the prediction, relative to the character's root.
    fn build_query(&mut self) {
        let settings = self.settings.controller;
        let s = &self.simulation;
        match &self.drive {
            Drive::Input => s.predict(self.desired_velocity, self.desired_rotation, &settings, &self.times, &mut self.predicted_positions, &mut self.predicted_rotations),
            Drive::Path { path, time } => {
                for (i, &t) in self.times.iter().enumerate() {
                    let (p, v) = path.sample(time + t);
                    self.predicted_positions[i] = p;
                    let goal = yaw_facing(v).unwrap_or(s.rotation);
                    let (mut q, mut w) = (s.rotation, s.angular_velocity);
                    spring_damper_exact_quat(&mut q, &mut w, goal, settings.rotation_halflife, t);
                    self.predicted_rotations[i] = q;
                }
            }
            Drive::Tracked(_) => {
                // §9: positions p̂ + t·v (t = 1/3, 2/3, 1 s at the default offsets); directions
                // the smoothed yaw sprung on toward the predicted one.
                for (i, &t) in self.times.iter().enumerate() {
                    self.predicted_positions[i] = s.position + s.velocity * t;
                }
                spring_rotation_predict(&mut self.predicted_rotations, s.rotation, s.angular_velocity, self.desired_rotation, settings.rotation_halflife, &self.times);
            }
        }
        let inv = self.root_rotation.inverse();
        for slot in &self.slots {
            let v = match slot.kind {
                FeatureKind::Position => inv * (self.predicted_positions[slot.time] - self.root_position),
                FeatureKind::Direction => inv * (self.predicted_rotations[slot.time] * slot.axis),
                // The simulation has one velocity; use it for any velocity-at-offset feature.
                FeatureKind::Velocity => inv * self.simulation.velocity,
            };
            let d = slot.first_dim;
            match slot.axes {
                Axes::Xyz => self.query[d..d + 3].copy_from_slice(&[v.x, v.y, v.z]),
                Axes::Xz => self.query[d..d + 2].copy_from_slice(&[v.x, v.z]),
            }
        }
    }

    fn search(&mut self, db: &Database, index: &SearchIndex) {
        self.force_search = false;
        self.frames_since_search = 0;
        assert_eq!(self.query.len(), db.num_features(), "the database's feature layout differs from the character's");
        // Pose part: the current frame's own (normalized) features (captured from the old
        // database when switching).
        let switching = std::mem::take(&mut self.switching);
        if !switching {
            self.query.copy_from_slice(db.feature(self.frame));
        }
        self.build_query();
        for slot in &self.slots {
            let n = slot.axes.num_dims();
            for d in slot.first_dim..slot.first_dim + n {
                self.query[d] = (self.query[d] - db.feature_mean[d]) / db.feature_scale[d];
            }
        }
        let r = self.settings.exclude_radius;
        let options = SearchOptions {
            beta_pose: self.settings.beta_pose,
            beta_trajectory: self.settings.beta_trajectory,
            exclude: (!switching).then(|| (self.frame.saturating_sub(r), self.frame + r + 1)),
            mask: if switching { None } else { self.mask.as_deref() },
        };
        // The current frame is the bar: jump only to something strictly better. After a
        // switch every frame is new: no bar.
        let valid_now = !switching && index.is_valid(self.frame) && self.mask.as_ref().is_none_or(|m| m[self.frame]);
        let bar = if valid_now { index.cost(self.frame, &self.query, &options) } else { f32::INFINITY };
        let best = index.search(self.settings.search_method, &self.query, &options, bar);
        self.stats.searches += 1;
        self.stats.current_cost = bar;
        if let Some((frame, cost)) = best {
            self.stats.best_cost = cost;
            self.transition(db, frame);
        } else if switching {
            // Nothing searchable in the new database: cut to its first frame.
            self.transition(db, 0);
        }
    }

    /// Jumps to `frame`, inertializing from what is being output now.
    fn transition(&mut self, db: &Database, frame: usize) {
        self.stats.transitions += 1;
        if self.settings.inertialize {
            let j = db.num_joints();
            let (lp, lr, lv, lw) = frame_slices(db, frame);
            self.inertializer.transition_from_output(
                &self.pose_positions[1..],
                &self.pose_velocities[1..],
                &self.pose_rotations[1..],
                &self.pose_angular_velocities[1..],
                &lp[1..j],
                &lv[1..j],
                &lr[1..j],
                &lw[1..j],
            );
            // Root: velocity and yaw rate in world space. What is output now already includes
            // the old offset, so the new offset is simply output − target (Bollo's form).
            let (new_velocity, new_angular) = self.root_motion(db, frame);
            self.root_velocity_offset = self.root_velocity - new_velocity;
            self.root_angular_offset = self.root_angular_velocity - new_angular;
        } else {
            self.inertializer.reset();
            self.root_velocity_offset = Vec3::ZERO;
            self.root_angular_offset = Vec3::ZERO;
        }
        self.frame = frame;
    }

    /// World velocity and angular velocity of the database root at `frame`, carried into the
    /// character's frame.
    fn root_motion(&self, db: &Database, frame: usize) -> (Vec3, Vec3) {
        let j = db.num_joints();
        let to_world = self.root_rotation * db.local_rotations[frame * j].inverse();
        (to_world * db.local_velocities[frame * j], to_world * db.local_angular_velocities[frame * j])
    }

    /// Advances one database frame and moves the root by the database's root motion.
    fn step_frame(&mut self, db: &Database) {
        let j = db.num_joints();
        let clip_end = db.clips[db.clip_at(self.frame)].end as usize;
        let next = if self.frame + 1 < clip_end { self.frame + 1 } else { self.frame };
        let (p0, r0) = (db.local_positions[self.frame * j], db.local_rotations[self.frame * j]);
        let (p1, r1) = (db.local_positions[next * j], db.local_rotations[next * j]);
        let frame_dt = 1.0 / db.fps;
        // Root motion as a delta in the database root's own frame, applied to ours, plus the
        // decaying inertialization offsets of velocity and yaw rate.
        let delta_position = self.root_rotation * (r0.inverse() * (p1 - p0));
        let delta_rotation = r0.inverse() * r1;
        self.root_position += delta_position + self.root_velocity_offset * frame_dt;
        self.root_rotation = (Quat::from_scaled_axis(self.root_angular_offset * frame_dt) * self.root_rotation * delta_rotation).normalize();
        let halflife = self.settings.inertialization_halflife;
        decay_spring_damper_exact(&mut self.root_velocity_offset, &mut self.root_velocity_offset_rate, halflife, frame_dt);
        decay_spring_damper_exact(&mut self.root_angular_offset, &mut self.root_angular_offset_rate, halflife, frame_dt);
        self.frame = next;
        self.frames_since_search += 1;
        let (v, w) = self.root_motion(db, self.frame);
        self.root_velocity = v + self.root_velocity_offset;
        self.root_angular_velocity = w + self.root_angular_offset;
    }

    /// Writes the current frame's pose, inertialized, into the output buffers.
    fn write_pose(&mut self, db: &Database, dt: f32) {
        let (lp, lr, lv, lw) = frame_slices(db, self.frame);
        if self.settings.inertialize {
            self.inertializer.update(
                &lp[1..],
                &lv[1..],
                &lr[1..],
                &lw[1..],
                self.settings.inertialization_halflife,
                dt,
                &mut self.pose_positions[1..],
                &mut self.pose_velocities[1..],
                &mut self.pose_rotations[1..],
                &mut self.pose_angular_velocities[1..],
            );
        } else {
            self.pose_positions[1..].copy_from_slice(&lp[1..]);
            self.pose_rotations[1..].copy_from_slice(&lr[1..]);
            self.pose_velocities[1..].copy_from_slice(&lv[1..]);
            self.pose_angular_velocities[1..].copy_from_slice(&lw[1..]);
        }
        self.pose_positions[0] = self.root_position;
        self.pose_rotations[0] = self.root_rotation;
        self.contacts = [db.contacts[2 * self.frame], db.contacts[2 * self.frame + 1]];
    }

    /// Adjustment toward the simulated character, then clamping at α (THESIS_NOTES §6).
    fn keep_with_simulation(&mut self, dt: f32) {
        let s = &self.settings;
        if s.adjustment && dt > 0.0 {
            // Exact exponential approach with the given half-life, capped by the character's
            // own speed so that an idle character is never dragged.
            let target = Vec3::new(self.simulation.position.x, 0.0, self.simulation.position.z);
            let mut step = (target - self.root_position) * (1.0 - (-dt / s.adjustment_position_halflife).exp2());
            let cap = (s.adjustment_max_ratio * self.root_velocity.length()).max(s.adjustment_min_speed) * dt;
            if step.length() > cap {
                step = step.normalize_or_zero() * cap;
            }
            self.root_position += step;
            let offset = quat_abs(self.simulation.rotation * self.root_rotation.inverse());
            let mut turn = offset.to_scaled_axis() * (1.0 - (-dt / s.adjustment_rotation_halflife).exp2());
            let cap = s.adjustment_max_ratio * self.root_angular_velocity.length() * dt;
            if turn.length() > cap {
                turn = turn.normalize_or_zero() * cap;
            }
            self.root_rotation = (Quat::from_scaled_axis(turn) * self.root_rotation).normalize();
        }
        if s.clamping {
            let target = Vec3::new(self.simulation.position.x, 0.0, self.simulation.position.z);
            let offset = self.root_position - target;
            if offset.length() > s.clamp_distance {
                self.root_position = target + offset.normalize() * s.clamp_distance;
            }
            // Both rotations are pure yaws: clamp the yaw difference.
            let (axis, angle) = quat_abs(self.root_rotation * self.simulation.rotation.inverse()).to_axis_angle();
            if angle > s.clamp_angle {
                self.root_rotation = (Quat::from_axis_angle(axis, s.clamp_angle) * self.simulation.rotation).normalize();
            }
        }
        self.pose_positions[0] = self.root_position;
        self.pose_rotations[0] = self.root_rotation;
    }
}

/// Local positions, rotations, velocities and angular velocities of one frame.
fn frame_slices(db: &Database, frame: usize) -> (&[Vec3], &[Quat], &[Vec3], &[Vec3]) {
    let j = db.num_joints();
    let r = frame * j..(frame + 1) * j;
    (&db.local_positions[r.clone()], &db.local_rotations[r.clone()], &db.local_velocities[r.clone()], &db.local_angular_velocities[r])
}
