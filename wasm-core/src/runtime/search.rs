//! Finding the database frame whose features best match a query (docs/method.md §3).
//! [`brute_force`] is the scalar reference; [`SearchIndex`] runs the same search fast (SIMD
//! lanes and a tree of bounding boxes) and must equal it exactly.

use crate::aabb::{BoxBounds, BOX_FRAMES, LEVELS, PADDING};
use crate::database::Database;
use crate::lanes::{as_f32_slice, F32x4};
use crate::tag_query::{frame_tag_bits, RunBias, TagQuery, TagSummary};
use crate::{Error, Result};

/// Per-search options. `Default` is β_q = β_r = 1, no exclusion, no mask, no tag query.
#[derive(Clone, Debug)]
pub struct SearchOptions<'a> {
    /// Multiplies the pose groups' cost (quality).
    pub beta_pose: f32,
    /// Multiplies the trajectory groups' cost (responsiveness).
    pub beta_trajectory: f32,
    /// Frames `[from, to)` that may not be returned (e.g. ±20 around the current frame).
    pub exclude: Option<(usize, usize)>,
    /// A second such window (the runtime's: around the frame it last jumped away from, so two
    /// frames cannot trade places every search).
    pub exclude_recent: Option<(usize, usize)>,
    /// Only frames where the mask is true may be returned.
    pub mask: Option<&'a [bool]>,
    /// Tags a frame must carry or lack, and the bias of frames lacking the preferred ones
    /// ([`crate::tag_query`]): cost = Σ w·(q − f)² + bias.
    pub tags: TagQuery,
}

impl Default for SearchOptions<'_> {
    fn default() -> Self {
        SearchOptions {
            beta_pose: 1.0,
            beta_trajectory: 1.0,
            exclude: None,
            exclude_recent: None,
            mask: None,
            tags: TagQuery::default(),
        }
    }
}

/// Per-dimension cost weights for the given β's (pose dims β_q, trajectory dims β_r).
pub fn dimension_weights(db: &Database, beta_pose: f32, beta_trajectory: f32) -> Vec<f32> {
    let mut w = vec![1.0; db.num_features()];
    for g in &db.groups {
        w[g.first_dim..g.first_dim + g.num_dims].fill(if g.is_trajectory { beta_trajectory } else { beta_pose });
    }
    w
}

/// Normalizes a raw feature vector (database units) the way the database's rows are.
pub fn normalize_query(db: &Database, raw: &[f32]) -> Vec<f32> {
    raw.iter().zip(&db.feature_mean).zip(&db.feature_scale).map(|((x, m), s)| (x - m) / s).collect()
}

/// The `k` best valid frames for a normalized `query`, best first, as (frame, cost).
pub fn brute_force(db: &Database, query: &[f32], options: &SearchOptions, k: usize) -> Vec<(usize, f32)> {
    let d = db.num_features();
    assert_eq!(query.len(), d, "query has {} dims, the database {d}", query.len());
    let weights = dimension_weights(db, options.beta_pose, options.beta_trajectory);
    let bits = frame_tag_bits(db);
    let mut best: Vec<(usize, f32)> = Vec::with_capacity(k + 1);
    for (frame, row) in db.features.chunks_exact(d).enumerate() {
        if db.valid[frame] == 0
            || options.exclude.is_some_and(|(a, b)| (a..b).contains(&frame))
            || options.exclude_recent.is_some_and(|(a, b)| (a..b).contains(&frame))
            || options.mask.is_some_and(|m| !m[frame])
            || !options.tags.allows(bits[frame])
        {
            continue;
        }
        let sum: f32 = row.iter().zip(query).zip(&weights).map(|((f, q), w)| w * (q - f) * (q - f)).sum();
        let cost = sum + options.tags.bias(bits[frame]);
        if best.len() < k || cost < best[best.len() - 1].1 {
            let at = best.partition_point(|&(_, c)| c <= cost);
            best.insert(at, (frame, cost));
            best.truncate(k);
        }
    }
    best
}

// ------------------------------------------------------------------------------------------
// The search index: the same search, fast.
// ------------------------------------------------------------------------------------------

/// Largest feature dimension count a [`SearchIndex`] accepts. The per-search splatted query
/// and weights live on the stack (2 × 2 KiB) so a search never allocates; the default feature
/// set has 27 dims.
pub const MAX_DIMS: usize = crate::limits::MAX_FEATURE_DIMS;

/// Which search algorithm to run; all return the same result.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SearchMethod {
    /// One frame at a time, in frame order (the reference, on the index's layout).
    Scalar = 0,
    /// Four frames per lane vector, every frame.
    Simd = 1,
    /// A tree of bounding boxes (1024, 256, 64, 16 frames), SIMD inside the 16-frame boxes that survive.
    Aabb = 2,
}

impl SearchMethod {
    pub const ALL: [SearchMethod; 3] = [SearchMethod::Scalar, SearchMethod::Simd, SearchMethod::Aabb];

    /// The method numbered `index` (0 scalar, 1 SIMD, 2 AABB).
    pub fn from_index(index: u32) -> Option<Self> {
        Self::ALL.get(index as usize).copied()
    }

    pub fn name(self) -> &'static str {
        match self {
            SearchMethod::Scalar => "scalar",
            SearchMethod::Simd => "simd",
            SearchMethod::Aabb => "aabb",
        }
    }
}

/// How a dimension is weighted: the rule of [`dimension_weights`], kept per dimension so the
/// β's can change per search without a rebuild.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum DimWeight {
    Pose,
    Trajectory,
    /// Dims outside every group (not produced by the builder) weigh 1.
    One,
}

/// A database's feature matrix laid out for fast exact search, built once (see
/// [`SearchIndex::new`]) and then searched without allocating.
///
/// Frames are stored in blocks of four, transposed: block `b` holds, for each dimension `d`,
/// one lane vector with dimension `d` of frames `4b .. 4b + 4`. A kernel then computes four
/// frame costs with one lane operation per step, each lane doing exactly the scalar steps of
/// [`brute_force`] — so all three methods return the very same `(frame, cost)`, bit for bit.
/// The frame count is padded to a multiple of [`PADDING`] (four top-level boxes) with invalid
/// frames.
///
/// Search semantics (all methods): among the frames that are valid, outside
/// `options.exclude` and inside `options.mask`, the one with the lowest cost if that cost is
/// strictly below `bar`; the earliest frame wins a tie. `bar` is the current frame's cost in
/// the runtime (jump only to something strictly better), `f32::INFINITY` to always get the best.
#[derive(Clone, Debug)]
pub struct SearchIndex {
    num_frames: usize,
    num_dims: usize,
    dim_weights: Vec<DimWeight>,
    /// Per padded frame; false for the padding.
    valid: Vec<bool>,
    /// `[block·D + d]`, lane `l` = frame `4·block + l`.
    lanes: Vec<F32x4>,
    bounds: BoxBounds,
    /// Per padded frame, its tag bits ([`crate::tag_query`]; 0 for the padding), and per box
    /// of every level the OR and AND of its valid frames' bits.
    tag_bits: Vec<u64>,
    box_tags: [Vec<TagSummary>; LEVELS],
}

/// The best frame so far and its cost. `frame` is only a tie-break key until a frame is found:
/// it starts at 0 with `cost` = the bar, so a frame costing exactly the bar (not strictly below
/// it) never wins, and a later frame wins only by a strictly lower cost.
#[derive(Clone, Copy)]
struct Best {
    frame: usize,
    cost: f32,
}

impl Best {
    /// Whether a frame `frame` costing `cost` beats the best: lower, or equal and earlier.
    #[inline(always)]
    fn beaten_by(&self, cost: f32, frame: usize) -> bool {
        cost < self.cost || (cost == self.cost && frame < self.frame)
    }

    /// The lanes of `costs` (lane `l` = a box or frame starting at `first + l·step`) that may
    /// beat the best: lower, or equal and starting before the best frame.
    #[inline(always)]
    fn lanes_beaten_by(&self, costs: F32x4, first: usize, step: usize) -> u32 {
        let best = F32x4::splat(self.cost);
        let before = if self.frame <= first { 0 } else { (1u32 << (self.frame - first).div_ceil(step).min(4)) - 1 };
        costs.cmplt(best).bitmask() | (costs.cmple(best).bitmask() & before)
    }

    fn result(self, bar: f32) -> Option<(usize, f32)> {
        (self.cost < bar).then_some((self.frame, self.cost))
    }
}

/// Top-level groups whose bounds a search keeps on the stack (512 B; 131k frames).
const TOP_CACHE: usize = 32;

/// Dimensions whose query lanes a search keeps in its small stack buffer (1 KiB, the default
/// feature set's 27 fit); more take a buffer for [`MAX_DIMS`] (4 KiB). Zeroing 6 KiB of stack
/// for every search (both buffers at their largest, and the top bounds' cache at 128 groups)
/// was ~4k instructions of a ~50k-instruction search.
const SMALL_DIMS: usize = 32;

/// A query and its per-dimension weights splatted across lanes (`d` of each), on the stack.
/// `weights` is `None` when every weight is 1 (the default β's): the kernels then skip the
/// multiplication by 1, which changes no bit (`fl(1·x) = x`), so the result is the same.
struct LaneQuery<'a> {
    query: &'a [F32x4],
    weights: Option<&'a [F32x4]>,
}

impl SearchIndex {
    /// Builds the index of `db`'s normalized features: ~1–2 ms natively for 19k frames, a few
    /// ms in WASM ([`crate::aabb`] has the measurements and why it is rebuilt, not stored).
    ///
    /// # Errors
    /// If the database has no feature dims or more than [`MAX_DIMS`], or a non-finite feature
    /// (whose cost could not be compared).
    pub fn new(db: &Database) -> Result<Self> {
        let d = db.num_features();
        if d == 0 || d > MAX_DIMS {
            return Err(Error::format(format!("{d} feature dims; the search supports 1 to {MAX_DIMS}")));
        }
        // A branch-free pass first (it vectorizes); find the culprit only for the message.
        if !db.features.iter().fold(true, |ok, f| ok & f.is_finite()) {
            let i = db.features.iter().position(|f| !f.is_finite()).unwrap_or(0);
            return Err(Error::format(format!(
                "FEAT: frame {} dim {} is {} (features must be finite)",
                i / d,
                i % d,
                db.features[i]
            )));
        }
        let mut dim_weights = vec![DimWeight::One; d];
        for g in &db.groups {
            dim_weights[g.first_dim..g.first_dim + g.num_dims].fill(if g.is_trajectory {
                DimWeight::Trajectory
            } else {
                DimWeight::Pose
            });
        }
        // Padded to whole groups of four large boxes, so every box the search may visit exists.
        let padded = db.num_frames.div_ceil(PADDING) * PADDING;
        let mut valid: Vec<bool> = db.valid.iter().map(|&v| v != 0).collect();
        valid.resize(padded, false);
        // Transpose 4 rows at a time; the padding frames are zeros (and invalid).
        fn transpose(four: &[f32], d: usize, lanes: &mut Vec<F32x4>) {
            lanes.extend((0..d).map(|i| F32x4::from_array([four[i], four[d + i], four[2 * d + i], four[3 * d + i]])));
        }
        let mut lanes = Vec::with_capacity(padded / 4 * d);
        let mut rows = db.features.chunks_exact(4 * d);
        for four in rows.by_ref() {
            transpose(four, d, &mut lanes);
        }
        if !rows.remainder().is_empty() {
            let mut four = vec![0.0; 4 * d];
            four[..rows.remainder().len()].copy_from_slice(rows.remainder());
            transpose(&four, d, &mut lanes);
        }
        lanes.resize(padded / 4 * d, F32x4::ZERO);
        let bounds = BoxBounds::from_lanes(&lanes, &valid, d);
        let mut tag_bits = frame_tag_bits(db);
        tag_bits.resize(padded, 0);
        let summarize = |size: usize| -> Vec<TagSummary> {
            (0..padded / size)
                .map(|b| {
                    (b * size..(b + 1) * size)
                        .filter(|&f| valid[f])
                        .fold(TagSummary::EMPTY, |s, f| s.with_frame(tag_bits[f]))
                })
                .collect()
        };
        let box_tags = BOX_FRAMES.map(summarize);
        Ok(SearchIndex {
            num_frames: db.num_frames,
            num_dims: d,
            dim_weights,
            valid,
            lanes,
            bounds,
            tag_bits,
            box_tags,
        })
    }

    pub fn num_frames(&self) -> usize {
        self.num_frames
    }

    pub fn num_dims(&self) -> usize {
        self.num_dims
    }

    /// Whether a search may return `frame` (the database's validity; false out of range).
    pub fn is_valid(&self, frame: usize) -> bool {
        frame < self.num_frames && self.valid[frame]
    }

    /// Whether `frame`'s tags satisfy `tags` (false out of range).
    pub fn tags_allow(&self, frame: usize, tags: &TagQuery) -> bool {
        frame < self.num_frames && tags.allows(self.tag_bits[frame])
    }

    /// The bounding boxes (for inspection and tests).
    pub fn bounds(&self) -> &BoxBounds {
        &self.bounds
    }

    /// Cost of `frame` for a normalized `query` with `options`' β's (exclusion and mask do not
    /// apply): the `bar` to pass when searching from `frame`. Same arithmetic as the searches.
    ///
    /// # Panics
    /// If `frame ≥ num_frames()` or `query.len() != num_dims()`.
    pub fn cost(&self, frame: usize, query: &[f32], options: &SearchOptions) -> f32 {
        assert!(frame < self.num_frames, "frame {frame} out of range 0..{}", self.num_frames);
        self.check_query(query, options);
        self.scalar_cost(frame, query, options)
    }

    /// Runs `method`; see the type's docs for the semantics.
    pub fn search(
        &self,
        method: SearchMethod,
        query: &[f32],
        options: &SearchOptions,
        bar: f32,
    ) -> Option<(usize, f32)> {
        match method {
            SearchMethod::Scalar => self.search_scalar(query, options, bar),
            SearchMethod::Simd => self.search_simd(query, options, bar),
            SearchMethod::Aabb => self.search_aabb(query, options, bar),
        }
    }

    /// The reference algorithm on this layout: every allowed frame's cost, one at a time.
    ///
    /// Preconditions (all methods): `query` normalized like the features and finite, β's ≥ 0
    /// (the box bounds need non-negative weights).
    ///
    /// # Panics
    /// If `query.len() != num_dims()` or a mask is shorter than `num_frames()`.
    pub fn search_scalar(&self, query: &[f32], options: &SearchOptions, bar: f32) -> Option<(usize, f32)> {
        self.check_query(query, options);
        let mut best = (usize::MAX, bar);
        for frame in 0..self.num_frames {
            if !self.is_allowed(frame, options) {
                continue;
            }
            let cost = self.scalar_cost(frame, query, options);
            if cost < best.1 {
                best = (frame, cost);
            }
        }
        (best.0 != usize::MAX).then_some(best)
    }

    /// Every frame, four at a time. Same preconditions and panics as [`Self::search_scalar`].
    pub fn search_simd(&self, query: &[f32], options: &SearchOptions, bar: f32) -> Option<(usize, f32)> {
        self.check_query(query, options);
        self.with_lane_query(query, options, |q| {
            let mut best = Best { frame: 0, cost: bar };
            for span in 0..self.lanes.len() / (4 * self.num_dims) {
                self.search_span(4 * span, q, options, &mut best);
            }
            best.result(bar)
        })
    }

    /// Pruned by the box tree, SIMD inside the 16-frame boxes it visits. Same preconditions
    /// and panics as [`Self::search_scalar`].
    ///
    /// The top-level box with the lowest bound is searched first: the best it yields prunes
    /// the rest, which is then visited in frame order (without that box). Visiting out of order
    /// keeps the result exact because ties go to the earliest frame ([`Best`]).
    pub fn search_aabb(&self, query: &[f32], options: &SearchOptions, bar: f32) -> Option<(usize, f32)> {
        self.check_query(query, options);
        self.with_lane_query(query, options, |q| {
            let mut best = Best { frame: 0, cost: bar };
            let top = LEVELS - 1;
            let groups = self.bounds.num_boxes(top) / 4;
            // The top-level bounds, computed once (four groups at a time) and kept for the visit in
            // frame order when they fit (`TOP_CACHE` groups: 131k frames), else computed again.
            let mut cache = [F32x4::ZERO; TOP_CACHE];
            let mut seed = (f32::INFINITY, usize::MAX);
            let tags = &options.tags;
            let mut note = |group: usize, bounds: F32x4| {
                if group < TOP_CACHE {
                    cache[group] = bounds;
                }
                for (l, &b) in bounds.to_array().iter().enumerate() {
                    // The seed's bound with its tags' (most boxes lose to the first on distance).
                    if b < seed.0 {
                        let b = if tags.is_trivial() { b } else { b + self.tag_bound(top, 4 * group + l, tags) };
                        if b < seed.0 {
                            seed = (b, 4 * group + l);
                        }
                    }
                }
            };
            // Four groups at a time while there are four, then one at a time.
            let whole = groups - groups % 4;
            for first in (0..whole).step_by(4) {
                for (g, bounds) in self.box_bounds4(top, first, q).into_iter().enumerate() {
                    note(first + g, bounds);
                }
            }
            for group in whole..groups {
                note(group, self.box_bounds(top, group, q));
            }
            if seed.1 != usize::MAX && seed.0 < best.cost {
                self.visit(top, seed.1, q, options, &mut best);
            }
            for group in 0..groups {
                let skip = if seed.1 / 4 == group { 1 << (seed.1 % 4) } else { 0 };
                let bounds = if group < TOP_CACHE { cache[group] } else { self.box_bounds(top, group, q) };
                self.visit_boxes(top, group, bounds, skip, q, options, &mut best);
            }
            best.result(bar)
        })
    }

    /// Lower bounds of the distance part of the cost of boxes `4·group ..` of `level`: the
    /// tags' part is added by [`Self::visit_boxes`] to the boxes the distance leaves in play.
    #[inline(always)]
    fn box_bounds(&self, level: usize, group: usize, q: &LaneQuery) -> F32x4 {
        self.bounds.lower_bounds(level, group, q.query, q.weights)
    }

    /// [`Self::box_bounds`] of groups `first .. first + 4`.
    #[inline(always)]
    fn box_bounds4(&self, level: usize, first: usize, q: &LaneQuery) -> [F32x4; 4] {
        self.bounds.lower_bounds4(level, first, q.query, q.weights)
    }

    /// The tags' part of box `index` of `level`'s bound: the least bias of its frames, +∞ when
    /// the tags allow none of them. Added to the distance bound, it stays exact: the sum never
    /// exceeds a frame's `fl(Σ + bias)` since rounding is monotone.
    #[inline(always)]
    fn tag_bound(&self, level: usize, index: usize, tags: &TagQuery) -> f32 {
        let summary = self.box_tags[level][index];
        if tags.may_allow(summary) {
            tags.min_bias(summary)
        } else {
            f32::INFINITY
        }
    }

    /// Visits the boxes of group `group` of `level` (their distance `bounds`; but those in
    /// `skip`, a lane mask) that may hold a frame beating the best, the lowest bound first. The
    /// tags' part of a bound is added only to the boxes the distance leaves in play: most lose
    /// on distance alone, and adding it to every box was 7 % of a runtime search (cachegrind).
    // The search's state is passed as it is (no struct per call in the hot loop).
    #[allow(clippy::too_many_arguments)]
    fn visit_boxes(
        &self,
        level: usize,
        group: usize,
        bounds: F32x4,
        skip: u32,
        q: &LaneQuery,
        options: &SearchOptions,
        best: &mut Best,
    ) {
        let size = BOX_FRAMES[level];
        let first = 4 * group * size;
        let mut lanes = best.lanes_beaten_by(bounds, first, size) & !skip;
        let mut bounds = bounds.to_array();
        let tags = &options.tags;
        if lanes != 0 && !tags.is_trivial() {
            let mut open = lanes;
            while open != 0 {
                let l = open.trailing_zeros() as usize;
                open &= open - 1;
                // Lane by lane as the vector addition would: the same bits.
                bounds[l] += self.tag_bound(level, 4 * group + l, tags);
            }
        }
        // Lowest bound first.
        let mut order = [0usize; 4];
        let mut n = 0;
        while lanes != 0 {
            let l = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            let mut at = n;
            while at > 0 && bounds[order[at - 1]] > bounds[l] {
                order[at] = order[at - 1];
                at -= 1;
            }
            order[at] = l;
            n += 1;
        }
        for &l in &order[..n] {
            // The best may have dropped while visiting an earlier box of this group.
            if best.beaten_by(bounds[l], first + l * size) {
                self.visit(level, 4 * group + l, q, options, best);
            }
        }
    }

    /// Visits box `index` of `level`: its four children, or its frames at the leaves.
    #[inline(always)]
    fn visit(&self, level: usize, index: usize, q: &LaneQuery, options: &SearchOptions, best: &mut Best) {
        if level == 0 {
            self.search_span(index * BOX_FRAMES[0] / 4, q, options, best);
        } else {
            self.visit_boxes(level - 1, index, self.box_bounds(level - 1, index, q), 0, q, options, best);
        }
    }

    fn check_query(&self, query: &[f32], options: &SearchOptions) {
        assert_eq!(query.len(), self.num_dims, "query has {} dims, the index {}", query.len(), self.num_dims);
        if let Some(mask) = options.mask {
            assert!(mask.len() >= self.num_frames, "mask has {} frames, the index {}", mask.len(), self.num_frames);
        }
        debug_assert!(options.beta_pose >= 0.0 && options.beta_trajectory >= 0.0, "β's must be ≥ 0");
    }

    #[inline(always)]
    fn is_allowed(&self, frame: usize, options: &SearchOptions) -> bool {
        self.valid[frame]
            && !options.exclude.is_some_and(|(a, b)| (a..b).contains(&frame))
            && !options.exclude_recent.is_some_and(|(a, b)| (a..b).contains(&frame))
            && options.mask.is_none_or(|m| m[frame])
            && options.tags.allows(self.tag_bits[frame])
    }

    #[inline(always)]
    fn weight(&self, dim: usize, options: &SearchOptions) -> f32 {
        match self.dim_weights[dim] {
            DimWeight::Pose => options.beta_pose,
            DimWeight::Trajectory => options.beta_trajectory,
            DimWeight::One => 1.0,
        }
    }

    /// [`brute_force`]'s cost expression, term for term, reading the transposed layout.
    #[inline(always)]
    fn scalar_cost(&self, frame: usize, query: &[f32], options: &SearchOptions) -> f32 {
        let d = self.num_dims;
        let floats = as_f32_slice(&self.lanes);
        let column = &floats[(frame / 4) * d * 4 + frame % 4..];
        let mut cost = 0.0;
        for (dim, &q) in query.iter().enumerate() {
            let f = column[4 * dim];
            cost += self.weight(dim, options) * (q - f) * (q - f);
        }
        cost + options.tags.bias(self.tag_bits[frame])
    }

    /// Runs `search` with the query's lanes on the stack: in a 1 KiB buffer for up to
    /// [`SMALL_DIMS`] dimensions, else in one for [`MAX_DIMS`]; only the buffer used is zeroed.
    #[inline(always)]
    fn with_lane_query<R>(&self, query: &[f32], options: &SearchOptions, search: impl FnOnce(&LaneQuery) -> R) -> R {
        if self.num_dims <= SMALL_DIMS {
            search(&self.lane_query(query, options, &mut [F32x4::ZERO; 2 * SMALL_DIMS]))
        } else {
            search(&self.lane_query(query, options, &mut [F32x4::ZERO; 2 * MAX_DIMS]))
        }
    }

    /// The query's lanes, written into `lanes` (at least twice the dimension count).
    fn lane_query<'a>(&self, query: &[f32], options: &SearchOptions, lanes: &'a mut [F32x4]) -> LaneQuery<'a> {
        let d = self.num_dims;
        let (q, w) = lanes[..2 * d].split_at_mut(d);
        let mut unit = true;
        for (dim, &v) in query.iter().enumerate() {
            q[dim] = F32x4::splat(v);
            let weight = self.weight(dim, options);
            unit &= weight == 1.0;
            w[dim] = F32x4::splat(weight);
        }
        LaneQuery { query: q, weights: (!unit).then_some(&*w) }
    }

    /// Costs of the 16 frames of blocks `first_block .. first_block + 4`, folded into `best`.
    /// Four independent accumulators so the lane additions pipeline instead of waiting on one
    /// dependency chain.
    #[inline(always)]
    fn search_span(&self, first_block: usize, q: &LaneQuery, options: &SearchOptions, best: &mut Best) {
        let tags = &options.tags;
        // The span is one 16-frame box.
        let summary = self.box_tags[0][first_block / 4];
        if !tags.is_trivial() && !tags.may_allow(summary) {
            return;
        }
        let d = self.num_dims;
        let rows = &self.lanes[first_block * d..(first_block + 4) * d];
        let (r0, r1, r2, r3) = (&rows[..d], &rows[d..2 * d], &rows[2 * d..3 * d], &rows[3 * d..]);
        let qs = q.query;
        let mut acc = [F32x4::ZERO; 4];
        // Same steps as the scalar cost: (w · (q − f)) · (q − f), summed in dim order.
        if let Some(ws) = q.weights {
            for i in 0..d {
                let (qd, wd) = (qs[i], ws[i]);
                let diff = [qd - r0[i], qd - r1[i], qd - r2[i], qd - r3[i]];
                for k in 0..4 {
                    acc[k] += wd * diff[k] * diff[k];
                }
            }
        } else {
            for i in 0..d {
                let qd = qs[i];
                let diff = [qd - r0[i], qd - r1[i], qd - r2[i], qd - r3[i]];
                for k in 0..4 {
                    acc[k] += diff[k] * diff[k];
                }
            }
        }
        // The bias last, as in the scalar cost (adding a 0 bias changes no bit).
        match tags.run_bias(summary) {
            RunBias::None => {}
            RunBias::All(bias) => acc.iter_mut().for_each(|a| *a += F32x4::splat(bias)),
            RunBias::Mixed => {
                for (k, a) in acc.iter_mut().enumerate() {
                    let frame = 4 * (first_block + k);
                    *a += F32x4::from_array(std::array::from_fn(|l| tags.bias(self.tag_bits[frame + l])));
                }
            }
        }
        for (k, costs) in acc.into_iter().enumerate() {
            let better = best.lanes_beaten_by(costs, 4 * (first_block + k), 1);
            if better != 0 {
                self.fold_block(first_block + k, costs, better, options, best);
            }
        }
    }

    /// The rare path: lanes of one block that beat the best; check that those frames may be
    /// returned, in frame order (the earliest frame wins a tie, as in the scalar loop).
    #[inline(never)]
    fn fold_block(&self, block: usize, costs: F32x4, mut lanes: u32, options: &SearchOptions, best: &mut Best) {
        let costs = costs.to_array();
        while lanes != 0 {
            let l = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            let frame = 4 * block + l;
            if best.beaten_by(costs[l], frame) && self.is_allowed(frame, options) {
                *best = Best { frame, cost: costs[l] };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::database::{Axes, FeatureGroup, FeatureKind, Skeleton, Tag};
    use crate::rng::Rng;
    use glam::Vec3;

    fn group(name: &str, is_trajectory: bool, first_dim: usize, num_dims: usize) -> FeatureGroup {
        FeatureGroup {
            name: name.into(),
            kind: FeatureKind::Position,
            is_trajectory,
            axes: Axes::Xyz,
            joint: 0,
            axis: Vec3::Z,
            offsets: vec![0],
            weight: 1.0,
            first_dim,
            num_dims,
        }
    }

    /// Only what the search reads: features (on a coarse grid, so exact ties are common),
    /// validity, groups (dims 0..3 pose, 3..5 trajectory, 5 in no group) and three tags over
    /// random runs of frames (runs of 1–40 frames, so boxes are uniform, mixed and empty).
    fn synthetic(num_frames: usize, rng: &mut Rng) -> Database {
        let d = 6;
        let tags = (0..3)
            .map(|i| {
                let (mut ranges, mut f) = (vec![], rng.below(30));
                while f < num_frames {
                    let e = (f + 1 + rng.below(40)).min(num_frames);
                    ranges.push((f as u32, e as u32));
                    f = e + 1 + rng.below(40);
                }
                Tag { name: format!("t{i}"), ranges }
            })
            .collect();
        Database {
            skeleton: Skeleton {
                names: vec!["root".into()],
                parents: vec![-1],
                offsets: vec![Vec3::ZERO],
                sites: vec![],
                mirror: vec![],
            },
            fps: 60.0,
            num_frames,
            clips: vec![],
            tags,
            local_positions: vec![],
            local_rotations: vec![],
            contacts: vec![],
            groups: vec![group("pose", false, 0, 3), group("trajectory", true, 3, 2)],
            feature_mean: vec![0.0; d],
            feature_scale: vec![1.0; d],
            features: (0..num_frames * d).map(|_| (rng.below(5) as f32 - 2.0) * 0.5).collect(),
            valid: (0..num_frames).map(|_| (rng.below(4) != 0) as u8).collect(),
            part: None,
            velocities: Default::default(),
        }
    }

    fn reference(db: &Database, query: &[f32], options: &SearchOptions, bar: f32) -> Option<(usize, f32)> {
        brute_force(db, query, options, 1).first().copied().filter(|&(_, c)| c < bar)
    }

    #[test]
    fn every_method_equals_brute_force_bit_for_bit_ties_included() {
        let mut rng = Rng(7);
        // Sizes around the box and padding boundaries (4, 16, 64, 256, 1024, 4096 frames), with
        // 1, 2 and 3 top-level groups past the last whole four, and past the cached top bounds.
        let beyond_cache = PADDING * (TOP_CACHE + 3) + 5;
        for num_frames in [
            1,
            3,
            4,
            17,
            63,
            64,
            65,
            255,
            256,
            257,
            1000,
            1024,
            1025,
            4096,
            4097,
            16_385,
            20_485,
            24_600,
            28_670,
            beyond_cache,
        ] {
            let db = synthetic(num_frames, &mut rng);
            let index = SearchIndex::new(&db).unwrap();
            let mask: Vec<bool> = (0..num_frames).map(|_| rng.below(3) != 0).collect();
            for round in 0..if num_frames > 10_000 { 20 } else { 300 } {
                // Grid queries make exact cost ties between frames likely.
                let query: Vec<f32> = (0..6).map(|_| (rng.below(7) as f32 - 3.0) * 0.5).collect();
                let a = rng.below(num_frames);
                let options = SearchOptions {
                    beta_pose: [0.0, 0.5, 1.0, 2.0][rng.below(4)],
                    beta_trajectory: [0.0, 1.0, 3.0][rng.below(3)],
                    exclude: (round % 2 == 0).then(|| (a, a + rng.below(40))),
                    exclude_recent: (round % 5 < 2).then(|| (a / 2, a / 2 + rng.below(40))),
                    mask: (round % 3 == 0).then_some(mask.as_slice()),
                    // Bits 0..3 are the tags; bit 3 is no tag (a required one allows nothing).
                    tags: TagQuery {
                        require: [0, 0, 1, 2, 8][rng.below(5)],
                        exclude: [0, 0, 2, 4][rng.below(4)],
                        prefer: [0, 1, 4, 5][rng.below(4)],
                        bias: [0.0, 0.25, 1.0, 100.0][rng.below(4)],
                    },
                };
                let best = reference(&db, &query, &options, f32::INFINITY);
                let bars = [f32::INFINITY, best.map_or(1.0, |b| b.1), best.map_or(1.0, |b| b.1 + 0.25), 0.0];
                for bar in bars {
                    let expected = reference(&db, &query, &options, bar);
                    for method in SearchMethod::ALL {
                        let got = index.search(method, &query, &options, bar);
                        assert_eq!(
                            got.map(|(f, c)| (f, c.to_bits())),
                            expected.map(|(f, c)| (f, c.to_bits())),
                            "{} frames, {method:?}, bar {bar}, {options:?}, query {query:?}",
                            num_frames
                        );
                    }
                }
            }
        }
    }

    /// The grid features above look alike in every box (each spans the whole grid), so they
    /// cannot tell a box bound taken from the wrong box; mocap-like features drift with the
    /// frame, and here each top-level box has its own range.
    #[test]
    fn box_tree_equals_brute_force_on_coherent_features() {
        let mut rng = Rng(11);
        for num_frames in [1024, 5121, 20_485, 24_600, 28_670, PADDING * (TOP_CACHE + 3) + 5] {
            let mut db = synthetic(num_frames, &mut rng);
            let phase: Vec<f32> = (0..6).map(|_| rng.below(1000) as f32 / 100.0).collect();
            for (i, f) in db.features.iter_mut().enumerate() {
                let (frame, dim) = ((i / 6) as f32, i % 6);
                *f = (frame * 0.01 * (dim + 1) as f32 + phase[dim]).sin() + frame / num_frames as f32 * 4.0;
            }
            let index = SearchIndex::new(&db).unwrap();
            for _ in 0..200 {
                let source = rng.below(num_frames);
                let query: Vec<f32> = db.features[source * 6..source * 6 + 6]
                    .iter()
                    .map(|v| v + (rng.below(100) as f32 - 50.0) / 200.0)
                    .collect();
                let options =
                    SearchOptions { exclude: Some((source.saturating_sub(20), source + 21)), ..Default::default() };
                let expected = reference(&db, &query, &options, f32::INFINITY);
                for method in [SearchMethod::Simd, SearchMethod::Aabb] {
                    let got = index.search(method, &query, &options, f32::INFINITY);
                    assert_eq!(
                        got.map(|(f, c)| (f, c.to_bits())),
                        expected.map(|(f, c)| (f, c.to_bits())),
                        "{num_frames} frames, {method:?}, query from frame {source}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_bar_is_strict_and_cost_matches_the_search() {
        let mut rng = Rng(3);
        let db = synthetic(500, &mut rng);
        let index = SearchIndex::new(&db).unwrap();
        let query = [0.3, -0.2, 0.9, 1.1, -0.4, 0.05];
        let options = SearchOptions { beta_pose: 1.5, beta_trajectory: 0.5, ..Default::default() };
        let (frame, cost) = index.search_aabb(&query, &options, f32::INFINITY).unwrap();
        assert_eq!(index.cost(frame, &query, &options).to_bits(), cost.to_bits());
        for method in SearchMethod::ALL {
            assert_eq!(
                index.search(method, &query, &options, cost),
                None,
                "{method:?}: equal to the bar is not better"
            );
            assert_eq!(index.search(method, &query, &options, cost.next_up()), Some((frame, cost)));
        }
    }

    #[test]
    fn nothing_allowed_means_none() {
        let mut rng = Rng(5);
        let mut db = synthetic(300, &mut rng);
        let index = SearchIndex::new(&db).unwrap();
        let query = [0.0; 6];
        let none = SearchOptions { exclude: Some((0, 300)), ..Default::default() };
        let mask = vec![false; 300];
        let masked = SearchOptions { mask: Some(&mask), ..Default::default() };
        for method in SearchMethod::ALL {
            assert_eq!(index.search(method, &query, &none, f32::INFINITY), None);
            assert_eq!(index.search(method, &query, &masked, f32::INFINITY), None);
        }
        db.valid.fill(0);
        let index = SearchIndex::new(&db).unwrap();
        for method in SearchMethod::ALL {
            assert_eq!(index.search(method, &query, &SearchOptions::default(), f32::INFINITY), None);
        }
    }

    #[test]
    fn rejects_what_it_cannot_search() {
        let mut rng = Rng(9);
        let mut db = synthetic(10, &mut rng);
        db.features[13] = f32::NAN;
        let e = SearchIndex::new(&db).unwrap_err().to_string();
        assert!(e.contains("frame 2 dim 1"), "{e}");
        let wide = Database {
            feature_mean: vec![0.0; MAX_DIMS + 1],
            feature_scale: vec![1.0; MAX_DIMS + 1],
            features: vec![0.0; 10 * (MAX_DIMS + 1)],
            groups: vec![],
            ..db
        };
        assert!(SearchIndex::new(&wide).unwrap_err().to_string().contains("1 to 128"));
    }

    #[test]
    fn methods_are_numbered_for_the_bindings() {
        for (i, m) in SearchMethod::ALL.iter().enumerate() {
            assert_eq!(SearchMethod::from_index(i as u32), Some(*m));
            assert_eq!(*m as u32, i as u32);
        }
        assert_eq!(SearchMethod::from_index(3), None);
        assert_eq!(SearchMethod::Aabb.name(), "aabb");
    }
}
