//! A tree of bounding boxes (16, 64, 256 and 1024 frames) over the feature matrix for exact pruned
//! search.
//!
//! Each box holds, per feature dimension, the min and max over the *valid* frames of a run of
//! consecutive frames (docs/method.md §3). For a query `q` and weights `w`, no frame in a box
//! can cost less than `Σ_d w_d · gap_d²`, with `gap_d` the distance from `q_d` to
//! `[min_d, max_d]` (0 inside). A search visits a box only if that bound beats its best cost
//! so far, then the box's four children the same way, down to the 16-frame boxes' frames.
//!
//! Why four levels: the bounds of every top-level box are computed for every search, so the
//! top level sets a floor under the search time that grows with the database. With 64-frame
//! boxes on top that pass alone took ~5.5 µs of a ~9 µs native search on 34k frames (one
//! dependency chain of 27 dimensions per four boxes); 256-frame boxes on top cut it to a
//! quarter, and the 64-frame bounds are computed only inside the top boxes that survive.
//! 1024-frame boxes on top took another 14 % of the instructions of a search on that database
//! (59.4k → 51.2k, cachegrind, the bench's 2,000 queries; −8 % on 14k frames, −11 % on 53k);
//! a fifth level (4096) lost it again (54.3k): its boxes are too loose to prune, and the
//! padding to four of them grows to 16k frames.
//!
//! Exactness in floating point, not only in real numbers: the bound is computed with the very
//! operations the frame cost uses — `(w·gap)·gap` accumulated from 0 in dimension order — and
//! every step is monotone in its inputs under IEEE rounding (`fl(lo − q) ≤ fl(f − q)` when
//! `q ≤ lo ≤ f`, products and sums of non-negative values likewise), so a box's computed bound
//! never exceeds the computed cost of any of its frames. A box is skipped only when its bound
//! cannot beat the best (`≥` it, or equal to it and after the best frame: ties go to the
//! earliest frame), so no frame that would win is ever skipped. This needs `w_d ≥ 0` and
//! finite queries.
//!
//! Layout: boxes are stored transposed like the frames ([`crate::lanes`]), four boxes per
//! lane vector, so one pass over the dimensions bounds four boxes at once with the same
//! per-lane operation order: the four children of a box share a vector, and the top-level
//! boxes are grouped in fours. A box without valid frames has min +∞ / max −∞, so its bound is
//! +∞ (or NaN when a weight is 0) and it is never visited.
//!
//! Stored or rebuilt? Rebuilt at load. Measured for the whole [`crate::search::SearchIndex`]
//! (transpose + the boxes), medians on this 2-core machine:
//! `locomotion.mmdb` (19,474 frames × 27 dims) ~1–2 ms native, ~2.5 ms in Chromium and
//! ~7 ms in Node 20 (WASM); the 53k-frame benchmark database ~4–7 ms native, ~6–10 ms in
//! Chromium, ~13 ms in Node. Parsing the same `.mmdb` bytes in WASM takes ~70 ms and ~180 ms,
//! so the boxes would save at most a tenth of the load time while adding a format section to
//! version and validate. (`cargo test --release --test integration -- --nocapture
//! search::index_build_time` prints the native figure; `npm run bench` prints the WASM ones.)

use crate::lanes::F32x4;

/// Levels of the box tree, leaves first.
pub const LEVELS: usize = 4;
/// Frames per box at each level: a box holds four boxes of the level below.
pub const BOX_FRAMES: [usize; LEVELS] = [16, 64, 256, 1024];
/// The frame count the search pads to: one lane vector of top-level boxes.
pub const PADDING: usize = 4 * BOX_FRAMES[LEVELS - 1];

/// Per-dimension min/max of the boxes of every level, four boxes per lane vector.
#[derive(Clone, Debug)]
pub struct BoxBounds {
    num_dims: usize,
    /// Per level, `[group·D + d]`: lane `l` = box `4·group + l` of that level, whose children
    /// are group `4·group + l` of the level below.
    min: [Vec<F32x4>; LEVELS],
    max: [Vec<F32x4>; LEVELS],
}

impl BoxBounds {
    /// Boxes over a feature matrix in the search's lane layout: `lanes[block·D + d]` holds
    /// dimension `d` of frames `4·block .. 4·block + 4` (see [`crate::search::SearchIndex`]).
    /// Only frames with `valid[frame]` count; padding frames must be invalid.
    ///
    /// # Panics
    /// If `num_dims` is 0, `lanes.len()` is not a multiple of `num_dims`, or the frame count
    /// (`4 · lanes.len() / num_dims`) is not a multiple of [`PADDING`] or differs from
    /// `valid.len()`.
    pub fn from_lanes(lanes: &[F32x4], valid: &[bool], num_dims: usize) -> Self {
        let d = num_dims;
        assert!(d > 0 && lanes.len().is_multiple_of(d), "lanes must be blocks × num_dims");
        let num_frames = 4 * lanes.len() / d;
        assert!(
            num_frames.is_multiple_of(PADDING) && num_frames == valid.len(),
            "frames must be padded to {PADDING} and match valid"
        );
        // Per block of 4 frames: +∞ in the lanes of invalid frames, 0 elsewhere. Adding it
        // (−it for the max) takes an invalid frame out of a min (max) and leaves a valid one
        // unchanged (finite features; −0 may become +0, which no bound can tell apart).
        let exclusion = |block: usize| {
            F32x4::from_array(std::array::from_fn(|l| if valid[4 * block + l] { 0.0 } else { f32::INFINITY }))
        };
        // Leaves: each 16-frame box is the lanes of its four blocks, reduced.
        let leaves = num_frames / BOX_FRAMES[0];
        let (mut min0, mut max0) = (Vec::with_capacity(leaves / 4 * d), Vec::with_capacity(leaves / 4 * d));
        let (mut box_min, mut box_max) = (vec![[0.0; 4]; d], vec![[0.0; 4]; d]);
        for group in 0..leaves / 4 {
            for leaf in 0..4 {
                let first = (4 * group + leaf) * BOX_FRAMES[0] / 4;
                let off: [F32x4; 4] = std::array::from_fn(|k| exclusion(first + k));
                for dim in 0..d {
                    let v: [F32x4; 4] = std::array::from_fn(|k| lanes[(first + k) * d + dim]);
                    let lo = ((v[0] + off[0]).min(v[1] + off[1])).min((v[2] + off[2]).min(v[3] + off[3]));
                    let hi = ((v[0] - off[0]).max(v[1] - off[1])).max((v[2] - off[2]).max(v[3] - off[3]));
                    box_min[dim][leaf] = lo.element_min();
                    box_max[dim][leaf] = hi.element_max();
                }
            }
            min0.extend(box_min.iter().map(|&a| F32x4::from_array(a)));
            max0.extend(box_max.iter().map(|&a| F32x4::from_array(a)));
        }
        let (mut min, mut max): ([Vec<F32x4>; LEVELS], [Vec<F32x4>; LEVELS]) = Default::default();
        (min[0], max[0]) = (min0, max0);
        // A box of a higher level is the union of its four children (one lane vector below).
        for level in 1..LEVELS {
            let groups = num_frames / BOX_FRAMES[level] / 4;
            let (below_min, below_max) = (&min[level - 1], &max[level - 1]);
            let (mut up_min, mut up_max) = (Vec::with_capacity(groups * d), Vec::with_capacity(groups * d));
            for group in 0..groups {
                for dim in 0..d {
                    let child = |lane: usize| (4 * group + lane) * d + dim;
                    up_min.push(F32x4::from_array(std::array::from_fn(|l| below_min[child(l)].element_min())));
                    up_max.push(F32x4::from_array(std::array::from_fn(|l| below_max[child(l)].element_max())));
                }
            }
            (min[level], max[level]) = (up_min, up_max);
        }
        BoxBounds { num_dims: d, min, max }
    }

    /// Number of boxes at `level`, padding included (a multiple of 4). They cover
    /// `num_boxes(level) · BOX_FRAMES[level]` frames.
    pub fn num_boxes(&self, level: usize) -> usize {
        4 * self.min[level].len() / self.num_dims
    }

    /// Lower bounds of the cost of every frame in boxes `4·group .. 4·group + 4` of `level`,
    /// one per lane. `query` and `weights` hold one splatted value per dimension.
    ///
    /// # Panics
    /// If `level ≥ LEVELS`, `group ≥ num_boxes(level) / 4` or the slices are shorter than the
    /// dimension count.
    #[inline(always)]
    pub fn lower_bounds(&self, level: usize, group: usize, query: &[F32x4], weights: Option<&[F32x4]>) -> F32x4 {
        let range = group * self.num_dims..(group + 1) * self.num_dims;
        lower_bounds(&self.min[level][range.clone()], &self.max[level][range], query, weights)
    }

    /// [`Self::lower_bounds`] of groups `first .. first + 4` at once: four independent
    /// accumulations, so the additions of one group do not wait on another's (a group's own
    /// additions must stay in dimension order for exactness, and are one dependency chain).
    ///
    /// # Panics
    /// As [`Self::lower_bounds`], for group `first + 3`.
    #[inline(always)]
    pub fn lower_bounds4(&self, level: usize, first: usize, query: &[F32x4], weights: Option<&[F32x4]>) -> [F32x4; 4] {
        let d = self.num_dims;
        let (min, max) = (&self.min[level][first * d..(first + 4) * d], &self.max[level][first * d..(first + 4) * d]);
        let query = &query[..d];
        let mut acc = [F32x4::ZERO; 4];
        match weights {
            Some(weights) => {
                let weights = &weights[..d];
                for i in 0..d {
                    let (q, w) = (query[i], weights[i]);
                    for (g, a) in acc.iter_mut().enumerate() {
                        let gap = q - q.max(min[g * d + i]).min(max[g * d + i]);
                        *a += w * gap * gap;
                    }
                }
            }
            None => {
                for i in 0..d {
                    let q = query[i];
                    for (g, a) in acc.iter_mut().enumerate() {
                        let gap = q - q.max(min[g * d + i]).min(max[g * d + i]);
                        *a += gap * gap;
                    }
                }
            }
        }
        acc
    }

    /// `(min, max)` of dimension `dim` over the valid frames of box `index` of `level` (frames
    /// `BOX_FRAMES[level]·index ..` one box on); `(+∞, −∞)` when it has none.
    pub fn bounds_of(&self, level: usize, index: usize, dim: usize) -> (f32, f32) {
        let at = (index / 4) * self.num_dims + dim;
        (self.min[level][at].to_array()[index % 4], self.max[level][at].to_array()[index % 4])
    }
}

/// `Σ_d w_d · gap_d²` per lane, in the operation order of the frame cost (see the module docs
/// for why that order makes the bound exact); `weights` `None`: every weight 1, whose
/// multiplication changes no bit and is left out.
///
/// The gap is `q − clamp(q, min, max)`: 0 inside the box, else `q − min` or `q − max`, the
/// negation of `min − q` (IEEE subtraction is exact under a sign change), so its square is that
/// of the distance to the box, in three lane operations instead of four.
#[inline(always)]
fn lower_bounds(min: &[F32x4], max: &[F32x4], query: &[F32x4], weights: Option<&[F32x4]>) -> F32x4 {
    let n = min.len();
    let (max, query) = (&max[..n], &query[..n]);
    let mut acc = F32x4::ZERO;
    match weights {
        Some(weights) => {
            let weights = &weights[..n];
            for d in 0..n {
                let q = query[d];
                let gap = q - q.max(min[d]).min(max[d]);
                acc += weights[d] * gap * gap;
            }
        }
        None => {
            for d in 0..n {
                let q = query[d];
                let gap = q - q.max(min[d]).min(max[d]);
                acc += gap * gap;
            }
        }
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 3 dims, 600 frames padded to 1024, frame `i` = (i, −i, i mod 7), in the lane layout.
    fn boxes(valid: impl Fn(usize) -> bool) -> (BoxBounds, Vec<f32>, Vec<bool>) {
        let (n, padded) = (600, PADDING);
        let features: Vec<f32> = (0..n).flat_map(|i| [i as f32, -(i as f32), (i % 7) as f32]).collect();
        let valid: Vec<bool> = (0..padded).map(|i| i < n && valid(i)).collect();
        let lanes: Vec<F32x4> = (0..padded / 4)
            .flat_map(|b| (0..3).map(move |d| (b, d)))
            .map(|(b, d)| {
                F32x4::from_array(std::array::from_fn(|l| features.get((4 * b + l) * 3 + d).copied().unwrap_or(0.0)))
            })
            .collect();
        (BoxBounds::from_lanes(&lanes, &valid, 3), features, valid)
    }

    #[test]
    fn boxes_hold_the_min_and_max_of_their_valid_frames() {
        let (b, _, _) = boxes(|i| i % 5 != 0);
        assert_eq!(std::array::from_fn(|l| b.num_boxes(l)), [256, 64, 16, 4]);
        // Leaf 1 = frames 16..32; 20, 25, 30 are invalid but not at the ends.
        assert_eq!(b.bounds_of(0, 1, 0), (16.0, 31.0));
        assert_eq!(b.bounds_of(0, 1, 1), (-31.0, -16.0));
        assert_eq!(b.bounds_of(0, 1, 2), (0.0, 6.0));
        // Leaf 0 = frames 0..16, frame 0 and 15 invalid.
        assert_eq!(b.bounds_of(0, 0, 0), (1.0, 14.0));
        // 64-frame box 2 = frames 128..192; top box 2 = frames 512..600 (the rest is padding).
        assert_eq!(b.bounds_of(1, 2, 0), (128.0, 191.0));
        assert_eq!(b.bounds_of(1, 0, 1), (-63.0, -1.0));
        assert_eq!(b.bounds_of(2, 2, 0), (512.0, 599.0));
        assert_eq!(b.bounds_of(2, 0, 1), (-254.0, -1.0));
        // Past the end: empty.
        assert_eq!(b.bounds_of(0, 40, 0), (f32::INFINITY, f32::NEG_INFINITY));
        assert_eq!(b.bounds_of(1, 10, 2), (f32::INFINITY, f32::NEG_INFINITY));
        assert_eq!(b.bounds_of(2, 3, 2), (f32::INFINITY, f32::NEG_INFINITY));
        // The 1024-frame top box 0 holds every frame; the others are padding.
        assert_eq!(b.bounds_of(3, 0, 0), (1.0, 599.0));
        assert_eq!(b.bounds_of(3, 1, 0), (f32::INFINITY, f32::NEG_INFINITY));
    }

    #[test]
    fn an_all_invalid_box_is_empty_and_never_beats_anything() {
        let (b, _, _) = boxes(|i| !(256..512).contains(&i));
        assert_eq!(b.bounds_of(2, 1, 0), (f32::INFINITY, f32::NEG_INFINITY));
        assert_eq!(b.bounds_of(1, 5, 0), (f32::INFINITY, f32::NEG_INFINITY));
        let q = [F32x4::splat(300.0), F32x4::splat(-300.0), F32x4::splat(3.0)];
        for w in [1.0, 0.0] {
            let bounds = b.lower_bounds(2, 0, &q, Some(&[F32x4::splat(w); 3])).to_array();
            // inf, or NaN when the weight is 0: either way `bound < best` is false.
            assert!(bounds[1] == f32::INFINITY || bounds[1].is_nan(), "{bounds:?}");
            assert!(bounds[3] == f32::INFINITY || bounds[3].is_nan(), "{bounds:?}");
            assert!(bounds[0] < f32::INFINITY && bounds[2] < f32::INFINITY);
        }
    }

    #[test]
    fn bounds_match_a_hand_computation_and_never_exceed_a_child_or_a_frame_cost() {
        let (b, features, valid) = boxes(|i| i % 3 != 1);
        let qv = [40.5f32, -100.0, 9.0];
        let wv = [0.5f32, 2.0, 1.0];
        let q: Vec<F32x4> = qv.iter().map(|&v| F32x4::splat(v)).collect();
        let w: Vec<F32x4> = wv.iter().map(|&v| F32x4::splat(v)).collect();
        // Leaf 2 = frames 32..48, valid range [32, 47] in dim 0, [-47, -32] in dim 1,
        // [0, 6] in dim 2 → gaps 0, 100 − 47 = 53, 3.
        let leaf = b.lower_bounds(0, 0, &q, Some(&w)).to_array();
        assert_eq!(leaf[2], 0.5 * 0.0 + 2.0 * 53.0 * 53.0 + 1.0 * 3.0 * 3.0);
        for level in 0..LEVELS {
            for index in 0..b.num_boxes(level) {
                let bound = b.lower_bounds(level, index / 4, &q, Some(&w)).to_array()[index % 4];
                if index + 16 <= b.num_boxes(level) {
                    let four = b.lower_bounds4(level, index / 4, &q, Some(&w))[0].to_array()[index % 4];
                    assert_eq!(four.to_bits(), bound.to_bits(), "level {level} box {index}: four at once differ");
                }
                if level > 0 {
                    for (c, &child) in b.lower_bounds(level - 1, index, &q, Some(&w)).to_array().iter().enumerate() {
                        assert!(
                            bound <= child || child.is_infinite(),
                            "level {level} box {index} bound {bound} > child {c} bound {child}"
                        );
                    }
                }
                let size = BOX_FRAMES[level];
                for frame in (index * size..index * size + size).filter(|&f| valid[f]) {
                    let cost: f32 = (0..3)
                        .map(|d| wv[d] * (qv[d] - features[frame * 3 + d]) * (qv[d] - features[frame * 3 + d]))
                        .sum();
                    assert!(bound <= cost, "level {level} frame {frame}: bound {bound} > cost {cost}");
                }
            }
        }
    }

    #[test]
    fn unit_weights_left_out_give_the_same_bits() {
        let (b, _, _) = boxes(|i| i % 4 != 2);
        let ones = [F32x4::splat(1.0); 3];
        for qv in [[40.5f32, -100.0, 9.0], [-3.25, 0.0, -0.0], [599.5, -17.0, 3.5]] {
            let q: Vec<F32x4> = qv.iter().map(|&v| F32x4::splat(v)).collect();
            for level in 0..LEVELS {
                for group in 0..b.num_boxes(level) / 4 {
                    let (with, without) =
                        (b.lower_bounds(level, group, &q, Some(&ones)), b.lower_bounds(level, group, &q, None));
                    assert_eq!(with.to_array().map(f32::to_bits), without.to_array().map(f32::to_bits));
                    if group + 4 <= b.num_boxes(level) / 4 {
                        let (with4, without4) =
                            (b.lower_bounds4(level, group, &q, Some(&ones)), b.lower_bounds4(level, group, &q, None));
                        assert_eq!(
                            with4.map(|v| v.to_array().map(f32::to_bits)),
                            without4.map(|v| v.to_array().map(f32::to_bits))
                        );
                        assert_eq!(with4[0].to_array().map(f32::to_bits), without.to_array().map(f32::to_bits));
                    }
                }
            }
        }
    }
}
