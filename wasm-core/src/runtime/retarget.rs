//! Retargeting a database skeleton's pose onto an avatar's skeleton (docs/method.md §8, the
//! T-pose method): for each joint whose role both skeletons have, the avatar's world rotation is
//!
//! `q_t = q_s · q_s0⁻¹ · q_t0`
//!
//! with `q_s` the source joint's world rotation now and `q_s0`, `q_t0` the two joints' world
//! rotations at rest; every other avatar joint keeps its rest local rotation. The hips
//! translation maps by the ratio of standing hip heights, about both skeletons' planted toe
//! heights, so feet stand on the floor whatever the foot geometry.
//!
//! Rest poses differ beyond "T": CMU's rest foot points down 20–30° where a game avatar's is
//! flat, arms hang at different angles. Plain T-pose retargeting carries that difference into
//! every frame (toes up, feet off the floor), so limb bones are first *direction-aligned*: the
//! source rest rotation is swung so its bone lies along the avatar's rest bone.
//!
//! Built once per (database, avatar); [`Retargeter::apply`] allocates nothing.

use crate::database::Database;
use crate::kinematics::local_to_model;
use crate::roles::{Role, Roles, LIMB_BONES};
use glam::{Quat, Vec3};

/// An avatar's skeleton at rest, as the renderer has it (glTF skins need not list parents
/// before children).
pub struct TargetSkeleton<'a> {
    /// Parent per joint, negative for a root.
    pub parents: &'a [i32],
    pub rest_local_rotations: &'a [Quat],
    pub rest_local_positions: &'a [Vec3],
    pub roles: Roles,
    /// World rotation of whatever carries the root joints (a glTF "Armature" node, a VRM 0 turn).
    pub root_parent_rotation: Quat,
}

/// Maps database poses onto one avatar.
#[derive(Clone, Debug)]
pub struct Retargeter {
    /// Avatar metres per database metre, in the avatar's bone units: the standing hips height
    /// over the toes of the avatar / of the source standing like the avatar.
    pub hips_scale: f32,
    /// Heights map as `y_t = (y_s − source_floor) · hips_scale + target_floor`.
    pub source_floor: f32,
    pub target_floor: f32,
    pub source_hips: usize,
    pub target_hips: usize,
    /// Avatar joints in an order where parents come first, and their parents in that order.
    order: Vec<usize>,
    parents_in_order: Vec<i32>,
    /// Source joint mapped to each avatar joint (avatar order), or none.
    source_of: Vec<Option<usize>>,
    /// `q_s0⁻¹ · q_t0` per mapped avatar joint (avatar order).
    offsets: Vec<Quat>,
    rest_local: Vec<Quat>,
    root_parent: Quat,
    /// Rest world rotation and position of the hips' parent (the hips' ancestors are unmapped).
    hips_parent_rotation: Quat,
    hips_parent_position: Vec3,
    /// Scratch: avatar world rotations (avatar order).
    world: Vec<Quat>,
}

/// A parent-first order of `parents`.
///
/// # Errors
/// A parent cycle or an out-of-range parent.
pub(crate) fn parent_first_order(parents: &[i32]) -> Result<Vec<usize>, String> {
    let n = parents.len();
    let mut order = Vec::with_capacity(n);
    let mut state = vec![0u8; n]; // 0 new, 1 visiting, 2 done
    for start in 0..n {
        let mut stack = vec![start];
        while let Some(&j) = stack.last() {
            if state[j] == 2 {
                stack.pop();
                continue;
            }
            let p = parents[j];
            if p >= n as i32 {
                return Err(format!("skeleton: joint {j} has parent {p}, out of range ({n} joints)"));
            }
            if p >= 0 && state[p as usize] != 2 {
                if state[p as usize] == 1 || stack.len() > n {
                    return Err(format!("skeleton: parent cycle through joint {j}"));
                }
                state[j] = 1;
                stack.push(p as usize);
                continue;
            }
            state[j] = 2;
            order.push(j);
            stack.pop();
        }
    }
    Ok(order)
}

/// The shortest rotation taking direction `a` to `b` (neither need be unit); identity when
/// either is zero.
fn rotation_between(a: Vec3, b: Vec3) -> Quat {
    match (a.try_normalize(), b.try_normalize()) {
        (Some(a), Some(b)) => crate::ik::rotation_arc(a, b, a.any_orthonormal_vector()),
        _ => Quat::IDENTITY,
    }
}

/// Height of `hips` above the lowest of `positions` (Y up).
fn hips_height(positions: &[Vec3], hips: usize) -> f32 {
    positions[hips].y - positions.iter().map(|p| p.y).fold(f32::INFINITY, f32::min)
}

/// Hips height over the toes (mean of both legs) of the avatar at rest and of the source
/// standing with its leg bones along the avatar's rest bones; and the avatar's rest toe height.
/// `None` unless both skeletons have hips, upper/lower leg, foot and toe on both sides.
fn standing_heights(
    source: &[Vec3],
    source_roles: &Roles,
    target: &[Vec3],
    target_roles: &Roles,
) -> Option<(f32, f32, f32)> {
    let chains = [
        [Role::Hips, Role::LeftUpperLeg, Role::LeftLowerLeg, Role::LeftFoot, Role::LeftToe],
        [Role::Hips, Role::RightUpperLeg, Role::RightLowerLeg, Role::RightFoot, Role::RightToe],
    ];
    let (mut s, mut t, mut toe) = (0.0, 0.0, 0.0);
    for chain in chains {
        let si: Vec<usize> = chain.iter().map(|&r| source_roles.get(r)).collect::<Option<_>>()?;
        let ti: Vec<usize> = chain.iter().map(|&r| target_roles.get(r)).collect::<Option<_>>()?;
        // Hips → upper leg as the source has it; each leg bone's length along the avatar's direction.
        let mut drop = source[si[0]].y - source[si[1]].y;
        for k in 1..4 {
            let length = (source[si[k + 1]] - source[si[k]]).length();
            let d = target[ti[k + 1]] - target[ti[k]];
            let l = d.length();
            drop -= if l > 0.0 { length * d.y / l } else { 0.0 };
        }
        s += drop / 2.0;
        t += (target[ti[0]].y - target[ti[4]].y) / 2.0;
        toe += target[ti[4]].y / 2.0;
    }
    (s > 0.0 && t > 0.0).then_some((s, t, toe))
}

impl Retargeter {
    /// A retargeter from `db`'s skeleton (roles from its sites, rest pose: identity rotations)
    /// onto `target`. `align_bones`: direction-align limb bones (see the module docs).
    /// `toe_floor`: `db`'s [`Database::toe_height_in_contact`], which a caller holding it passes
    /// rather than have it computed again (an FK pass over a quarter of the frames).
    ///
    /// # Errors
    /// Mismatched array lengths, a bad hierarchy, no hips on either skeleton, or a skeleton
    /// with no height.
    pub fn new(
        db: &Database,
        target: &TargetSkeleton,
        align_bones: bool,
        toe_floor: Option<f32>,
    ) -> Result<Retargeter, String> {
        let t_count = target.parents.len();
        if target.rest_local_rotations.len() != t_count || target.rest_local_positions.len() != t_count {
            return Err(format!(
                "retarget: {t_count} avatar joints but {} rest rotations and {} rest positions",
                target.rest_local_rotations.len(),
                target.rest_local_positions.len()
            ));
        }
        // A rest pose read from a broken file must not poison every later frame.
        let bad_rotation = |q: &Quat| !q.is_finite() || q.length() < 1e-6;
        if let Some(j) = target.rest_local_rotations.iter().position(bad_rotation) {
            return Err(format!(
                "retarget: avatar joint {j}'s rest rotation is not a rotation ({:?})",
                target.rest_local_rotations[j]
            ));
        }
        if let Some(j) = target.rest_local_positions.iter().position(|p| !p.is_finite()) {
            return Err(format!(
                "retarget: avatar joint {j}'s rest position is not finite ({:?})",
                target.rest_local_positions[j]
            ));
        }
        if bad_rotation(&target.root_parent_rotation) {
            return Err(format!(
                "retarget: the avatar's root parent rotation is not a rotation ({:?})",
                target.root_parent_rotation
            ));
        }
        let mut source_roles = Roles::default();
        for site in &db.skeleton.sites {
            // A toe site on a foot's end point (no toe joint) is not a joint of the role.
            if let Some(role) = Role::from_name(&site.name) {
                if site.joint >= 0 && site.offset == Vec3::ZERO {
                    source_roles.set(role, Some(site.joint as usize));
                }
            }
        }
        let source_hips = source_roles.get(Role::Hips).ok_or("retarget: the database skeleton has no hips")?;
        let target_hips = target.roles.get(Role::Hips).ok_or("retarget: the avatar has no hips bone")?;
        for (role, j) in target.roles.iter() {
            if j >= t_count {
                return Err(format!("retarget: role {} maps to joint {j} of {t_count}", role.name()));
            }
        }

        // The avatar in parent-first order, so the one FK can run over it.
        let order = parent_first_order(target.parents)?;
        let mut position_of = vec![0usize; t_count];
        for (k, &j) in order.iter().enumerate() {
            position_of[j] = k;
        }
        let parents_in_order: Vec<i32> = order
            .iter()
            .map(|&j| if target.parents[j] < 0 { -1 } else { position_of[target.parents[j] as usize] as i32 })
            .collect();
        let rest_local: Vec<Quat> = order.iter().map(|&j| target.rest_local_rotations[j].normalize()).collect();
        let rest_positions: Vec<Vec3> = order.iter().map(|&j| target.rest_local_positions[j]).collect();
        let (mut rest_world_p, mut rest_world_r) = (vec![Vec3::ZERO; t_count], vec![Quat::IDENTITY; t_count]);
        let root_parent = target.root_parent_rotation.normalize();
        local_to_model(
            &parents_in_order,
            0..t_count,
            Some((Vec3::ZERO, root_parent)),
            &rest_positions,
            &rest_local,
            &mut rest_world_p,
            &mut rest_world_r,
        );
        // Avatar-order roles, and avatar rest world positions indexed like the avatar's joints.
        let mut roles_in_order = Roles::default();
        for (role, j) in target.roles.iter() {
            roles_in_order.set(role, Some(position_of[j]));
        }

        let source_rest = db.rest_positions();
        let mut source_rest_rotations = vec![Quat::IDENTITY; db.num_joints()];
        if align_bones {
            for (role, child) in LIMB_BONES {
                let (Some(s), Some(sc), Some(t), Some(tc)) = (
                    source_roles.get(role),
                    source_roles.get(child),
                    roles_in_order.get(role),
                    roles_in_order.get(child),
                ) else {
                    continue;
                };
                // q_s0' = R(d_s → d_t) · q_s0: the source rotation at which its bone lies along
                // the avatar's rest bone, which then maps to the avatar's rest.
                let swing = rotation_between(source_rest[sc] - source_rest[s], rest_world_p[tc] - rest_world_p[t]);
                source_rest_rotations[s] = (swing * source_rest_rotations[s]).normalize();
            }
        }
        let mut source_of = vec![None; t_count];
        let mut offsets = vec![Quat::IDENTITY; t_count];
        for (role, t) in roles_in_order.iter() {
            if let Some(s) = source_roles.get(role) {
                source_of[t] = Some(s);
                offsets[t] = source_rest_rotations[s].inverse() * rest_world_r[t];
            }
        }

        let source_height = hips_height(&source_rest, source_hips);
        let target_height = hips_height(&rest_world_p, position_of[target_hips]);
        if !(source_height > 0.0 && target_height > 0.0) {
            return Err(format!(
                "retarget: hips heights must be positive (database {source_height}, avatar {target_height})"
            ));
        }
        let mut hips_scale = target_height / source_height;
        let (mut source_floor, mut target_floor) = (0.0, 0.0);
        // Better: the hips' height over the toes with the source standing like the avatar (its
        // leg bones along the avatar's rest bones) — the rest foot's tilt no longer counts.
        if let Some((s, t, toe)) = standing_heights(&source_rest, &source_roles, &rest_world_p, &roles_in_order) {
            if align_bones {
                hips_scale = t / s;
            }
            if let Some(h) = toe_floor {
                source_floor = h;
                target_floor = toe;
            }
        }
        let hp = parents_in_order[position_of[target_hips]];
        let (hips_parent_rotation, hips_parent_position) =
            if hp < 0 { (root_parent, Vec3::ZERO) } else { (rest_world_r[hp as usize], rest_world_p[hp as usize]) };
        Ok(Retargeter {
            hips_scale,
            source_floor,
            target_floor,
            source_hips,
            target_hips,
            order,
            parents_in_order,
            source_of,
            offsets,
            rest_local,
            root_parent,
            hips_parent_rotation,
            hips_parent_position,
            world: vec![Quat::IDENTITY; t_count],
        })
    }

    /// Retargets one pose: `source_world_rotations` (the database skeleton's, unit) and the
    /// source hips' world position (`lift` metres of the avatar's units added to its height, the
    /// avatar's grounding) → the avatar's local rotations (indexed like its joints) and the
    /// hips' local translation in its parent's rest frame, returned.
    pub fn apply(
        &mut self,
        source_world_rotations: &[Quat],
        source_hips: Vec3,
        lift: f32,
        local_rotations: &mut [Quat],
    ) -> Vec3 {
        for k in 0..self.order.len() {
            let p = self.parents_in_order[k];
            let parent = if p < 0 { self.root_parent } else { self.world[p as usize] };
            let t = self.order[k];
            match self.source_of[k] {
                Some(s) => {
                    // q_t = q_s · (q_s0⁻¹ · q_t0), renormalized against drift; local = parent⁻¹ · q_t.
                    self.world[k] = (source_world_rotations[s] * self.offsets[k]).normalize();
                    local_rotations[t] = parent.inverse() * self.world[k];
                }
                None => {
                    local_rotations[t] = self.rest_local[k];
                    self.world[k] = parent * self.rest_local[k];
                }
            }
        }
        let s = self.hips_scale;
        let v = Vec3::new(
            source_hips.x * s,
            (source_hips.y - self.source_floor) * s + self.target_floor + lift,
            source_hips.z * s,
        ) - self.hips_parent_position;
        self.hips_parent_rotation.inverse() * v
    }
}
