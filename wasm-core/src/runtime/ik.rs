//! Analytic two-bone IK and the foot lock built on it (docs/method.md §7).
//!
//! - [`two_bone_ik`]: hip–knee–ankle or shoulder–elbow–wrist by the law of cosines, bending in
//!   the plane of a pole vector, exact up to float rounding. The one two-bone IK of the product:
//!   the foot lock's legs here, the VR avatar's arms through the bindings.
//! - [`FootLock`]: per foot, turns the animated toe position and the contact flag into a toe target
//!   that stays put while the foot is planted and blends in and out with a decay spring.
//! - [`leg_ik`]: moves one leg of a posed skeleton so its toe reaches that target and stays above
//!   the floor, writing local rotations.
//!
//! All positions and rotations passed together must be in one space (world, or character space
//! if the root transform is left out); nothing here allocates.

use crate::database::Skeleton;
use crate::inertialize::decay_spring_vec3;
use crate::persist::{Persist, Visitor};
use glam::{Mat3, Quat, Vec3};

/// Below this length a direction is treated as undefined (metres, or unit-vector length).
const TINY: f32 = 1e-6;

/// Peak lift of a foot lock's corrective step over its length (a 0.3 m step lifts the toe 9 cm
/// at its middle; a walking step lifts it 5–15 cm).
const STEP_LIFT: f32 = 0.3;

/// Most a corrective step lifts the toe (m): a long step (the body dragged far while the other
/// foot was stepping) swings low rather than high, as people's quick steps do, and its knee
/// bends within the data's own joint speeds.
const STEP_MAX_LIFT: f32 = 0.12;

/// How long a foot lock's corrective step swings (s): a walking swing phase is 0.35–0.4 s, a quick
/// step shorter. A bounded swing lets the feet take turns: the other foot holds its lock while
/// this one is in the air (`character::legs`), so it must land soon.
pub const STEP_TIME: f32 = 0.3;

/// Weight of the pole in the *current* bend plane's normal, relative to the sine of the knee
/// angle: the bones decide once the knee is bent more than ~0.6°, the pole decides for a straight
/// leg, and the normal changes continuously in between (no pop when a leg straightens).
const POLE_WEIGHT_STRAIGHT: f32 = 0.01;

/// `v` without its component along the unit vector `axis`, normalized; `None` when `v` is (nearly)
/// parallel to `axis` or zero.
#[inline]
fn perpendicular(v: Vec3, axis: Vec3) -> Option<Vec3> {
    let p = v - axis * v.dot(axis);
    let l = p.length();
    (l > TINY * v.length().max(1.0)).then(|| p / l)
}

/// The shortest rotation taking unit vector `from` to unit vector `to`. Unlike
/// `Quat::from_rotation_arc`, which returns the identity below ~7e-4 rad (0.3 mm on a 0.4 m
/// bone), small angles are kept: the half-way form `normalize(from × to, 1 + from·to)` is exact.
/// Opposite vectors turn by π about `fallback_axis` (made perpendicular to `from`).
#[inline]
pub(crate) fn rotation_arc(from: Vec3, to: Vec3, fallback_axis: Vec3) -> Quat {
    let w = 1.0 + from.dot(to);
    if w < 1e-6 {
        let axis = perpendicular(fallback_axis, from).unwrap_or_else(|| from.any_orthonormal_vector());
        return Quat::from_axis_angle(axis, std::f32::consts::PI);
    }
    let c = from.cross(to);
    Quat::from_xyzw(c.x, c.y, c.z, w).normalize()
}

/// Where the knee `b` sticks out of the line from `a` to `c`: `b` minus its projection on that
/// line (not normalized; zero for a straight chain). A good `pole` for [`two_bone_ik`]/[`leg_ik`]
/// that keeps the animation's bend plane.
pub fn knee_bend_direction(a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let ac = c - a;
    let l2 = ac.length_squared();
    if l2 < TINY * TINY {
        return Vec3::ZERO;
    }
    (b - a) - ac * ((b - a).dot(ac) / l2)
}

/// Analytic two-bone IK (law of cosines; Holden's `ik_two_bone` with an exact pole plane), as
/// world-space rotation deltas: returns `(r_a, r_b)` such that the new world rotations are
/// `r_a · a_gr` for the root joint `a` and `r_b · b_gr` for the middle joint `b` (`r_b` moves
/// everything below `b` rigidly; joints between `a` and `b` turn with `r_a`).
///
/// - `a`, `b`, `c`: positions of the root (hip, shoulder), middle (knee, elbow) and end (ankle,
///   wrist) joints;
/// - `target`: where `c` should go. Out of reach, `c` goes to the closest reachable point in the
///   target's direction: distance from `a` clamped to `[|l1 − l2| + eps, l1 + l2 − eps]`;
/// - `pole`: the direction the middle joint should bend toward, e.g. [`knee_bend_direction`]
///   (keeps the current bend plane) or the knee's forward axis. Only its part perpendicular to
///   `a → target` counts; if that vanishes (`Vec3::ZERO`, or parallel) the current bend plane is
///   kept. A pole opposite to the current bend swings the chain about the root–end axis;
/// - `eps`: reach margin (e.g. 0.01 m); it keeps the chain from locking straight, where the bend
///   direction is lost.
///
/// Method: the new middle-joint position comes from the law of cosines in the plane spanned by
/// the direction `u` to the (clamped) target and the pole's part perpendicular to `u`; `r_a`
/// maps the upper bone's direction and the old bend-plane normal onto the new ones (so the bone
/// does not twist more than the bend-plane change requires), and
/// `r_b = arc(r_a·lower bone, new lower bone) · r_a`. Bone lengths are kept by construction; a
/// chain with a zero-length bone gets identities. Never NaN for finite inputs.
pub fn two_bone_ik(a: Vec3, b: Vec3, c: Vec3, target: Vec3, pole: Vec3, eps: f32) -> (Quat, Quat) {
    let (ab, bc) = (b - a, c - b);
    let (l1, l2) = (ab.length(), bc.length());
    if l1 < TINY || l2 < TINY {
        return (Quat::IDENTITY, Quat::IDENTITY);
    }
    let e1 = ab / l1;

    // Direction and (clamped) distance to the target. Reach is [|l1 − l2| + eps, l1 + l2 − eps]:
    // the upper bound keeps the knee from locking straight (where the bend direction is lost).
    let to_target = target - a;
    let dist = to_target.length();
    let u = if dist > TINY {
        to_target / dist
    } else if (c - a).length() > TINY {
        (c - a).normalize()
    } else {
        e1
    };
    let (lo, hi) = ((l1 - l2).abs() + eps, l1 + l2 - eps);
    let d = dist.min(hi).max(lo.min(hi)).max(TINY);

    // Bend direction: the pole, else the current knee bend, else any perpendicular.
    let p = perpendicular(pole, u).or_else(|| perpendicular(ab, u)).unwrap_or_else(|| u.any_orthonormal_vector());

    // Law of cosines at `a`: angle α between the thigh and a→target.
    let cos_a = ((l1 * l1 + d * d - l2 * l2) / (2.0 * l1 * d)).clamp(-1.0, 1.0);
    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
    let e1_new = u * cos_a + p * sin_a;
    let b_new = a + e1_new * l1;
    let c_new = a + u * d;
    // Normal of the new bend plane, oriented like (b − a) × (c − b) for a knee bent toward `p`.
    let n_new = p.cross(u);

    // Normal of the current bend plane; for a (nearly) straight leg the pole decides.
    let p_old = perpendicular(pole, e1).or_else(|| perpendicular(p, e1)).unwrap_or_else(|| e1.any_orthonormal_vector());
    let n_old = ab.cross(bc) + p_old.cross(e1) * (POLE_WEIGHT_STRAIGHT * l1 * l2);
    let n_old = perpendicular(n_old, e1).unwrap_or_else(|| p_old.cross(e1));

    let old_frame = Mat3::from_cols(e1, n_old.cross(e1), n_old);
    let new_frame = Mat3::from_cols(e1_new, n_new.cross(e1_new), n_new);
    let r_a = Quat::from_mat3(&(new_frame * old_frame.transpose())).normalize();

    // Knee: turn the (already swung) shin onto its new direction.
    let s1 = r_a * (bc / l2);
    let s_new = (c_new - b_new).normalize();
    // Folded ↔ straight (opposite directions): turn about the hinge, not an arbitrary axis.
    let knee = rotation_arc(s1, s_new, n_new);
    (r_a, (knee * r_a).normalize())
}

/// Joints of one leg and its toe point, for [`leg_ik`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegJoints {
    /// Hip joint (thigh).
    pub upper_leg: usize,
    /// Knee joint (shin); `upper_leg` is an ancestor.
    pub lower_leg: usize,
    /// Ankle joint; `lower_leg` is an ancestor.
    pub foot: usize,
    /// Joint carrying the toe point: `foot` or a descendant of it.
    pub toe: usize,
    /// Toe point in `toe`'s space.
    pub toe_offset: Vec3,
}

impl LegJoints {
    /// The leg named by the skeleton's sites `{side}_upper_leg`, `{side}_lower_leg`, `{side}_foot`,
    /// `{side}_toe` (`side` is `"left"` or `"right"`). `None` if a site is missing or the joints do
    /// not form an upper leg → lower leg → foot → toe chain of ancestors.
    pub fn from_skeleton(skeleton: &Skeleton, side: &str) -> Option<LegJoints> {
        let site = |part: &str| skeleton.site(&format!("{side}_{part}")).map(|s| (s.joint as usize, s.offset));
        let (upper_leg, _) = site("upper_leg")?;
        let (lower_leg, _) = site("lower_leg")?;
        let (foot, _) = site("foot")?;
        let (toe, toe_offset) = site("toe")?;
        let is_ancestor = |anc: usize, mut j: usize| loop {
            if j == anc {
                return true;
            }
            match skeleton.parents.get(j) {
                Some(&p) if p >= 0 => j = p as usize,
                _ => return false,
            }
        };
        let chain = upper_leg != lower_leg
            && lower_leg != foot
            && is_ancestor(upper_leg, lower_leg)
            && is_ancestor(lower_leg, foot)
            && is_ancestor(foot, toe);
        chain.then_some(LegJoints { upper_leg, lower_leg, foot, toe, toe_offset })
    }
}

/// Parent's world rotation, identity for a root.
#[inline]
fn parent_rotation(parents: &[i32], global_rotations: &[Quat], joint: usize) -> Quat {
    match parents[joint] {
        p if p >= 0 => global_rotations[p as usize],
        _ => Quat::IDENTITY,
    }
}

/// Foot-lock touch-up of one leg (docs/method.md §7): two-bone IK on hip–knee–ankle moves the
/// ankle by the delta the toe must move (`target − toe`), then the ankle turns so the toe
/// reaches the target; the target is first lifted to `y ≥ floor_height`. When that ankle position
/// is out of the leg's reach, the heel lifts instead (the ankle goes to the reachable point at the
/// foot's length from the target), so the toe still reaches whenever
/// `|target − hip| < leg length − eps + |toe − ankle|`.
///
/// Inputs: `global_positions`/`global_rotations` are the forward kinematics of the current
/// `local_rotations` (all joints, one space, `floor_height` measured along its y);
/// `pole` as in [`two_bone_ik`] (`Vec3::ZERO` keeps the animation's bend plane); `eps` the
/// reach margin (e.g. 0.01 m), reduced to the leg's current slack so a leg the animation already
/// extends further is not pulled in. Output: the local rotations of `upper_leg`, `lower_leg` and `foot`
/// are overwritten; joints between them keep theirs. Returns where the toe point ends up (the
/// target when reachable). Global arrays are not updated: run forward kinematics again.
///
/// # Panics
/// If a joint index of `leg` is out of range of the slices.
#[allow(clippy::too_many_arguments)]
pub fn leg_ik(
    leg: &LegJoints,
    parents: &[i32],
    global_positions: &[Vec3],
    global_rotations: &[Quat],
    toe_target: Vec3,
    pole: Vec3,
    floor_height: f32,
    eps: f32,
    local_rotations: &mut [Quat],
) -> Vec3 {
    let (a, b, c) = (global_positions[leg.upper_leg], global_positions[leg.lower_leg], global_positions[leg.foot]);
    let toe = global_positions[leg.toe] + global_rotations[leg.toe] * leg.toe_offset;
    let target = toe_target.with_y(toe_target.y.max(floor_height));

    // The toe is rigid with the ankle, so moving the ankle by the toe's delta puts the toe on the
    // target without turning the foot.
    let mut ankle_goal = c + (target - toe);
    // The reach margin never pulls in a leg the animation already extends beyond it: that would
    // bend a straight standing leg by `eps` every frame.
    let (l1, l2) = ((b - a).length(), (c - b).length());
    let eps = eps.min((l1 + l2 - (c - a).length()).max(0.0));
    let reach = l1 + l2 - eps;
    let r = (toe - c).length();
    if (ankle_goal - a).length() > reach {
        // Out of reach (late stance: the hip has moved on past the planted toe): lift the heel.
        // The ankle goes where the reach sphere (centre a) meets the sphere of radius r around the
        // target, on that circle the point nearest the wanted position; the foot then pivots about
        // the toe in the turn below. If the spheres do not meet, the toe cannot reach: keep going.
        let to_target = target - a;
        let dist = to_target.length();
        if dist < reach + r && dist > (reach - r).abs() && dist > TINY {
            let w = to_target / dist;
            let x = (dist * dist + reach * reach - r * r) / (2.0 * dist);
            let h = (reach * reach - x * x).max(0.0).sqrt();
            let centre = a + w * x;
            let side = perpendicular(ankle_goal - centre, w).unwrap_or_else(|| w.any_orthonormal_vector());
            ankle_goal = centre + side * h;
        }
    }
    let (r_a, r_b) = two_bone_ik(a, b, c, ankle_goal, pole, eps);
    let b_new = a + r_a * (b - a);
    let c_new = b_new + r_b * (c - b);
    let toe_rel = r_b * (toe - c);

    // Turn the ankle so the toe points at the target (Holden's `ik_look_at`)…
    let mut aim = target;
    let to_aim = aim - c_new;
    // …and if the toe would still pass below the floor (ankle short of the target), aim at the
    // point of the toe's circle at floor height instead.
    if r > TINY && to_aim.length() > TINY {
        let toe_end = c_new + to_aim.normalize() * r;
        let dy = floor_height - c_new.y;
        if toe_end.y < floor_height && dy.abs() < r {
            let horizontal = (toe_end - c_new).with_y(0.0);
            let h = (r * r - dy * dy).sqrt();
            let dir = if horizontal.length() > TINY {
                horizontal.normalize()
            } else {
                toe_rel.with_y(0.0).normalize_or_zero()
            };
            aim = c_new + dir * h + Vec3::Y * dy;
        }
    }
    let to_aim = aim - c_new;
    let r_f = if r > TINY && to_aim.length() > TINY {
        (rotation_arc(toe_rel / r, to_aim.normalize(), (c_new - b_new).cross(toe_rel)) * r_b).normalize()
    } else {
        r_b
    };

    // New locals: a joint's new world rotation is Δ·gr, its parent's is Δ_parent·gr_parent, where Δ
    // is r_a for the thigh and what hangs rigidly on it, r_b for the shin, r_f for the foot.
    let gr = global_rotations;
    let upper_parent = parent_rotation(parents, gr, leg.upper_leg);
    let lower_parent = parent_rotation(parents, gr, leg.lower_leg);
    let foot_parent = parent_rotation(parents, gr, leg.foot);
    local_rotations[leg.upper_leg] = (upper_parent.inverse() * r_a * gr[leg.upper_leg]).normalize();
    local_rotations[leg.lower_leg] = (lower_parent.inverse() * r_a.inverse() * r_b * gr[leg.lower_leg]).normalize();
    local_rotations[leg.foot] = (foot_parent.inverse() * r_b.inverse() * r_f * gr[leg.foot]).normalize();

    c_new + r_f * (toe - c)
}

/// Foot locking for one foot (docs/method.md §7): turns the animated toe position and the contact
/// flag into the toe target for [`leg_ik`].
///
/// - When a contact starts, the lock point is the current target (the toe as shown), so locking
///   never pops. The target's velocity drops to zero there: the foot plants (contacts start only
///   when the toe is slow, < 0.15 m/s, docs/method.md §1).
/// - While locked the target stays on the lock point.
/// - The lock is released when the contact ends or the animated toe drifts more than
///   `unlock_radius` from the lock point; the target then returns to the animated toe by
///   inertialization (offset decayed by the critically damped spring, docs/method.md §4–5), with no
///   jump in position or velocity. A new lock needs a new contact start, or the end of a drift
///   release's blend.
/// - A drift release happens while the animation still stands on that foot (a dragged body), so
///   the way back is a **step**, not a slide: a swing of [`STEP_TIME`] to the animated toe, the
///   floor travel eased in and out (smoothstep), the target lifted by
///   `min(STEP_LIFT · span, STEP_MAX_LIFT) · 4s(1 − s)` with `s` the share of the time and `span`
///   the floor distance between the ends — 9 cm at the middle of a 0.3 m step, nothing at either
///   end. It starts from rest (the target was locked) and lands on the animated toe, moving with
///   it. (It used to follow the release blend's decay spring: fastest at the start, while the toe
///   was still low, and ~0.6 s long, so the other foot slid while it waited.) A contact end needs none:
///   the animation lifts the foot itself; nor one whose caller sets `may_step` false (the
///   other foot is off the ground): it slides back.
///
/// All positions are in world space (the lock must not move with the character), Y up. No
/// allocation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FootLock {
    initialized: bool,
    contact: bool,
    locked: bool,
    lock_position: Vec3,
    /// Offset of the target from its input (the lock point or the animated toe), and its velocity.
    offset: Vec3,
    offset_velocity: Vec3,
    position: Vec3,
    velocity: Vec3,
    /// A drift release's step under way: where the target was released (its lift is added on
    /// top of the blend) and the lift now.
    stepping: bool,
    step_from: Vec3,
    /// Seconds since the step's release.
    step_time: f32,
    lift: f32,
    /// Whether a drift release may step (lift the foot): the caller says no while the other
    /// foot is off the ground, and the foot slides back instead.
    pub may_step: bool,
    /// Height of a planted toe on a flat floor (m): locks are made at this height, so a toe
    /// that touches down while an inertialization offset still holds it in the air (or below
    /// the floor) is brought to the floor over the lock's blend. `None`: lock where it is.
    pub floor: Option<f32>,
}

/// Everything but `floor` and `may_step` (the legs set them every update).
impl Persist for FootLock {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.initialized.persist(v, "foot lock initialized");
        self.contact.persist(v, "foot lock contact");
        self.locked.persist(v, "foot lock locked");
        self.lock_position.persist(v, "foot lock position");
        self.offset.persist(v, "foot lock offset");
        self.offset_velocity.persist(v, "foot lock offset velocity");
        self.position.persist(v, "foot lock target");
        self.velocity.persist(v, "foot lock target velocity");
        self.stepping.persist(v, "foot lock stepping");
        self.step_from.persist(v, "foot lock step start");
        self.step_time.persist(v, "foot lock step time");
        self.lift.persist(v, "foot lock step lift");
    }
}

impl Default for FootLock {
    fn default() -> Self {
        Self::new()
    }
}

impl FootLock {
    /// Unlocked; the first `update` starts at the animated toe.
    pub fn new() -> Self {
        FootLock {
            initialized: false,
            contact: false,
            locked: false,
            lock_position: Vec3::ZERO,
            offset: Vec3::ZERO,
            offset_velocity: Vec3::ZERO,
            position: Vec3::ZERO,
            velocity: Vec3::ZERO,
            stepping: false,
            step_from: Vec3::ZERO,
            step_time: 0.0,
            lift: 0.0,
            may_step: true,
            floor: None,
        }
    }

    /// Unlocks and puts the target on the animated toe `(position, velocity)` (e.g. when foot
    /// locking is switched on or the character teleports). A contact in the next `update` locks.
    pub fn reset(&mut self, position: Vec3, velocity: Vec3) {
        *self = FootLock {
            initialized: true,
            position,
            velocity,
            floor: self.floor,
            may_step: self.may_step,
            ..FootLock::new()
        };
    }

    pub fn is_locked(&self) -> bool {
        self.locked
    }

    /// The lock point (meaningful while [`FootLock::is_locked`]).
    pub fn lock_position(&self) -> Vec3 {
        self.lock_position
    }

    /// Target returned by the last `update`.
    pub fn position(&self) -> Vec3 {
        self.position
    }

    pub fn velocity(&self) -> Vec3 {
        self.velocity
    }

    /// Whether a drift release's step is under way (the target lifted on its way back).
    pub fn is_stepping(&self) -> bool {
        self.stepping
    }

    /// How high the step lifts the target now (m; 0 when not stepping).
    pub fn lift(&self) -> f32 {
        self.lift
    }

    /// Advances by `dt` and returns the toe target. `contact` is the database's contact flag for
    /// this foot at the frame now playing; `animated_toe_pos`/`animated_toe_vel` are the toe of the
    /// inertialized pose in world space. Defaults: `unlock_radius` 0.2 m, `halflife` 0.12 s (exact half-life; Holden's 0.1 s).
    ///
    /// Preconditions: `dt ≥ 0`, `halflife ≥ 0`.
    pub fn update(
        &mut self,
        contact: bool,
        animated_toe_pos: Vec3,
        animated_toe_vel: Vec3,
        dt: f32,
        unlock_radius: f32,
        halflife: f32,
    ) -> Vec3 {
        if !self.initialized {
            self.reset(animated_toe_pos, animated_toe_vel);
        }
        // Lock when a contact starts — or again during a long contact once the blend out of a
        // drift unlock has finished (a dragged, standing character re-plants its foot with a
        // short corrective step instead of sliding for the rest of the stance).
        let relock = self.contact && self.offset.length_squared() < 1e-4;
        if contact && !self.locked && (!self.contact || relock) {
            // Lock where the target is now (on the floor, if known); the offset from there to the
            // target decays, so the target never jumps (see type docs).
            self.locked = true;
            // The lift is part of the target: the offset takes it and lands it (no drop).
            (self.stepping, self.lift) = (false, 0.0);
            self.lock_position = self.position;
            if let Some(h) = self.floor {
                self.lock_position.y = h;
            }
            self.offset = self.position - self.lock_position;
            self.offset_velocity = Vec3::ZERO;
        } else if self.locked && (!contact || self.lock_position.distance(animated_toe_pos) > unlock_radius) {
            // Transition from the lock to the animated toe (docs/method.md §5, additive form):
            // the offset takes what separates the current target from the new input.
            self.locked = false;
            self.offset = self.position - animated_toe_pos;
            self.offset_velocity = self.velocity - animated_toe_vel;
            // Released by drift while still in contact: step back (see type docs).
            self.stepping = contact && self.may_step;
            self.step_from = self.position;
            self.step_time = 0.0;
        }
        self.contact = contact;

        let (input, input_velocity) =
            if self.locked { (self.lock_position, Vec3::ZERO) } else { (animated_toe_pos, animated_toe_vel) };
        if self.stepping {
            self.step(input, input_velocity, dt);
        } else {
            (self.offset, self.offset_velocity) = decay_spring_vec3(self.offset, self.offset_velocity, halflife, dt);
            self.position = input + self.offset;
            self.velocity = input_velocity + self.offset_velocity;
        }
        self.position
    }

    /// One update of a drift release's step: a swing of [`STEP_TIME`] from where the lock released
    /// to the animated toe (`input`, moving with the body), along `smoothstep(s)` on the floor
    /// plane and lifted by `min(STEP_LIFT · span, STEP_MAX_LIFT) · 4s(1 − s)` (`s` the share of
    /// the time, `span` the floor distance still between the two ends). The lift grows linearly from the start while
    /// the floor travel grows as s², so the toe leaves the floor before it travels: a step, not a
    /// slide. It starts from rest (the target was locked) and lands on the animated toe with its
    /// velocity; the offset is kept equal to what separates the target from the input, so a
    /// contact change mid-step blends on from where the foot is.
    fn step(&mut self, input: Vec3, input_velocity: Vec3, dt: f32) {
        self.step_time += dt;
        let s = (self.step_time / STEP_TIME).min(1.0);
        let w = s * s * (3.0 - 2.0 * s);
        let previous = self.position;
        let span = Vec3::new(input.x - self.step_from.x, 0.0, input.z - self.step_from.z).length();
        self.lift = (STEP_LIFT * span).min(STEP_MAX_LIFT) * 4.0 * s * (1.0 - s);
        self.position = self.step_from.lerp(input, w) + Vec3::Y * self.lift;
        self.velocity = if dt > 0.0 { (self.position - previous) / dt } else { input_velocity };
        if s >= 1.0 {
            // Landed on the animated toe (a contact re-locks on the next update).
            (self.stepping, self.lift, self.position, self.velocity) = (false, 0.0, input, input_velocity);
        }
        self.offset = self.position - input;
        self.offset_velocity = self.velocity - input_velocity;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::database::Site;
    use crate::rng::Rng;

    /// A random chain: parent rotation, hip position, random bone directions in local space.
    struct Chain {
        parent_gr: Quat,
        a: Vec3,
        a_lr: Quat,
        b_lr: Quat,
        offset_b: Vec3,
        offset_c: Vec3,
    }

    impl Chain {
        fn random(rng: &mut Rng) -> Chain {
            Chain {
                parent_gr: rng.axis_angle_quat(),
                a: Vec3::new(rng.uniform(-1.0, 1.0), rng.uniform(0.5, 1.5), rng.uniform(-1.0, 1.0)),
                a_lr: rng.axis_angle_quat(),
                b_lr: rng.axis_angle_quat(),
                offset_b: rng.unit_vector() * rng.uniform(0.3, 0.5),
                offset_c: rng.unit_vector() * rng.uniform(0.3, 0.5),
            }
        }
        /// Forward kinematics: (b, c, a_gr, b_gr).
        fn fk(&self, a_lr: Quat, b_lr: Quat) -> (Vec3, Vec3, Quat, Quat) {
            let a_gr = self.parent_gr * a_lr;
            let b = self.a + a_gr * self.offset_b;
            let b_gr = a_gr * b_lr;
            (b, b_gr * self.offset_c + b, a_gr, b_gr)
        }
        fn solve(&self, target: Vec3, pole: Vec3, eps: f32) -> (Vec3, Vec3) {
            let (b, c, a_gr, b_gr) = self.fk(self.a_lr, self.b_lr);
            let (r_a, r_b) = two_bone_ik(self.a, b, c, target, pole, eps);
            let a_gr_new = r_a * a_gr;
            let (a_lr, b_lr) =
                ((self.parent_gr.inverse() * a_gr_new).normalize(), (a_gr_new.inverse() * (r_b * b_gr)).normalize());
            assert!((a_lr.length() - 1.0).abs() < 1e-5 && (b_lr.length() - 1.0).abs() < 1e-5);
            let (b, c, _, _) = self.fk(a_lr, b_lr);
            (b, c)
        }
    }

    #[test]
    fn two_bone_ik_reaches_keeps_lengths_and_bends_toward_the_pole() {
        let mut rng = Rng(11);
        let eps = 1e-3;
        let mut worst = 0.0f32;
        for _ in 0..5000 {
            let chain = Chain::random(&mut rng);
            let (l1, l2) = (chain.offset_b.length(), chain.offset_c.length());
            let dir = rng.unit_vector();
            let reach = rng.uniform((l1 - l2).abs() + 0.01, l1 + l2 - 0.01);
            let target = chain.a + dir * reach;
            let pole = rng.unit_vector();
            let (b, c) = chain.solve(target, pole, eps);
            worst = worst.max((c - target).length());
            assert!((c - target).length() < 1e-4, "missed by {}", (c - target).length());
            assert!(((b - chain.a).length() - l1).abs() < 1e-5 && ((c - b).length() - l2).abs() < 1e-5);
            // The knee lies in the plane of a→target and the pole, on the pole's side.
            if let Some(p) = perpendicular(pole, dir) {
                let bend = knee_bend_direction(chain.a, b, c);
                assert!(bend.dot(p) >= -1e-5, "knee bends away from the pole");
                assert!(bend.dot(dir.cross(p)).abs() < 1e-4, "knee out of the pole plane");
            }
        }
        eprintln!("two-bone IK: worst end error {worst:e} m");
    }

    #[test]
    fn two_bone_ik_with_zero_pole_keeps_the_bend_plane() {
        let mut rng = Rng(12);
        for _ in 0..1000 {
            let chain = Chain::random(&mut rng);
            let (b0, c0, _, _) = chain.fk(chain.a_lr, chain.b_lr);
            let n0 = (b0 - chain.a).cross(c0 - b0);
            if n0.length() < 0.05 {
                continue;
            }
            // A small move inside the current bend plane keeps the plane.
            let along = (c0 - chain.a).normalize() * rng.uniform(-0.05, 0.05);
            let target = c0 + along + (b0 - chain.a).reject_from(n0).normalize() * 0.01;
            let (b, c) = chain.solve(target, Vec3::ZERO, 1e-3);
            let n = (b - chain.a).cross(c - b);
            assert!(n.normalize().dot(n0.normalize()) > 0.999, "bend plane changed");
        }
    }

    #[test]
    fn two_bone_ik_clamps_unreachable_targets_to_the_reach_direction() {
        let mut rng = Rng(13);
        let eps = 0.01;
        for _ in 0..1000 {
            let chain = Chain::random(&mut rng);
            let (l1, l2) = (chain.offset_b.length(), chain.offset_c.length());
            let dir = rng.unit_vector();
            let (b, c) = chain.solve(chain.a + dir * rng.uniform(l1 + l2, 3.0), rng.unit_vector(), eps);
            let expected = chain.a + dir * (l1 + l2 - eps);
            assert!((c - expected).length() < 1e-4, "{c} vs {expected}");
            assert!(((b - chain.a).length() - l1).abs() < 1e-5 && ((c - b).length() - l2).abs() < 1e-5);
            // Too close: clamped to the minimum reach in the target's direction.
            let (_, c) = chain.solve(chain.a + dir * 0.5 * (l1 - l2).abs(), rng.unit_vector(), eps);
            let expected = chain.a + dir * ((l1 - l2).abs() + eps);
            assert!((c - expected).length() < 1e-4, "{c} vs {expected}");
        }
    }

    #[test]
    fn two_bone_ik_handles_straight_and_folded_chains() {
        // Straight leg hanging down, target pulled up: the knee bends toward the pole (+Z).
        let (a, b, c) = (Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.55, 0.0), Vec3::new(0.0, 0.1, 0.0));
        let (r_a, r_b) = two_bone_ik(a, b, c, Vec3::new(0.0, 0.3, 0.0), Vec3::Z, 1e-3);
        let b_new = a + r_a * (b - a);
        let c_new = b_new + r_b * (c - b);
        assert!((c_new - Vec3::new(0.0, 0.3, 0.0)).length() < 1e-5);
        assert!(b_new.z > 0.1 && b_new.x.abs() < 1e-5);
        // Target at the hip itself: no NaN, clamped to minimum reach.
        let (r_a, r_b) = two_bone_ik(a, b, c, a, Vec3::Z, 1e-3);
        assert!(r_a.is_finite() && r_b.is_finite());
    }

    /// root(0) → hips(1) → upper(2) → lower(3) → foot(4) → toe(5).
    fn leg_skeleton() -> (Vec<i32>, Vec<Vec3>) {
        let parents = vec![-1, 0, 1, 2, 3, 4];
        let offsets = vec![
            Vec3::ZERO,
            Vec3::new(0.0, 0.95, 0.0),
            Vec3::new(0.1, -0.05, 0.0),
            Vec3::new(0.0, -0.42, 0.0),
            Vec3::new(0.0, -0.4, 0.0),
            Vec3::new(0.0, -0.06, 0.14),
        ];
        (parents, offsets)
    }

    fn fk(parents: &[i32], offsets: &[Vec3], root: Vec3, locals: &[Quat], gp: &mut [Vec3], gr: &mut [Quat]) {
        let mut positions = offsets.to_vec();
        positions[0] = root;
        crate::kinematics::local_to_model(parents, 0..parents.len(), None, &positions, locals, gp, gr);
    }

    #[test]
    fn leg_ik_puts_the_toe_on_the_target_above_the_floor() {
        let (parents, offsets) = leg_skeleton();
        let leg = LegJoints { upper_leg: 2, lower_leg: 3, foot: 4, toe: 5, toe_offset: Vec3::new(0.0, 0.0, 0.05) };
        let mut rng = Rng(14);
        let (mut gp, mut gr) = ([Vec3::ZERO; 6], [Quat::IDENTITY; 6]);
        let mut reachable = 0;
        for _ in 0..2000 {
            // A walking-like pose: thigh swung, knee bent forward, foot flexed.
            let mut locals = [Quat::IDENTITY; 6];
            locals[0] = Quat::from_rotation_y(rng.uniform(-3.0, 3.0));
            locals[1] = Quat::from_rotation_z(rng.uniform(-0.1, 0.1));
            locals[2] = Quat::from_rotation_x(rng.uniform(-0.6, 0.4)) * Quat::from_rotation_z(rng.uniform(-0.2, 0.2));
            locals[3] = Quat::from_rotation_x(rng.uniform(0.05, 1.0));
            locals[4] = Quat::from_rotation_x(rng.uniform(-0.4, 0.4));
            locals[5] = Quat::from_rotation_x(rng.uniform(-0.3, 0.3));
            let root = Vec3::new(rng.uniform(-5.0, 5.0), 0.0, rng.uniform(-5.0, 5.0));
            fk(&parents, &offsets, root, &locals, &mut gp, &mut gr);
            let gp0 = gp;
            let toe = gp[5] + gr[5] * leg.toe_offset;
            let target = toe + rng.unit_vector() * rng.uniform(0.0, 0.08);
            let floor = 0.0;
            let pole = knee_bend_direction(gp[2], gp[3], gp[4]);
            let reached = leg_ik(&leg, &parents, &gp, &gr, target, pole, floor, 0.01, &mut locals);
            fk(&parents, &offsets, root, &locals, &mut gp, &mut gr);
            let toe_new = gp[5] + gr[5] * leg.toe_offset;
            assert!((toe_new - reached).length() < 1e-5, "returned toe {reached} vs FK {toe_new}");
            assert!(toe_new.y >= floor - 1e-5, "toe below the floor: {toe_new}");
            let expected = target.with_y(target.y.max(floor));
            // Reachable when the ankle, moved by the toe's delta, is within the (eps-shortened) reach.
            let ankle_target = gp0[4] + (expected - toe);
            if (ankle_target - gp0[2]).length() < 0.42 + 0.4 - 0.01 - 1e-4 {
                reachable += 1;
                assert!((toe_new - expected).length() < 1e-4, "toe {toe_new} vs target {expected}");
            } else {
                assert!((toe_new - expected).length() < (toe - expected).length() + 1e-5, "out of reach and no closer");
            }
            assert!(((gp[3] - gp[2]).length() - 0.42).abs() < 1e-5 && ((gp[4] - gp[3]).length() - 0.4).abs() < 1e-5);
            for q in &locals {
                assert!((q.length() - 1.0).abs() < 1e-5);
            }
        }
        assert!(reachable > 1500, "only {reachable} reachable cases");
    }

    #[test]
    fn leg_ik_lifts_the_heel_and_respects_the_floor() {
        let (parents, offsets) = leg_skeleton();
        let leg = LegJoints { upper_leg: 2, lower_leg: 3, foot: 4, toe: 5, toe_offset: Vec3::ZERO };
        let (mut gp, mut gr) = ([Vec3::ZERO; 6], [Quat::IDENTITY; 6]);
        // Standing, knee slightly bent, foot flat.
        let mut locals = [Quat::IDENTITY; 6];
        locals[2] = Quat::from_rotation_x(-0.05);
        locals[3] = Quat::from_rotation_x(0.1);
        locals[4] = Quat::from_rotation_x(-0.05);
        fk(&parents, &offsets, Vec3::ZERO, &locals, &mut gp, &mut gr);
        let (toe, ankle) = (gp[5], gp[4]);

        // Late stance: the toe must stay 0.3 m behind, out of reach for a flat foot → heel lifts.
        let target = toe - Vec3::Z * 0.3;
        let mut out = locals;
        let reached = leg_ik(&leg, &parents, &gp, &gr, target, Vec3::ZERO, 0.0, 0.01, &mut out);
        let (mut gp2, mut gr2) = ([Vec3::ZERO; 6], [Quat::IDENTITY; 6]);
        fk(&parents, &offsets, Vec3::ZERO, &out, &mut gp2, &mut gr2);
        assert!((gp2[5] - target).length() < 1e-4 && (reached - target).length() < 1e-4, "toe {} vs {target}", gp2[5]);
        assert!(gp2[4].y - gp2[5].y > ankle.y - toe.y + 0.02, "heel did not lift");

        // Target under the floor: the toe stops on the floor.
        let target = toe.with_y(-0.05) + Vec3::Z * 0.05;
        let mut out = locals;
        leg_ik(&leg, &parents, &gp, &gr, target, Vec3::ZERO, 0.0, 0.01, &mut out);
        fk(&parents, &offsets, Vec3::ZERO, &out, &mut gp2, &mut gr2);
        assert!((gp2[5] - target.with_y(0.0)).length() < 1e-4, "toe {}", gp2[5]);
    }

    #[test]
    fn leg_joints_from_skeleton_sites() {
        let (parents, offsets) = leg_skeleton();
        let site = |name: &str, joint: i32, offset: Vec3| Site { name: name.to_string(), joint, offset };
        let mut skeleton = Skeleton {
            names: ["root", "hips", "lthigh", "lshin", "lfoot", "ltoe"].iter().map(|s| s.to_string()).collect(),
            parents,
            offsets,
            sites: vec![
                site("left_upper_leg", 2, Vec3::ZERO),
                site("left_lower_leg", 3, Vec3::ZERO),
                site("left_foot", 4, Vec3::ZERO),
                site("left_toe", 5, Vec3::new(0.0, 0.0, 0.05)),
                site("right_toe", -1, Vec3::ZERO),
            ],
            mirror: vec![],
        };
        let leg = LegJoints::from_skeleton(&skeleton, "left").unwrap();
        assert_eq!(
            leg,
            LegJoints { upper_leg: 2, lower_leg: 3, foot: 4, toe: 5, toe_offset: Vec3::new(0.0, 0.0, 0.05) }
        );
        assert_eq!(LegJoints::from_skeleton(&skeleton, "right"), None);
        skeleton.sites[2].joint = 1; // foot not below the knee
        assert_eq!(LegJoints::from_skeleton(&skeleton, "left"), None);
    }

    const DT: f32 = 1.0 / 60.0;

    #[test]
    fn foot_lock_holds_a_sliding_toe_then_returns_smoothly() {
        let mut lock = FootLock::new();
        let slide = Vec3::new(0.3, 0.0, 0.0);
        let mut toe = Vec3::new(0.0, 0.05, 0.0);
        let mut prev = lock.update(false, toe, Vec3::ZERO, DT, 0.2, 0.12);
        // Swing in: toe approaching at 1 m/s, no contact.
        for _ in 0..10 {
            toe += Vec3::Z * DT;
            prev = lock.update(false, toe, Vec3::Z, DT, 0.2, 0.12);
        }
        // Contact for 0.5 s while the animation slides 0.3 m/s (0.15 m < unlock radius).
        let mut first = None;
        for _ in 0..30 {
            toe += slide * DT;
            let target = lock.update(true, toe, slide, DT, 0.2, 0.12);
            assert!(lock.is_locked());
            let first = *first.get_or_insert(target);
            assert!((target - first).length() < 1e-3, "locked target moved {}", (target - first).length());
            assert!((target - prev).length() < 0.02);
            prev = target;
        }
        // Contact ends: back to the animated toe within ~0.5 s, with bounded per-frame steps —
        // and no corrective step: the animation lifts the foot itself.
        let lift = Vec3::new(0.3, 0.5, 1.0);
        let mut max_step = 0.0f32;
        for frame in 1..=60 {
            toe += lift * DT;
            let target = lock.update(false, toe, lift, DT, 0.2, 0.12);
            assert!(!lock.is_locked() && !lock.is_stepping() && lock.lift() == 0.0);
            max_step = max_step.max((target - prev).length());
            if frame == 30 {
                assert!((target - toe).length() < 0.005, "0.5 s after release: {}", (target - toe).length());
            }
            prev = target;
        }
        assert!((prev - toe).length() < 1e-4);
        // The animated toe itself moves 1.16 m/s · dt ≈ 19 mm per frame; the blend adds a little.
        assert!(max_step < 0.03, "per-frame step {max_step}");
    }

    #[test]
    fn a_drift_release_steps_back_through_the_air_and_lands() {
        // A standing foot under a body dragged at 0.5 m/s: the lock holds, releases at 0.3 m,
        // and the foot goes back under the body lifted — not sliding — then plants again.
        let mut lock = FootLock::new();
        lock.floor = Some(0.0);
        let drag = Vec3::new(0.5, 0.0, 0.0);
        let mut toe = Vec3::ZERO;
        lock.update(false, toe, Vec3::ZERO, DT, 0.3, 0.12);
        let mut prev = lock.position();
        let (mut steps, mut peak, mut on_floor, mut in_air, mut max_step) = (0, 0.0f32, 0.0f32, 0.0f32, 0.0f32);
        let (mut was_stepping, mut run, mut longest) = (false, 0, 0);
        for _ in 0..240 {
            toe += drag * DT;
            let target = lock.update(true, toe, drag, DT, 0.3, 0.12);
            assert!(target.is_finite());
            assert!(target.y >= -1e-6, "below the floor: {}", target.y);
            steps += (lock.is_stepping() && !was_stepping) as usize;
            was_stepping = lock.is_stepping();
            run = if was_stepping { run + 1 } else { 0 };
            longest = longest.max(run);
            let moved = Vec3::new(target.x - prev.x, 0.0, target.z - prev.z).length();
            if target.y < 0.033 {
                on_floor += moved
            } else {
                in_air += moved
            }
            peak = peak.max(target.y);
            max_step = max_step.max((target - prev).length());
            prev = target;
        }
        // 2 m of drag in 4 s: a step every ~0.3 m, each lifting the toe ~9 cm (0.3 × span at mid-way).
        println!("{steps} steps, peak {peak:.3} m, {on_floor:.3} m on the floor, {in_air:.3} m in the air, longest {longest} frames");
        assert!((4..=8).contains(&steps), "{steps} steps");
        assert!(peak > 0.06 && peak < 0.15, "peak lift {peak}");
        // Nearly all the way back is in the air: the toe rises before it travels (the lift grows
        // linearly, the floor travel as s²); what slides is the take-off and the landing. (The
        // decay-spring step it replaced slid ~30 % of the way.)
        assert!(on_floor < 0.1 * (on_floor + in_air), "on the floor {on_floor} m of {} m", on_floor + in_air);
        // Each swing lasts STEP_TIME (the other foot waits for it to land).
        assert!(longest as f32 * DT <= STEP_TIME + 1.5 * DT, "a step of {longest} frames");
        assert!(max_step < 0.05, "per-frame step {max_step}");
    }

    #[test]
    fn a_foot_that_may_not_step_slides_back_on_the_floor() {
        // The other foot is in the air (the legs say so): no hop, the old slide.
        let mut lock = FootLock::new();
        lock.floor = Some(0.0);
        lock.may_step = false;
        let drag = Vec3::new(0.5, 0.0, 0.0);
        let mut toe = Vec3::ZERO;
        let mut released = false;
        for _ in 0..120 {
            toe += drag * DT;
            let target = lock.update(true, toe, drag, DT, 0.3, 0.12);
            released |= !lock.is_locked();
            assert!(!lock.is_stepping() && target.y.abs() < 1e-6);
        }
        assert!(released);
    }

    #[test]
    fn foot_lock_unlocks_when_drifting_beyond_the_radius() {
        let mut lock = FootLock::new();
        let slide = Vec3::new(0.0, 0.0, 0.7);
        let mut toe = Vec3::ZERO;
        lock.update(false, toe, Vec3::ZERO, DT, 0.2, 0.12);
        let (mut unlocked_at, mut relocked_at) = (None, None);
        let mut prev = lock.position();
        let mut max_step = 0.0f32;
        for frame in 0..60 {
            toe += slide * DT;
            let target = lock.update(true, toe, slide, DT, 0.2, 0.12);
            if unlocked_at.is_none() && !lock.is_locked() {
                unlocked_at = Some(frame);
            }
            if unlocked_at.is_some() && relocked_at.is_none() && lock.is_locked() {
                // Re-planted during the same contact only once the blend out caught up.
                relocked_at = Some(frame);
                assert!((target - toe).length() < 0.03, "re-locked {} m from the toe", (target - toe).length());
            }
            if lock.is_locked() {
                assert!(lock.lock_position().distance(toe) <= 0.2 + 1e-6);
            }
            max_step = max_step.max((target - prev).length());
            prev = target;
        }
        // Locked at the previous frame's toe; 0.2 m at 0.7 m/s is 17.1 frames, so the 18th frame
        // (index 17) releases; the foot re-plants later in the same contact, not at once.
        assert_eq!(unlocked_at, Some(17));
        assert!(relocked_at.is_some_and(|f| f > 17 + 3), "re-lock at {relocked_at:?}");
        assert!(max_step < 0.05, "per-frame step {max_step}");
        // A new contact locks again, where the target is.
        lock.update(false, toe, slide, DT, 0.2, 0.12);
        let at = lock.position();
        lock.update(true, toe, slide, DT, 0.2, 0.12);
        assert!(lock.is_locked() && lock.lock_position() == at);
    }
}
