//! Cross-skeleton import: a take recorded on another skeleton (another topology: 100STYLE's
//! Xsens rig into a CMU database) retargeted onto the database's reference skeleton, so one
//! database holds several sources (docs/database.md, "Several skeletons").
//!
//! The method is the runtime's (docs/method.md §8, `crate::retarget`): per joint whose role
//! both skeletons have, the target's world rotation is the source's, `q_t = q_s · q_s0⁻¹ · q_t0`
//! with the rest world rotations of both (identity in a BVH), after two alignments of the rest
//! poses:
//! - **facing**: the source's rest faces (left hip → right hip) × up; the whole source is turned
//!   about Y to the reference's facing;
//! - **limb directions**: rest poses differ beyond "T" (CMU's rest foot points down 20–30°, an
//!   Xsens foot is flat; arms hang at different angles), so the source's rest rotation of each
//!   limb bone is swung to lie along the reference's rest bone, and the target bone then points
//!   where the source bone points.
//!
//! Joints the source lacks keep their rest (identity) rotation. The hips move like the source's,
//! their floor motion scaled by the ratio of leg lengths (the feet keep their stride), their
//! height then shifted so the planted toes stand at the reference's planted toe height.
//!
//! The retargeting error is measured on every frame: each end effector (feet, toes, hands,
//! head) relative to the hip joints' midpoint, target against the source scaled by the leg ratio.

use super::poses::Poses;
use crate::ik::{knee_bend_direction, two_bone_ik};
use crate::kinematics::local_to_model;
use crate::roles::{Role, Roles, LIMB_BONES};
use glam::{DQuat, DVec3};

/// End effectors the error is measured on, in report groups (toes: where both skeletons have them).
const FEET: [Role; 2] = [Role::LeftFoot, Role::RightFoot];
const TOES: [Role; 2] = [Role::LeftToe, Role::RightToe];
const HANDS: [Role; 2] = [Role::LeftHand, Role::RightHand];
const HEAD: [Role; 1] = [Role::Head];

/// One skeleton as the retargeter needs it: hierarchy, roles, rest offsets and end sites in
/// metres, Y up.
#[derive(Clone, Copy)]
pub struct Rig<'a> {
    pub parents: &'a [i32],
    pub roles: &'a Roles,
    pub offsets: &'a [DVec3],
    pub end_sites: &'a [Option<DVec3>],
}

impl Rig<'_> {
    fn rest(&self) -> Vec<DVec3> {
        let n = self.offsets.len();
        let (mut p, mut r) = (vec![DVec3::ZERO; n], vec![DQuat::IDENTITY; n]);
        local_to_model(self.parents, 0..n, None, self.offsets, &vec![DQuat::IDENTITY; n], &mut p, &mut r);
        p
    }

    /// Rest direction of a limb bone: to the child role's joint, else along the end site.
    fn bone(&self, rest: &[DVec3], role: Role, child: Role) -> Option<DVec3> {
        let j = self.roles.get(role)?;
        let d = match self.roles.get(child) {
            Some(c) => rest[c] - rest[j],
            None => self.end_sites[j]?,
        };
        d.try_normalize()
    }

    /// Midpoint of the hip joints (the upper legs) in world positions `p`.
    fn pelvis(&self, p: &[DVec3]) -> DVec3 {
        0.5 * (p[self.roles[Role::LeftUpperLeg]] + p[self.roles[Role::RightUpperLeg]])
    }

    /// Rest facing: (left hip − right hip) × up on the floor (the builder's virtual-root rule).
    fn facing(&self, rest: &[DVec3]) -> DVec3 {
        let (l, r) = (self.roles[Role::LeftUpperLeg], self.roles[Role::RightUpperLeg]);
        let f = (rest[l] - rest[r]).cross(DVec3::Y);
        DVec3::new(f.x, 0.0, f.z).try_normalize().unwrap_or(DVec3::Z)
    }
}

/// One target leg for the ankle IK.
struct Leg {
    upper: usize,
    lower: usize,
    foot: usize,
    source_foot: usize,
    /// Joints from the upper leg to the foot, parents first, the foot included.
    chain: Vec<usize>,
    /// Those of `chain` from the knee on (they turn with the knee's delta).
    below_knee: Vec<usize>,
}

/// Mean and largest error of one group of end effectors over a take (m).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ErrorStats {
    pub mean: f64,
    pub max: f64,
}

/// What one take's retargeting did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RetargetReport {
    /// Leg length of the reference over the source's: the scale of the root motion.
    pub leg_ratio: f64,
    /// Height added to the hips so the planted toes stand where the reference's do (m).
    pub floor_shift: f64,
    /// Ankles (the foot joints).
    pub feet: ErrorStats,
    pub toes: ErrorStats,
    pub hands: ErrorStats,
    pub head: ErrorStats,
    /// Source roles the reference has but the source lacks (their joints stay at rest).
    pub unmapped: Vec<&'static str>,
}

/// Maps local poses of one source skeleton onto the reference skeleton.
pub struct Retargeter<'a> {
    source: Rig<'a>,
    target: Rig<'a>,
    /// Source joint per target joint, if their roles match.
    source_of: Vec<Option<usize>>,
    /// `Y⁻¹ · S⁻¹` per target joint: `W_t = Y · W_s · align` (identity where unmapped).
    align: Vec<DQuat>,
    /// Facing alignment `Y` (a rotation about +Y).
    facing: DQuat,
    leg_ratio: f64,
    target_hips: usize,
    /// The target's rest joint positions (where the hips' unmapped ancestors stay).
    target_rest: Vec<DVec3>,
    /// The target's hip-joint midpoint in the hips' frame.
    target_pelvis: DVec3,
    legs: Vec<Leg>,
    unmapped: Vec<&'static str>,
}

impl<'a> Retargeter<'a> {
    /// A retargeter from `source` onto `target`; `leg_ratio` = target leg / source leg.
    pub fn new(source: Rig<'a>, target: Rig<'a>, leg_ratio: f64) -> Retargeter<'a> {
        let (rest_s, rest_t) = (source.rest(), target.rest());
        let facing = DQuat::from_rotation_arc(source.facing(&rest_s), target.facing(&rest_t));
        let n = target.offsets.len();
        let mut source_of = vec![None; n];
        let mut align = vec![DQuat::IDENTITY; n];
        let mut unmapped = Vec::new();
        for (role, t) in target.roles.iter() {
            match source.roles.get(role) {
                Some(s) => {
                    source_of[t] = Some(s);
                    align[t] = facing.conjugate();
                }
                None => unmapped.push(role.name()),
            }
        }
        for (role, child) in LIMB_BONES {
            let (Some(t), Some(ds), Some(dt)) =
                (target.roles.get(role), source.bone(&rest_s, role, child), target.bone(&rest_t, role, child))
            else {
                continue;
            };
            if source_of[t].is_some() {
                // The source's rest rotation becomes S·Y, S swinging its (turned) bone onto the
                // reference's: W_t = Y·W_s·(S·Y)⁻¹.
                let swing = DQuat::from_rotation_arc(facing * ds, dt);
                align[t] = (swing * facing).conjugate();
            }
        }
        let target_hips = target.roles[Role::Hips];
        let mut legs = Vec::new();
        for [upper, lower, foot] in [
            [Role::LeftUpperLeg, Role::LeftLowerLeg, Role::LeftFoot],
            [Role::RightUpperLeg, Role::RightLowerLeg, Role::RightFoot],
        ] {
            let (Some(u), Some(l), Some(f), Some(sf)) =
                (target.roles.get(upper), target.roles.get(lower), target.roles.get(foot), source.roles.get(foot))
            else {
                continue;
            };
            let path = |from: usize, to: usize| {
                let mut v = vec![to];
                let mut j = to;
                while j != from && target.parents[j] >= 0 {
                    j = target.parents[j] as usize;
                    v.push(j);
                }
                v.reverse();
                v
            };
            let chain = path(u, f);
            let below_knee = path(l, f);
            if chain.first() == Some(&u) && below_knee.first() == Some(&l) {
                legs.push(Leg { upper: u, lower: l, foot: f, source_foot: sf, chain, below_knee });
            }
        }
        Retargeter {
            source,
            target,
            source_of,
            align,
            facing,
            leg_ratio,
            target_hips,
            legs,
            target_pelvis: target.pelvis(&rest_t) - rest_t[target_hips],
            target_rest: rest_t,
            unmapped,
        }
    }

    /// Retargets `src` (local poses of the source skeleton, metres, Y up) into `out` (local poses
    /// of the target) and measures the error; `toe_floor` is the reference's planted toe height,
    /// which the hips are shifted to (`None`: no shift).
    pub fn apply(&self, src: &Poses, toe_floor: Option<f64>, out: &mut Poses) -> RetargetReport {
        let (ns, nt) = (self.source.offsets.len(), self.target.offsets.len());
        let frames = src.num_frames();
        out.reset(nt, frames);
        let (mut ws_p, mut ws_r) = (vec![DVec3::ZERO; ns], vec![DQuat::IDENTITY; ns]);
        let (mut wt_p, mut wt_r) = (vec![DVec3::ZERO; nt], vec![DQuat::IDENTITY; nt]);
        let mut local_r = vec![DQuat::IDENTITY; nt];
        let mut local_p = self.target.offsets.to_vec();
        let hips_parent = self.target.parents[self.target_hips];
        for f in 0..frames {
            let range = f * ns..(f + 1) * ns;
            local_to_model(
                self.source.parents,
                0..ns,
                None,
                &src.positions[range.clone()],
                &src.rotations[range],
                &mut ws_p,
                &mut ws_r,
            );
            // World rotations, parents first (every BVH lists parents before children).
            for t in 0..nt {
                let parent = self.target.parents[t];
                let parent_world = if parent < 0 { DQuat::IDENTITY } else { wt_r[parent as usize] };
                wt_r[t] = match self.source_of[t] {
                    Some(s) => (self.facing * ws_r[s] * self.align[t]).normalize(),
                    None => parent_world,
                };
                local_r[t] = (parent_world.conjugate() * wt_r[t]).normalize();
            }
            // The hips: placed so that the hip joints' midpoint is the source's, turned and
            // scaled (the hips joint itself sits anywhere between them and the waist: CMU's is
            // 10 cm above and 4 cm behind them, an Xsens one level with them).
            let hips =
                self.facing * self.source.pelvis(&ws_p) * self.leg_ratio - wt_r[self.target_hips] * self.target_pelvis;
            local_p[self.target_hips] = if hips_parent < 0 {
                hips
            } else {
                // Ancestors of the hips are unmapped (rest rotations): their rest positions.
                hips - self.target_rest[hips_parent as usize]
            };
            // Legs: the retargeted rotations keep the source's joint angles, so with other
            // thigh/shin proportions the ankles miss the source's by centimetres; two-bone IK in
            // the leg's own bend plane puts them there (feet are what contacts, foot features
            // and skating are measured on). The feet keep their world rotations.
            local_to_model(self.target.parents, 0..nt, None, &local_p, &local_r, &mut wt_p, &mut wt_r);
            let pelvis = self.target.pelvis(&wt_p);
            let source_pelvis = self.source.pelvis(&ws_p);
            for leg in &self.legs {
                let (a, b, c) = (wt_p[leg.upper] - pelvis, wt_p[leg.lower] - pelvis, wt_p[leg.foot] - pelvis);
                let goal = self.facing * (ws_p[leg.source_foot] - source_pelvis) * self.leg_ratio;
                let pole = knee_bend_direction(a.as_vec3(), b.as_vec3(), c.as_vec3());
                let (ra, rb) = two_bone_ik(a.as_vec3(), b.as_vec3(), c.as_vec3(), goal.as_vec3(), pole, 1e-3);
                let (ra, rb) = (ra.as_dquat(), rb.as_dquat());
                for &j in &leg.chain {
                    wt_r[j] = if j == leg.foot {
                        wt_r[j]
                    } else if leg.below_knee.contains(&j) {
                        (rb * wt_r[j]).normalize()
                    } else {
                        (ra * wt_r[j]).normalize()
                    };
                }
                for &j in &leg.chain {
                    let parent = self.target.parents[j];
                    let parent_world = if parent < 0 { DQuat::IDENTITY } else { wt_r[parent as usize] };
                    local_r[j] = (parent_world.conjugate() * wt_r[j]).normalize();
                }
            }
            for t in 0..nt {
                out.push(local_p[t], local_r[t]);
            }
        }
        let mut report =
            RetargetReport { leg_ratio: self.leg_ratio, unmapped: self.unmapped.clone(), ..Default::default() };
        // Planted toes on the reference's floor: the lower toe's 5th-percentile height.
        if let Some(floor) = toe_floor {
            if let Some(own) = toe_floor_of(out, &self.target) {
                report.floor_shift = floor - own;
                for f in 0..frames {
                    out.positions[f * nt + self.target_hips].y += report.floor_shift;
                }
            }
        }
        // Errors: end effectors relative to the hips, target vs the turned, scaled source.
        let mut sums = [(0.0, 0.0, 0usize); 4];
        for f in 0..frames {
            let (rs, rt) = (f * ns..(f + 1) * ns, f * nt..(f + 1) * nt);
            local_to_model(
                self.source.parents,
                0..ns,
                None,
                &src.positions[rs.clone()],
                &src.rotations[rs],
                &mut ws_p,
                &mut ws_r,
            );
            local_to_model(
                self.target.parents,
                0..nt,
                None,
                &out.positions[rt.clone()],
                &out.rotations[rt],
                &mut wt_p,
                &mut wt_r,
            );
            for (group, roles) in [&FEET[..], &TOES[..], &HANDS[..], &HEAD[..]].into_iter().enumerate() {
                for &role in roles {
                    let (Some(s), Some(t)) = (self.source.roles.get(role), self.target.roles.get(role)) else {
                        continue;
                    };
                    let expected = self.facing * (ws_p[s] - self.source.pelvis(&ws_p)) * self.leg_ratio;
                    let e = (wt_p[t] - self.target.pelvis(&wt_p) - expected).length();
                    let g = &mut sums[group];
                    g.0 += e;
                    g.1 = f64::max(g.1, e);
                    g.2 += 1;
                }
            }
        }
        let stats = |(sum, max, count): (f64, f64, usize)| ErrorStats {
            mean: if count > 0 { sum / count as f64 } else { 0.0 },
            max,
        };
        (report.feet, report.toes, report.hands, report.head) =
            (stats(sums[0]), stats(sums[1]), stats(sums[2]), stats(sums[3]));
        report
    }
}

/// Planted toe height of a take on `rig`: the 5th percentile over frames of the lower toe
/// (or foot) joint's height. `None` without feet.
pub fn toe_floor_of(poses: &Poses, rig: &Rig) -> Option<f64> {
    let n = rig.offsets.len();
    let toe = |toe: Role, foot: Role| rig.roles.get(toe).or(rig.roles.get(foot));
    let (l, r) = (toe(Role::LeftToe, Role::LeftFoot)?, toe(Role::RightToe, Role::RightFoot)?);
    let (mut p, mut q) = (vec![DVec3::ZERO; n], vec![DQuat::IDENTITY; n]);
    let mut heights: Vec<f64> = (0..poses.num_frames())
        .map(|f| {
            let range = f * n..(f + 1) * n;
            local_to_model(
                rig.parents,
                0..n,
                None,
                &poses.positions[range.clone()],
                &poses.rotations[range],
                &mut p,
                &mut q,
            );
            p[l].y.min(p[r].y)
        })
        .collect();
    if heights.is_empty() {
        return None;
    }
    heights.sort_by(f64::total_cmp);
    Some(heights[heights.len() / 20])
}
