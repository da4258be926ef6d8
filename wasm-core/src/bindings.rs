//! The only JS-facing file: thin `Raw*` wrappers over the core, mirrored one-to-one by the
//! TypeScript classes in `web/src/core/`, which own their lifetime (`free()`).
//! Arrays are exposed as pointers into WASM memory so TS reads them as zero-copy views.

use crate::builder::{self, Source};
use crate::config::BuildConfig;
use crate::database::Database;
use crate::{format, inspect, Bvh, Error};
use glam::{Quat, Vec3};
use wasm_bindgen::prelude::*;

fn js_error(e: Error) -> JsError {
    JsError::new(&e.to_string())
}

/// A loaded motion database plus FK scratch buffers (so per-frame calls never allocate).
#[wasm_bindgen]
pub struct RawDatabase {
    db: Database,
    world_positions: Vec<Vec3>,
    world_rotations: Vec<Quat>,
}

#[wasm_bindgen]
impl RawDatabase {
    /// Parses and validates `.mmdb` bytes; throws an `Error` saying what is wrong.
    #[wasm_bindgen(constructor)]
    pub fn new(bytes: &[u8]) -> Result<RawDatabase, JsError> {
        let db = format::from_bytes(bytes).map_err(js_error)?;
        let j = db.num_joints();
        Ok(RawDatabase { db, world_positions: vec![Vec3::ZERO; j], world_rotations: vec![Quat::IDENTITY; j] })
    }

    pub fn num_frames(&self) -> usize {
        self.db.num_frames
    }
    pub fn num_joints(&self) -> usize {
        self.db.num_joints()
    }
    pub fn num_features(&self) -> usize {
        self.db.num_features()
    }
    pub fn num_clips(&self) -> usize {
        self.db.clips.len()
    }
    pub fn fps(&self) -> f32 {
        self.db.fps
    }
    pub fn joint_name(&self, joint: usize) -> String {
        self.db.skeleton.names.get(joint).cloned().unwrap_or_default()
    }
    /// Parent joint index, `-1` for the root (and for an out-of-range joint).
    pub fn joint_parent(&self, joint: usize) -> i32 {
        self.db.skeleton.parents.get(joint).copied().unwrap_or(-1)
    }
    pub fn clip_name(&self, clip: usize) -> String {
        self.db.clips.get(clip).map(|c| c.name.clone()).unwrap_or_default()
    }
    pub fn clip_start(&self, clip: usize) -> u32 {
        self.db.clips.get(clip).map_or(0, |c| c.start)
    }
    pub fn clip_end(&self, clip: usize) -> u32 {
        self.db.clips.get(clip).map_or(0, |c| c.end)
    }
    pub fn clip_mirrored(&self, clip: usize) -> bool {
        self.db.clips.get(clip).is_some_and(|c| c.mirrored)
    }
    /// Index of the clip containing `frame` (clamped into range).
    pub fn clip_at(&self, frame: usize) -> usize {
        self.db.clip_at(frame.min(self.db.num_frames - 1))
    }
    /// The same JSON as `mmdb inspect --json`.
    pub fn inspect_json(&self) -> String {
        inspect::summary(&self.db, None).to_string()
    }

    /// `F×J×3` f32 local positions.
    pub fn local_positions_ptr(&self) -> *const f32 {
        self.db.local_positions.as_ptr().cast()
    }
    /// `F×J×4` f32 local rotations (x, y, z, w).
    pub fn local_rotations_ptr(&self) -> *const f32 {
        self.db.local_rotations.as_ptr().cast()
    }
    pub fn local_velocities_ptr(&self) -> *const f32 {
        self.db.local_velocities.as_ptr().cast()
    }
    pub fn local_angular_velocities_ptr(&self) -> *const f32 {
        self.db.local_angular_velocities.as_ptr().cast()
    }
    /// `F×2` u8 contacts (left, right).
    pub fn contacts_ptr(&self) -> *const u8 {
        self.db.contacts.as_ptr()
    }
    /// `F×D` f32 normalized features.
    pub fn features_ptr(&self) -> *const f32 {
        self.db.features.as_ptr()
    }

    /// Forward kinematics of `frame` (clamped into range) into the internal buffers; returns
    /// the pointer to `J×3` f32 world positions. Rotations: [`Self::world_rotations_ptr`].
    pub fn world_positions(&mut self, frame: usize) -> *const f32 {
        let frame = frame.min(self.db.num_frames - 1);
        self.db.forward_kinematics(frame, false, &mut self.world_positions, &mut self.world_rotations);
        self.world_positions.as_ptr().cast()
    }
    /// `J×4` f32 world rotations from the last [`Self::world_positions`] call.
    pub fn world_rotations_ptr(&self) -> *const f32 {
        self.world_rotations.as_ptr().cast()
    }
}

/// Builds a database in the page from BVH files (drag and drop): add files, then `build()`.
#[wasm_bindgen]
pub struct RawBuilder {
    config: BuildConfig,
    sources: Vec<Source>,
    warnings: Vec<String>,
}

#[wasm_bindgen]
impl RawBuilder {
    /// `config_json` uses the `mmdb build --config` schema; `"{}"` means the defaults.
    #[wasm_bindgen(constructor)]
    pub fn new(config_json: &str) -> Result<RawBuilder, JsError> {
        let config = BuildConfig::from_json(config_json).map_err(js_error)?;
        Ok(RawBuilder { config, sources: Vec::new(), warnings: Vec::new() })
    }

    /// Parses a BVH file now, so a bad file is reported (file:line) when it is added.
    pub fn add_bvh(&mut self, name: &str, bytes: &[u8]) -> Result<(), JsError> {
        let bvh = Bvh::parse(name, bytes).map_err(js_error)?;
        self.sources.push(Source { name: name.to_string(), bvh });
        Ok(())
    }

    pub fn num_files(&self) -> usize {
        self.sources.len()
    }

    /// The `.mmdb` bytes of a database built from the added files.
    pub fn build(&mut self) -> Result<Vec<u8>, JsError> {
        let out = builder::build(&self.config, &self.sources).map_err(js_error)?;
        self.warnings = out.warnings;
        Ok(format::to_bytes(&out.database))
    }

    /// Warnings of the last build, as a JSON array of strings.
    pub fn warnings_json(&self) -> String {
        serde_json::to_string(&self.warnings).unwrap_or_default()
    }
}

/// Parses BVH bytes and returns a JSON summary (joints, frames, fps); throws on bad input.
#[wasm_bindgen]
pub fn bvh_info(name: &str, bytes: &[u8]) -> Result<String, JsError> {
    let bvh = Bvh::parse(name, bytes).map_err(js_error)?;
    Ok(serde_json::json!({
        "num_joints": bvh.joints.len(),
        "num_frames": bvh.num_frames,
        "fps": bvh.fps(),
        "joints": bvh.joints.iter().map(|j| j.name.as_str()).collect::<Vec<_>>(),
    })
    .to_string())
}
