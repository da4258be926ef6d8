//! An avatar's bone world matrices and skinning matrices from its retargeted pose, in one pass:
//! what three.js computes from posed bones (`Object3D.updateMatrixWorld`, then
//! `Skeleton.update`: `bone world · inverse bind` per bone of each skin), for avatars posed many
//! at a time (a crowd), where those two passes cost more than the character's whole runtime.
//!
//! The bones' model transforms come from the one FK ([`local_to_model`]) over a parent-first
//! order of the avatar's bones; a bone's world matrix is the carrier's (whatever holds the root
//! bones, an "Armature" node, with the scene above it) times its model transform. Bones must
//! have unit scale (the carrier may scale): the caller checks. Allocates nothing per update.

use crate::kinematics::local_to_model;
use crate::retarget::parent_first_order;
use glam::{Mat4, Quat, Vec3};

/// One skinned mesh's skeleton: which avatar bone each of its slots is, and its inverse bind
/// matrices (three.js `Skeleton.bones`, `boneInverses`).
struct Skin {
    bones: Vec<usize>,
    inverse_bind: Vec<Mat4>,
    matrices: Vec<Mat4>,
}

pub struct Skinning {
    /// Avatar bones in a parent-first order, their parents in that order, and rest local positions.
    order: Vec<usize>,
    parents_in_order: Vec<i32>,
    rest_positions: Vec<Vec3>,
    /// The hips bone (avatar index), whose local translation is animated.
    hips: usize,
    skins: Vec<Skin>,
    /// Scratch in order space, then world matrices by avatar bone.
    local_positions: Vec<Vec3>,
    local_rotations: Vec<Quat>,
    model_positions: Vec<Vec3>,
    model_rotations: Vec<Quat>,
    world: Vec<Mat4>,
}

impl Skinning {
    /// The avatar's bones (`parents`, negative for a root, in any order), their rest local
    /// positions, its hips bone, and per skeleton its bone slots (avatar indices) and inverse
    /// bind matrices.
    ///
    /// # Errors
    /// A parent cycle or out of range, a slot naming no bone, or slots and inverse binds of
    /// different lengths.
    pub fn new(
        parents: &[i32],
        rest_positions: &[Vec3],
        hips: usize,
        skins: Vec<(Vec<usize>, Vec<Mat4>)>,
    ) -> Result<Skinning, String> {
        let order = parent_first_order(parents)?;
        let n = parents.len();
        if order.len() != n || rest_positions.len() != n || hips >= n {
            return Err(format!(
                "skinning: {n} bones, {} in order, {} rest positions",
                order.len(),
                rest_positions.len()
            ));
        }
        let mut at = vec![0usize; n];
        for (k, &t) in order.iter().enumerate() {
            at[t] = k;
        }
        let parents_in_order =
            order.iter().map(|&t| if parents[t] < 0 { -1 } else { at[parents[t] as usize] as i32 }).collect();
        let skins = skins
            .into_iter()
            .enumerate()
            .map(|(s, (bones, inverse_bind))| {
                if bones.len() != inverse_bind.len() || bones.iter().any(|&b| b >= n) {
                    return Err(format!(
                        "skinning: skin {s} has {} slots and {} inverse binds for {n} bones",
                        bones.len(),
                        inverse_bind.len()
                    ));
                }
                let matrices = vec![Mat4::IDENTITY; bones.len()];
                Ok(Skin { bones, inverse_bind, matrices })
            })
            .collect::<Result<Vec<_>, String>>()?;
        Ok(Skinning {
            rest_positions: order.iter().map(|&t| rest_positions[t]).collect(),
            order,
            parents_in_order,
            hips,
            skins,
            local_positions: vec![Vec3::ZERO; n],
            local_rotations: vec![Quat::IDENTITY; n],
            model_positions: vec![Vec3::ZERO; n],
            model_rotations: vec![Quat::IDENTITY; n],
            world: vec![Mat4::IDENTITY; n],
        })
    }

    /// Poses every bone: `local_rotations` by avatar bone, the hips at `hips_position` (its
    /// local translation), under `carrier` (the root bones' parent's world matrix).
    pub fn update(&mut self, carrier: &Mat4, local_rotations: &[Quat], hips_position: Vec3) {
        for (k, &t) in self.order.iter().enumerate() {
            self.local_rotations[k] = local_rotations[t];
            self.local_positions[k] = if t == self.hips { hips_position } else { self.rest_positions[k] };
        }
        let n = self.order.len();
        local_to_model(
            &self.parents_in_order,
            0..n,
            None,
            &self.local_positions,
            &self.local_rotations,
            &mut self.model_positions,
            &mut self.model_rotations,
        );
        for (k, &t) in self.order.iter().enumerate() {
            self.world[t] =
                *carrier * Mat4::from_rotation_translation(self.model_rotations[k], self.model_positions[k]);
        }
        for skin in &mut self.skins {
            for (m, (&b, inverse)) in skin.matrices.iter_mut().zip(skin.bones.iter().zip(&skin.inverse_bind)) {
                *m = self.world[b] * *inverse;
            }
        }
    }

    /// World matrix of every bone (column-major, by avatar bone) after [`Self::update`].
    pub fn world(&self) -> &[Mat4] {
        &self.world
    }

    /// Skin `s`'s matrices (`bone world · inverse bind` per slot) after [`Self::update`].
    pub fn skin(&self, s: usize) -> &[Mat4] {
        &self.skins[s].matrices
    }

    pub fn num_skins(&self) -> usize {
        self.skins.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of three bones under a scaled, moved carrier: world matrices are the carrier's
    /// times the FK's, and a skin's matrices are world · inverse bind.
    #[test]
    fn matrices_are_carrier_times_fk_and_world_times_inverse_bind() {
        // Bones listed child first: the order puts parents first.
        let parents = [1, 2, -1];
        let rest = [Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 2.0, 0.0), Vec3::new(5.0, 0.0, 0.0)];
        let inverse = Mat4::from_translation(Vec3::new(0.0, -3.0, 0.0));
        let mut s = Skinning::new(&parents, &rest, 2, vec![(vec![0, 2], vec![inverse, Mat4::IDENTITY])]).unwrap();
        let carrier = Mat4::from_scale_rotation_translation(Vec3::splat(0.5), Quat::IDENTITY, Vec3::X);
        let turn = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        s.update(&carrier, &[Quat::IDENTITY, turn, Quat::IDENTITY], Vec3::new(1.0, 0.0, 0.0));
        // Root (hips) at (1, 0, 0); bone 1 at +2 y; bone 0 one unit along the turned y: −x.
        let expected = carrier
            * Mat4::from_translation(Vec3::new(1.0, 0.0, 0.0))
            * Mat4::from_translation(Vec3::new(0.0, 2.0, 0.0))
            * Mat4::from_quat(turn)
            * Mat4::from_translation(Vec3::new(0.0, 1.0, 0.0));
        assert!(s.world()[0].abs_diff_eq(expected, 1e-5), "{:?} vs {expected:?}", s.world()[0]);
        assert!(s.skin(0)[0].abs_diff_eq(expected * inverse, 1e-5));
        assert!(s.skin(0)[1].abs_diff_eq(s.world()[2], 1e-6));
        assert!(Skinning::new(&parents, &rest, 2, vec![(vec![3], vec![Mat4::IDENTITY])]).is_err());
    }
}
