//! Native search speed on a `.mmdb`, with the queries of the browser benchmark
//! (`web/src/bench/queries.ts`: a valid frame's features with the ground-plane trajectory turned
//! by up to ±135° and its positions scaled 0.6–1.4; ±20 frames around it excluded; bar +∞):
//! `cargo run --release --example search_speed -- DB.mmdb [QUERIES] [ROUNDS]`.
//! Prints per-search median and p95 (each query its fastest round) for every method, so a change
//! to the search can be measured natively before the WASM build (`npm run bench`).
//! `AABB_ONLY=1`: only the AABB searches (no SIMD check or timing), for counting a search's
//! instructions: `valgrind --tool=cachegrind --cache-sim=no` over it, divided by 20 × QUERIES × ROUNDS.

use mmcore::database::{Axes, FeatureKind};
use mmcore::search::{SearchIndex, SearchMethod, SearchOptions};
use mmcore::Database;
use std::time::Instant;

/// mulberry32, as `seededRandom` in queries.ts (uniform in [0, 1)).
struct Mulberry32(u32);

impl Mulberry32 {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x6d2b_79f5);
        let mut t = self.0;
        t = (t ^ (t >> 15)).wrapping_mul(t | 1);
        t ^= t.wrapping_add((t ^ (t >> 7)).wrapping_mul(t | 61));
        f64::from(t ^ (t >> 14)) / 4_294_967_296.0
    }
}

fn queries(db: &Database, index: &SearchIndex, count: usize) -> Vec<(usize, Vec<f32>)> {
    let d = db.num_features();
    let mut random = Mulberry32(1);
    let mut out = Vec::with_capacity(count);
    while out.len() < count {
        let source = (random.next() * db.num_frames as f64) as usize;
        if !index.is_valid(source) {
            continue;
        }
        let mut values = db.features[source * d..(source + 1) * d].to_vec();
        let angle = (random.next() * 2.0 - 1.0) * 0.75 * std::f64::consts::PI;
        let speed = (0.6 + 0.8 * random.next()) as f32;
        let (s, c) = (angle.sin() as f32, angle.cos() as f32);
        for g in db.groups.iter().filter(|g| g.is_trajectory && g.axes == Axes::Xz) {
            let factor = if g.kind == FeatureKind::Position { speed } else { 1.0 };
            for dim in (g.first_dim..g.first_dim + g.num_dims - 1).step_by(2) {
                let (mx, mz, scale) = (db.feature_mean[dim], db.feature_mean[dim + 1], db.feature_scale[dim]);
                let (x, z) = (values[dim] * scale + mx, values[dim + 1] * scale + mz);
                values[dim] = (factor * (c * x + s * z) - mx) / scale;
                values[dim + 1] = (factor * (-s * x + c * z) - mz) / scale;
            }
        }
        out.push((source, values));
    }
    out
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().expect("usage: search_speed DB.mmdb [QUERIES] [ROUNDS]");
    let count: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(2000);
    let rounds: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(5);
    let db = mmcore::format::from_bytes(&std::fs::read(path).expect("readable .mmdb")).expect("a valid .mmdb");
    let index = SearchIndex::new(&db).expect("an index");
    let qs = queries(&db, &index, count);
    let options =
        |source: usize| SearchOptions { exclude: Some((source.saturating_sub(20), source + 21)), ..Default::default() };
    let mut mismatches = 0;
    for (source, q) in qs.iter().filter(|_| std::env::var_os("AABB_ONLY").is_none()) {
        let reference = index.search(SearchMethod::Simd, q, &options(*source), f32::INFINITY);
        if index.search(SearchMethod::Aabb, q, &options(*source), f32::INFINITY) != reference {
            mismatches += 1;
        }
    }
    println!(
        "{path}: {} frames × {} dims, {count} queries, {mismatches} AABB results differing from SIMD",
        db.num_frames,
        db.num_features()
    );
    let methods: &[SearchMethod] = if std::env::var_os("AABB_ONLY").is_some() {
        &[SearchMethod::Aabb]
    } else {
        &[SearchMethod::Simd, SearchMethod::Aabb]
    };
    for &method in methods {
        let reps = if method == SearchMethod::Aabb { 20 } else { 2 };
        let mut best = vec![f64::INFINITY; qs.len()];
        for _ in 0..rounds {
            for (i, (source, q)) in qs.iter().enumerate() {
                let o = options(*source);
                let t = Instant::now();
                for _ in 0..reps {
                    std::hint::black_box(index.search(method, std::hint::black_box(q), &o, f32::INFINITY));
                }
                best[i] = best[i].min(t.elapsed().as_secs_f64() * 1e6 / reps as f64);
            }
        }
        best.sort_by(f64::total_cmp);
        let at = |p: f64| best[((best.len() - 1) as f64 * p) as usize];
        println!("{:>6}: median {:>8.2} µs, p95 {:>8.2} µs", method.name(), at(0.5), at(0.95));
    }
}
