//! `RawSearchIndex`: the motion-matching search (crate::search::SearchIndex) on its own, for
//! benchmarks and tools. JS writes the normalized query into a Float32Array over `query_ptr()`,
//! then calls `search(...)`: no allocation and no copy per call.

use super::database::RawDatabase;
use super::js_error;
use crate::database::{Database, Tag};
use crate::format;
use crate::search::{SearchIndex, SearchMethod, SearchOptions};
use wasm_bindgen::prelude::*;

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
        Self::build(&database.shared.db)
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
            // The loader checks ranges; `get_mut` keeps this total all the same.
            if let Some(frames) = self.mask.get_mut(start as usize..end as usize) {
                frames.fill(true);
            }
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
    pub fn search(
        &mut self,
        method: u32,
        beta_pose: f32,
        beta_trajectory: f32,
        exclude_from: i32,
        exclude_to: i32,
        bar: f32,
    ) -> Result<i32, JsError> {
        let method = SearchMethod::from_index(method).ok_or_else(|| {
            JsError::new(&format!("search method {method}: expected 0 (scalar), 1 (simd) or 2 (aabb)"))
        })?;
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
            ..Default::default()
        }
    }
}
