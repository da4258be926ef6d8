//! `RawRetargeter`: maps a character's world pose onto an avatar's bones
//! ([`crate::retarget::Retargeter`]); TS copies the result into the three.js bones.

use super::character::RawCharacter;
use super::database::RawDatabase;
use super::{Kind, LiveToken};
use crate::retarget::{Retargeter, TargetSkeleton};
use crate::roles::{Role, Roles, NUM_ROLES};
use crate::skinning::Skinning;
use glam::{Mat4, Quat, Vec3};
use wasm_bindgen::prelude::*;

#[wasm_bindgen]
pub struct RawRetargeter {
    retargeter: Retargeter,
    /// Joints of the database the retargeter was made for: a character on another database
    /// (another skeleton) cannot be mapped through it.
    source_joints: usize,
    local_rotations: Vec<Quat>,
    hips_position: [f32; 3],
    /// The bone and skinning matrices (`enable_skinning`), and the carrier's world matrix JS
    /// writes before each `skin` (`carrier_ptr`: no copy, no allocation per frame).
    skinning: Option<Skinning>,
    carrier: [f32; 16],
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
        let retargeter = Retargeter::new(&database.shared.db, &target, align_bones, database.shared.toe_floor)
            .map_err(|e| JsError::new(&e))?;
        let source_joints = database.shared.db.num_joints();
        Ok(RawRetargeter {
            retargeter,
            source_joints,
            local_rotations: vec![Quat::IDENTITY; t],
            hips_position: [0.0; 3],
            skinning: None,
            carrier: Mat4::IDENTITY.to_cols_array(),
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

    /// Computes the bones' world matrices and the skins' matrices in the core from now on
    /// (`skin`), instead of three.js (`runtime/skinning.rs`): `parents` and `rest_positions`
    /// as given to the constructor; per skin `skin_lengths[s]` slots, their bones in
    /// `skin_bones` (concatenated) and inverse bind matrices in `inverse_binds` (16 f32 each,
    /// column-major). Throws on inconsistent input (nothing changes).
    pub fn enable_skinning(
        &mut self,
        parents: &[i32],
        rest_positions: &[f32],
        skin_lengths: &[u32],
        skin_bones: &[u32],
        inverse_binds: &[f32],
    ) -> Result<(), JsError> {
        let total: usize = skin_lengths.iter().map(|&n| n as usize).sum();
        if rest_positions.len() != 3 * parents.len() || skin_bones.len() != total || inverse_binds.len() != 16 * total {
            return Err(JsError::new(&format!(
                "skinning: {} bones need {} rest position floats, {total} slots need as many bones and {} inverse bind floats; got {}, {}, {}",
                parents.len(),
                3 * parents.len(),
                16 * total,
                rest_positions.len(),
                skin_bones.len(),
                inverse_binds.len()
            )));
        }
        let positions: Vec<Vec3> = rest_positions.chunks_exact(3).map(Vec3::from_slice).collect();
        let mut at = 0;
        let skins = skin_lengths
            .iter()
            .map(|&n| {
                let range = at..at + n as usize;
                at += n as usize;
                let bones = skin_bones[range.clone()].iter().map(|&b| b as usize).collect();
                let binds = range.map(|k| Mat4::from_cols_slice(&inverse_binds[16 * k..16 * k + 16])).collect();
                (bones, binds)
            })
            .collect();
        let skinning =
            Skinning::new(parents, &positions, self.retargeter.target_hips, skins).map_err(|e| JsError::new(&e))?;
        self.skinning = Some(skinning);
        Ok(())
    }

    /// Where JS writes the carrier's world matrix (16 f32, column-major) before `skin`.
    pub fn carrier_ptr(&mut self) -> *mut f32 {
        self.carrier.as_mut_ptr()
    }

    /// After [`Self::apply`]: the bones' world matrices and the skins' matrices (nothing without
    /// `enable_skinning`).
    pub fn skin(&mut self) {
        let carrier = Mat4::from_cols_array(&self.carrier);
        let hips = Vec3::from_array(self.hips_position);
        if let Some(s) = &mut self.skinning {
            s.update(&carrier, &self.local_rotations, hips);
        }
    }

    /// `T×16` f32: every bone's world matrix after `skin` (null before `enable_skinning`).
    pub fn world_matrices_ptr(&self) -> *const f32 {
        self.skinning.as_ref().map_or(std::ptr::null(), |s| s.world().as_ptr().cast())
    }

    /// Skin `s`'s matrices after `skin`, 16 f32 per slot (null for a skin that is not there).
    pub fn skin_matrices_ptr(&self, s: usize) -> *const f32 {
        self.skinning.as_ref().filter(|k| s < k.num_skins()).map_or(std::ptr::null(), |k| k.skin(s).as_ptr().cast())
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
