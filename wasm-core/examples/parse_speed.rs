//! Parse speed of every BVH file listed in `../shared/mocap/manifest.json` (native, release):
//! `cargo run --release --example parse_speed [-- ROUNDS]`. Prints the best and median MB/s
//! over the rounds, so hardening changes to the parser can be checked for speed regressions.

use std::path::Path;
use std::time::Instant;

fn main() {
    let rounds: usize = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(15);
    let mocap = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/mocap");
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(mocap.join("manifest.json")).expect("../shared/mocap/manifest.json"))
            .unwrap();
    let files: Vec<(String, Vec<u8>)> = manifest
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            let rel = format!("{}/{}", e["folder"].as_str().unwrap(), e["file"].as_str().unwrap());
            let bytes = std::fs::read(mocap.join(&rel)).unwrap();
            (rel, bytes)
        })
        .collect();
    let megabytes = files.iter().map(|(_, b)| b.len()).sum::<usize>() as f64 / 1e6;
    let mut times = Vec::new();
    for _ in 0..rounds {
        let t = Instant::now();
        for (name, bytes) in &files {
            std::hint::black_box(mmcore::Bvh::parse(name, bytes).unwrap());
        }
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    println!(
        "{} files, {megabytes:.1} MB: best {:.0} MB/s, median {:.0} MB/s ({rounds} rounds)",
        files.len(),
        megabytes / times[0],
        megabytes / times[times.len() / 2]
    );
}
