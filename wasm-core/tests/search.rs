//! The accelerated searches against the scalar brute force on a real database: 10,000 seeded
//! random queries (database rows plus noise, far-away vectors, random β's, exclusion windows,
//! tag masks, finite bars). Uses `public/databases/locomotion.mmdb` when it has been built
//! (`npm run build`), else builds a smaller database from `../shared/mocap`.

use mmcore::config::BuildConfig;
use mmcore::rng::Rng;
use mmcore::search::{self, SearchIndex, SearchMethod, SearchOptions};
use mmcore::tag_query::TagQuery;
use mmcore::{build, format, Bvh, Database, Source};
use std::path::Path;
use std::time::Instant;

fn database() -> (Database, &'static str) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let path = root.join("public/databases/locomotion.mmdb");
    if let Ok(bytes) = std::fs::read(&path) {
        return (format::from_bytes(&bytes).expect("locomotion.mmdb parses"), "locomotion.mmdb");
    }
    let files = ["cmu_16_15.bvh", "cmu_16_17.bvh", "cmu_16_35.bvh", "cmu_16_41.bvh", "cmu_127_13.bvh"];
    let sources: Vec<Source> = files
        .iter()
        .map(|f| {
            let p = root.join("../shared/mocap/cmu-asf").join(f);
            let bytes =
                std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e} (is ../shared beside the repo?)", p.display()));
            Source { name: f.to_string(), bvh: Bvh::parse(f, &bytes).unwrap() }
        })
        .collect();
    let config = BuildConfig::from_json(r#"{"mirror": true}"#).unwrap();
    (build(&config, &sources).unwrap().database, "5 files of ../shared/mocap (locomotion.mmdb not built)")
}

fn reference(db: &Database, query: &[f32], options: &SearchOptions, bar: f32) -> Option<(usize, f32)> {
    search::brute_force(db, query, options, 1).first().copied().filter(|&(_, c)| c < bar)
}

/// Same frame, or a cost equal within 1e-5 relative (a tie), and `None` exactly together.
fn agrees(got: Option<(usize, f32)>, expected: Option<(usize, f32)>) -> bool {
    match (got, expected) {
        (None, None) => true,
        (Some((f, c)), Some((ef, ec))) => f == ef || (c - ec).abs() <= 1e-5 * ec.abs().max(f32::MIN_POSITIVE),
        _ => false,
    }
}

#[test]
fn aabb_and_simd_equal_brute_force_on_10000_random_queries() {
    let (db, what) = database();
    let index = SearchIndex::new(&db).unwrap();
    let (f, d) = (db.num_frames, db.num_features());
    let valid: Vec<usize> = (0..f).filter(|&i| db.valid[i] != 0).collect();
    let trajectory: Vec<bool> = {
        let mut t = vec![false; d];
        for g in db.groups.iter().filter(|g| g.is_trajectory) {
            t[g.first_dim..g.first_dim + g.num_dims].fill(true);
        }
        t
    };
    let masks: Vec<Vec<bool>> = db.tags.iter().map(|t| db.tag_mask(&t.name).unwrap()).collect();
    let mut rng = Rng(0x5EED);
    let (mut exact, mut ties, mut nones) = (0, 0, 0);
    let mut query = vec![0.0f32; d];
    for i in 0..10_000 {
        let source = valid[rng.below(valid.len())];
        match rng.below(10) {
            // Far away: uniform in a large box, or huge.
            0 => query.iter_mut().for_each(|q| *q = rng.uniform(-20.0, 20.0)),
            1 => query.iter_mut().for_each(|q| *q = rng.uniform(-1e3, 1e3)),
            // A user changing direction: the row with only its trajectory part moved.
            2 | 3 => {
                query.copy_from_slice(db.feature(source));
                let s = rng.uniform(0.1, 2.0);
                query.iter_mut().zip(&trajectory).filter(|(_, &t)| t).for_each(|(q, _)| *q += s * rng.normal());
            }
            // A row plus noise of a random scale, sometimes none (an exact self-match).
            _ => {
                let s = [0.0, 0.01, 0.1, 0.5, 1.0][rng.below(5)];
                query.iter_mut().zip(db.feature(source)).for_each(|(q, &x)| *q = x + s * rng.normal());
            }
        }
        let pick = |rng: &mut Rng| match rng.below(8) {
            0 => 0.0,
            1 => 1.0,
            _ => rng.uniform(0.0, 3.0),
        };
        let (beta_pose, beta_trajectory) = (pick(&mut rng), pick(&mut rng));
        let exclude = match rng.below(4) {
            0 => None,
            1 => {
                let a = rng.below(f);
                Some((a, (a + rng.below(2000)).min(f)))
            }
            _ => Some((source.saturating_sub(20), source + 21)),
        };
        let mask = (!masks.is_empty() && rng.below(5) == 0).then(|| masks[rng.below(masks.len())].as_slice());
        // A tag query over the database's tags (the runtime's idle exclusion and styles): a
        // random tag required, excluded or preferred with a random bias, or none.
        let mut tags = TagQuery::default();
        let num_tags = db.tags.len().min(64);
        if num_tags > 0 {
            let bit = |rng: &mut Rng| if rng.below(2) == 0 { 1u64 << rng.below(num_tags) } else { 0 };
            tags = TagQuery {
                require: bit(&mut rng),
                exclude: bit(&mut rng),
                prefer: bit(&mut rng),
                bias: [0.0, 0.5, 2.0, 20.0][rng.below(4)],
            };
        }
        let exclude_recent = (rng.below(3) == 0).then(|| {
            let a = rng.below(f);
            (a, (a + 41).min(f))
        });
        let options = SearchOptions { beta_pose, beta_trajectory, exclude, exclude_recent, mask, tags };
        let best = reference(&db, &query, &options, f32::INFINITY);
        let bar = match rng.below(10) {
            // The runtime's bar: the cost of the frame playing now.
            0..=2 => index.cost(source, &query, &options),
            // Exactly the best cost (strictly-less ⇒ None), or just above / below it.
            3 => best.map_or(1.0, |b| b.1),
            4 => best.map_or(1.0, |b| b.1 * 1.001 + 1e-6),
            5 => best.map_or(1.0, |b| b.1 * 0.999),
            _ => f32::INFINITY,
        };
        let expected = reference(&db, &query, &options, bar);
        nones += expected.is_none() as usize;
        for method in SearchMethod::ALL {
            let got = index.search(method, &query, &options, bar);
            assert!(
                agrees(got, expected),
                "query {i} ({method:?}): got {got:?}, brute force {expected:?}; bar {bar}, β {beta_pose}/{beta_trajectory}, exclude {exclude:?}, mask {}",
                mask.is_some()
            );
            if got.map(|(f, c)| (f, c.to_bits())) == expected.map(|(f, c)| (f, c.to_bits())) {
                exact += 1;
            } else {
                ties += 1;
            }
        }
    }
    println!("{what}: {f} frames; 10000 queries × 3 methods: {exact} bit-identical, {ties} ties on another frame; {nones} expected None");
    assert!(nones > 500 && nones < 9500, "the bars should give a mix of None and Some ({nones})");
}

#[test]
fn index_build_time() {
    let (db, what) = database();
    let (_, median) = min_and_median_ms(&mut || drop(std::hint::black_box(SearchIndex::new(&db).unwrap())));
    println!(
        "SearchIndex::new on {what} ({} frames × {} dims): median {median:.2} ms",
        db.num_frames,
        db.num_features()
    );
    // Generous: the point is "a few ms, rebuild at load" (see aabb.rs).
    assert!(median < 100.0, "index build took {median} ms");
}

/// What loading costs (docs/mmdb-format.md, "What is not stored"): decoding the file and, in
/// it, deriving the features that version 3 does not store (velocities are derived a frame at
/// a time as it plays: every frame's, for comparison). Printed, not asserted.
#[test]
fn load_time() {
    let (db, what) = database();
    let bytes = format::to_bytes(&db);
    let load = min_and_median_ms(&mut || drop(std::hint::black_box(format::from_bytes(&bytes).unwrap())));
    let mut copy = db.clone();
    let velocities = min_and_median_ms(&mut || {
        std::hint::black_box(mmcore::database::pose_velocities(
            db.num_joints(),
            db.fps,
            &db.clips,
            &db.local_positions,
            &db.local_rotations,
        ));
    });
    let features = min_and_median_ms(&mut || copy.compute_features());
    println!(
        "format::from_bytes on {what} ({:.2} MB): min {:.1} / median {:.1} ms, of which deriving features {:.1} / {:.1} ms (every frame's velocities, not done at load: {:.1} / {:.1} ms)",
        bytes.len() as f64 / 1e6,
        load.0,
        load.1,
        features.0,
        features.1,
        velocities.0,
        velocities.1
    );
}

/// Seven timed runs of `f`: the fastest and the median, in ms (the minimum is what the code
/// costs, the median what a shared machine gives).
fn min_and_median_ms(f: &mut dyn FnMut()) -> (f64, f64) {
    let mut t: Vec<f64> = (0..7)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[0], t[3])
}
