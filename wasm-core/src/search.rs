//! Finding the database frame whose features best match a query (THESIS_NOTES §3).
//! This is the scalar brute-force reference; the accelerated searches must equal it.

use crate::database::Database;

/// Per-search options. `Default` is β_q = β_r = 1, no exclusion, no tag mask.
#[derive(Clone, Debug)]
pub struct SearchOptions<'a> {
    /// Multiplies the pose groups' cost (quality).
    pub beta_pose: f32,
    /// Multiplies the trajectory groups' cost (responsiveness).
    pub beta_trajectory: f32,
    /// Frames `[from, to)` that may not be returned (e.g. ±20 around the current frame).
    pub exclude: Option<(usize, usize)>,
    /// Only frames where the mask is true may be returned.
    pub mask: Option<&'a [bool]>,
}

impl Default for SearchOptions<'_> {
    fn default() -> Self {
        SearchOptions { beta_pose: 1.0, beta_trajectory: 1.0, exclude: None, mask: None }
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
    let mut best: Vec<(usize, f32)> = Vec::with_capacity(k + 1);
    for (frame, row) in db.features.chunks_exact(d).enumerate() {
        if db.valid[frame] == 0
            || options.exclude.is_some_and(|(a, b)| (a..b).contains(&frame))
            || options.mask.is_some_and(|m| !m[frame])
        {
            continue;
        }
        let cost: f32 = row.iter().zip(query).zip(&weights).map(|((f, q), w)| w * (q - f) * (q - f)).sum();
        if best.len() < k || cost < best[best.len() - 1].1 {
            let at = best.partition_point(|&(_, c)| c <= cost);
            best.insert(at, (frame, cost));
            best.truncate(k);
        }
    }
    best
}
