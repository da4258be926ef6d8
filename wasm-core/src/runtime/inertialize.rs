//! Inertialization (Bollo 2017, offset form): transitions without pops, decayed by springs.
//!
//! docs/method.md §5. At a transition from the pose that was playing (source) to a new database
//! frame (target) we store, per joint, the *offset* between them; every frame the offset decays
//! to zero with a critically damped spring (docs/method.md §4) and is applied to the pose that is
//! now playing. Only one pose is evaluated per frame and the output is continuous (position and
//! velocity) across the transition.
//!
//! Conventions (same as Holden's `inertialize_transition/update` in `spring.h`):
//! - The **source** of a transition is the *raw* pose that was fed to the last [`Inertializer::update`]
//!   (the database frame that was playing), not the inertialized output: the current offsets are
//!   folded in by the transition itself, `d_r' = abs(d_r · s_r · t_r⁻¹)`. When only the output is
//!   at hand (e.g. after a database switch), [`Inertializer::transition_from_output`] does the same
//!   from the output pose.
//! - Rotation offsets act on the left, `out_r = d_r · in_r`; angular velocities are in the
//!   parent's space with the convention ω = scaled axis of `q_i · q_{i−1}⁻¹` / dt (docs/method.md §1),
//!   so `out_ω = d_ω + d_r · in_ω`.
//! - Positions and velocities add: `out_p = in_p + d_p`, `out_v = in_v + d_v`.
//!
//! The root (joint 0) stores a *world* position and yaw that jump arbitrarily between takes, so
//! it is not inertialized here: the character's root motion (`character::root`) plays the new
//! take's motion from where the character stands and inertializes only the velocity mismatch.

use crate::lanes::{F32x4, Vec3x4};
use crate::persist::{Persist, Visitor};
use crate::spring::{quat_from_rotation_vector, DecayStep};
use glam::{Quat, Vec3};

/// Exact critically damped decay toward zero, the same spring as everywhere in the crate
/// ([`crate::spring`]: one half-life halves a released offset). Returns `(x', v')`.
#[inline]
pub fn decay_spring(x: f32, v: f32, halflife: f32, dt: f32) -> (f32, f32) {
    let (mut x, mut v) = (x, v);
    crate::spring::decay_spring_damper_exact(&mut x, &mut v, halflife, dt);
    (x, v)
}

/// [`decay_spring`] for a vector (each component independently, one decay rate).
#[inline]
pub fn decay_spring_vec3(x: Vec3, v: Vec3, halflife: f32, dt: f32) -> (Vec3, Vec3) {
    let (mut x, mut v) = (x, v);
    crate::spring::decay_spring_damper_exact(&mut x, &mut v, halflife, dt);
    (x, v)
}

pub use crate::spring::quat_abs;

/// Transition of one vector channel (docs/method.md §5, additive form): folds the jump from the raw
/// source `(src, src_vel)` to the target `(dst, dst_vel)` into the offset:
/// `d' = (d + s) − t`, `d_v' = (d_v + s_v) − t_v`.
#[inline]
pub fn inertialize_transition_vec3(
    offset: &mut Vec3,
    offset_vel: &mut Vec3,
    src: Vec3,
    src_vel: Vec3,
    dst: Vec3,
    dst_vel: Vec3,
) {
    *offset = (*offset + src) - dst;
    *offset_vel = (*offset_vel + src_vel) - dst_vel;
}

/// Transition of one rotation channel (docs/method.md §5): `d_r' = abs(d_r · s_r · t_r⁻¹)`, so that
/// `d_r' · t_r = d_r · s_r` (the output does not move), and the angular velocity offset that keeps
/// the output's angular velocity `d_ω + d_r · ω` continuous: `d_ω' = d_ω + d_r·s_ω − d_r'·t_ω`.
///
/// The thesis/Holden write `d_ω' = (d_ω + s_ω) − t_ω`, which is the same when the offset is small;
/// the rotated form here is exact for the update's `out_ω = d_ω + d_r · in_ω`.
///
/// Preconditions: `src` and `dst` are unit quaternions (`offset` is kept unit by this module).
#[inline]
pub fn inertialize_transition_quat(
    offset: &mut Quat,
    offset_vel: &mut Vec3,
    src: Quat,
    src_vel: Vec3,
    dst: Quat,
    dst_vel: Vec3,
) {
    // Normalizing costs little and keeps repeated transitions from accumulating drift.
    let new_offset = quat_abs((*offset * src * dst.inverse()).normalize());
    *offset_vel = (*offset_vel + *offset * src_vel) - new_offset * dst_vel;
    *offset = new_offset;
}

/// Whether every component of `a` and `b` is ±0: their bits but the signs ORed, one branch
/// instead of six comparisons.
#[inline(always)]
fn both_zero(a: Vec3, b: Vec3) -> bool {
    ((a.x.to_bits() | a.y.to_bits() | a.z.to_bits() | b.x.to_bits() | b.y.to_bits() | b.z.to_bits()) << 1) == 0
}

/// Per-joint inertialization offsets for a whole pose (local positions, velocities, rotations and
/// angular velocities, as stored in [`crate::Database`]). Allocates only in [`Inertializer::new`].
///
/// Per frame:
/// 1. on a jump to a new frame `t` (or another database with the same skeleton), call
///    [`Inertializer::transition`] with the pose that was playing (the last `update` input) as
///    source and `t` as target;
/// 2. call [`Inertializer::update`] with the pose now playing.
#[derive(Clone, Debug, PartialEq)]
pub struct Inertializer {
    offset_positions: Vec<Vec3>,
    offset_velocities: Vec<Vec3>,
    /// `d_r` as a rotation vector (scaled axis, docs/method.md §4 "via scaled axis-angle"): the
    /// spring decays this vector, so an update takes no logarithm of a quaternion (an `atan2` per
    /// joint per update, a tenth of a character's update). `d_r` itself is its exponential
    /// ([`Inertializer::offset_rotation`]); a transition sets the vector from the new `d_r`.
    /// Joint `i` is lane `i % 4` of element `i / 4`, here and in `offset_angular_velocities`:
    /// nearly every joint's rotation offset is live, so an update decays and exponentiates
    /// them four at a time ([`half_angle`]). Per joint, with a libm sine (a software one in
    /// WASM), they were a fifth of a character's update in V8's profile; four at a time, the
    /// update runs 4 % fewer instructions there.
    offset_rotation_vectors: Vec<Vec3x4>,
    offset_angular_velocities: Vec<Vec3x4>,
    /// Per joint, which of its channels has an offset ([`LIVE_POSITION`], [`LIVE_ROTATION`]):
    /// set where a transition leaves one that is not zero. A zero offset stays zero and
    /// changes nothing — most joints' local positions are the skeleton's constant bone
    /// offsets, so their position offsets are exactly zero after every transition (`(0 + s) −
    /// t` with `s = t`) — and a live one decays toward zero without reaching it (but by
    /// underflow, after ~100 half-lives, where the update then adds zeros). Testing the
    /// offsets' bits in every update instead was 4 % of a crowd's instructions.
    live: Vec<u8>,
    /// The joints whose position channel is live, in order (allocated once, `num_joints` long
    /// at most): the update copies the positions and touches only these.
    moving: Vec<u32>,
}

/// [`Inertializer`]'s `live` bits.
const LIVE_POSITION: u8 = 1;
const LIVE_ROTATION: u8 = 2;

/// The `live` bits of a joint whose position offset and velocity are `p`, `v` and rotation
/// offset and angular velocity `r`, `w`.
fn live_bits(p: Vec3, v: Vec3, r: Vec3, w: Vec3) -> u8 {
    (u8::from(!both_zero(p, v)) * LIVE_POSITION) | (u8::from(!both_zero(r, w)) * LIVE_ROTATION)
}

/// Largest squared half-angle [`half_angle`]'s series take: `(π/2)²`, a rotation of half a turn
/// (every offset a transition sets, the short way); a larger one (a fast angular velocity
/// offset carrying it further while it decays) takes libm's sine and cosine.
const SERIES_MAX_H2: f32 = 2.467_4;

/// `(sin h / (2h), cos h)` from `h2 = h²`, `h` the half-angle of a rotation vector `r` (angle
/// `2h = |r|`): the quaternion `exp(r/2)` is `(r · sin h / (2h), cos h)` — no square root, no
/// division and no libm call, and the same operations on a lane as on a scalar, so four
/// joints at a time give the bits one at a time does. Taylor series to `h¹²` and `h¹⁴`: for
/// `h2 ≤` [`SERIES_MAX_H2`] the first term left out is below 5·10⁻¹⁰ (f32's ε is 1.2·10⁻⁷).
#[inline(always)]
fn half_angle<T: Copy + std::ops::Add<Output = T> + std::ops::Mul<Output = T> + From<f32>>(h2: T) -> (T, T) {
    let c = |v: f32| T::from(v);
    // sin h / h = Σ (−h²)ᵏ / (2k + 1)!,  cos h = Σ (−h²)ᵏ / (2k)!
    let sinc = c(1.0)
        + h2 * (c(-1.0 / 6.0)
            + h2 * (c(1.0 / 120.0)
                + h2 * (c(-1.0 / 5040.0)
                    + h2 * (c(1.0 / 362_880.0) + h2 * (c(-1.0 / 39_916_800.0) + h2 * c(1.0 / 6_227_020_800.0))))));
    let cos = c(1.0)
        + h2 * (c(-0.5)
            + h2 * (c(1.0 / 24.0)
                + h2 * (c(-1.0 / 720.0)
                    + h2 * (c(1.0 / 40_320.0)
                        + h2 * (c(-1.0 / 3_628_800.0)
                            + h2 * (c(1.0 / 479_001_600.0) + h2 * c(-1.0 / 87_178_291_200.0)))))));
    (sinc * c(0.5), cos)
}

/// `exp(r/2)` as a quaternion, as the update takes it for one lane: [`half_angle`] within its
/// range, else libm's.
#[inline]
fn rotation_vector_quat(r: Vec3) -> Quat {
    let h2 = (r.x * r.x + r.y * r.y + r.z * r.z) * 0.25;
    if h2 <= SERIES_MAX_H2 {
        let (k, w) = half_angle(h2);
        Quat::from_xyzw(r.x * k, r.y * k, r.z * k, w)
    } else {
        quat_from_rotation_vector(r)
    }
}

/// Lanes `0..n` of `lanes` (joint `i` in lane `i % 4` of element `i / 4`) as `n` vectors in
/// joint order: the state's layout is the same as for any other per-joint vectors.
fn persist_lanes(lanes: &mut [Vec3x4], n: usize, v: &mut dyn Visitor, what: &'static str) {
    v.count(n, what);
    for i in 0..n {
        let mut x = lanes[i / 4].lane(i % 4);
        x.persist(v, what);
        if v.reading() {
            lanes[i / 4].set_lane(i % 4, x);
        }
    }
}

impl Persist for Inertializer {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        let n = self.num_joints();
        self.offset_positions.persist(v, "inertialization position offsets");
        self.offset_velocities.persist(v, "inertialization velocity offsets");
        persist_lanes(&mut self.offset_rotation_vectors, n, v, "inertialization rotation offsets");
        persist_lanes(&mut self.offset_angular_velocities, n, v, "inertialization angular velocity offsets");
        if v.reading() {
            for i in 0..self.num_joints() {
                self.set_live(i);
            }
            self.list_moving();
        }
    }
}

impl Inertializer {
    /// Zero offsets for `num_joints` joints.
    pub fn new(num_joints: usize) -> Self {
        Inertializer {
            offset_positions: vec![Vec3::ZERO; num_joints],
            offset_velocities: vec![Vec3::ZERO; num_joints],
            offset_rotation_vectors: vec![Vec3x4::ZERO; num_joints.div_ceil(4)],
            offset_angular_velocities: vec![Vec3x4::ZERO; num_joints.div_ceil(4)],
            live: vec![0; num_joints],
            moving: Vec::with_capacity(num_joints),
        }
    }

    /// Joint `i`'s `live` bits from its offsets.
    fn set_live(&mut self, i: usize) {
        let (p, v) = (self.offset_positions[i], self.offset_velocities[i]);
        self.live[i] = live_bits(p, v, self.offset_rotation_vector(i), self.offset_angular_velocity(i));
    }

    /// [`Self::moving`] from the `live` bits.
    fn list_moving(&mut self) {
        self.moving.clear();
        let live = self.live.iter().enumerate().filter(|(_, &b)| b & LIVE_POSITION != 0);
        self.moving.extend(live.map(|(i, _)| i as u32));
    }

    pub fn num_joints(&self) -> usize {
        self.offset_positions.len()
    }

    /// Drops every offset: the next `update` outputs its input unchanged (a hard cut).
    pub fn reset(&mut self) {
        self.offset_positions.fill(Vec3::ZERO);
        self.offset_velocities.fill(Vec3::ZERO);
        self.offset_rotation_vectors.fill(Vec3x4::ZERO);
        self.offset_angular_velocities.fill(Vec3x4::ZERO);
        self.live.fill(0);
        self.moving.clear();
    }

    /// Current position offsets `d_p` (local space of each joint's parent).
    pub fn offset_positions(&self) -> &[Vec3] {
        &self.offset_positions
    }

    pub fn offset_velocities(&self) -> &[Vec3] {
        &self.offset_velocities
    }

    /// Joint `i`'s current rotation offset `d_r`, the exponential of its rotation vector (unit,
    /// w ≥ 0 right after a transition).
    pub fn offset_rotation(&self, i: usize) -> Quat {
        rotation_vector_quat(self.offset_rotation_vector(i))
    }

    fn offset_rotation_vector(&self, i: usize) -> Vec3 {
        self.offset_rotation_vectors[i / 4].lane(i % 4)
    }

    /// Joint `i`'s current angular velocity offset `d_ω`.
    pub fn offset_angular_velocity(&self, i: usize) -> Vec3 {
        self.offset_angular_velocities[i / 4].lane(i % 4)
    }

    /// Records a jump from the source pose `src_*` to the target pose `dst_*` (docs/method.md §5).
    ///
    /// `src_*` is the **raw** pose that was the input of the last [`Inertializer::update`] (the
    /// database frame that was playing, without offsets); the existing offsets are folded in, so
    /// transitions can follow each other at any rate. `dst_*` is the new frame, possibly from another
    /// database with the same skeleton. After this, `update(dst_*, halflife, 0.0, …)` outputs
    /// exactly the previous output.
    ///
    /// # Panics
    /// If any slice's length differs from [`Inertializer::num_joints`].
    #[allow(clippy::too_many_arguments)]
    pub fn transition(
        &mut self,
        src_pos: &[Vec3],
        src_vel: &[Vec3],
        src_rot: &[Quat],
        src_angvel: &[Vec3],
        dst_pos: &[Vec3],
        dst_vel: &[Vec3],
        dst_rot: &[Quat],
        dst_angvel: &[Vec3],
    ) {
        let n = self.num_joints();
        for (name, len) in [
            ("src_pos", src_pos.len()),
            ("src_vel", src_vel.len()),
            ("src_rot", src_rot.len()),
            ("src_angvel", src_angvel.len()),
            ("dst_pos", dst_pos.len()),
            ("dst_vel", dst_vel.len()),
            ("dst_rot", dst_rot.len()),
            ("dst_angvel", dst_angvel.len()),
        ] {
            assert_eq!(len, n, "Inertializer::transition: {name} has {len} joints, expected {n}");
        }
        for (g, (r4, w4)) in
            self.offset_rotation_vectors.iter_mut().zip(&mut self.offset_angular_velocities).enumerate()
        {
            let (mut r, mut w) = (r4.to_vec3s(), w4.to_vec3s());
            for i in 4 * g..(4 * g + 4).min(n) {
                let l = i - 4 * g;
                let (p, v) = (&mut self.offset_positions[i], &mut self.offset_velocities[i]);
                inertialize_transition_vec3(p, v, src_pos[i], src_vel[i], dst_pos[i], dst_vel[i]);
                let mut d = rotation_vector_quat(r[l]);
                inertialize_transition_quat(&mut d, &mut w[l], src_rot[i], src_angvel[i], dst_rot[i], dst_angvel[i]);
                // The short way (w ≥ 0): an angle of at most π.
                r[l] = d.to_scaled_axis();
                self.live[i] = live_bits(*p, *v, r[l], w[l]);
            }
            (*r4, *w4) = (Vec3x4::from_vec3s(r), Vec3x4::from_vec3s(w));
        }
        self.list_moving();
    }

    /// The same transition as [`Inertializer::transition`], computed from the current **output**
    /// pose `out_*` (what the last `update` wrote) instead of the raw source: the offsets become
    /// `d_p = out_p − t_p`, `d_v = out_v − t_v`, `d_r = abs(out_r · t_r⁻¹)`,
    /// `d_ω = out_ω − d_r · t_ω`. Equivalent when `out_*` is unmodified.
    ///
    /// # Panics
    /// If any slice's length differs from [`Inertializer::num_joints`].
    #[allow(clippy::too_many_arguments)]
    pub fn transition_from_output(
        &mut self,
        out_pos: &[Vec3],
        out_vel: &[Vec3],
        out_rot: &[Quat],
        out_angvel: &[Vec3],
        dst_pos: &[Vec3],
        dst_vel: &[Vec3],
        dst_rot: &[Quat],
        dst_angvel: &[Vec3],
    ) {
        self.reset();
        // With zero offsets the raw transition's source is the output itself.
        self.transition(out_pos, out_vel, out_rot, out_angvel, dst_pos, dst_vel, dst_rot, dst_angvel);
    }

    /// Decays the offsets over `dt` seconds (critically damped, docs/method.md §4) and writes the
    /// inertialized pose: `out_p = in_p + d_p`, `out_r = d_r · in_r`. `in_*` is the raw pose
    /// playing now (usually a database frame). The output's velocities are not written: only a
    /// transition reads them, so [`Inertializer::velocities`] derives them then.
    ///
    /// Preconditions: `dt ≥ 0`, `halflife ≥ 0` (the method's default 0.1 s), unit input rotations.
    ///
    /// # Panics
    /// If any slice's length differs from [`Inertializer::num_joints`].
    pub fn update(
        &mut self,
        in_pos: &[Vec3],
        in_rot: &[Quat],
        halflife: f32,
        dt: f32,
        out_pos: &mut [Vec3],
        out_rot: &mut [Quat],
    ) {
        let n = self.num_joints();
        for (name, len) in
            [("in_pos", in_pos.len()), ("in_rot", in_rot.len()), ("out_pos", out_pos.len()), ("out_rot", out_rot.len())]
        {
            assert_eq!(len, n, "Inertializer::update: {name} has {len} joints, expected {n}");
        }
        let decay = DecayStep::new(halflife, dt);
        // Positions: a copy, then the few joints with an offset (the hips, usually).
        out_pos.copy_from_slice(in_pos);
        for &i in &self.moving {
            let i = i as usize;
            decay.apply(&mut self.offset_positions[i], &mut self.offset_velocities[i]);
            out_pos[i] = in_pos[i] + self.offset_positions[i];
        }
        let live = &self.live[..n];
        // Rotations four joints at a time: the offsets decay as vectors and only their
        // exponentials are taken (docs/method.md §4). A lane that is not live holds zeros and
        // stays zero.
        let (quarter, series_max) = (F32x4::splat(0.25), F32x4::splat(SERIES_MAX_H2));
        for (g, (r, w)) in self.offset_rotation_vectors.iter_mut().zip(&mut self.offset_angular_velocities).enumerate()
        {
            let joints = 4 * g..(4 * g + 4).min(n);
            let lanes = joints.clone().fold(0u32, |m, i| m | (u32::from(live[i] & LIVE_ROTATION != 0) << (i - 4 * g)));
            if lanes == 0 {
                out_rot[joints.clone()].copy_from_slice(&in_rot[joints]);
                continue;
            }
            decay.apply(r, w);
            let h2 = r.length_squared() * quarter;
            let (k, cos) = half_angle(h2);
            let (x, y, z, cos) = ((r.x * k).to_array(), (r.y * k).to_array(), (r.z * k).to_array(), cos.to_array());
            let within = h2.cmple(series_max).bitmask();
            if lanes & within == 0b1111 {
                // The usual case, with no branch per joint.
                for l in 0..4 {
                    let i = 4 * g + l;
                    out_rot[i] = Quat::from_xyzw(x[l], y[l], z[l], cos[l]) * in_rot[i];
                }
                continue;
            }
            for i in joints {
                let l = i - 4 * g;
                out_rot[i] = if lanes & (1 << l) == 0 {
                    in_rot[i]
                } else if within & (1 << l) != 0 {
                    Quat::from_xyzw(x[l], y[l], z[l], cos[l]) * in_rot[i]
                } else {
                    quat_from_rotation_vector(r.lane(l)) * in_rot[i]
                };
            }
        }
    }

    /// The velocities of the pose [`Inertializer::update`] wrote last, for input velocities
    /// `in_*` (those of the pose it was given): `out_v = in_v + d_v`, `out_ω = d_ω + d_r · in_ω`,
    /// with the offsets as that update left them — the same operations it would have done, so
    /// the same bits. Only a transition's source needs them (one update in ten or so): writing
    /// them every update was 7 % of a crowd's instructions (cachegrind, `mmdb bench-runtime`).
    ///
    /// # Panics
    /// If any slice's length differs from [`Inertializer::num_joints`].
    pub fn velocities(&self, in_vel: &[Vec3], in_angvel: &[Vec3], out_vel: &mut [Vec3], out_angvel: &mut [Vec3]) {
        let n = self.num_joints();
        for (name, len) in [
            ("in_vel", in_vel.len()),
            ("in_angvel", in_angvel.len()),
            ("out_vel", out_vel.len()),
            ("out_angvel", out_angvel.len()),
        ] {
            assert_eq!(len, n, "Inertializer::velocities: {name} has {len} joints, expected {n}");
        }
        for i in 0..n {
            out_vel[i] =
                if self.live[i] & LIVE_POSITION == 0 { in_vel[i] } else { in_vel[i] + self.offset_velocities[i] };
            out_angvel[i] = if self.live[i] & LIVE_ROTATION == 0 {
                in_angvel[i]
            } else {
                self.offset_angular_velocity(i) + self.offset_rotation(i) * in_angvel[i]
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use glam::Vec4;

    /// Exact angle between two rotations (glam's `angle_between` uses an approximate acos).
    fn angle(a: Quat, b: Quat) -> f32 {
        let d = a.inverse() * b;
        2.0 * d.xyz().length().atan2(d.w.abs())
    }

    struct Pose {
        pos: Vec<Vec3>,
        vel: Vec<Vec3>,
        rot: Vec<Quat>,
        angvel: Vec<Vec3>,
    }

    impl Pose {
        fn random(rng: &mut Rng, n: usize) -> Pose {
            Pose {
                pos: (0..n).map(|_| rng.vec3(1.0)).collect(),
                vel: (0..n).map(|_| rng.vec3(2.0)).collect(),
                rot: (0..n).map(|_| rng.quat()).collect(),
                angvel: (0..n).map(|_| rng.vec3(5.0)).collect(),
            }
        }
        fn zeroed(n: usize) -> Pose {
            Pose {
                pos: vec![Vec3::ZERO; n],
                vel: vec![Vec3::ZERO; n],
                rot: vec![Quat::IDENTITY; n],
                angvel: vec![Vec3::ZERO; n],
            }
        }
    }

    fn update(inert: &mut Inertializer, input: &Pose, halflife: f32, dt: f32, out: &mut Pose) {
        inert.update(&input.pos, &input.rot, halflife, dt, &mut out.pos, &mut out.rot);
        inert.velocities(&input.vel, &input.angvel, &mut out.vel, &mut out.angvel);
    }

    fn transition(inert: &mut Inertializer, src: &Pose, dst: &Pose) {
        inert.transition(&src.pos, &src.vel, &src.rot, &src.angvel, &dst.pos, &dst.vel, &dst.rot, &dst.angvel);
    }

    /// Largest difference between two poses (rotations compared up to sign, as rotations).
    fn max_diff(a: &Pose, b: &Pose) -> f32 {
        let mut m = 0.0f32;
        for i in 0..a.pos.len() {
            m = m.max((a.pos[i] - b.pos[i]).abs().max_element());
            m = m.max((a.vel[i] - b.vel[i]).abs().max_element());
            m = m.max((a.angvel[i] - b.angvel[i]).abs().max_element());
            m = m.max(1.0 - a.rot[i].dot(b.rot[i]).abs());
        }
        m
    }

    #[test]
    fn decay_spring_scalar_is_monotonic_and_never_overshoots() {
        let h = 0.1;
        let dt = 1.0 / 60.0;
        let (mut x, mut v) = (1.0f32, 0.0f32);
        let mut t = 0.0;
        while t < 1.0 {
            let (nx, nv) = decay_spring(x, v, h, dt);
            assert!(nx <= x && nx >= 0.0, "x went {x} -> {nx} at t = {t}");
            assert!(nv <= 0.0);
            (x, v) = (nx, nv);
            t += dt;
        }
        // One half-life halves a released offset (crate::spring's definition).
        let (x_h, _) = decay_spring(1.0, 0.0, h, h);
        assert!((x_h - 0.5).abs() < 1e-5, "{x_h}");
        assert!(decay_spring(1.0, 0.0, h, 7.0 * h).0 < 0.01);
        // Halflife 0 snaps without NaN, also with dt = 0.
        assert_eq!(decay_spring(1.0, 3.0, 0.0, 0.0), (1.0, 3.0));
        let (x0, v0) = decay_spring(1.0, 3.0, 0.0, dt);
        assert!(x0.abs() < 1e-6 && v0.is_finite());
    }

    #[test]
    fn decay_spring_is_exact_under_substepping() {
        let mut rng = Rng(7);
        for _ in 0..200 {
            let (x, v) = (rng.vec3(1.0), rng.vec3(10.0));
            let h = rng.uniform(0.05, 0.5);
            let dt = rng.uniform(0.0, 0.1);
            let (x1, v1) = decay_spring_vec3(x, v, h, dt);
            let (mut x2, mut v2) = (x, v);
            for _ in 0..10 {
                (x2, v2) = decay_spring_vec3(x2, v2, h, dt / 10.0);
            }
            assert!((x1 - x2).length() < 1e-5 && (v1 - v2).length() < 1e-4, "{x1} {x2} {v1} {v2}");
        }
    }

    #[test]
    fn transition_keeps_the_output() {
        let mut rng = Rng(1);
        let n = 24;
        let mut inert = Inertializer::new(n);
        let mut out = Pose::zeroed(n);
        let mut out_after = Pose::zeroed(n);
        let mut src = Pose::random(&mut rng, n);
        for step in 0..300 {
            // Build up non-zero offsets from earlier transitions, then check the invariant.
            update(&mut inert, &src, 0.1, rng.uniform(0.0, 0.05), &mut out);
            let dst = Pose::random(&mut rng, n);
            transition(&mut inert, &src, &dst);
            update(&mut inert, &dst, 0.1, 0.0, &mut out_after);
            let d = max_diff(&out, &out_after);
            assert!(d < 1e-5, "step {step}: output moved by {d} at a transition");
            for q in &out_after.rot {
                assert!((q.length() - 1.0).abs() < 1e-5);
            }
            src = dst;
        }
    }

    #[test]
    fn transition_from_output_equals_raw_transition() {
        let mut rng = Rng(2);
        let n = 10;
        let (mut a, mut b) = (Inertializer::new(n), Inertializer::new(n));
        let (mut out_a, mut out_b) = (Pose::zeroed(n), Pose::zeroed(n));
        let mut src = Pose::random(&mut rng, n);
        for _ in 0..100 {
            update(&mut a, &src, 0.15, 1.0 / 60.0, &mut out_a);
            update(&mut b, &src, 0.15, 1.0 / 60.0, &mut out_b);
            let dst = Pose::random(&mut rng, n);
            transition(&mut a, &src, &dst);
            b.transition_from_output(
                &out_b.pos,
                &out_b.vel,
                &out_b.rot,
                &out_b.angvel,
                &dst.pos,
                &dst.vel,
                &dst.rot,
                &dst.angvel,
            );
            update(&mut a, &dst, 0.15, 1.0 / 60.0, &mut out_a);
            update(&mut b, &dst, 0.15, 1.0 / 60.0, &mut out_b);
            assert!(max_diff(&out_a, &out_b) < 1e-4, "{}", max_diff(&out_a, &out_b));
            src = dst;
        }
    }

    /// A pose moving with constant velocities from `base` after `t` seconds.
    fn animate(base: &Pose, t: f32, out: &mut Pose) {
        for i in 0..base.pos.len() {
            out.pos[i] = base.pos[i] + base.vel[i] * t;
            out.vel[i] = base.vel[i];
            out.rot[i] = Quat::from_scaled_axis(base.angvel[i] * t) * base.rot[i];
            out.angvel[i] = base.angvel[i];
        }
    }

    #[test]
    fn quick_transitions_stay_continuous_and_decay() {
        let mut rng = Rng(3);
        let n = 8;
        let h = 0.1;
        let y = 2.0 * std::f32::consts::LN_2 / h;
        let dt = 1.0 / 600.0; // fine steps so continuity can be judged from consecutive outputs
        for _ in 0..20 {
            let clips: Vec<Pose> = (0..3).map(|_| Pose::random(&mut rng, n)).collect();
            let mut inert = Inertializer::new(n);
            let (mut input, mut prev, mut out, mut dst) =
                (Pose::zeroed(n), Pose::zeroed(n), Pose::zeroed(n), Pose::zeroed(n));
            let (mut clip, mut t) = (0usize, 0.0f32);
            animate(&clips[clip], t, &mut input);
            update(&mut inert, &input, h, 0.0, &mut prev);
            // Per joint: the bound x0 + v0/y on the offsets left by the second transition.
            let mut bound = vec![(0.0f32, 0.0f32); n];
            let second = 22;
            let frames = second + (7.0 * h / dt).ceil() as usize;
            for frame in 0..frames {
                // Two transitions 20 ms apart (the second one with live offsets), each to a random
                // time of another clip; the source is the raw pose that was playing.
                if frame == 10 || frame == second {
                    clip = (clip + 1) % 3;
                    t = rng.uniform(0.0, 1.0);
                    animate(&clips[clip], t, &mut dst);
                    transition(&mut inert, &input, &dst);
                    std::mem::swap(&mut input, &mut dst);
                    update(&mut inert, &input, h, 0.0, &mut out);
                    assert!(max_diff(&out, &prev) < 1e-5, "frame {frame}: output moved at the transition");
                    for (i, b) in bound.iter_mut().enumerate() {
                        let r = inert.offset_rotation(i).to_scaled_axis().length();
                        *b = (
                            inert.offset_positions()[i].length() + inert.offset_velocities()[i].length() / y,
                            r + inert.offset_angular_velocity(i).length() / y,
                        );
                    }
                }
                t += dt;
                animate(&clips[clip], t, &mut input);
                update(&mut inert, &input, h, dt, &mut out);
                // Output speed is bounded (input speed + offset spring speed): no pops.
                let mut step = 0.0f32;
                for i in 0..n {
                    step = step.max((out.pos[i] - prev.pos[i]).length());
                    step = step.max(angle(out.rot[i], prev.rot[i]));
                    assert!((out.rot[i].length() - 1.0).abs() < 1e-5);
                }
                assert!(step < 0.06, "frame {frame}: output jumped by {step}");
                std::mem::swap(&mut prev, &mut out);
            }
            // 7 half-lives after the second transition: x(t) = e^(−yt)·(x0 + (v0 + x0·y)·t) is
            // below 0.07 % of x0 + v0/y, so < 1 % holds with margin.
            for (i, &(bp, br)) in bound.iter().enumerate() {
                assert!(inert.offset_positions()[i].length() <= 0.01 * bp + 1e-6);
                assert!(inert.offset_rotation(i).to_scaled_axis().length() <= 0.01 * br + 1e-5);
            }
        }
    }

    #[test]
    fn offsets_decay_monotonically_below_one_percent_after_seven_halflives() {
        let mut rng = Rng(4);
        let n = 16;
        let h = 0.2f32;
        let mut inert = Inertializer::new(n);
        let src = Pose::random(&mut rng, n);
        let mut dst = Pose::random(&mut rng, n);
        // Equal velocities so the offsets start as pure position/rotation offsets (v0 = 0).
        dst.vel.copy_from_slice(&src.vel);
        dst.angvel.copy_from_slice(&src.angvel);
        let mut out = Pose::zeroed(n);
        transition(&mut inert, &src, &dst);
        let before: Vec<(f32, f32)> = (0..n)
            .map(|i| (inert.offset_positions()[i].length(), inert.offset_rotation(i).to_scaled_axis().length()))
            .collect();
        let mut prev = before.clone();
        let dt = 1.0f32 / 60.0;
        for _ in 0..(7.0 * h / dt).ceil() as usize {
            update(&mut inert, &dst, h, dt, &mut out);
            for (i, p) in prev.iter_mut().enumerate() {
                // Zero initial offset velocity: the critically damped decay never overshoots.
                let now = (inert.offset_positions()[i].length(), inert.offset_rotation(i).to_scaled_axis().length());
                assert!(now.0 <= p.0 + 1e-7 && now.1 <= p.1 + 1e-6, "joint {i}: {p:?} -> {now:?}");
                *p = now;
            }
        }
        for i in 0..n {
            assert!(prev[i].0 <= 0.01 * before[i].0 + 1e-6);
            assert!(prev[i].1 <= 0.01 * before[i].1 + 1e-5);
            assert!((out.rot[i].length() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn the_series_exponential_is_libms_to_a_few_ulps() {
        let mut rng = Rng(6);
        let mut worst = 0.0f32;
        for step in 0..20_000 {
            // Angles across the series' range and past it (where libm takes over), and tiny ones.
            let angle = match step % 4 {
                0 => rng.uniform(0.0, 1e-3),
                1 => rng.uniform(0.0, std::f32::consts::PI),
                2 => rng.uniform(3.0, 3.3),
                _ => rng.uniform(0.0, 2.0 * std::f32::consts::TAU),
            };
            let r = rng.vec3(1.0).normalize_or(Vec3::X) * angle;
            let (ours, libm) = (rotation_vector_quat(r), quat_from_rotation_vector(r));
            let d = (Vec4::from(ours) - Vec4::from(libm)).abs().max_element();
            worst = worst.max(d);
            assert!(d < 4e-7, "r = {r}: {ours} against {libm}");
            assert!((ours.length() - 1.0).abs() < 4e-7, "r = {r}: |q| = {}", ours.length());
        }
        assert!(worst > 0.0, "the series is not libm's sine: something must differ");
    }

    #[test]
    fn four_joints_at_a_time_give_the_bits_of_one_at_a_time() {
        // The transition's source velocities (`velocities`) take each joint's offset one at a
        // time; the update takes them four at a time: the output must be the same bits.
        let mut rng = Rng(8);
        for n in [1, 3, 4, 7, 31] {
            let mut inert = Inertializer::new(n);
            let (mut a, mut b) = (Pose::random(&mut rng, n), Pose::random(&mut rng, n));
            // One joint without a rotation offset; one turned by 3.1 rad and spun on (an offset
            // of −30 rad/s about the same axis), so that its offset grows past π, beyond the
            // series' range, before it decays.
            b.rot[0] = a.rot[0];
            b.angvel[0] = a.angvel[0];
            b.rot[n - 1] = Quat::from_rotation_y(3.1) * a.rot[n - 1];
            (a.angvel[n - 1], b.angvel[n - 1]) = (Vec3::Y * -30.0, Vec3::ZERO);
            let mut out = Pose::zeroed(n);
            transition(&mut inert, &a, &b);
            let mut beyond = false;
            for _ in 0..5 {
                update(&mut inert, &b, 0.1, 1.0 / 60.0, &mut out);
                beyond |= inert.offset_rotation_vector(n - 1).length() > std::f32::consts::PI;
                for i in 0..n {
                    let one = inert.offset_rotation(i) * b.rot[i];
                    assert_eq!(
                        out.rot[i].to_array().map(f32::to_bits),
                        one.to_array().map(f32::to_bits),
                        "n {n} joint {i}"
                    );
                }
            }
            assert!(beyond, "n {n}: the offset never left the series' range");
        }
    }

    #[test]
    fn only_zeros_of_either_sign_are_zero() {
        assert!(both_zero(Vec3::ZERO, Vec3::new(-0.0, 0.0, -0.0)));
        for tiny in [f32::MIN_POSITIVE / 8.0, -1e-30, f32::NAN, f32::INFINITY] {
            assert!(!both_zero(Vec3::new(0.0, tiny, 0.0), Vec3::ZERO), "{tiny}");
            assert!(!both_zero(Vec3::ZERO, Vec3::new(0.0, 0.0, tiny)), "{tiny}");
        }
    }

    #[test]
    fn reset_drops_offsets() {
        let mut rng = Rng(5);
        let mut inert = Inertializer::new(3);
        let (a, b) = (Pose::random(&mut rng, 3), Pose::random(&mut rng, 3));
        transition(&mut inert, &a, &b);
        inert.reset();
        let mut out = Pose::zeroed(3);
        update(&mut inert, &b, 0.1, 1.0 / 60.0, &mut out);
        assert!(max_diff(&out, &b) < 1e-6);
    }

    #[test]
    #[should_panic(expected = "dst_rot has 2 joints, expected 3")]
    fn transition_checks_lengths() {
        let mut inert = Inertializer::new(3);
        let p = Pose::zeroed(3);
        let q = Pose::zeroed(2);
        inert.transition(&p.pos, &p.vel, &p.rot, &p.angvel, &p.pos, &p.vel, &q.rot, &p.angvel);
    }
}
