//! The character-update fuzz property on every `cargo test`: the committed seeds and the
//! fuzzer's saved findings (`fuzz/corpus/character`, `fuzz/regressions/character`), then a
//! fixed-seed run of random call sequences whose values are drawn mostly from the troublemakers
//! (NaN, ±∞, ±1e38, 0, negative, subnormal) — the CI form of the AFL target.

#[path = "../fuzz/src/character.rs"]
mod character;

use mmcore::rng::Rng;
use std::path::Path;

const NASTY: [f32; 12] =
    [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e38, -1e38, 0.0, -0.0, -1.0, 1e-40, 1e9, 0.25, 1.0 / 60.0];

#[test]
fn committed_character_corpus_replays() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut count = 0;
    for sub in ["corpus/character", "regressions/character"] {
        let Ok(entries) = std::fs::read_dir(dir.join(sub)) else { continue };
        for e in entries {
            let path = e.unwrap().path();
            let bytes = std::fs::read(&path).unwrap();
            let outcome = std::panic::catch_unwind(|| character::check_character(&bytes));
            assert!(outcome.is_ok(), "{}", path.display());
            count += 1;
        }
    }
    assert!(count >= 8, "only {count} committed character cases");
}

#[test]
fn random_call_sequences_keep_the_character_finite_and_near_its_simulation() {
    let mut rng = Rng(13);
    for case in 0..4000 {
        let ops = 4 + (rng.uniform(0.0, 60.0) as usize);
        let mut bytes = Vec::new();
        for _ in 0..ops {
            bytes.push(rng.uniform(0.0, 256.0) as u8);
            for _ in 0..12 {
                // Mostly whole floats (troublemakers or ordinary values), sometimes raw bytes.
                let x = rng.uniform(0.0, 1.0);
                let v = if x < 0.5 {
                    NASTY[(rng.uniform(0.0, NASTY.len() as f32) as usize).min(NASTY.len() - 1)]
                } else {
                    rng.uniform(-3.0, 3.0)
                };
                if x < 0.9 {
                    bytes.extend(v.to_le_bytes());
                } else {
                    bytes.push(rng.uniform(0.0, 256.0) as u8);
                }
            }
        }
        let outcome = std::panic::catch_unwind(|| character::check_character(&bytes));
        if outcome.is_err() {
            let out = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("target/character-failure-{case}.bin"));
            std::fs::write(&out, &bytes).unwrap();
            panic!("case {case} broke a property; its bytes are in {}", out.display());
        }
    }
}
