//! What moves the simulated character (docs/method.md §4, §9): keyboard/gamepad input through
//! the velocity and rotation springs, a path, or a tracked (VR) user; and the trajectory each
//! of them predicts for the query.

use super::Character;
use crate::controller::{
    desired_rotation, desired_velocity, yaw_facing, ChangeDetector, ControllerSettings, Input, Path, Simulation,
};
use crate::persist::{Persist, Visitor};
use crate::spring::{quat_abs, spring_damper_exact, spring_damper_exact_quat, spring_rotation_predict};
use glam::{Quat, Vec2, Vec3};

/// Which source a [`DriveInput`] asks to move the character (the runtime's [`Mode`] without
/// its data; a path's points are given once, with [`Character::set_path`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DriveMode {
    /// Keyboard/gamepad move input.
    #[default]
    Move,
    /// The path last set.
    Path,
    /// A tracked (VR) user.
    Tracked,
}

/// The one drive value: everything that moves a character for its next step, in database
/// units — which mode, the move input, the tracked sample, the crouch and α. A page's
/// `Character` builds one from its devices; a shared room sends each step's value and every copy
/// replays it; the runtime takes it whole with [`Character::set_drive`]. Read flat from JS in
/// [`DriveInput::FIELDS`] order (`RawCharacter::set_drive`); `web/src/core/drive.ts` mirrors
/// it field for field and a test checks the two orders agree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveInput {
    pub mode: DriveMode,
    /// Move mode: stick direction, facing, run, strafe (database axes).
    pub input: Input,
    /// Tracked mode: the raw head floor sample (the drive smooths it).
    pub tracked: Tracked,
    /// Hips lowered below the animation (database units; ≥ 0), the legs bent by IK (any mode).
    pub hips_drop: f32,
    /// Torso bent forward (rad; any mode).
    pub bend: f32,
    /// α, how far the root may lag the simulated character (database units); NaN: unchanged.
    pub clamp_distance: f32,
}

impl Default for DriveInput {
    fn default() -> Self {
        DriveInput {
            mode: DriveMode::Move,
            input: Input::default(),
            tracked: Tracked::default(),
            hips_drop: 0.0,
            bend: 0.0,
            clamp_distance: f32::NAN,
        }
    }
}

impl DriveInput {
    /// The flat order: `mode` is 0 move, 1 path, 2 tracked; flags are 0 or 1.
    pub const FIELDS: [&'static str; 16] = [
        "mode",
        "move_x",
        "move_z",
        "face_x",
        "face_z",
        "run",
        "strafe",
        "head_x",
        "head_z",
        "velocity_x",
        "velocity_z",
        "yaw",
        "body",
        "hips_drop",
        "bend",
        "clamp_distance",
    ];

    /// Reads the value from `v` in [`Self::FIELDS`] order.
    ///
    /// # Errors
    /// A length other than the field count, or a mode that is not 0, 1 or 2. Values that are not
    /// finite pass through: the character refuses them one by one (keeping its last good ones).
    pub fn from_flat(v: &[f32]) -> Result<DriveInput, String> {
        let n = Self::FIELDS.len();
        if v.len() != n {
            return Err(format!("a drive value has {n} numbers ({}), got {}", Self::FIELDS.join(", "), v.len()));
        }
        let mode = match v[0] {
            0.0 => DriveMode::Move,
            1.0 => DriveMode::Path,
            2.0 => DriveMode::Tracked,
            m => return Err(format!("drive mode {m} (0 move, 1 path, 2 tracked)")),
        };
        Ok(DriveInput {
            mode,
            input: Input {
                direction: Vec2::new(v[1], v[2]),
                facing: Vec2::new(v[3], v[4]),
                run: v[5] != 0.0,
                strafe: v[6] != 0.0,
            },
            tracked: Tracked {
                position: Vec3::new(v[7], 0.0, v[8]),
                velocity: Vec3::new(v[9], 0.0, v[10]),
                yaw: v[11],
                body: v[12] != 0.0,
            },
            hips_drop: v[13],
            bend: v[14],
            clamp_distance: v[15],
        })
    }
}

impl Character {
    /// Takes the drive value for the next [`Character::update`] (its move input goes to
    /// `update`, whose argument it is). Move mode leaves a path or a tracked user; path mode
    /// follows the path last set (without one it is refused and counted); tracked mode takes
    /// the sample ([`Character::set_tracked`]). The crouch applies in every mode; α only when
    /// it is a number ≥ 0.
    pub fn set_drive(&mut self, d: &DriveInput) {
        match d.mode {
            DriveMode::Move => self.set_path(None),
            DriveMode::Path if matches!(self.drive.mode, Mode::Path { .. }) => {}
            DriveMode::Path => self.stats.rejected_inputs += 1,
            DriveMode::Tracked => self.set_tracked(d.tracked),
        }
        self.set_hips_drop(d.hips_drop);
        self.set_torso_bend(d.bend);
        if d.clamp_distance >= 0.0 && d.clamp_distance.is_finite() {
            self.settings.clamp_distance = d.clamp_distance;
        }
    }
}

/// A tracked user (VR), as given each frame: raw, the drive smooths it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tracked {
    /// The head centre projected on the floor (y ignored), m; with `body`, the hips'.
    pub position: Vec3,
    /// The head's ground velocity (y ignored), m/s; with `body`, the hips'.
    pub velocity: Vec3,
    /// Body yaw, radians, 0 = facing +Z: predicted from the head and hands, or with `body` the
    /// tracked hips' facing.
    pub yaw: f32,
    /// The sample is the user's tracked hips (WebXR body tracking, docs/vr.md), not their head:
    /// the root's target is the hips' floor point itself (no head or bend offset), and the shown
    /// hips are moved and turned onto them ([`super::legs::Legs::follow`]), the legs keeping the
    /// feet by IK.
    pub body: bool,
}

/// The source of motion.
#[derive(Clone, Debug)]
pub enum Mode {
    /// Keyboard/gamepad [`Input`] through the velocity and rotation springs.
    Input,
    /// Along a polyline, `time` seconds since its start.
    Path { path: Path, time: f32 },
    /// Along with a tracked user.
    Tracked(Tracked),
}

/// The drive: its mode, what it asks for now, and the detectors of sharp changes (which force a
/// search: Holden's trigger).
#[derive(Clone, Debug)]
pub struct Drive {
    pub mode: Mode,
    /// Tracked mode: where the avatar's head is relative to its root (world, on the floor,
    /// smoothed; set by the character each frame, zero when off). The user's head is where the
    /// avatar's head should be, so the simulated character — the root's target — is the head
    /// minus this offset (`CharacterSettings::tracked_head_offset`).
    pub head_offset: Vec3,
    pub desired_velocity: Vec3,
    pub desired_rotation: Quat,
    velocity_change: ChangeDetector,
    rotation_change: ChangeDetector,
}

impl Persist for Tracked {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.position.persist(v, "tracked position");
        self.velocity.persist(v, "tracked velocity");
        self.yaw.persist(v, "tracked yaw");
        self.body.persist(v, "tracked body");
    }
}

/// The mode and how far along it is; a path's points are not state (the receiver is given the
/// same path first, as a shared room's PATH message does).
impl Persist for Drive {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        let mut tag: u32 = match self.mode {
            Mode::Input => 0,
            Mode::Path { .. } => 1,
            Mode::Tracked(_) => 2,
        };
        tag.persist(v, "drive mode");
        if v.reading() {
            match (tag, &self.mode) {
                (0, _) => self.mode = Mode::Input,
                (1, Mode::Path { .. }) | (2, Mode::Tracked(_)) => {}
                (1, _) => {
                    v.fail("the state follows a path this character was not given (set the same path first)".into())
                }
                (2, _) => self.mode = Mode::Tracked(Tracked::default()),
                _ => v.fail(format!("drive mode {tag} (0 input, 1 path, 2 tracked)")),
            }
        }
        match &mut self.mode {
            Mode::Input => {}
            Mode::Path { time, .. } => time.persist(v, "path time"),
            Mode::Tracked(t) => t.persist(v, "tracked sample"),
        }
        self.head_offset.persist(v, "drive head offset");
        self.desired_velocity.persist(v, "desired velocity");
        self.desired_rotation.persist(v, "desired rotation");
        self.velocity_change.persist(v, "velocity change detector");
        self.rotation_change.persist(v, "rotation change detector");
    }
}

impl Default for Drive {
    fn default() -> Self {
        Drive {
            mode: Mode::Input,
            head_offset: Vec3::ZERO,
            desired_velocity: Vec3::ZERO,
            desired_rotation: Quat::IDENTITY,
            velocity_change: ChangeDetector::default(),
            rotation_change: ChangeDetector::default(),
        }
    }
}

impl Drive {
    /// Moves `simulation` by `dt` under the mode (`input` is used in input mode only). Returns
    /// whether what is asked for changed sharply (velocity or facing rate above the thresholds).
    pub fn update(
        &mut self,
        simulation: &mut Simulation,
        settings: &ControllerSettings,
        thresholds: (f32, f32),
        input: &Input,
        dt: f32,
    ) -> bool {
        let (velocity, rotation) = match &mut self.mode {
            Mode::Input => {
                let v = desired_velocity(input, simulation.rotation, settings);
                (v, desired_rotation(input, v, simulation.rotation))
            }
            Mode::Path { path, time } => {
                // The simulated character rides the path exactly; its facing follows the
                // path direction through the rotation spring.
                *time += dt;
                let (p, v) = path.sample(*time);
                simulation.position = p;
                simulation.velocity = v;
                simulation.acceleration = Vec3::ZERO;
                (v, yaw_facing(v).unwrap_or(simulation.rotation))
            }
            Mode::Tracked(t) => {
                // The simulated character is the user's head on the floor (§9), less where the
                // avatar's head sits from its root; its velocity is the head's ground velocity,
                // spring-smoothed: the head bobs and sways every step, the trajectory must not.
                simulation.position =
                    Vec3::new(t.position.x - self.head_offset.x, 0.0, t.position.z - self.head_offset.z);
                let goal = Vec3::new(t.velocity.x, 0.0, t.velocity.z);
                spring_damper_exact(
                    &mut simulation.velocity,
                    &mut simulation.acceleration,
                    goal,
                    settings.velocity_halflife,
                    dt,
                );
                (goal, Quat::from_rotation_y(t.yaw))
            }
        };
        let velocity_jump = (velocity - self.desired_velocity).length();
        let rotation_jump = quat_abs(rotation * self.desired_rotation.inverse()).to_scaled_axis().length();
        let sharp_velocity = self.velocity_change.update(velocity_jump, dt, thresholds.0);
        let sharp_rotation = self.rotation_change.update(rotation_jump, dt, thresholds.1);
        self.desired_velocity = velocity;
        self.desired_rotation = rotation;
        match self.mode {
            Mode::Input => simulation.update(velocity, rotation, settings, dt),
            // The path or the user sets the position; only the facing is sprung.
            Mode::Path { .. } | Mode::Tracked(_) => {
                spring_damper_exact_quat(
                    &mut simulation.rotation,
                    &mut simulation.angular_velocity,
                    rotation,
                    settings.rotation_halflife,
                    dt,
                );
            }
        }
        sharp_velocity || sharp_rotation
    }

    /// After a recovery: what is asked for is where the simulated character now is and faces,
    /// and the change detectors start afresh.
    pub fn settle(&mut self, simulation: &Simulation) {
        self.desired_velocity = Vec3::ZERO;
        self.desired_rotation = simulation.rotation;
        self.velocity_change = ChangeDetector::default();
        self.rotation_change = ChangeDetector::default();
        if let Mode::Path { time, .. } = &mut self.mode {
            if !time.is_finite() {
                *time = 0.0;
            }
        }
    }

    /// Where the simulated character will be, and facing, after each of `times` seconds (world).
    pub fn predict(
        &self,
        simulation: &Simulation,
        settings: &ControllerSettings,
        times: &[f32],
        positions: &mut [Vec3],
        rotations: &mut [Quat],
    ) {
        let s = simulation;
        match &self.mode {
            Mode::Input => {
                s.predict(self.desired_velocity, self.desired_rotation, settings, times, positions, rotations)
            }
            Mode::Path { path, time } => {
                for (i, &t) in times.iter().enumerate() {
                    let (p, v) = path.sample(time + t);
                    positions[i] = p;
                    let goal = yaw_facing(v).unwrap_or(s.rotation);
                    let (mut q, mut w) = (s.rotation, s.angular_velocity);
                    spring_damper_exact_quat(&mut q, &mut w, goal, settings.rotation_halflife, t);
                    rotations[i] = q;
                }
            }
            Mode::Tracked(_) => {
                // §9: positions p̂ + t·v (t = 1/3, 2/3, 1 s at the default offsets); directions
                // the smoothed yaw sprung on toward the predicted one.
                for (i, &t) in times.iter().enumerate() {
                    positions[i] = s.position + s.velocity * t;
                }
                spring_rotation_predict(
                    rotations,
                    s.rotation,
                    s.angular_velocity,
                    self.desired_rotation,
                    settings.rotation_halflife,
                    times,
                );
            }
        }
    }
}
