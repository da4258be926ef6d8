//! Critically damped springs parametrized by half-life (Holden, "Spring-It-On", and
//! docs/method.md §4): exact steps for values, vectors, rotations, and the velocity-driven
//! character spring with its analytic prediction.
//!
//! A critically damped spring released at rest from offset x₀ follows
//! `x(t) = x₀·e^(−y·t)·(1 + y·t)`: it never overshoots. We choose `y` so that the offset is
//! exactly halved after one half-life: `e^(−s)(1 + s) = ½` at `s = 1.678347`, so
//! `y = 1.678347 / halflife`. (Holden uses `y = 2·ln2 / halflife`, which
//! halves the offset only after ~1.21 half-lives; the shapes are identical, only the name of
//! the time constant differs. Defaults below are in our exact half-lives.)

use glam::{Quat, Vec3};
use std::ops::{Add, Mul, Sub};

/// `s` solving `e^(−s)·(1 + s) = ½`.
const HALF_DECAY: f32 = 1.678_347;

/// The spring's `y` (1/s) for a half-life in seconds (clamped away from zero).
#[inline]
pub fn halflife_to_y(halflife: f32) -> f32 {
    HALF_DECAY / halflife.max(1e-5)
}

/// Values a spring can move: scalars and vectors.
pub trait SpringValue: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<f32, Output = Self> {}
impl<T: Copy + Add<Output = T> + Sub<Output = T> + Mul<f32, Output = T>> SpringValue for T {}

/// One exact step of a critically damped spring moving `x` (with velocity `v`) toward `goal`:
/// `j0 = x − ĝ; j1 = v + j0·y; x' = e^(−y·dt)(j0 + j1·dt) + ĝ; v' = e^(−y·dt)(v − j1·y·dt)`.
#[inline]
pub fn spring_damper_exact<T: SpringValue>(x: &mut T, v: &mut T, goal: T, halflife: f32, dt: f32) {
    let y = halflife_to_y(halflife);
    let j0 = *x - goal;
    let j1 = *v + j0 * y;
    let e = (-y * dt).exp();
    *x = (j0 + j1 * dt) * e + goal;
    *v = (*v - j1 * (y * dt)) * e;
}

/// [`spring_damper_exact`] toward zero: how inertialization offsets fade out.
#[inline]
pub fn decay_spring_damper_exact<T: SpringValue>(x: &mut T, v: &mut T, halflife: f32, dt: f32) {
    DecayStep::new(halflife, dt).apply(x, v);
}

/// One step of [`decay_spring_damper_exact`] with its exponential taken once: an inertializer
/// decays every joint's offsets by the same half-life over the same `dt`, and `e^(−y·dt)` was
/// the costliest part of each joint's step.
#[derive(Clone, Copy, Debug)]
pub struct DecayStep {
    y: f32,
    dt: f32,
    e: f32,
}

impl DecayStep {
    pub fn new(halflife: f32, dt: f32) -> DecayStep {
        let y = halflife_to_y(halflife);
        DecayStep { y, dt, e: (-y * dt).exp() }
    }

    /// `j1 = v + x·y; x' = e^(−y·dt)(x + j1·dt); v' = e^(−y·dt)(v − j1·y·dt)`.
    #[inline]
    pub fn apply<T: SpringValue>(&self, x: &mut T, v: &mut T) {
        let j1 = *v + *x * self.y;
        *x = (*x + j1 * self.dt) * self.e;
        *v = (*v - j1 * (self.y * self.dt)) * self.e;
    }
}

/// The spring on rotations: the offset `x·goal⁻¹` is moved as a rotation vector (axis·angle,
/// the short way), `v` is an angular velocity (rad/s, world).
#[inline]
pub fn spring_damper_exact_quat(x: &mut Quat, v: &mut Vec3, goal: Quat, halflife: f32, dt: f32) {
    let mut offset = quat_abs(*x * goal.inverse()).to_scaled_axis();
    spring_damper_exact(&mut offset, v, Vec3::ZERO, halflife, dt);
    *x = (quat_from_rotation_vector(offset) * goal).normalize();
}

/// `Quat::from_scaled_axis(r)`, the rotation by `|r|` radians about `r`, with one sine: below a
/// quarter turn of half-angle the cosine is `√(1 − sin²)` (exact to an ulp there, as
/// `cos ≥ √½`), one square root where the cosine was a second libm call. An inertializer takes
/// one per joint per update (−2.4 % of a character update in WASM).
#[inline]
pub fn quat_from_rotation_vector(r: Vec3) -> Quat {
    let angle = r.length();
    if angle == 0.0 {
        return Quat::IDENTITY;
    }
    let half = 0.5 * angle;
    let sin = half.sin();
    let cos = if half < std::f32::consts::FRAC_PI_4 { (1.0 - sin * sin).sqrt() } else { half.cos() };
    let v = r * (sin / angle);
    Quat::from_xyzw(v.x, v.y, v.z, cos)
}

/// The same rotation in the hemisphere `w ≥ 0` (the short way round).
#[inline]
pub fn quat_abs(q: Quat) -> Quat {
    if q.w < 0.0 {
        -q
    } else {
        q
    }
}

/// The simulated character: position `x` driven by a velocity spring (velocity `v`,
/// acceleration `a`) toward the desired velocity `v_goal`, integrated exactly over `dt`
/// (the velocity spring of [`spring_damper_exact`] integrated once more in closed form).
#[inline]
pub fn spring_character_update(x: &mut Vec3, v: &mut Vec3, a: &mut Vec3, v_goal: Vec3, halflife: f32, dt: f32) {
    let y = halflife_to_y(halflife);
    let j0 = *v - v_goal;
    let j1 = *a + j0 * y;
    let e = (-y * dt).exp();
    *x = e * (((-j1) / (y * y)) + ((-j0 - j1 * dt) / y)) + (j1 / (y * y)) + j0 / y + v_goal * dt + *x;
    *v = e * (j0 + j1 * dt) + v_goal;
    *a = e * (*a - j1 * y * dt);
}

/// Where the rotation spring will be after each of `times` toward a fixed `goal`.
///
/// # Panics
/// If `rotations` is shorter than `times`.
pub fn spring_rotation_predict(rotations: &mut [Quat], q: Quat, w: Vec3, goal: Quat, halflife: f32, times: &[f32]) {
    for (i, &t) in times.iter().enumerate() {
        let (mut pq, mut pw) = (q, w);
        spring_damper_exact_quat(&mut pq, &mut pw, goal, halflife, t);
        rotations[i] = pq;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_in_one_halflife_and_never_overshoots() {
        for halflife in [0.05, 0.1, 0.27, 1.0] {
            let (mut x, mut v) = (1.0f32, 0.0f32);
            let dt = halflife / 50.0;
            let mut last = x;
            for step in 1..=500 {
                spring_damper_exact(&mut x, &mut v, 0.0, halflife, dt);
                assert!(x > 0.0 && x <= last, "overshoot or reversal at step {step}: {x}");
                last = x;
                if step == 50 {
                    assert!((x - 0.5).abs() < 1e-4, "after one half-life {x}");
                }
            }
            // Exactness: one big step equals many small ones.
            let (mut x1, mut v1) = (1.0f32, 0.3f32);
            spring_damper_exact(&mut x1, &mut v1, 0.0, halflife, halflife);
            let (mut x2, mut v2) = (1.0f32, 0.3f32);
            for _ in 0..100 {
                spring_damper_exact(&mut x2, &mut v2, 0.0, halflife, halflife / 100.0);
            }
            assert!((x1 - x2).abs() < 1e-4 && (v1 - v2).abs() < 1e-3);
        }
    }

    #[test]
    fn decay_and_vectors_agree_with_the_goal_form() {
        let (mut a, mut va) = (Vec3::new(1.0, -2.0, 0.5), Vec3::new(0.1, 0.0, -0.3));
        let (mut b, mut vb) = (a, va);
        decay_spring_damper_exact(&mut a, &mut va, 0.2, 0.05);
        spring_damper_exact(&mut b, &mut vb, Vec3::ZERO, 0.2, 0.05);
        assert!((a - b).length() < 1e-6 && (va - vb).length() < 1e-6);
    }

    #[test]
    fn rotation_spring_halves_the_angle_and_stays_unit() {
        let goal = Quat::from_rotation_y(0.7);
        let mut q = Quat::from_rotation_y(0.7 + 1.2);
        let mut w = Vec3::ZERO;
        for _ in 0..30 {
            spring_damper_exact_quat(&mut q, &mut w, goal, 0.3, 0.01);
            assert!((q.length() - 1.0).abs() < 1e-5);
        }
        assert!((q.angle_between(goal) - 0.6).abs() < 1e-3, "{}", q.angle_between(goal));
    }

    #[test]
    fn the_rotation_vector_exponential_equals_glams() {
        let mut worst = 0.0f32;
        for i in 0..=4000 {
            // 1e-30 … 1e-3 rad, then 0 … 8 rad (past π the same rotation the other way round).
            let angle = if i < 10 { 10f32.powi(-3 * i - 3) } else { (i - 10) as f32 * 8.0 / 3990.0 };
            for axis in [Vec3::X, Vec3::new(0.3, -0.8, 0.52).normalize(), Vec3::new(-1.0, 1.0, 1.0).normalize()] {
                let (ours, glams) = (quat_from_rotation_vector(axis * angle), Quat::from_scaled_axis(axis * angle));
                worst = worst.max((ours - glams).length());
                assert!((ours.length() - 1.0).abs() < 1e-6, "{angle}: |q| = {}", ours.length());
            }
        }
        assert!(worst < 1e-6, "largest difference {worst}");
        assert_eq!(quat_from_rotation_vector(Vec3::ZERO), Quat::IDENTITY);
        assert!(quat_from_rotation_vector(Vec3::new(f32::NAN, 0.0, 0.0)).is_nan());
    }

    #[test]
    fn character_spring_reaches_the_desired_velocity_and_predicts_exactly() {
        let (mut x, mut v, mut a) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
        let goal = Vec3::new(0.0, 0.0, 1.75);
        // Prediction = one exact step of t seconds (how the controller predicts its trajectory).
        let predict = |t: f32| {
            let (mut px, mut pv, mut pa) = (x, v, a);
            spring_character_update(&mut px, &mut pv, &mut pa, goal, 0.27, t);
            (px, pv)
        };
        let predicted = [predict(1.0 / 3.0), predict(2.0 / 3.0), predict(1.0)];
        // Stepping at 60 Hz lands on the prediction (the update is exact for any dt).
        for step in 1..=60 {
            spring_character_update(&mut x, &mut v, &mut a, goal, 0.27, 1.0 / 60.0);
            if step % 20 == 0 {
                let (px, pv) = predicted[step / 20 - 1];
                assert!((x - px).length() < 1e-4 && (v - pv).length() < 1e-4, "step {step}");
            }
        }
        // 1 s = 3.7 half-lives: e^(−6.2)·(1 + 6.2) = 1.5% of the error is left.
        assert!((v - goal).length() < 0.03, "velocity after 1 s: {v}");
        // Distance covered is a bit less than goal·t (it started at rest).
        assert!(x.z > 1.0 && x.z < 1.75, "{x}");
        // Half the velocity error is gone after one half-life.
        let (mut x, mut v, mut a) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
        spring_character_update(&mut x, &mut v, &mut a, goal, 0.27, 0.27);
        assert!((v.z - goal.z / 2.0).abs() < 1e-3, "{v}");
    }
}
