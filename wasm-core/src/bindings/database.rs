//! `RawDatabase`: a loaded `.mmdb` with its search index, shared by every character made from it.

use super::{js_error, Kind, LiveToken};
use crate::database::Database;
use crate::search::SearchIndex;
use crate::{format, inspect};
use glam::{Quat, Vec3};
use std::rc::Rc;
use wasm_bindgen::prelude::*;

/// What characters share: the database, its index, and its planted toe height.
pub(crate) struct Shared {
    pub db: Database,
    pub index: SearchIndex,
    pub toe_floor: Option<f32>,
    /// The file's CRC-32 (its header's): a first part names its whole by it.
    pub checksum: u32,
}

/// A loaded motion database plus FK scratch buffers (so per-frame calls never allocate).
#[wasm_bindgen]
pub struct RawDatabase {
    pub(crate) shared: Rc<Shared>,
    world_positions: Vec<Vec3>,
    world_rotations: Vec<Quat>,
    _live: LiveToken,
}

#[wasm_bindgen]
impl RawDatabase {
    /// Parses and validates `.mmdb` bytes and builds the search index; throws an `Error` saying
    /// what is wrong.
    #[wasm_bindgen(constructor)]
    pub fn new(bytes: &[u8]) -> Result<RawDatabase, JsError> {
        let db = format::from_bytes(bytes).map_err(js_error)?;
        let index = SearchIndex::new(&db).map_err(js_error)?;
        let j = db.num_joints();
        let toe_floor = db.toe_height_in_contact();
        // A file that loaded has its 32-byte header.
        let checksum = u32::from_le_bytes([bytes[24], bytes[25], bytes[26], bytes[27]]);
        Ok(RawDatabase {
            shared: Rc::new(Shared { db, index, toe_floor, checksum }),
            world_positions: vec![Vec3::ZERO; j],
            world_rotations: vec![Quat::IDENTITY; j],
            _live: LiveToken::new(Kind::Database),
        })
    }

    fn db(&self) -> &Database {
        &self.shared.db
    }

    pub fn num_frames(&self) -> usize {
        self.db().num_frames
    }
    pub fn num_joints(&self) -> usize {
        self.db().num_joints()
    }
    pub fn num_features(&self) -> usize {
        self.db().num_features()
    }
    pub fn fps(&self) -> f32 {
        self.db().fps
    }
    /// Index of the clip containing `frame` (clamped into range).
    pub fn clip_at(&self, frame: usize) -> usize {
        let db = self.db();
        db.clip_at(frame.min(db.num_frames.saturating_sub(1)))
    }
    /// When this database is the first part of a larger one: the whole's file name (beside
    /// this file); otherwise undefined.
    pub fn whole_name(&self) -> Option<String> {
        self.db().part.as_ref().map(|p| p.whole.clone())
    }

    /// Whether `whole` is the database this one is the first part of (its frame count and
    /// file checksum are the ones the part names).
    pub fn is_part_of(&self, whole: &RawDatabase) -> bool {
        super::character::database_is_whole(&self.shared, &whole.shared)
    }

    /// The same JSON as `mmdb inspect --json`: joints, sites (roles), clips, tags, features,
    /// and the scans of its arrays (feature ranges, contact shares).
    pub fn inspect_json(&self) -> String {
        inspect::summary(self.db(), None).to_string()
    }

    /// What a page needs of [`Self::inspect_json`] to run the database (no scan of its arrays:
    /// read at every load, before the first frame).
    pub fn header_json(&self) -> String {
        inspect::header(self.db(), self.shared.toe_floor).to_string()
    }

    /// `F×J×3` f32 local positions.
    pub fn local_positions_ptr(&self) -> *const f32 {
        self.db().local_positions.as_ptr().cast()
    }
    /// `F×J×4` f32 local rotations (x, y, z, w).
    pub fn local_rotations_ptr(&self) -> *const f32 {
        self.db().local_rotations.as_ptr().cast()
    }
    /// `F×2` u8 contacts (left, right).
    pub fn contacts_ptr(&self) -> *const u8 {
        self.db().contacts.as_ptr()
    }
    /// `F×D` f32 normalized features.
    pub fn features_ptr(&self) -> *const f32 {
        self.db().features.as_ptr()
    }

    /// World pose of `frame` (clamped into range) by the one FK into the internal buffers;
    /// returns the pointer to `J×3` f32 world positions. Rotations: [`Self::world_rotations_ptr`].
    pub fn world_positions(&mut self, frame: usize) -> *const f32 {
        let frame = frame.min(self.shared.db.num_frames.saturating_sub(1));
        self.shared.db.forward_kinematics(frame, &mut self.world_positions, &mut self.world_rotations);
        self.world_positions.as_ptr().cast()
    }
    /// `J×4` f32 world rotations from the last [`Self::world_positions`] call.
    pub fn world_rotations_ptr(&self) -> *const f32 {
        self.world_rotations.as_ptr().cast()
    }
    /// Rest pose (identity rotations, virtual root at the origin): `J×3` f32 world positions,
    /// written to the same buffer as [`Self::world_positions`].
    pub fn rest_positions(&mut self) -> *const f32 {
        let rest = self.shared.db.rest_positions();
        self.world_positions.copy_from_slice(&rest);
        self.world_rotations.fill(Quat::IDENTITY);
        self.world_positions.as_ptr().cast()
    }
}
