//! `RawCharacter`: one motion-matched character on a shared database. The per-frame recipe's
//! runtime half: input → update → world pose, read as zero-copy views.

use super::database::{RawDatabase, Shared};
use super::{Kind, LiveToken};
use crate::character::drive::DriveInput;
use crate::character::{Character, CharacterSettings};
use crate::controller::{Input, Path};
use crate::database::{Axes, FeatureKind};
use glam::{Quat, Vec3};
use std::rc::Rc;
use wasm_bindgen::prelude::*;

#[wasm_bindgen]
pub struct RawCharacter {
    shared: Rc<Shared>,
    pub(crate) character: Character,
    input: Input,
    /// Root x, y, z, yaw; simulation position (3) and facing (4); toes (6): per-frame outputs.
    root: [f32; 4],
    simulation: [f32; 7],
    toes: [f32; 6],
    /// The drive value, flat in `DriveInput::FIELDS` order: JS writes it in place (`drive_ptr`),
    /// then `apply_drive` reads it — no copy or allocation per frame.
    drive: [f32; DriveInput::FIELDS.len()],
    /// Matched trajectory (world x, z, direction x, z per point).
    matched: Vec<f32>,
    _live: LiveToken,
}

#[wasm_bindgen]
impl RawCharacter {
    /// A character standing at the origin facing +Z on `database` (shared, not copied), with
    /// the default settings patched by `settings_json` (`"{}"` for none).
    #[wasm_bindgen(constructor)]
    pub fn new(database: &RawDatabase, settings_json: &str) -> Result<RawCharacter, JsError> {
        let shared = Rc::clone(&database.shared);
        let settings = CharacterSettings::default().patched(settings_json).map_err(|e| JsError::new(&e))?;
        let mut character = Character::new(&shared.db, settings);
        character.set_toe_floor(shared.toe_floor);
        let points = shared
            .db
            .groups
            .iter()
            .find(|g| g.is_trajectory && g.kind == FeatureKind::Position)
            .map_or(0, |g| g.offsets.len());
        let mut c = RawCharacter {
            shared,
            character,
            input: Input::default(),
            root: [0.0; 4],
            simulation: [0.0; 7],
            toes: [0.0; 6],
            drive: [0.0; DriveInput::FIELDS.len()],
            matched: vec![0.0; points * 4],
            _live: LiveToken::new(Kind::Character),
        };
        c.write_outputs();
        Ok(c)
    }

    /// Where JS writes the drive value for the next `update`: `DriveInput::FIELDS.len()` f32 in
    /// that order (database units; `web/src/core/drive.ts` writes it), then `apply_drive`.
    pub fn drive_ptr(&mut self) -> *mut f32 {
        self.drive.as_mut_ptr()
    }

    /// Takes the drive value written at `drive_ptr`. Throws on an unknown mode; nothing changes then.
    pub fn apply_drive(&mut self) -> Result<(), JsError> {
        let drive = DriveInput::from_flat(&self.drive).map_err(|e| JsError::new(&e))?;
        self.input = drive.input;
        self.character.set_drive(&drive);
        Ok(())
    }

    /// The drive value's field names in their flat order, comma-separated (the TS mirror's
    /// test compares its own).
    pub fn drive_fields() -> String {
        DriveInput::FIELDS.join(",")
    }

    /// Follow a path on the floor: `points` as x, z pairs (≥ 2 points), `speeds` in m/s per
    /// segment (one fewer than the points, or as many when `looped`). Throws with the reason on
    /// a bad path; the character keeps its current drive then.
    pub fn set_path(&mut self, points: &[f32], speeds: &[f32], looped: bool) -> Result<(), JsError> {
        if !points.len().is_multiple_of(2) {
            return Err(JsError::new(&format!("path points must be x, z pairs, got {} numbers", points.len())));
        }
        let points: Vec<Vec3> = points.chunks_exact(2).map(|p| Vec3::new(p[0], 0.0, p[1])).collect();
        let path = Path::new(&points, speeds, looped).map_err(|e| JsError::new(&e))?;
        self.character.set_path(Some(path));
        Ok(())
    }

    /// VR: a head `head_drop` m below standing, headset pitched `pitch` rad → hips drop and torso
    /// bend (`crouch::split`); read them back with `hips_drop` and `torso_bend`.
    pub fn set_crouch(&mut self, head_drop: f32, pitch: f32) {
        self.character.set_crouch(head_drop, pitch);
    }

    pub fn hips_drop(&self) -> f32 {
        self.character.crouch().hips_drop
    }

    pub fn torso_bend(&self) -> f32 {
        self.character.crouch().bend
    }

    /// Moves the character from the first part it plays to `whole`, the database the part
    /// names (`RawDatabase::is_part_of`), playing the same frame there: nothing it shows
    /// changes. Throws, changing nothing, when `whole` is not that database.
    pub fn enter_whole(&mut self, whole: &RawDatabase) -> Result<(), JsError> {
        let part = match &self.shared.db.part {
            Some(part) if database_is_whole(&self.shared, &whole.shared) => part.clone(),
            Some(part) => {
                return Err(JsError::new(&format!(
                    "this database is the first part of {} ({} frames, checksum {:08x}), not of the one given ({} frames, checksum {:08x})",
                    part.whole,
                    part.whole_frames,
                    part.whole_checksum,
                    whole.shared.db.num_frames,
                    whole.shared.checksum
                )))
            }
            None => return Err(JsError::new("the character's database is not a first part")),
        };
        self.character.enter_whole(&part);
        self.character.set_toe_floor(whole.shared.toe_floor);
        self.shared = Rc::clone(&whole.shared);
        Ok(())
    }

    /// Places the character at (x, z) facing `yaw` (rad, 0 = +Z), searching afresh.
    pub fn teleport(&mut self, x: f32, z: f32, yaw: f32) {
        self.character.teleport(&self.shared.db, Vec3::new(x, 0.0, z), Quat::from_rotation_y(yaw));
        self.write_outputs();
    }

    /// Places the character like `teleport` and plays database `frame` from there, moving as
    /// that frame moves (a late joiner's copy of someone walking; see `Character::teleport_playing`).
    pub fn teleport_playing(&mut self, frame: usize, x: f32, z: f32, yaw: f32) {
        self.character.teleport_playing(&self.shared.db, frame, Vec3::new(x, 0.0, z), Quat::from_rotation_y(yaw));
        self.write_outputs();
    }

    /// The runtime state as bytes (`Character::save_state`): what a shared room sends a late
    /// joiner so that its copy continues from this character's own floats.
    pub fn save_state(&self) -> Vec<u8> {
        self.character.save_state(&self.shared.db)
    }

    /// Continues from `save_state` bytes of a character on the same database (a path it follows
    /// must be set first). Throws with the reason on bytes it refuses; the character is unchanged then.
    pub fn load_state(&mut self, bytes: &[u8]) -> Result<(), JsError> {
        self.character.load_state(&self.shared.db, bytes).map_err(|e| JsError::new(&e))?;
        self.write_outputs();
        Ok(())
    }

    /// Settings patch as JSON (`CharacterSettings` fields; unknown ones throw).
    pub fn set_settings_json(&mut self, json: &str) -> Result<(), JsError> {
        self.character.settings = self.character.settings.patched(json).map_err(|e| JsError::new(&e))?;
        Ok(())
    }
    pub fn settings_json(&self) -> String {
        serde_json::to_string(&self.character.settings).unwrap_or_default()
    }

    /// Advances the character by `dt` seconds.
    pub fn update(&mut self, dt: f32) {
        let s = &*self.shared;
        self.character.update(&s.db, &s.index, &self.input, dt);
        self.write_outputs();
    }

    fn write_outputs(&mut self) {
        let c = &self.character;
        let (p, q) = (c.root_position(), c.root_rotation());
        let forward = q * Vec3::Z;
        self.root = [p.x, p.y, p.z, forward.x.atan2(forward.z)];
        let (sp, sq) = c.simulation_transform();
        self.simulation[..3].copy_from_slice(&sp.to_array());
        self.simulation[3..].copy_from_slice(&sq.to_array());
        let [l, r] = c.toes();
        self.toes[..3].copy_from_slice(&l.to_array());
        self.toes[3..].copy_from_slice(&r.to_array());
    }

    /// `J×3` f32 world positions of the shown pose.
    pub fn world_positions_ptr(&self) -> *const f32 {
        self.character.world_positions().as_ptr().cast()
    }
    /// `J×4` f32 world rotations (x, y, z, w) of the shown pose.
    pub fn world_rotations_ptr(&self) -> *const f32 {
        self.character.world_rotations().as_ptr().cast()
    }
    /// 4 f32: root x, y, z (m) and yaw (rad, 0 = +Z).
    pub fn root_ptr(&self) -> *const f32 {
        self.root.as_ptr()
    }
    /// 7 f32: the simulated character's position (3) and facing quaternion (4).
    pub fn simulation_ptr(&self) -> *const f32 {
        self.simulation.as_ptr()
    }
    /// 6 f32: the toe points (left xyz, right xyz) of the shown pose.
    pub fn toes_ptr(&self) -> *const f32 {
        self.toes.as_ptr()
    }
    /// Number of predicted trajectory points.
    pub fn num_predictions(&self) -> usize {
        self.character.predicted_positions().len()
    }
    /// `K×3` world positions of the predicted trajectory at the last search.
    pub fn predicted_positions_ptr(&self) -> *const f32 {
        self.character.predicted_positions().as_ptr().cast()
    }
    /// `K×4` world facings of the predicted trajectory at the last search.
    pub fn predicted_rotations_ptr(&self) -> *const f32 {
        self.character.predicted_rotations().as_ptr().cast()
    }
    /// Number of points of [`Self::matched_trajectory`].
    pub fn num_matched(&self) -> usize {
        self.matched.len() / 4
    }
    /// The trajectory stored with the frame playing (what was matched), in the world: per
    /// point x, z and a facing direction x, z. Returns a pointer to `K×4` f32.
    pub fn matched_trajectory(&mut self) -> *const f32 {
        let db = &self.shared.db;
        let (p, q) = (self.character.root_position(), self.character.root_rotation());
        let f = db.feature(self.character.frame());
        let raw = |d: usize| f[d] * db.feature_scale[d] + db.feature_mean[d];
        let position =
            db.groups.iter().find(|g| g.is_trajectory && g.kind == FeatureKind::Position && g.axes == Axes::Xz);
        let direction =
            db.groups.iter().find(|g| g.is_trajectory && g.kind == FeatureKind::Direction && g.axes == Axes::Xz);
        if let Some(g) = position {
            for k in 0..g.offsets.len().min(self.matched.len() / 4) {
                let d = g.first_dim + 2 * k;
                let at = p + q * Vec3::new(raw(d), 0.0, raw(d + 1));
                let dir = match direction.filter(|h| h.offsets.len() == g.offsets.len()) {
                    Some(h) => q * Vec3::new(raw(h.first_dim + 2 * k), 0.0, raw(h.first_dim + 2 * k + 1)),
                    None => q * Vec3::Z,
                };
                self.matched[4 * k..4 * k + 4].copy_from_slice(&[at.x, at.z, dir.x, dir.z]);
            }
        }
        self.matched.as_ptr()
    }
    pub fn frame(&self) -> usize {
        self.character.frame()
    }
    /// Index of the clip playing (names in the database's inspect JSON).
    pub fn clip(&self) -> usize {
        self.shared.db.clip_at(self.character.frame())
    }
    /// Contacts of the frame playing as bits: 1 left, 2 right.
    pub fn contacts(&self) -> u32 {
        let [l, r] = self.character.contacts();
        l as u32 | (r as u32) << 1
    }
    /// Foot locks as bits: 1 left, 2 right.
    pub fn foot_locks(&self) -> u32 {
        let [l, r] = self.character.foot_locked();
        l as u32 | (r as u32) << 1
    }
    /// Feet stepping back under a dragged body (a foot lock's drift release) as bits: 1 left,
    /// 2 right. Such a foot is lifted on purpose, whatever the contact flag says.
    pub fn foot_steps(&self) -> u32 {
        let [l, r] = self.character.foot_stepping();
        l as u32 | (r as u32) << 1
    }
    pub fn searches(&self) -> f64 {
        self.character.stats.searches as f64
    }
    pub fn transitions(&self) -> f64 {
        self.character.stats.transitions as f64
    }
    /// Cost of the playing frame and of the chosen one at the last search.
    pub fn search_cost(&self) -> f32 {
        self.character.stats.current_cost
    }
    pub fn best_cost(&self) -> f32 {
        self.character.stats.best_cost
    }
    /// Refused inputs (not numbers, out of range; the last good value was used), updates whose
    /// `dt` was a gap searched afresh, and recoveries from a non-finite state, as
    /// `[rejected, gaps, recoveries]`.
    pub fn faults(&self) -> Vec<f64> {
        let s = &self.character.stats;
        vec![s.rejected_inputs as f64, s.gaps as f64, s.recoveries as f64]
    }
    /// Planted-toe sliding of the shown pose since the last teleport (m, `SkatingMeter`).
    pub fn skating(&self) -> f32 {
        self.character.skating().distance
    }
}

/// Whether `whole` is the database `part` is the first part of (frame count and checksum).
pub(crate) fn database_is_whole(part: &Shared, whole: &Shared) -> bool {
    part.db
        .part
        .as_ref()
        .is_some_and(|p| p.whole_frames as usize == whole.db.num_frames && p.whole_checksum == whole.checksum)
}
