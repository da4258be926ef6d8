//! Two-level bounding boxes (64 and 16 frames) over the feature matrix for exact pruned search.
//!
//! Each box holds, per feature dimension, the min and max over the *valid* frames of a run of
//! consecutive frames (docs/method.md §3). For a query `q` and weights `w`, no frame in a box
//! can cost less than `Σ_d w_d · gap_d²`, with `gap_d` the distance from `q_d` to
//! `[min_d, max_d]` (0 inside). A search visits a 64-frame box only if that bound beats its
//! best cost so far, then the box's four 16-frame boxes the same way, then their frames.
//!
//! Exactness in floating point, not only in real numbers: the bound is computed with the very
//! operations the frame cost uses — `(w·gap)·gap` accumulated from 0 in dimension order — and
//! every step is monotone in its inputs under IEEE rounding (`fl(lo − q) ≤ fl(f − q)` when
//! `q ≤ lo ≤ f`, products and sums of non-negative values likewise), so a box's computed bound
//! never exceeds the computed cost of any of its frames. A box is skipped only when its bound
//! is `≥` the best cost, so no frame that would beat the best is ever skipped. This needs
//! `w_d ≥ 0` and finite queries.
//!
//! Layout: boxes are stored transposed like the frames ([`crate::lanes`]), four boxes per
//! lane vector, so one pass over the dimensions bounds four boxes at once with the same
//! per-lane operation order: the four 16-frame boxes of a 64-frame box share a vector, and the
//! 64-frame boxes are grouped in fours. A box without valid frames has min +∞ / max −∞, so its
//! bound is +∞ (or NaN when a weight is 0) and it is never visited.
//!
//! Stored or rebuilt? Rebuilt at load. Measured for the whole [`crate::search::SearchIndex`]
//! (transpose + both box levels), medians on this 2-core machine:
//! `locomotion.mmdb` (19,474 frames × 27 dims) ~1–2 ms native, ~2.5 ms in Chromium and
//! ~7 ms in Node 20 (WASM); the 53k-frame benchmark database ~4–7 ms native, ~6–10 ms in
//! Chromium, ~13 ms in Node. Parsing the same `.mmdb` bytes in WASM takes ~70 ms and ~180 ms,
//! so the boxes would save at most a tenth of the load time while adding a format section to
//! version and validate. (`cargo test --release --test search -- --nocapture index_build_time`
//! prints the native figure; `npm run bench` prints the WASM ones.)

use crate::lanes::F32x4;

/// Frames per large box.
pub const LARGE_BOX: usize = 64;
/// Frames per small box; a large box holds four, one per lane.
pub const SMALL_BOX: usize = 16;

/// Per-dimension min/max of 64- and 16-frame boxes, four boxes per lane vector.
#[derive(Clone, Debug)]
pub struct BoxBounds {
    num_dims: usize,
    /// Large boxes (a multiple of 4; the padding boxes are empty).
    num_large: usize,
    /// `[group·D + d]`, lane `l` = large box `4·group + l`.
    large_min: Vec<F32x4>,
    large_max: Vec<F32x4>,
    /// `[large·D + d]`, lane `s` = small box `4·large + s` (frames `64·large + 16·s ..+16`).
    small_min: Vec<F32x4>,
    small_max: Vec<F32x4>,
}

impl BoxBounds {
    /// Boxes over a feature matrix in the search's lane layout: `lanes[block·D + d]` holds
    /// dimension `d` of frames `4·block .. 4·block + 4` (see [`crate::search::SearchIndex`]).
    /// Only frames with `valid[frame]` count; padding frames must be invalid.
    ///
    /// # Panics
    /// If `num_dims` is 0, `lanes.len()` is not a multiple of `num_dims`, or the frame count
    /// (`4 · lanes.len() / num_dims`) is not a multiple of 256 (four large boxes) or differs
    /// from `valid.len()`.
    pub fn from_lanes(lanes: &[F32x4], valid: &[bool], num_dims: usize) -> Self {
        let d = num_dims;
        assert!(d > 0 && lanes.len().is_multiple_of(d), "lanes must be blocks × num_dims");
        let num_frames = 4 * lanes.len() / d;
        assert!(num_frames.is_multiple_of(4 * LARGE_BOX) && num_frames == valid.len(), "frames must be padded to 256 and match valid");
        let num_large = num_frames / LARGE_BOX;
        let mut small_min = Vec::with_capacity(num_large * d);
        let mut small_max = Vec::with_capacity(num_large * d);
        let mut large_min = Vec::with_capacity(num_large / 4 * d);
        let mut large_max = Vec::with_capacity(num_large / 4 * d);
        // Per block of 4 frames: +∞ in the lanes of invalid frames, 0 elsewhere. Adding it
        // (−it for the max) takes an invalid frame out of a min (max) and leaves a valid one
        // unchanged (finite features; −0 may become +0, which no bound can tell apart).
        let exclusion = |block: usize| F32x4::from_array(std::array::from_fn(|l| if valid[4 * block + l] { 0.0 } else { f32::INFINITY }));
        let mut group_min = vec![[f32::INFINITY; 4]; d];
        let mut group_max = vec![[f32::NEG_INFINITY; 4]; d];
        // Small boxes of the current large box, [dim][small]; every entry is rewritten per box.
        let mut box_min = vec![[0.0; 4]; d];
        let mut box_max = vec![[0.0; 4]; d];
        for large in 0..num_large {
            for small in 0..4 {
                let first = (LARGE_BOX * large + SMALL_BOX * small) / 4;
                let off: [F32x4; 4] = std::array::from_fn(|k| exclusion(first + k));
                for dim in 0..d {
                    let v: [F32x4; 4] = std::array::from_fn(|k| lanes[(first + k) * d + dim]);
                    let lo = ((v[0] + off[0]).min(v[1] + off[1])).min((v[2] + off[2]).min(v[3] + off[3]));
                    let hi = ((v[0] - off[0]).max(v[1] - off[1])).max((v[2] - off[2]).max(v[3] - off[3]));
                    let [a, b, c, e] = lo.to_array();
                    box_min[dim][small] = a.min(b).min(c.min(e));
                    let [a, b, c, e] = hi.to_array();
                    box_max[dim][small] = a.max(b).max(c.max(e));
                }
            }
            // A large box is the union of its four small ones.
            for dim in 0..d {
                small_min.push(F32x4::from_array(box_min[dim]));
                small_max.push(F32x4::from_array(box_max[dim]));
                group_min[dim][large % 4] = box_min[dim].into_iter().fold(f32::INFINITY, f32::min);
                group_max[dim][large % 4] = box_max[dim].into_iter().fold(f32::NEG_INFINITY, f32::max);
            }
            if large % 4 == 3 {
                large_min.extend(group_min.iter().map(|&a| F32x4::from_array(a)));
                large_max.extend(group_max.iter().map(|&a| F32x4::from_array(a)));
            }
        }
        BoxBounds { num_dims: d, num_large, large_min, large_max, small_min, small_max }
    }

    /// Number of large boxes, padding included (a multiple of 4). They cover
    /// `num_large_boxes() · 64` frames.
    pub fn num_large_boxes(&self) -> usize {
        self.num_large
    }

    /// Lower bounds of the cost of every frame in large boxes `4·group .. 4·group + 4`, one per
    /// lane. `query` and `weights` hold one splatted value per dimension.
    ///
    /// # Panics
    /// If `group ≥ num_large_boxes() / 4` or the slices are shorter than the dimension count.
    #[inline(always)]
    pub fn large_lower_bounds(&self, group: usize, query: &[F32x4], weights: &[F32x4]) -> F32x4 {
        let range = group * self.num_dims..(group + 1) * self.num_dims;
        lower_bounds(&self.large_min[range.clone()], &self.large_max[range], query, weights)
    }

    /// Lower bounds of the cost of every frame in the four small boxes of large box `large`,
    /// one per lane. Same arguments as [`Self::large_lower_bounds`].
    ///
    /// # Panics
    /// If `large ≥ num_large_boxes()` or the slices are shorter than the dimension count.
    #[inline(always)]
    pub fn small_lower_bounds(&self, large: usize, query: &[F32x4], weights: &[F32x4]) -> F32x4 {
        let range = large * self.num_dims..(large + 1) * self.num_dims;
        lower_bounds(&self.small_min[range.clone()], &self.small_max[range], query, weights)
    }

    /// `(min, max)` of dimension `dim` over the valid frames of small box `small` (frames
    /// `16·small .. 16·small + 16`); `(+∞, −∞)` when it has none.
    pub fn small_box(&self, small: usize, dim: usize) -> (f32, f32) {
        let at = (small / 4) * self.num_dims + dim;
        (self.small_min[at].to_array()[small % 4], self.small_max[at].to_array()[small % 4])
    }

    /// `(min, max)` of dimension `dim` over the valid frames of large box `large`.
    pub fn large_box(&self, large: usize, dim: usize) -> (f32, f32) {
        let at = (large / 4) * self.num_dims + dim;
        (self.large_min[at].to_array()[large % 4], self.large_max[at].to_array()[large % 4])
    }
}

/// `Σ_d w_d · gap_d²` per lane, in the operation order of the frame cost (see the module docs
/// for why that order makes the bound exact).
#[inline(always)]
fn lower_bounds(min: &[F32x4], max: &[F32x4], query: &[F32x4], weights: &[F32x4]) -> F32x4 {
    let n = min.len();
    let (max, query, weights) = (&max[..n], &query[..n], &weights[..n]);
    let mut acc = F32x4::ZERO;
    for d in 0..n {
        let q = query[d];
        // Below the box: min − q > 0 ≥ q − max; above: the reverse; inside: both ≤ 0.
        let gap = (min[d] - q).max(q - max[d]).max(F32x4::ZERO);
        acc += weights[d] * gap * gap;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 3 dims, 150 frames padded to 256, frame `i` = (i, −i, i mod 7), in the lane layout.
    fn boxes(valid: impl Fn(usize) -> bool) -> (BoxBounds, Vec<f32>, Vec<bool>) {
        let (n, padded) = (150, 256);
        let features: Vec<f32> = (0..n).flat_map(|i| [i as f32, -(i as f32), (i % 7) as f32]).collect();
        let valid: Vec<bool> = (0..padded).map(|i| i < n && valid(i)).collect();
        let lanes: Vec<F32x4> = (0..padded / 4)
            .flat_map(|b| (0..3).map(move |d| (b, d)))
            .map(|(b, d)| F32x4::from_array(std::array::from_fn(|l| features.get((4 * b + l) * 3 + d).copied().unwrap_or(0.0))))
            .collect();
        (BoxBounds::from_lanes(&lanes, &valid, 3), features, valid)
    }

    #[test]
    fn boxes_hold_the_min_and_max_of_their_valid_frames() {
        let (b, _, _) = boxes(|i| i % 5 != 0);
        assert_eq!(b.num_large_boxes(), 4);
        // Small box 1 = frames 16..32; 20, 25, 30 are invalid but not at the ends.
        assert_eq!(b.small_box(1, 0), (16.0, 31.0));
        assert_eq!(b.small_box(1, 1), (-31.0, -16.0));
        assert_eq!(b.small_box(1, 2), (0.0, 6.0));
        // Small box 0 = frames 0..16, frame 0 and 15 invalid.
        assert_eq!(b.small_box(0, 0), (1.0, 14.0));
        // Large box 2 = frames 128..150 (130, 135… invalid).
        assert_eq!(b.large_box(2, 0), (128.0, 149.0));
        assert_eq!(b.large_box(0, 1), (-63.0, -1.0));
        // Past the end: empty.
        assert_eq!(b.small_box(10, 0), (f32::INFINITY, f32::NEG_INFINITY));
        assert_eq!(b.large_box(3, 2), (f32::INFINITY, f32::NEG_INFINITY));
    }

    #[test]
    fn an_all_invalid_box_is_empty_and_never_beats_anything() {
        let (b, _, _) = boxes(|i| !(64..128).contains(&i));
        assert_eq!(b.large_box(1, 0), (f32::INFINITY, f32::NEG_INFINITY));
        let q = [F32x4::splat(70.0), F32x4::splat(-70.0), F32x4::splat(3.0)];
        for w in [1.0, 0.0] {
            let bounds = b.large_lower_bounds(0, &q, &[F32x4::splat(w); 3]).to_array();
            // inf, or NaN when the weight is 0: either way `bound < best` is false.
            assert!(bounds[1] == f32::INFINITY || bounds[1].is_nan(), "{bounds:?}");
            assert!(bounds[3] == f32::INFINITY || bounds[3].is_nan(), "{bounds:?}");
            assert!(bounds[0] < f32::INFINITY && bounds[2] < f32::INFINITY);
        }
    }

    #[test]
    fn bounds_match_a_hand_computation_and_never_exceed_a_frame_cost() {
        let (b, features, valid) = boxes(|i| i % 3 != 1);
        let qv = [40.5f32, -100.0, 9.0];
        let wv = [0.5f32, 2.0, 1.0];
        let q: Vec<F32x4> = qv.iter().map(|&v| F32x4::splat(v)).collect();
        let w: Vec<F32x4> = wv.iter().map(|&v| F32x4::splat(v)).collect();
        // Small box 2 = frames 32..48, valid range [32, 47] in dim 0, [-47, -32] in dim 1,
        // [0, 6] in dim 2 → gaps 0, 100 − 47 = 53, 3.
        let small = b.small_lower_bounds(0, &q, &w).to_array();
        assert_eq!(small[2], 0.5 * 0.0 + 2.0 * 53.0 * 53.0 + 1.0 * 3.0 * 3.0);
        for large in 0..b.num_large_boxes() {
            let lb = b.large_lower_bounds(large / 4, &q, &w).to_array()[large % 4];
            let sb = b.small_lower_bounds(large, &q, &w).to_array();
            for (s, &bound) in sb.iter().enumerate() {
                assert!(lb <= bound || bound.is_infinite(), "large {large} bound {lb} > small {s} bound {bound}");
                for frame in (large * 64 + s * 16..large * 64 + s * 16 + 16).filter(|&f| valid[f]) {
                    let cost: f32 = (0..3).map(|d| wv[d] * (qv[d] - features[frame * 3 + d]) * (qv[d] - features[frame * 3 + d])).sum();
                    assert!(bound <= cost, "frame {frame}: bound {bound} > cost {cost}");
                }
            }
        }
    }
}
