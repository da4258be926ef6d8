//! Leg touch-ups of the shown pose (docs/method.md §7, §9): the foot lock holds each toe in
//! contact where the contact began (blended in and out by [`FootLock`]) and the leg reaches it
//! by the two-bone IK; a hips drop (VR crouching) lowers the hips with the feet kept where they
//! are, and a torso bend (VR bending over, [`super::crouch`]) pitches the spine forward about the
//! root's lateral axis; with body tracking the hips are moved and turned onto the user's tracked
//! hips ([`Legs::follow`]), the feet again kept by IK. Only the touched subtrees are recomputed
//! by FK afterwards.

use super::crouch::MAX_BEND;
use super::pose::Pose;
use super::settings::CharacterSettings;
use crate::database::Database;
use crate::ik::{knee_bend_direction, leg_ik, FootLock, LegJoints};
use crate::kinematics::subtree_range;
use crate::persist::{Persist, Visitor};
use crate::skating::ON_FLOOR;
use glam::{Quat, Vec3};
use std::ops::Range;

/// Most the spine chain bends (rad) to match a torso bend: past this the head would come back up.
const MAX_CHAIN_BEND: f32 = 100.0 * std::f32::consts::PI / 180.0;

/// A foot lifted more than this by its corrective step (m) is in the air.
const STEP_AIRBORNE: f32 = 0.01;

/// How fast the shown hips go onto tracked ones when body tracking starts, and back to the
/// animation's when it is lost (half-life, s): a tenth of a second hides the switch without
/// lagging a walking user (a 10 cm offset moves ≤ 1.2 cm per 60 Hz frame).
const FOLLOW_HALFLIFE: f32 = 0.08;

/// Farthest the shown hips move from where the animation has them to reach tracked hips (m):
/// the rest is the root's clamp's (α), or the body would lean out over its feet.
const MAX_FOLLOW_SHIFT: f32 = 0.15;

/// A hips drop beyond this share of the standing hips height is a crouch: the database's crouched
/// frames are searched ([`crate::tag_query::CROUCHED_TAG`]); back under the lower share, the
/// upright ones again (hysteresis: a user hovering at the edge does not flip every frame). The
/// crouch data's crouched idle has the hips at 45–60 % of standing; a quarter is well into a squat.
const CROUCH_ENTER: f32 = 0.25;
const CROUCH_LEAVE: f32 = 0.18;

/// Most the legs' IK raises the hips of a crouch from the data that goes deeper than the user
/// (m): bent knees have that much to give.
const MAX_CROUCH_RAISE: f32 = 0.15;

/// Most the shown hips turn about the vertical to face as the tracked ones do (rad, 35°): a
/// pelvis swings ±5–10° in a step; the root's own yaw follows the tracked facing (the clamp).
const MAX_FOLLOW_TURN: f32 = 35.0 * std::f32::consts::PI / 180.0;

#[derive(Clone, Debug)]
pub struct Legs {
    legs: [Option<LegJoints>; 2],
    /// Joint ranges to recompute after each leg's IK.
    leg_ranges: [Range<usize>; 2],
    locks: [FootLock; 2],
    /// Height of a planted toe on the floor, if known ([`Database::toe_height_in_contact`]).
    pub toe_floor: Option<f32>,
    /// How far the hips are lowered below the animation (m), legs bent by IK to keep the feet
    /// planted; the hips joint (the child of the root above the legs) and its subtree.
    pub hips_drop: f32,
    hips: Option<usize>,
    hips_range: Range<usize>,
    /// How far the torso bends forward (rad): a torso hinged at the hips, `torso` long, bent by
    /// it lowers the head by `torso (1 − cos bend)`. The spine joints (spine, chest, upper chest:
    /// those the skeleton has, `spine_count` of them) share the angle that lowers this skeleton's
    /// head as much ([`Self::chain_angle`]).
    pub bend: f32,
    spine: [usize; 3],
    spine_count: usize,
    /// From each spine joint to the next (the last: to the head) at rest: (forward, up), m.
    segments: [(f32, f32); 3],
    head: Option<usize>,
    /// Hips → head at rest (m); 0 when the skeleton has no spine joint to bend or no head.
    pub torso: f32,
    /// How far the last update's bend moved the head on the floor (world): the tracked root's
    /// target is that much behind the user's head, where bent-over people's hips are.
    pub bend_shift: Vec3,
    /// The hips are dropped into a crouch ([`CROUCH_ENTER`]): crouched frames are searched, and
    /// the IK drop is only what the animation's own head does not already go down.
    pub crouched: bool,
    /// How much of the IK drop still follows that crouched rule (0–1): 1 while crouched, then
    /// fading with the inertialization's half-life once the character leaves the crouch, as the
    /// shown pose comes up out of the crouch data. Switching to the whole drop at once lowered
    /// hips the fading crouch still held down: a user standing up saw them dip 26 cm.
    crouch_weight: f32,
    /// The hips' and the head's heights in the rest pose (standing, above its lowest joint), m;
    /// 0 without them.
    rest_hips_height: f32,
    rest_head_height: f32,
    /// Body tracking: the user's hips on the floor (world) and the way they face (yaw, rad),
    /// which the shown hips are moved and turned onto this update; `None`: the animation's hips.
    pub follow: Option<(Vec3, f32)>,
    /// How much of the way onto the tracked hips the shown ones go (0–1, blended in and out over
    /// [`FOLLOW_HALFLIFE`]), and the last tracked hips (what it blends out from when lost).
    follow_weight: f32,
    follow_last: (Vec3, f32),
    /// The hips move (drop, follow) applied to the pose by the last update in the root's frame,
    /// undone before the next one: like the leg IK it is a touch-up of the output, never a state
    /// the animation continues.
    applied_shift: Vec3,
    previous_toes: [Vec3; 2],
    /// Toe points of the shown pose (world), after the touch-ups.
    pub toes: [Vec3; 2],
}

/// The locks and the drop; the joints, ranges and toe floor come from the database.
impl Persist for Legs {
    fn persist(&mut self, v: &mut dyn Visitor, _: &'static str) {
        self.locks.persist(v, "");
        self.hips_drop.persist(v, "hips drop");
        self.applied_shift.persist(v, "applied hips shift");
        self.crouched.persist(v, "crouched");
        self.crouch_weight.persist(v, "crouch weight");
        self.follow_weight.persist(v, "hips follow weight");
        self.follow_last.0.persist(v, "followed hips");
        self.follow_last.1.persist(v, "followed hips yaw");
        self.bend.persist(v, "torso bend");
        self.bend_shift.persist(v, "bend shift");
        self.previous_toes.persist(v, "previous toes");
        self.toes.persist(v, "toes");
    }
}

impl Legs {
    pub fn new(db: &Database) -> Legs {
        let parents = &db.skeleton.parents;
        let legs = [LegJoints::from_skeleton(&db.skeleton, "left"), LegJoints::from_skeleton(&db.skeleton, "right")];
        let range = |leg: &Option<LegJoints>| leg.map_or(0..0, |l| subtree_range(parents, l.upper_leg));
        // The hips: the ancestor of the legs directly under the root.
        let hips = legs.iter().flatten().next().and_then(|leg| {
            let mut k = leg.upper_leg;
            while parents[k] > 0 {
                k = parents[k] as usize;
            }
            (parents[k] == 0).then_some(k)
        });
        let mut spine = [0; 3];
        let mut spine_count = 0;
        for j in ["spine", "chest", "upper_chest"].into_iter().filter_map(|role| db.skeleton.site_joint(role)) {
            // Only joints under the hips bend the torso (a skeleton whose roles say otherwise
            // keeps its torso straight rather than folding the legs).
            if hips.is_some_and(|h| hips_subtree_holds(parents, h, j)) {
                spine[spine_count] = j;
                spine_count += 1;
            }
        }
        let head = db.skeleton.site_joint("head");
        // The rest pose once (an FK pass): the torso's segments and the standing heights.
        let rest = db.rest_positions();
        let floor = rest.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
        let mut segments = [(0.0, 0.0); 3];
        let torso = match (hips, head, spine_count) {
            (Some(h), Some(hd), 1..) => {
                // Facing at rest: (left hip − right hip) × up, the builder's virtual-root rule.
                let forward = match &legs {
                    [Some(l), Some(r)] => {
                        (rest[l.upper_leg] - rest[r.upper_leg]).cross(Vec3::Y).with_y(0.0).normalize_or(Vec3::Z)
                    }
                    _ => Vec3::Z,
                };
                for k in 0..spine_count {
                    let next = if k + 1 < spine_count { rest[spine[k + 1]] } else { rest[hd] };
                    let d = next - rest[spine[k]];
                    segments[k] = (d.dot(forward), d.y);
                }
                rest[hd].distance(rest[h])
            }
            _ => 0.0,
        };
        Legs {
            leg_ranges: [range(&legs[0]), range(&legs[1])],
            legs,
            locks: [FootLock::new(); 2],
            toe_floor: None,
            hips_drop: 0.0,
            hips_range: hips.map_or(0..0, |h| subtree_range(parents, h)),
            hips,
            crouched: false,
            crouch_weight: 0.0,
            // Above the rest pose's lowest joint (its toes on the floor).
            rest_hips_height: hips.map_or(0.0, |h| rest[h].y - floor),
            rest_head_height: head.map_or(0.0, |h| rest[h].y - floor),
            follow: None,
            follow_weight: 0.0,
            follow_last: (Vec3::ZERO, 0.0),
            applied_shift: Vec3::ZERO,
            bend: 0.0,
            spine,
            spine_count,
            segments,
            head,
            torso,
            bend_shift: Vec3::ZERO,
            previous_toes: [Vec3::ZERO; 2],
            toes: [Vec3::ZERO; 2],
        }
    }

    fn toe(&self, pose: &Pose, side: usize) -> Option<Vec3> {
        let leg = self.legs[side].as_ref()?;
        Some(pose.world_positions[leg.toe] + pose.world_rotations[leg.toe] * leg.toe_offset)
    }

    /// Unlocks both feet and restarts their velocity estimate from the shown pose (its world
    /// transforms must be current).
    pub fn reset(&mut self, pose: &Pose) {
        for side in 0..2 {
            if let Some(toe) = self.toe(pose, side) {
                self.previous_toes[side] = toe;
                self.toes[side] = toe;
                self.locks[side].reset(toe, Vec3::ZERO);
            }
        }
    }

    /// Undoes the last update's hips drop and follow on the inertialized pose (call before
    /// playing on).
    pub fn undo_drop(&mut self, pose: &mut Pose) {
        if let (Some(h), true) = (self.hips, self.applied_shift != Vec3::ZERO) {
            pose.positions[h] -= self.applied_shift;
            self.applied_shift = Vec3::ZERO;
        }
    }

    /// Moves the crouch state on from the hips drop; returns whether it changed (a search is due).
    pub fn update_crouched(&mut self) -> bool {
        let h = self.rest_hips_height;
        let crouched = h > 0.0 && self.hips_drop > if self.crouched { CROUCH_LEAVE } else { CROUCH_ENTER } * h;
        std::mem::replace(&mut self.crouched, crouched) != crouched
    }

    /// Forgets any tracked hips: the next update shows the animation's (a recovery).
    pub fn reset_follow(&mut self) {
        self.follow = None;
        self.follow_weight = 0.0;
    }

    /// Which way the shown hips face (yaw, rad, 0 = +Z): (left hip − right hip) × up, the
    /// builder's virtual-root rule; `None` without both legs. World transforms current.
    fn hips_facing(&self, pose: &Pose) -> Option<f32> {
        let [Some(l), Some(r)] = &self.legs else { return None };
        let f = (pose.world_positions[l.upper_leg] - pose.world_positions[r.upper_leg]).cross(Vec3::Y);
        (f.x * f.x + f.z * f.z > 1e-12).then(|| f.x.atan2(f.z))
    }

    /// Body tracking: moves the shown hips toward the tracked ones on the floor (at most
    /// [`MAX_FOLLOW_SHIFT`]) and turns them about the vertical to their facing (at most
    /// [`MAX_FOLLOW_TURN`]), by the blend weight. The root is a pure yaw, so a turn about the
    /// world vertical is the same turn of the hips' local rotation, and a floor shift is the
    /// root's inverse yaw of it in the hips' local position. Returns whether the hips moved.
    fn follow_hips(&mut self, pose: &mut Pose, dt: f32) -> bool {
        let Some(h) = self.hips else { return false };
        if let Some(t) = self.follow {
            self.follow_last = t;
        }
        let goal = if self.follow.is_some() { 1.0 } else { 0.0 };
        self.follow_weight += (goal - self.follow_weight) * (1.0 - (-dt.max(0.0) / FOLLOW_HALFLIFE).exp2());
        if !(self.follow_weight > 1e-3) {
            self.follow_weight = 0.0;
            return false;
        }
        let w = self.follow_weight;
        let (target, yaw) = self.follow_last;
        if let Some(facing) = self.hips_facing(pose) {
            let d = (yaw - facing + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI;
            let turn = d.clamp(-MAX_FOLLOW_TURN, MAX_FOLLOW_TURN) * w;
            pose.output_rotations[h] = (Quat::from_rotation_y(turn) * pose.output_rotations[h]).normalize();
        }
        let at = pose.world_positions[h];
        let shift = (Vec3::new(target.x - at.x, 0.0, target.z - at.z) * w).clamp_length_max(MAX_FOLLOW_SHIFT);
        let local = pose.rotations[0].inverse() * shift;
        pose.positions[h] += local;
        self.applied_shift += local;
        true
    }

    /// Pitches the spine joints forward by `bend` in all, about the root's lateral axis (world
    /// transforms of the shown pose current; the caller re-runs FK). Each local is computed from
    /// the unbent parents, `P⁻¹·R(wθ)·P·L`, and rotations about one world axis commute, so the
    /// chain composes to the whole bend. Returns the head's world position before the bend, or
    /// `None` when nothing bends.
    fn bend_torso(&self, parents: &[i32], pose: &mut Pose, facing: Quat) -> Option<Vec3> {
        if !(self.bend > 0.0) || self.spine_count == 0 {
            return None;
        }
        let head = self.head.map_or(Vec3::ZERO, |h| pose.world_positions[h]);
        // Facing +Z, +X is the left: a positive turn about it takes the head forward and down.
        let share = Quat::from_axis_angle(
            facing * Vec3::X,
            self.chain_angle(self.bend.min(MAX_BEND)) / self.spine_count as f32,
        );
        for &j in &self.spine[..self.spine_count] {
            let parent = pose.world_rotations[parents[j] as usize];
            pose.output_rotations[j] = (parent.inverse() * share * parent * pose.output_rotations[j]).normalize();
        }
        Some(head)
    }

    /// The angle the spine joints share so that this skeleton's head, at rest, goes down as far
    /// as a hips-hinged torso's bent by `bend`: the spine bends above the hips, with a shorter
    /// lever, so it takes more (bisection; the drop grows with the angle up to past 90°).
    fn chain_angle(&self, bend: f32) -> f32 {
        let target = self.torso * (1.0 - bend.cos());
        let n = self.spine_count as f32;
        let drop = |a: f32| {
            self.segments[..self.spine_count].iter().enumerate().fold(0.0, |sum, (k, &(f, u))| {
                let (sin, cos) = (a * (k + 1) as f32 / n).sin_cos();
                sum + u - (u * cos - f * sin)
            })
        };
        let (mut lo, mut hi) = (0.0f32, MAX_CHAIN_BEND);
        if drop(hi) <= target {
            return hi;
        }
        for _ in 0..24 {
            let mid = 0.5 * (lo + hi);
            if drop(mid) < target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// Whether each foot is locked now.
    pub fn locked(&self) -> [bool; 2] {
        [self.locks[0].is_locked(), self.locks[1].is_locked()]
    }

    /// Whether each foot is stepping back under the body after a drift release.
    pub fn stepping(&self) -> [bool; 2] {
        [self.locks[0].is_stepping(), self.locks[1].is_stepping()]
    }

    /// Whether each foot is in the air on a corrective step (lifted more than 1 cm by it).
    pub fn airborne(&self) -> [bool; 2] {
        [self.locks[0].lift() > STEP_AIRBORNE, self.locks[1].lift() > STEP_AIRBORNE]
    }

    /// Touches up the shown pose, whose world transforms must be current; they are current
    /// again afterwards. `facing` breaks a tie for a straight leg's bend direction.
    pub fn apply(&mut self, db: &Database, pose: &mut Pose, settings: &CharacterSettings, facing: Quat, dt: f32) {
        let parents = &db.skeleton.parents;
        // Toe targets from the pose as animated (before any hips drop).
        let mut targets = [None; 2];
        // Each foot's rule reads the other's step as it was before this update (not as the
        // first foot's update just left it), so neither foot goes first.
        let airborne = self.airborne();
        for side in 0..2 {
            let Some(toe) = self.toe(pose, side) else { continue };
            let velocity = if dt > 0.0 { (toe - self.previous_toes[side]) / dt } else { Vec3::ZERO };
            self.previous_toes[side] = toe;
            if !settings.foot_lock {
                self.locks[side].reset(toe, velocity);
                targets[side] = Some((toe, toe));
                continue;
            }
            let contact = pose.contacts[side] != 0;
            self.locks[side].floor = if settings.foot_lock_floor { self.toe_floor } else { None };
            // The clamp lets the body drift up to α from where the animation puts it, so a lock
            // that released before α would re-plant while the character is being dragged: the
            // unlock radius is at least α (VR's α = 0.3 m: held-out replays skate 48 → 31 cm/s).
            let alpha = if settings.clamping { settings.clamp_distance } else { 0.0 };
            let radius = settings.foot_lock_unlock_radius.max(alpha);
            // A corrective step needs the other foot on the ground (planted in the animation,
            // locked, or its shown toe of the last update within `ON_FLOOR` of the floor, and not
            // lifted by a step of its own); otherwise the foot slides back rather than making the
            // body hop. While the other foot is in the air on a step, this one holds its lock
            // whatever the drift (the step lands within `ik::STEP_TIME`), so the steps take turns:
            // releasing then meant sliding the whole way back under a body that starts faster than
            // the data can (the quality harness's stop-and-go, five-run median: 16.0 → 4.0 cm/s).
            let other = &self.locks[1 - side];
            let stepping = airborne[1 - side];
            let radius = if stepping { f32::INFINITY } else { radius };
            let near_floor = self.toe_floor.is_some_and(|h| self.toes[1 - side].y - h < ON_FLOOR);
            self.locks[side].may_step = !stepping && (pose.contacts[1 - side] != 0 || other.is_locked() || near_floor);
            let target = self.locks[side].update(contact, toe, velocity, dt, radius, settings.foot_lock_halflife);
            targets[side] = Some((toe, target));
        }
        let fade = (-dt.max(0.0) / settings.inertialization_halflife.max(1e-3)).exp2();
        self.crouch_weight = if self.crouched { 1.0 } else { self.crouch_weight * fade };
        if self.crouch_weight <= 1e-3 {
            self.crouch_weight = 0.0;
        }
        let dropped = match self.hips {
            Some(h) if self.hips_drop > 0.0 => {
                // The root is a pure yaw, so the hips' local y is world height above the root.
                let y = pose.positions[h].y.max(0.0);
                // Crouched, the animation (crouch data) is already down: the legs' IK takes the
                // hips only the rest of the way to where the user's head is — measured at the
                // head, since a crouching body leans and its head goes down further than its
                // hips — or raises them by up to `MAX_CROUCH_RAISE` where the mocap crouches
                // deeper than the user. Upright, the whole drop; in between (the crouch fading
                // out) a blend of the two by `crouch_weight`.
                let w = self.crouch_weight;
                let drop = if w > 0.0 {
                    let crouched = match self.head {
                        Some(hd) => {
                            let animated = self.rest_head_height - (pose.world_positions[hd].y - pose.positions[0].y);
                            (self.hips_drop - animated.max(0.0)).max(-MAX_CROUCH_RAISE)
                        }
                        None => self.hips_drop - (self.rest_hips_height - y).max(0.0),
                    };
                    w * crouched + (1.0 - w) * self.hips_drop
                } else {
                    self.hips_drop
                }
                .min(0.6 * y);
                pose.positions[h].y -= drop;
                self.applied_shift.y -= drop;
                drop != 0.0
            }
            _ => false,
        };
        let dropped = self.follow_hips(pose, dt) || dropped;
        let head_before = self.bend_torso(parents, pose, facing);
        if dropped || head_before.is_some() {
            pose.forward_kinematics(parents, self.hips_range.clone());
        }
        self.bend_shift = match (head_before, self.head) {
            (Some(before), Some(hd)) => {
                let s = pose.world_positions[hd] - before;
                Vec3::new(s.x, 0.0, s.z)
            }
            _ => Vec3::ZERO,
        };
        for side in 0..2 {
            let (Some(leg), Some((toe, target))) = (&self.legs[side], targets[side]) else { continue };
            // Unlocked and blended out: the animation is already right, leave the leg alone.
            if !dropped && (target - toe).length_squared() < 1e-10 {
                continue;
            }
            // Keep the knee in the animation's own bend plane, even a slightly backward
            // (hyperextended) one: a pole on the other side makes the solver turn the leg half
            // a turn about the hip–ankle axis in one frame. Facing only breaks an exact tie.
            let (hip, knee, ankle) = (
                pose.world_positions[leg.upper_leg],
                pose.world_positions[leg.lower_leg],
                pose.world_positions[leg.foot],
            );
            let bend = knee_bend_direction(hip, knee, ankle);
            let pole = if bend.length_squared() > 1e-8 { bend } else { facing * Vec3::Z };
            leg_ik(
                leg,
                parents,
                &pose.world_positions,
                &pose.world_rotations,
                target,
                pole,
                0.0,
                1e-4,
                &mut pose.output_rotations,
            );
            pose.forward_kinematics(parents, self.leg_ranges[side].clone());
        }
        for side in 0..2 {
            if let Some(toe) = self.toe(pose, side) {
                self.toes[side] = toe;
            }
        }
    }
}

/// Whether joint `j` is in the subtree of `root` (parents precede children).
fn hips_subtree_holds(parents: &[i32], root: usize, j: usize) -> bool {
    let mut k = j;
    while k > root {
        k = parents[k].max(0) as usize;
    }
    k == root
}
