//! Malformed BVH as tests: every case of `hostile::bvh_cases()` (and the big generated ones)
//! is a clear error naming the file and line, or a valid result — never a panic, a hang, or
//! heap use beyond `limits::BVH_ALLOCATION_FACTOR` × its size + 1 MiB. Parsed files that look
//! like a body also go through the builder and the `.mmdb` round trip.

use crate::hostile;

use hostile::{alloc, Case, Expect};
use mmcore::config::BuildConfig;
use mmcore::limits::{BVH_ALLOCATION_FACTOR, MAX_FRAME_TIME, MAX_JOINTS, MAX_MESSAGE_CHARS, MIN_FRAME_TIME};
use mmcore::{format, Bvh, Source};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::time::{Duration, Instant};

const FILE: &str = "case.bvh";

/// Parses one case and returns a description of what is wrong with the outcome, if anything.
fn check(case: &Case) -> Option<String> {
    let name = &case.name;
    let started = Instant::now();
    let (result, peak) = alloc::measure(|| catch_unwind(AssertUnwindSafe(|| Bvh::parse(FILE, &case.bytes))));
    let elapsed = started.elapsed();
    let Ok(result) = result else { return Some(format!("{name}: panicked")) };
    let bound = BVH_ALLOCATION_FACTOR * case.bytes.len() + (1 << 20);
    if peak > bound {
        return Some(format!("{name}: peak heap {peak} B exceeds the bound {bound} B"));
    }
    // 20 MB/s is far below the parser's speed even on a loaded 2-core machine.
    let budget = Duration::from_secs(2) + Duration::from_secs_f64(case.bytes.len() as f64 / 20e6);
    if elapsed > budget {
        return Some(format!("{name}: took {elapsed:?} (budget {budget:?})"));
    }
    match (&result, &case.expect) {
        (Ok(bvh), Expect::Ok | Expect::Either) => {
            let ok = bvh.values.len() == bvh.num_frames * bvh.num_channels
                && bvh.joints.len() <= MAX_JOINTS
                && (MIN_FRAME_TIME..=MAX_FRAME_TIME).contains(&bvh.frame_time)
                && bvh.values.iter().all(|v| v.is_finite());
            (!ok).then(|| format!("{name}: parsed into an inconsistent Bvh"))
        }
        (Ok(_), Expect::Error(want)) => Some(format!("{name}: parsed, expected an error containing {want:?}")),
        (Err(e), Expect::Ok) => Some(format!("{name}: expected to parse, got: {e}")),
        (Err(e), want) => {
            let m = e.to_string();
            if m.chars().count() > MAX_MESSAGE_CHARS + FILE.len() + 20 {
                return Some(format!("{name}: message of {} chars", m.chars().count()));
            }
            let located = m.starts_with(&format!("{FILE}:"))
                && (m.starts_with(&format!("{FILE}: end of file: "))
                    || m[FILE.len() + 1..].split(':').next().is_some_and(|l| l.parse::<usize>().is_ok_and(|l| l > 0)));
            if !located {
                return Some(format!("{name}: message does not name file and line: {m}"));
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

fn check_all(cases: &[Case]) {
    let failures: Vec<String> = cases.iter().filter_map(check).collect();
    assert!(failures.is_empty(), "{} of {} cases failed:\n{}", failures.len(), cases.len(), failures.join("\n"));
}

#[test]
fn malformed_bvh_cases_give_clear_errors() {
    let cases = hostile::bvh_cases();
    let (ok, err) = (
        cases.iter().filter(|c| c.expect == Expect::Ok).count(),
        cases.iter().filter(|c| matches!(c.expect, Expect::Error(_))).count(),
    );
    println!(
        "{} BVH cases: {ok} valid, {err} errors with an expected message, {} either",
        cases.len(),
        cases.len() - ok - err
    );
    assert!(err >= 60, "the issue asks for at least 60 malformed cases ({err})");
    check_all(&cases);
}

#[test]
fn big_generated_cases() {
    check_all(&hostile::big_bvh_cases());
}

/// A 200 MB file parses at full speed within the documented memory bound.
#[test]
fn a_200_mb_file() {
    let bytes = hostile::huge_valid_bvh(200_000_000);
    let case = Case { name: "valid_200mb".into(), bytes, expect: Expect::Ok };
    if let Some(f) = check(&case) {
        panic!("{f}");
    }
}

/// Valid cases that carry a body (the humanoid) build, and the database reloads.
#[test]
fn valid_cases_build_and_reload() {
    for case in hostile::bvh_cases().iter().filter(|c| c.expect == Expect::Ok && c.name.contains("humanoid")) {
        let source = Source { name: case.name.clone(), bvh: Bvh::parse(FILE, &case.bytes).unwrap() };
        let db = mmcore::build(&BuildConfig::default(), &[source]).unwrap().database;
        let again = format::from_bytes(&format::to_bytes(&db)).unwrap();
        format::check_round_trip(&db, &again).unwrap_or_else(|e| panic!("{}: {e}", case.name));
    }
}

/// Files in the fuzz seed corpus and the fuzzers' saved findings (`fuzz/corpus/bvh`,
/// `fuzz/regressions/bvh`): each a clear error or a valid result.
#[test]
fn committed_corpus_replays() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut cases = Vec::new();
    for dir in ["corpus/bvh", "corpus/build", "regressions/bvh", "regressions/build"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir)) else { continue };
        for e in entries.flatten() {
            cases.push(Case {
                name: format!("{dir}/{}", e.file_name().to_string_lossy()),
                bytes: std::fs::read(e.path()).unwrap(),
                expect: Expect::Either,
            });
        }
    }
    println!("{} committed BVH corpus files", cases.len());
    check_all(&cases);
}

/// The CI form of fuzzing the parser and the builder: 20,000 random mutations (fixed seed) of
/// the valid small cases; each parses or fails clearly, and what parses and looks like a body
/// builds (or is refused with an error) into a database its loader accepts.
#[test]
fn bounded_random_mutation_run() {
    // Valid inputs only (mutants of errors stay errors), the humanoid three times over.
    let mut seeds: Vec<Vec<u8>> = hostile::bvh_cases()
        .into_iter()
        .filter(|c| c.bytes.len() <= 64 << 10 && c.expect == Expect::Ok)
        .map(|c| c.bytes)
        .collect();
    seeds.extend([12, 30, 60].map(|f| hostile::humanoid_bvh(f).into_bytes()));
    let mut rng = hostile::Rng(0x5EED_B7B5_0000_0001);
    let config = BuildConfig { fps: 30.0, mirror: false, ..BuildConfig::default() };
    let (mut failures, mut parsed, mut built) = (Vec::new(), 0, 0);
    for i in 0..20_000 {
        let bytes = hostile::mutate(&seeds[rng.below(seeds.len())], &mut rng);
        let case = Case { name: format!("mutation {i}"), bytes, expect: Expect::Either };
        if let Some(f) = check(&case) {
            failures.push(f);
            continue;
        }
        let Ok(bvh) = Bvh::parse(FILE, &case.bytes) else { continue };
        parsed += 1;
        if bvh.joints.len() < 5 {
            continue;
        }
        let started = Instant::now();
        let source = Source { name: FILE.into(), bvh };
        match catch_unwind(AssertUnwindSafe(|| mmcore::build(&config, &[source]))) {
            Err(_) => failures.push(format!("mutation {i}: the builder panicked")),
            Ok(Err(_)) => {}
            Ok(Ok(out)) => {
                built += 1;
                if let Err(e) = format::from_bytes(&format::to_bytes(&out.database)) {
                    failures.push(format!("mutation {i}: the builder wrote a database its loader refuses: {e}"));
                }
            }
        }
        if started.elapsed() > Duration::from_secs(2) {
            failures.push(format!("mutation {i}: building took {:?}", started.elapsed()));
        }
    }
    println!("20000 mutations: {parsed} parsed, {built} built");
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.iter().take(30).cloned().collect::<Vec<_>>().join("\n")
    );
}
