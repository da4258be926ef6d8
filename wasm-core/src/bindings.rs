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
        self.db.forward_kinematics(frame, &mut self.world_positions, &mut self.world_rotations);
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

// ---- character bindings

/// Characters animated by motion matching on one database (one character is a crowd of one).
/// Pose buffers live in WASM memory: read them through the `*_ptr` views, no copies.
#[wasm_bindgen]
pub struct RawCrowd {
    db: crate::Database,
    index: crate::search::SearchIndex,
    crowd: crate::crowd::Crowd,
    scratch: [f32; 7],
}

#[wasm_bindgen]
impl RawCrowd {
    /// Loads `.mmdb` bytes and places `count` characters on a 2 m grid.
    #[wasm_bindgen(constructor)]
    pub fn new(bytes: &[u8], count: usize) -> Result<RawCrowd, JsError> {
        let db = format::from_bytes(bytes).map_err(js_error)?;
        let index = crate::search::SearchIndex::new(&db).map_err(js_error)?;
        let crowd = crate::crowd::Crowd::new(&db, count, &crate::character::CharacterSettings::default());
        Ok(RawCrowd { db, index, crowd, scratch: [0.0; 7] })
    }

    pub fn num_characters(&self) -> usize {
        self.crowd.characters.len()
    }
    pub fn num_joints(&self) -> usize {
        self.db.num_joints()
    }

    /// Input of character `i`: move direction (x, z) with length 0–1, facing (x, z) used when
    /// strafing, run and strafe flags. Out-of-range `i` is ignored.
    #[allow(clippy::too_many_arguments)]
    pub fn set_input(&mut self, i: usize, move_x: f32, move_z: f32, face_x: f32, face_z: f32, run: bool, strafe: bool) {
        if let Some(input) = self.crowd.inputs.get_mut(i) {
            *input = crate::controller::Input {
                direction: glam::Vec2::new(move_x, move_z),
                facing: glam::Vec2::new(face_x, face_z),
                run,
                strafe,
            };
        }
    }

    /// Makes character `i` follow a path on the floor: `points` as x, z pairs (≥ 2 points),
    /// `speeds` in m/s per segment (one fewer than the points, or as many when `looped`).
    /// Throws with the reason on a bad path; the character keeps its current control then.
    pub fn set_path(&mut self, i: usize, points: &[f32], speeds: &[f32], looped: bool) -> Result<(), JsError> {
        if points.len() % 2 != 0 {
            return Err(JsError::new(&format!("path points must be x, z pairs, got {} numbers", points.len())));
        }
        let points: Vec<glam::Vec3> = points.chunks_exact(2).map(|p| glam::Vec3::new(p[0], 0.0, p[1])).collect();
        let path = crate::controller::Path::new(&points, speeds, looped).map_err(|e| JsError::new(&e))?;
        let c = self.crowd.characters.get_mut(i).ok_or_else(|| JsError::new(&format!("no character {i}")))?;
        c.set_path(Some(path));
        Ok(())
    }

    /// Makes character `i` follow a tracked user (VR); call every frame. `head_x, head_z`: the
    /// head centre on the floor (m); `velocity_x, velocity_z`: its raw ground velocity (m/s);
    /// `yaw`: the predicted body yaw (rad, 0 = +Z). The runtime smooths velocity and yaw.
    pub fn set_tracked(&mut self, i: usize, head_x: f32, head_z: f32, velocity_x: f32, velocity_z: f32, yaw: f32) {
        if let Some(c) = self.crowd.characters.get_mut(i) {
            c.set_tracked(crate::character::Tracked {
                position: glam::Vec3::new(head_x, 0.0, head_z),
                velocity: glam::Vec3::new(velocity_x, 0.0, velocity_z),
                yaw,
            });
        }
    }

    /// Lowers character `i`'s hips `drop` m below the animation, legs bent by IK to keep the
    /// feet planted (VR crouching).
    pub fn set_hips_drop(&mut self, i: usize, drop: f32) {
        if let Some(c) = self.crowd.characters.get_mut(i) {
            c.set_hips_drop(drop);
        }
    }

    /// Places character `i` at (x, z) facing `yaw` (rad, 0 = +Z), searching afresh — e.g. to
    /// carry a character over to a crowd on another database.
    pub fn teleport(&mut self, i: usize, x: f32, z: f32, yaw: f32) {
        if let Some(c) = self.crowd.characters.get_mut(i) {
            c.teleport(&self.db, glam::Vec3::new(x, 0.0, z), glam::Quat::from_rotation_y(yaw));
        }
    }

    /// Returns character `i` to input control (from a path or a tracked user).
    pub fn clear_path(&mut self, i: usize) {
        if let Some(c) = self.crowd.characters.get_mut(i) {
            c.set_path(None);
        }
    }

    /// Search method of every character: 0 scalar, 1 SIMD, 2 AABB (default).
    pub fn set_search_method(&mut self, method: u32) {
        if let Some(m) = crate::search::SearchMethod::from_index(method) {
            self.crowd.characters.iter_mut().for_each(|c| c.settings.search_method = m);
        }
    }

    /// Advances every character by `dt` seconds.
    pub fn update(&mut self, dt: f32) {
        self.crowd.update(&self.db, &self.index, dt);
    }

    /// `J×3` f32: joint 0 the root's world position, others local positions.
    pub fn pose_positions_ptr(&self, i: usize) -> *const f32 {
        self.crowd.characters[i].pose_positions().as_ptr().cast()
    }
    /// `J×4` f32 (x, y, z, w): joint 0 the root's world rotation, others local rotations.
    pub fn pose_rotations_ptr(&self, i: usize) -> *const f32 {
        self.crowd.characters[i].pose_rotations().as_ptr().cast()
    }
    pub fn frame(&self, i: usize) -> usize {
        self.crowd.characters[i].frame()
    }
    /// Contacts of character `i` as bits: 1 left, 2 right.
    pub fn contacts(&self, i: usize) -> u32 {
        let [l, r] = self.crowd.characters[i].contacts();
        l as u32 | (r as u32) << 1
    }
    /// Settings of every character as JSON (`CharacterSettings` fields; missing ones keep
    /// their value, unknown ones throw): `{"beta_pose": 1.5, "clamp_distance": 0.2}`.
    pub fn set_settings_json(&mut self, json: &str) -> Result<(), JsError> {
        let patch: serde_json::Value = serde_json::from_str(json).map_err(|e| JsError::new(&format!("settings: {e}")))?;
        let Some(patch) = patch.as_object() else {
            return Err(JsError::new("settings: expected a JSON object"));
        };
        let _ = patch;
        for c in &mut self.crowd.characters {
            c.settings = c.settings.patched(json).map_err(|e| JsError::new(&e))?;
        }
        Ok(())
    }
    /// The settings of character `i` as JSON.
    pub fn settings_json(&self, i: usize) -> String {
        serde_json::to_string(&self.crowd.characters[i].settings).unwrap_or_default()
    }

    // Debug views (zero-copy where they are arrays).

    /// Simulated character of `i`: position (3) then facing quaternion (4), in a buffer
    /// reused by every call.
    pub fn simulation_ptr(&mut self, i: usize) -> *const f32 {
        let (p, q) = self.crowd.characters[i].simulation_transform();
        self.scratch[..3].copy_from_slice(&p.to_array());
        self.scratch[3..7].copy_from_slice(&q.to_array());
        self.scratch.as_ptr()
    }
    /// Number of predicted trajectory points (the feature offsets ahead).
    pub fn num_predictions(&self) -> usize {
        self.crowd.characters.first().map_or(0, |c| c.predicted_positions().len())
    }
    /// `K×3` world positions of the predicted trajectory at the last search.
    pub fn predicted_positions_ptr(&self, i: usize) -> *const f32 {
        self.crowd.characters[i].predicted_positions().as_ptr().cast()
    }
    /// `K×4` world facings of the predicted trajectory at the last search.
    pub fn predicted_rotations_ptr(&self, i: usize) -> *const f32 {
        self.crowd.characters[i].predicted_rotations().as_ptr().cast()
    }
    /// `D` normalized features of the last query (what was asked for).
    pub fn query_ptr(&self, i: usize) -> *const f32 {
        self.crowd.characters[i].query().as_ptr()
    }
    /// `D` normalized features of the frame playing (what was matched).
    pub fn current_features_ptr(&self, i: usize) -> *const f32 {
        self.db.feature(self.crowd.characters[i].frame()).as_ptr()
    }
    pub fn num_features(&self) -> usize {
        self.db.num_features()
    }
    /// Index of the clip playing for character `i` (names via the database's inspect JSON).
    pub fn clip(&self, i: usize) -> usize {
        self.db.clip_at(self.crowd.characters[i].frame())
    }
    /// Cost of the playing frame and of the chosen one at the last search.
    pub fn search_cost(&self, i: usize) -> f32 {
        self.crowd.characters[i].stats.current_cost
    }
    pub fn best_cost(&self, i: usize) -> f32 {
        self.crowd.characters[i].stats.best_cost
    }
    /// Foot locks of character `i` as bits: 1 left, 2 right.
    pub fn foot_locks(&self, i: usize) -> u32 {
        let [l, r] = self.crowd.characters[i].foot_locked();
        l as u32 | (r as u32) << 1
    }
    /// Same JSON as `mmdb inspect --json` for the crowd's database.
    pub fn inspect_json(&self) -> String {
        inspect::summary(&self.db, None).to_string()
    }

    pub fn searches(&self, i: usize) -> f64 {
        self.crowd.characters[i].stats.searches as f64
    }
    pub fn transitions(&self, i: usize) -> f64 {
        self.crowd.characters[i].stats.transitions as f64
    }
}

// ---- search bindings (begin)
// Motion-matching search (crate::search::SearchIndex). JS writes the normalized query into a
// Float32Array over `query_ptr()`, then calls `search(...)`: no allocation and no copy per call.

use crate::database::Tag;
use crate::search::{SearchIndex, SearchMethod, SearchOptions};

/// A search index over a database's features, plus the query buffer JS fills and the active
/// tag mask.
#[wasm_bindgen]
pub struct RawSearchIndex {
    index: SearchIndex,
    query: Vec<f32>,
    tags: Vec<Tag>,
    /// Per frame, used when `mask_active`.
    mask: Vec<bool>,
    mask_active: bool,
    last_cost: f32,
}

#[wasm_bindgen]
impl RawSearchIndex {
    /// Parses `.mmdb` bytes and builds the index; keeps only what the search needs (features,
    /// validity, tags), not the poses. Throws an `Error` saying what is wrong.
    #[wasm_bindgen(constructor)]
    pub fn new(bytes: &[u8]) -> Result<RawSearchIndex, JsError> {
        let db = format::from_bytes(bytes).map_err(js_error)?;
        Self::build(&db)
    }

    /// Builds the index of an already loaded database (no second parse).
    pub fn from_database(database: &RawDatabase) -> Result<RawSearchIndex, JsError> {
        Self::build(&database.db)
    }

    fn build(db: &Database) -> Result<RawSearchIndex, JsError> {
        let index = SearchIndex::new(db).map_err(js_error)?;
        Ok(RawSearchIndex {
            query: vec![0.0; index.num_dims()],
            mask: vec![false; index.num_frames()],
            index,
            tags: db.tags.clone(),
            mask_active: false,
            last_cost: f32::NAN,
        })
    }

    pub fn num_frames(&self) -> usize {
        self.index.num_frames()
    }
    pub fn num_features(&self) -> usize {
        self.index.num_dims()
    }

    /// Whether a search may return `frame` (false near clip ends and out of range).
    pub fn is_valid(&self, frame: usize) -> bool {
        self.index.is_valid(frame)
    }

    /// `num_features()` f32: the normalized query, written by JS before `search` / `cost`.
    pub fn query_ptr(&mut self) -> *mut f32 {
        self.query.as_mut_ptr()
    }

    /// Restricts later searches to the frames tagged `tag`; returns false (and clears the
    /// restriction) when the database has no such tag.
    pub fn use_tag(&mut self, tag: &str) -> bool {
        self.mask.fill(false);
        self.mask_active = false;
        let Some(tag) = self.tags.iter().find(|t| t.name == tag) else { return false };
        for &(start, end) in &tag.ranges {
            self.mask[start as usize..end as usize].fill(true);
        }
        self.mask_active = true;
        true
    }

    /// Lifts the tag restriction.
    pub fn clear_tag(&mut self) {
        self.mask_active = false;
    }

    /// Searches for the query in `query_ptr()`: method 0 scalar, 1 SIMD, 2 AABB (all return
    /// the same result). Frames `[exclude_from, exclude_to)` are skipped (none when
    /// `exclude_to <= exclude_from`); β's below 0 count as 0. Returns the best frame whose cost
    /// is strictly below `bar` (`Infinity` for the overall best) and stores its cost for
    /// `last_cost()`, or returns -1 (and `last_cost()` is NaN) when there is none.
    pub fn search(&mut self, method: u32, beta_pose: f32, beta_trajectory: f32, exclude_from: i32, exclude_to: i32, bar: f32) -> Result<i32, JsError> {
        let method = SearchMethod::from_index(method).ok_or_else(|| JsError::new(&format!("search method {method}: expected 0 (scalar), 1 (simd) or 2 (aabb)")))?;
        let options = self.options(beta_pose, beta_trajectory, exclude_from, exclude_to);
        let found = self.index.search(method, &self.query, &options, bar);
        self.last_cost = found.map_or(f32::NAN, |(_, cost)| cost);
        Ok(found.map_or(-1, |(frame, _)| frame as i32))
    }

    /// Cost of the last found frame, NaN after a search that found none.
    pub fn last_cost(&self) -> f32 {
        self.last_cost
    }

    /// Cost of `frame` for the query in `query_ptr()` (the `bar` when searching from it);
    /// NaN when `frame` is out of range.
    pub fn cost(&self, frame: usize, beta_pose: f32, beta_trajectory: f32) -> f32 {
        if frame >= self.index.num_frames() {
            return f32::NAN;
        }
        self.index.cost(frame, &self.query, &self.options(beta_pose, beta_trajectory, 0, 0))
    }

    /// The lane backend compiled in: `"simd128"` in the SIMD build, `"scalar"` otherwise.
    pub fn backend() -> String {
        crate::lanes::BACKEND.to_string()
    }

    fn options(&self, beta_pose: f32, beta_trajectory: f32, exclude_from: i32, exclude_to: i32) -> SearchOptions<'_> {
        SearchOptions {
            // `max` also maps NaN to 0: the box bounds need non-negative weights.
            beta_pose: beta_pose.max(0.0),
            beta_trajectory: beta_trajectory.max(0.0),
            exclude: (exclude_to > exclude_from).then(|| (exclude_from.max(0) as usize, exclude_to.max(0) as usize)),
            mask: self.mask_active.then_some(self.mask.as_slice()),
        }
    }
}
// ---- search bindings (end)
