//! From user input to the simulated character and its predicted trajectory (docs/method.md §4):
//! the input gives a *desired velocity* and facing; springs move the simulated character toward
//! them; the same springs, integrated analytically, predict where it will be at the feature
//! offsets (+20/40/60 frames). A path mode drives the simulated character along a polyline.

use crate::persist::{Persist, Visitor};
use crate::spring::{spring_character_update, spring_damper_exact_quat};
use glam::{Quat, Vec2, Vec3};

/// What the user asks for this frame, on the ground plane in world space.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Input {
    /// Desired move direction (x, z); length 0–1 is the stick magnitude (longer is clamped).
    pub direction: Vec2,
    /// Desired facing (x, z) while strafing; ignored otherwise (facing follows the motion).
    pub facing: Vec2,
    pub run: bool,
    /// Keep facing `facing` while moving in any direction (side-steps, backwards).
    pub strafe: bool,
}

/// Speeds in m/s by direction relative to the facing (Holden's defaults).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Speeds {
    pub forward: f32,
    pub side: f32,
    pub backward: f32,
}

/// Controller tuning. Half-lives are exact (see [`crate::spring`]): 0.33 s here is Holden's
/// 0.27 s "halflife" (his constant halves the offset after 1.21 of his half-lives).
///
/// Walking speeds are the data's, not Holden's (1.75 / 1.5 / 1.25 m/s for his data set): the
/// default databases side-step at 0.45–0.85 m/s and walk backward at 0.65–1.26 m/s (median 1.07;
/// 100STYLE), so the walk asks for 0.8 m/s sideways and 1.1 m/s backward. Asking for motion the
/// data lacks makes the clamp drag the character: strafing at 1.5 m/s skated 35 cm/s with the
/// foot lock, at 0.8 m/s 2 cm/s (docs/runtime.md, quality table).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ControllerSettings {
    pub walk: Speeds,
    pub run: Speeds,
    pub velocity_halflife: f32,
    pub rotation_halflife: f32,
}

impl Default for ControllerSettings {
    fn default() -> Self {
        ControllerSettings {
            walk: Speeds { forward: 1.75, side: 0.8, backward: 1.1 },
            run: Speeds { forward: 4.0, side: 3.0, backward: 2.5 },
            velocity_halflife: 0.33,
            rotation_halflife: 0.33,
        }
    }
}

/// The simulated character: where the user wants the avatar to be (a point and a yaw).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Simulation {
    pub position: Vec3,
    pub velocity: Vec3,
    pub acceleration: Vec3,
    pub rotation: Quat,
    pub angular_velocity: Vec3,
}

impl Persist for Simulation {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.position.persist(v, "simulation position");
        self.velocity.persist(v, "simulation velocity");
        self.acceleration.persist(v, "simulation acceleration");
        self.rotation.persist(v, "simulation rotation");
        self.angular_velocity.persist(v, "simulation angular velocity");
    }
}

impl Persist for Input {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.direction.persist(v, "input direction");
        self.facing.persist(v, "input facing");
        self.run.persist(v, "input run");
        self.strafe.persist(v, "input strafe");
    }
}

impl Default for Simulation {
    fn default() -> Self {
        Simulation {
            position: Vec3::ZERO,
            velocity: Vec3::ZERO,
            acceleration: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            angular_velocity: Vec3::ZERO,
        }
    }
}

/// Yaw rotation facing the ground direction `d` (x, z); `None` for a zero direction.
pub fn yaw_facing(d: Vec3) -> Option<Quat> {
    let g = Vec3::new(d.x, 0.0, d.z);
    (g.length_squared() > 1e-8).then(|| Quat::from_rotation_y(g.x.atan2(g.z)))
}

/// The velocity the input asks for, in world space: the stick direction expressed relative to
/// the current facing, each axis scaled by its speed (forward, side, backward differ).
pub fn desired_velocity(input: &Input, facing: Quat, settings: &ControllerSettings) -> Vec3 {
    let d = Vec3::new(input.direction.x, 0.0, input.direction.y).clamp_length_max(1.0);
    let speeds = if input.run { settings.run } else { settings.walk };
    let local = facing.inverse() * d;
    let local =
        Vec3::new(local.x * speeds.side, 0.0, local.z * if local.z > 0.0 { speeds.forward } else { speeds.backward });
    facing * local
}

/// The facing the input asks for: `facing` while strafing, else the direction of motion,
/// else unchanged.
pub fn desired_rotation(input: &Input, desired_velocity: Vec3, current: Quat) -> Quat {
    if input.strafe {
        if let Some(q) = yaw_facing(Vec3::new(input.facing.x, 0.0, input.facing.y)) {
            return q;
        }
    }
    yaw_facing(desired_velocity).unwrap_or(current)
}

impl Simulation {
    /// Moves the simulated character `dt` seconds toward the desired velocity and rotation.
    pub fn update(&mut self, desired_velocity: Vec3, desired_rotation: Quat, settings: &ControllerSettings, dt: f32) {
        spring_character_update(
            &mut self.position,
            &mut self.velocity,
            &mut self.acceleration,
            desired_velocity,
            settings.velocity_halflife,
            dt,
        );
        spring_damper_exact_quat(
            &mut self.rotation,
            &mut self.angular_velocity,
            desired_rotation,
            settings.rotation_halflife,
            dt,
        );
    }

    /// Predicts positions and rotations after each of `times` (seconds, ascending) if the
    /// desired velocity and rotation stay as given. Writes `positions[i]`, `rotations[i]`.
    ///
    /// # Panics
    /// If the outputs are shorter than `times`.
    pub fn predict(
        &self,
        desired_velocity: Vec3,
        desired_rotation: Quat,
        settings: &ControllerSettings,
        times: &[f32],
        positions: &mut [Vec3],
        rotations: &mut [Quat],
    ) {
        for (i, &t) in times.iter().enumerate() {
            let mut s = *self;
            s.update(desired_velocity, desired_rotation, settings, t);
            positions[i] = s.position;
            rotations[i] = s.rotation;
        }
    }
}

/// Detects a sharp change of a desired quantity: the rising edge of its rate of change
/// crossing a threshold, so one flick triggers one search (Holden's trigger).
#[derive(Clone, Copy, Debug, Default)]
pub struct ChangeDetector {
    previous_rate: f32,
}

impl Persist for ChangeDetector {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        self.previous_rate.persist(v, what);
    }
}

impl ChangeDetector {
    /// `change` is how much the quantity changed over `dt`; returns true on a sharp change.
    pub fn update(&mut self, change: f32, dt: f32, threshold: f32) -> bool {
        let rate = if dt > 0.0 { change / dt } else { 0.0 };
        let sharp = rate > threshold && self.previous_rate <= threshold;
        self.previous_rate = rate;
        sharp
    }
}

/// Most keypoints a [`Path`] takes.
pub const MAX_PATH_POINTS: usize = 100_000;
/// Farthest a path keypoint may be from the origin on each axis (m): far enough for any scene,
/// near enough that f32 positions keep millimetres.
pub const MAX_PATH_COORDINATE: f32 = 1.0e5;

/// A polyline on the floor walked at a speed per segment, optionally looping.
#[derive(Clone, Debug, PartialEq)]
pub struct Path {
    points: Vec<Vec3>,
    speeds: Vec<f32>,
    looped: bool,
    /// Start time of each segment (seconds from the path start), plus the total at the end.
    times: Vec<f32>,
}

impl Path {
    /// `points` (≥ 2, y ignored) joined by segments walked at `speeds[i]` m/s (one per segment:
    /// `points.len() − 1`, or `points.len()` when `looped`, the last closing the loop).
    ///
    /// # Errors
    /// Fewer than 2 points, a wrong number of speeds, a speed that is not a positive number, a
    /// point that is not finite or farther than [`MAX_PATH_COORDINATE`] m from the origin, or a
    /// path longer than [`MAX_PATH_POINTS`] points.
    pub fn new(points: &[Vec3], speeds: &[f32], looped: bool) -> Result<Path, String> {
        if points.len() < 2 {
            return Err(format!("a path needs at least 2 points, got {}", points.len()));
        }
        if points.len() > MAX_PATH_POINTS {
            return Err(format!("a path has at most {MAX_PATH_POINTS} points, got {}", points.len()));
        }
        if let Some((i, p)) = points
            .iter()
            .enumerate()
            .find(|(_, p)| !(p.x.abs() <= MAX_PATH_COORDINATE && p.z.abs() <= MAX_PATH_COORDINATE))
        {
            return Err(format!(
                "path point {i} is ({}, {}): coordinates must be finite and within ±{MAX_PATH_COORDINATE} m",
                p.x, p.z
            ));
        }
        let segments = if looped { points.len() } else { points.len() - 1 };
        if speeds.len() != segments {
            return Err(format!(
                "a path with {} points needs {segments} segment speeds, got {}",
                points.len(),
                speeds.len()
            ));
        }
        if let Some(s) = speeds.iter().find(|s| !(**s > 0.0 && **s <= 100.0)) {
            return Err(format!("segment speeds must be in (0, 100] m/s, got {s}"));
        }
        let points: Vec<Vec3> = points.iter().map(|p| Vec3::new(p.x, 0.0, p.z)).collect();
        let mut times = vec![0.0];
        for i in 0..segments {
            let length = (points[(i + 1) % points.len()] - points[i]).length();
            times.push(times[i] + length / speeds[i]);
        }
        Ok(Path { points, speeds: speeds.to_vec(), looped, times })
    }

    /// Seconds to walk the whole path once.
    pub fn duration(&self) -> f32 {
        *self.times.last().unwrap()
    }

    /// Position and velocity at time `t` (wrapping when looped; at rest at the end otherwise).
    pub fn sample(&self, t: f32) -> (Vec3, Vec3) {
        let total = self.duration();
        let t = if self.looped && total > 0.0 { t.rem_euclid(total) } else { t.clamp(0.0, total) };
        let segment = self.times.partition_point(|&s| s <= t).saturating_sub(1).min(self.speeds.len() - 1);
        let (a, b) = (self.points[segment], self.points[(segment + 1) % self.points.len()]);
        let span = self.times[segment + 1] - self.times[segment];
        let u = if span > 0.0 { ((t - self.times[segment]) / span).clamp(0.0, 1.0) } else { 1.0 };
        let at_end = !self.looped && t >= total;
        let velocity = if at_end { Vec3::ZERO } else { (b - a).normalize_or_zero() * self.speeds[segment] };
        (a.lerp(b, u), velocity)
    }

    /// Shortest distance from `p` to the path (on the ground plane).
    pub fn distance_to(&self, p: Vec3) -> f32 {
        let p = Vec3::new(p.x, 0.0, p.z);
        (0..self.speeds.len())
            .map(|i| {
                let (a, b) = (self.points[i], self.points[(i + 1) % self.points.len()]);
                let ab = b - a;
                let u = if ab.length_squared() > 0.0 {
                    ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (a + ab * u - p).length()
            })
            .fold(f32::INFINITY, f32::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-4
    }

    #[test]
    fn desired_velocity_uses_direction_dependent_speeds() {
        let s = ControllerSettings::default();
        let facing = Quat::IDENTITY; // facing +Z
        let fwd = Input { direction: Vec2::new(0.0, 1.0), ..Default::default() };
        assert!(close(desired_velocity(&fwd, facing, &s), Vec3::new(0.0, 0.0, 1.75)));
        let back = Input { direction: Vec2::new(0.0, -1.0), ..Default::default() };
        assert!(close(desired_velocity(&back, facing, &s), Vec3::new(0.0, 0.0, -1.1)));
        let side = Input { direction: Vec2::new(1.0, 0.0), run: true, ..Default::default() };
        assert!(close(desired_velocity(&side, facing, &s), Vec3::new(3.0, 0.0, 0.0)));
        // Facing +X, stick +X is forward for the character.
        let turned = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        assert!(close(desired_velocity(&side, turned, &s), Vec3::new(4.0, 0.0, 0.0)));
        // Strafe keeps the requested facing; otherwise facing follows the motion.
        let strafe = Input { direction: Vec2::new(1.0, 0.0), facing: Vec2::new(0.0, 1.0), strafe: true, run: false };
        assert!(desired_rotation(&strafe, Vec3::X, turned).angle_between(Quat::IDENTITY) < 1e-3);
        assert!(desired_rotation(&Input::default(), Vec3::X, Quat::IDENTITY).angle_between(turned) < 1e-3);
        assert_eq!(desired_rotation(&Input::default(), Vec3::ZERO, turned), turned);
    }

    #[test]
    fn prediction_matches_simulation() {
        let s = ControllerSettings::default();
        let mut sim = Simulation::default();
        let (v, r) = (Vec3::new(1.0, 0.0, 1.0), Quat::from_rotation_y(0.8));
        let times = [1.0 / 3.0, 2.0 / 3.0, 1.0];
        let (mut pos, mut rot) = ([Vec3::ZERO; 3], [Quat::IDENTITY; 3]);
        sim.predict(v, r, &s, &times, &mut pos, &mut rot);
        for step in 1..=60 {
            sim.update(v, r, &s, 1.0 / 60.0);
            if step % 20 == 0 {
                assert!(close(sim.position, pos[step / 20 - 1]));
                assert!(sim.rotation.angle_between(rot[step / 20 - 1]) < 1e-3);
            }
        }
    }

    #[test]
    fn sharp_changes_trigger_once() {
        let mut d = ChangeDetector::default();
        assert!(!d.update(0.01, 1.0 / 60.0, 50.0));
        assert!(d.update(2.0, 1.0 / 60.0, 50.0));
        assert!(!d.update(2.0, 1.0 / 60.0, 50.0), "still changing fast: no second trigger");
        assert!(!d.update(0.0, 1.0 / 60.0, 50.0));
    }

    #[test]
    fn path_sampling() {
        let square = [Vec3::ZERO, Vec3::new(4.0, 0.0, 0.0), Vec3::new(4.0, 0.0, 4.0), Vec3::new(0.0, 0.0, 4.0)];
        let p = Path::new(&square, &[2.0, 1.0, 2.0, 1.0], true).unwrap();
        assert!((p.duration() - 12.0).abs() < 1e-5);
        assert!(close(p.sample(1.0).0, Vec3::new(2.0, 0.0, 0.0)));
        assert!(close(p.sample(1.0).1, Vec3::new(2.0, 0.0, 0.0)));
        assert!(close(p.sample(4.0).0, Vec3::new(4.0, 0.0, 2.0)));
        assert!(close(p.sample(12.5).0, Vec3::new(1.0, 0.0, 0.0)), "loops");
        assert!(p.distance_to(Vec3::new(2.0, 0.0, 0.3)) < 0.3001);
        let open = Path::new(&square[..2], &[2.0], false).unwrap();
        assert_eq!(open.sample(5.0), (Vec3::new(4.0, 0.0, 0.0), Vec3::ZERO));
        assert!(Path::new(&square, &[1.0], false).unwrap_err().contains("3 segment speeds"));
    }
}
