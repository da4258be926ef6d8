//! `.mmdb` mutations as tests: at least 2,000 deterministic mutations of the seed files
//! (`hostile::mmdb_mutations`) each load into a database the runtime can play, or fail with a
//! clear error — never a panic, a hang, or heap use beyond
//! `limits::MMDB_ALLOCATION_FACTOR` × the file size + 64 KiB.

use crate::hostile;

use hostile::{alloc, Case, Expect};
use mmcore::character::CharacterSettings;
use mmcore::limits::{MAX_FPS, MAX_MESSAGE_CHARS, MIN_FPS, MMDB_ALLOCATION_FACTOR};
use mmcore::search::{SearchIndex, SearchMethod, SearchOptions};
use mmcore::{format, inspect, Database};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::time::{Duration, Instant};

/// The seed files: the handmade tiny database and the committed humanoid build.
fn seeds() -> Vec<(String, Vec<u8>)> {
    let humanoid = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/mmdb/humanoid.mmdb");
    vec![
        ("tiny".into(), format::to_bytes(&hostile::tiny_database())),
        (
            "humanoid".into(),
            std::fs::read(&humanoid).unwrap_or_else(|e| {
                panic!(
                    "{}: {e} (write it with `cargo run --release --bin mmdb-cases -- --seeds fuzz/corpus`)",
                    humanoid.display()
                )
            }),
        ),
    ]
}

/// What a loaded database must allow: the summary, an index and a search, a character
/// playing it for half a second, a round trip within the quantization bound. Returns what went wrong.
fn exercise(db: &Database) -> Option<String> {
    if !((MIN_FPS as f32..=MAX_FPS as f32).contains(&db.fps)
        && db.num_frames >= 1
        && !db.groups.is_empty()
        && db.num_features() >= 1)
    {
        return Some("loaded a database outside the documented limits".into());
    }
    let started = Instant::now();
    let run = catch_unwind(AssertUnwindSafe(|| {
        let summary = inspect::summary(db, None);
        let _ = inspect::text(db, None);
        let index = SearchIndex::new(db).map_err(|e| format!("index: {e}"))?;
        let query = db.feature(db.num_frames / 2).to_vec();
        index.search(SearchMethod::Aabb, &query, &SearchOptions::default(), f32::INFINITY);
        let mut crowd = mmcore::crowd::Crowd::new(db, 1, &CharacterSettings::default(), db.toe_height_in_contact())?;
        for step in 0..30 {
            crowd.inputs[0].direction = glam::Vec2::new((step as f32).sin(), 1.0);
            crowd.update(db, &index, 1.0 / 60.0);
        }
        match format::from_bytes(&format::to_bytes(db)) {
            Ok(again) => {
                format::check_round_trip(db, &again).map_err(|e| format!("round trip changed the database: {e}"))?
            }
            // A version-1/2 file stores features its poses need not give; written as version 3
            // (features derived) the derived ones may be out of bounds: a clear error is right.
            Err(e)
                if e.to_string().contains("features derived from PANM and QROT")
                    && db.derived_features() != db.features => {}
            Err(e) => return Err(format!("round trip: {e}")),
        }
        Ok(summary["num_frames"].as_u64())
    }));
    match run {
        Err(_) => Some("the runtime panicked on a database the loader accepted".into()),
        Ok(Err(e)) => Some(e),
        Ok(Ok(_)) if started.elapsed() > Duration::from_secs(2) => {
            Some(format!("playing took {:?}", started.elapsed()))
        }
        Ok(Ok(_)) => None,
    }
}

fn check(case: &Case) -> Option<String> {
    let name = &case.name;
    let started = Instant::now();
    let (result, peak) = alloc::measure(|| catch_unwind(AssertUnwindSafe(|| format::from_bytes(&case.bytes))));
    let elapsed = started.elapsed();
    let Ok(result) = result else { return Some(format!("{name}: the loader panicked")) };
    let bound = MMDB_ALLOCATION_FACTOR * case.bytes.len() + (64 << 10);
    if peak > bound {
        return Some(format!("{name}: peak heap {peak} B exceeds the bound {bound} B"));
    }
    if elapsed > Duration::from_secs(1) {
        return Some(format!("{name}: loading took {elapsed:?}"));
    }
    match (result, &case.expect) {
        (Ok(db), Expect::Ok | Expect::Either) => exercise(&db).map(|e| format!("{name}: {e}")),
        (Ok(_), Expect::Error(w)) => Some(format!("{name}: loaded, expected an error containing {w:?}")),
        (Err(e), Expect::Ok) => Some(format!("{name}: expected to load, got: {e}")),
        (Err(e), want) => {
            let m = e.to_string();
            if !m.starts_with("invalid .mmdb: ") || m.chars().count() > MAX_MESSAGE_CHARS + 20 {
                return Some(format!("{name}: unclear message: {m}"));
            }
            match want {
                Expect::Error(w) if !m.contains(w.as_str()) => {
                    Some(format!("{name}: got {m:?}, expected it to contain {w:?}"))
                }
                _ => None,
            }
        }
    }
}

#[test]
fn seeds_load_and_play() {
    for (name, bytes) in seeds() {
        let db = format::from_bytes(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(exercise(&db), None, "{name}");
    }
}

/// The cases the issue names (a flipped fps bit, no feature groups, an empty last group, no
/// frames, NaN and zero scales, huge counts, overlapping sections): each its exact message.
#[test]
fn named_cases_give_their_messages() {
    let failures: Vec<String> = hostile::mmdb_named_cases().iter().filter_map(check).collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn mutations_are_clear_errors_or_playable_databases() {
    let mut total = 0;
    let mut loaded = 0;
    let mut failures = Vec::new();
    for (seed_name, seed) in seeds() {
        let cases = hostile::mmdb_mutations(&seed_name, &seed);
        total += cases.len();
        for case in &cases {
            loaded += format::from_bytes(&case.bytes).is_ok() as usize;
            failures.extend(check(case));
        }
    }
    println!("{total} .mmdb mutations: {loaded} loaded (and played), {} rejected", total - loaded);
    assert!(total >= 2000, "the issue asks for at least 2,000 mutations ({total})");
    assert!(
        failures.is_empty(),
        "{} of {total} mutations failed:\n{}",
        failures.len(),
        failures.iter().take(40).cloned().collect::<Vec<_>>().join("\n")
    );
}

/// The fuzzers' seed corpus and saved findings (`fuzz/corpus/mmdb`, `fuzz/regressions/mmdb`),
/// raw and with size and checksum rewritten (what the fuzz target does).
#[test]
fn committed_corpus_replays() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut failures = Vec::new();
    let mut n = 0;
    for dir in ["corpus/mmdb", "regressions/mmdb"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir)) else { continue };
        for e in entries.flatten() {
            let bytes = std::fs::read(e.path()).unwrap();
            let mut fixed = bytes.clone();
            hostile::refix(&mut fixed);
            for (kind, b) in [("raw", bytes), ("fixed", fixed)] {
                n += 1;
                failures.extend(check(&Case {
                    name: format!("{dir}/{}.{kind}", e.file_name().to_string_lossy()),
                    bytes: b,
                    expect: Expect::Either,
                }));
            }
        }
    }
    println!("{n} committed .mmdb corpus cases");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
