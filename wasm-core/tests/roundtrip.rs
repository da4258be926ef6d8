//! The round-trip property on every `cargo test` (issue 28): anything `build` accepts, `load`
//! accepts and a character plays (finite output, root within α). The generator and the checks
//! are the AFL target's (`fuzz/src/roundtrip.rs`); here they run on the committed seeds and
//! findings (`fuzz/corpus/roundtrip`, `fuzz/regressions/roundtrip`) and on fixed-seed random
//! cases — random configurations and BVH takes around every limit.

#[path = "../fuzz/src/roundtrip.rs"]
mod property;

use mmcore::rng::Rng;
use property::Verdict;
use std::path::Path;

/// Cases per run: bounded so `npm test` stays quick (~1 min in the test-opt profile).
const CASES: usize = 600;

#[test]
fn committed_round_trip_corpus_replays() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut count = 0;
    for sub in ["corpus/roundtrip", "regressions/roundtrip"] {
        let Ok(entries) = std::fs::read_dir(dir.join(sub)) else { continue };
        for e in entries {
            let path = e.unwrap().path();
            let bytes = std::fs::read(&path).unwrap();
            let outcome = std::panic::catch_unwind(|| property::check_round_trip(&bytes));
            assert!(outcome.is_ok(), "{}", path.display());
            count += 1;
        }
    }
    assert!(count >= 4, "only {count} committed round-trip cases");
}

#[test]
fn random_builds_load_and_play() {
    let mut rng = Rng(28);
    let (mut played, mut refused, mut frames) = (0, 0, 0);
    let mut reasons: std::collections::BTreeMap<String, usize> = Default::default();
    for i in 0..CASES {
        let bytes: Vec<u8> = (0..400).map(|_| (rng.next_u64() >> 24) as u8).collect();
        match std::panic::catch_unwind(|| property::check_round_trip(&bytes)) {
            Ok(Verdict::Played { frames: n }) => {
                played += 1;
                frames += n;
            }
            Ok(Verdict::Refused(e)) => {
                refused += 1;
                let reason: String =
                    e.split(|c: char| c.is_ascii_digit()).next().unwrap_or("").chars().take(50).collect();
                *reasons.entry(reason).or_default() += 1;
            }
            Err(_) => panic!("case {i} broke the round trip: {:?}", property::generate(&bytes).config),
        }
    }
    eprintln!("round trip: {CASES} random cases, {played} built, loaded and played ({frames} frames in all), {refused} refused: {reasons:#?}");
    // The generator must exercise the property, not only the refusals.
    assert!(played >= CASES / 3, "only {played} of {CASES} cases built");
}
