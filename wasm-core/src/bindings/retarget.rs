//! `RawRetargeter`: maps a character's world pose onto an avatar's bones
//! ([`crate::retarget::Retargeter`]); TS copies the result into the three.js bones.

use super::character::RawCharacter;
use super::database::RawDatabase;
use super::{Kind, LiveToken};
use crate::retarget::{Retargeter, TargetSkeleton};
use crate::roles::{Role, Roles, NUM_ROLES};
use glam::{Quat, Vec3};
use wasm_bindgen::prelude::*;

#[wasm_bindgen]
pub struct RawRetargeter {
    retargeter: Retargeter,
    /// Joints of the database the retargeter was made for: a character on another database
    /// (another skeleton) cannot be mapped through it.
    source_joints: usize,
    local_rotations: Vec<Quat>,
    hips_position: [f32; 3],
    _live: LiveToken,
}

#[wasm_bindgen]
impl RawRetargeter {
    /// An avatar of `T` joints: `parents` (T, −1 for roots), rest local rotations (T×4),
    /// rest local positions (T×3), the joint of each role (22, −1 for none; see
    /// `role_names_json`), the rotation of whatever carries the root joints (4), and whether
    /// to direction-align limb bones. Throws on inconsistent input.
    #[wasm_bindgen(constructor)]
    pub fn new(
        database: &RawDatabase,
        parents: &[i32],
        rest_rotations: &[f32],
        rest_positions: &[f32],
        roles: &[i32],
        root_parent_rotation: &[f32],
        align_bones: bool,
    ) -> Result<RawRetargeter, JsError> {
        let t = parents.len();
        if rest_rotations.len() != 4 * t
            || rest_positions.len() != 3 * t
            || roles.len() != NUM_ROLES
            || root_parent_rotation.len() != 4
        {
            return Err(JsError::new(&format!(
                "retarget: {t} joints need {} rest rotation and {} rest position floats and {NUM_ROLES} roles; got {}, {}, {}",
                4 * t,
                3 * t,
                rest_rotations.len(),
                rest_positions.len(),
                roles.len()
            )));
        }
        let rotations: Vec<Quat> = rest_rotations.chunks_exact(4).map(Quat::from_slice).collect();
        let positions: Vec<Vec3> = rest_positions.chunks_exact(3).map(Vec3::from_slice).collect();
        let mut target_roles = Roles::default();
        for (k, &j) in roles.iter().enumerate() {
            target_roles.set(Role::ALL[k], (j >= 0).then_some(j as usize));
        }
        let target = TargetSkeleton {
            parents,
            rest_local_rotations: &rotations,
            rest_local_positions: &positions,
            roles: target_roles,
            root_parent_rotation: Quat::from_slice(root_parent_rotation),
        };
        let retargeter = Retargeter::new(&database.shared.db, &target, align_bones).map_err(|e| JsError::new(&e))?;
        let source_joints = database.shared.db.num_joints();
        Ok(RawRetargeter {
            retargeter,
            source_joints,
            local_rotations: vec![Quat::IDENTITY; t],
            hips_position: [0.0; 3],
            _live: LiveToken::new(Kind::Retargeter),
        })
    }

    /// Retargets `character`'s current world pose, lifting the hips `lift` (avatar units; the
    /// avatar's grounding; not a number counts as 0). Then read [`Self::local_rotations_ptr`]
    /// and [`Self::hips_position_ptr`].
    ///
    /// # Errors
    /// A character on a database with another skeleton than this retargeter's (nothing changes).
    pub fn apply(&mut self, character: &RawCharacter, lift: f32) -> Result<(), JsError> {
        let c = &character.character;
        if c.world_rotations().len() != self.source_joints {
            return Err(JsError::new(&format!(
                "retarget: the character's skeleton has {} joints, this retargeter was made for {}; bind the avatar to the character's database",
                c.world_rotations().len(),
                self.source_joints
            )));
        }
        let hips = c.world_positions()[self.retargeter.source_hips];
        let lift = if lift.is_finite() { lift } else { 0.0 };
        let p = self.retargeter.apply(c.world_rotations(), hips, lift, &mut self.local_rotations);
        self.hips_position = p.to_array();
        Ok(())
    }

    /// `T×4` f32: the avatar's local rotations after [`Self::apply`].
    pub fn local_rotations_ptr(&self) -> *const f32 {
        self.local_rotations.as_ptr().cast()
    }
    /// 3 f32: the hips' local translation after [`Self::apply`].
    pub fn hips_position_ptr(&self) -> *const f32 {
        self.hips_position.as_ptr()
    }
    /// The avatar's hips joint index.
    pub fn target_hips(&self) -> usize {
        self.retargeter.target_hips
    }
    /// Avatar bone units per database metre (see `Retargeter::hips_scale`).
    pub fn hips_scale(&self) -> f32 {
        self.retargeter.hips_scale
    }
}
