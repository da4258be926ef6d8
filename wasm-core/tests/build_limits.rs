//! The builder's limits, checked before work starts (issue 28): the memory a build will need is
//! estimated up front and bounds what it really holds; a build over it is refused before
//! anything is allocated; a take that reaches too far once scaled, feature dimensions the
//! search cannot take and leg ratios the loader refuses never become a database the loader
//! refuses. `docs/robustness.md` ("Limits") names these tests.

use crate::common;
use crate::hostile;

use common::{config, source};
use hostile::alloc;
use mmcore::limits::{BuildFootprint, MAX_BUILD_BYTES};
use mmcore::{build, format, Bvh, Source};

fn parsed(name: &str, text: &str) -> Source {
    Source { name: name.into(), bvh: Bvh::parse(name, text.as_bytes()).unwrap() }
}

/// The first `frames` frames of a real take with `Frame Time:` replaced: the issue's 563 kB,
/// 600-frame, 31-joint file with `Frame Time: 1`.
fn cut(rel: &str, frames: usize, frame_time: &str) -> String {
    let text = std::fs::read_to_string(common::mocap().join(rel)).unwrap();
    let (head, motion) = text.split_once("MOTION").unwrap();
    let lines: Vec<&str> = motion.lines().filter(|l| !l.trim().is_empty()).skip(3).take(frames).collect();
    format!("{head}MOTION\nFrames: {frames}\nFrame Time: {frame_time}\n{}\n", lines.join("\n"))
}

/// Builds and writes the database as the page does (`RawBuilder.build`) and returns the
/// estimate and the peak heap above what the sources already held.
fn measured(json: &str, sources: &[Source]) -> (BuildFootprint, usize) {
    let ((footprint, bytes), peak) = alloc::measure(|| {
        let out = build(&config(json), sources).unwrap();
        let bytes = format::to_bytes(&out.database);
        (out.footprint, bytes.len())
    });
    assert!(bytes > 0);
    (footprint, peak)
}

/// The estimate is an upper bound of the heap a single-threaded build holds (what WASM runs),
/// and not a wild one: on builds of tens of MB the counted peak is a large share of it.
#[test]
fn the_memory_estimate_bounds_what_a_build_holds() {
    // One thread, so the counting allocator (per thread) sees every allocation; the takes are
    // built one after the other as in WASM.
    std::env::set_var("MMDB_THREADS", "1");
    let walk = parsed("walk.bvh", &hostile::humanoid_bvh(600));
    let cmu = source("cmu-asf/cmu_02_06.bvh");
    let style = source("100style/Angry_BW.bvh");
    let cases: Vec<(&str, Vec<Source>)> = vec![
        (r#"{}"#, vec![walk]),
        (r#"{"fps": 1000, "mirror": false}"#, vec![parsed("walk.bvh", &hostile::humanoid_bvh(600))]),
        (
            r#"{"fps": 120, "reverse": true, "motion_tags": true}"#,
            vec![parsed("walk.bvh", &hostile::humanoid_bvh(600))],
        ),
        (r#"{}"#, vec![source("cmu-asf/cmu_02_06.bvh")]),
        (r#"{"fps": 240, "mirror": false}"#, vec![cmu]),
        (r#"{"fps": 1000, "mirror": false}"#, vec![source("cmu-asf/cmu_02_06.bvh")]),
        // A second skeleton, retargeted onto the first.
        (r#"{"fps": 30}"#, vec![source("cmu-asf/cmu_02_06.bvh"), style]),
        // 128 dimensions, the most the search takes.
        (
            r#"{"features": [{"name": "t", "kind": "position", "joint": "root", "offsets": [0,1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17,18,19,20,21,22,23,24,25,26,27,28,29,30,31,32,33]},
                             {"name": "h", "kind": "velocity", "joint": "hips", "offsets": [0,1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16,17,18,19]}]}"#,
            vec![source("cmu-asf/cmu_02_06.bvh")],
        ),
    ];
    for (json, sources) in &cases {
        let (footprint, peak) = measured(json, sources);
        let estimate = footprint.bytes() - footprint.source_bytes;
        let share = peak as f64 / estimate as f64;
        eprintln!(
            "{json:.40} {} frames: peak {:.1} MB, estimate {:.1} MB ({:.0} %)",
            footprint.frames,
            peak as f64 / 1e6,
            estimate as f64 / 1e6,
            100.0 * share
        );
        assert!(peak as u64 <= estimate, "{json}: the build held {peak} B, more than the {estimate} B estimated");
        // Past the fixed 48 MiB allowance for small things the estimate is within 2× of the peak.
        assert!(
            (estimate - (48 << 20)) as f64 <= 2.0 * peak as f64,
            "{json}: estimate {estimate} B for a peak of {peak} B"
        );
    }
}

/// Issue 28, case 1: 600 frames at `Frame Time: 1` built at 1,000 fps is 599,001 frames, inside
/// the 1 GiB and 2²⁴-frame limits, but its working copies need ~4 GB: the WASM builder trapped
/// at 3.7 GB. Now it is refused with the estimate, before anything is allocated.
#[test]
fn a_600_frame_take_at_1_fps_built_at_1000_fps_is_refused_before_allocating() {
    let text = cut("cmu-asf/cmu_02_06.bvh", 600, "1");
    let slow = parsed("slow.bvh", &text);
    let (result, peak) =
        alloc::measure(|| build(&config(r#"{"fps": 1000, "mirror": false}"#), std::slice::from_ref(&slow)).map(|_| ()));
    let e = result.unwrap_err().to_string();
    assert!(
        e.contains("the build would need about 3.9 GB of memory")
            && e.contains("599001 frames")
            && e.contains("more than the 3.2 GB a build may use"),
        "{e}"
    );
    assert!(peak < 64 << 20, "{peak} B held before refusing");
    // The same take at 100 fps is well inside (60,000 frames).
    let out = build(&config(r#"{"fps": 100, "mirror": false}"#), &[slow]).unwrap();
    assert!(out.footprint.bytes() < MAX_BUILD_BYTES / 4);
    format::from_bytes(&format::to_bytes(&out.database)).unwrap();
}

/// Issue 28, case 3: every number ≤ 10⁷ with `--scale 1000 --fps 1000` built, and its own
/// loader refused it ("FNRM: scale of dim 6 is 1.34e12"). Refused now by the take's reach,
/// before resampling; a take that fits loads.
#[test]
fn a_take_scaled_past_its_reach_is_refused_and_what_builds_loads() {
    let text = hostile::humanoid_bvh(60).replace("Frame Time: 0.00833333", "Frame Time: 0.001");
    // The root jumps ±10⁷ units sideways every other frame at 1,000 fps (every value ≤ 10⁷):
    // at 1,000 m per unit the build wrote a file its loader refused ("FNRM: scale of dim 6 is
    // 3.3049718e12", the left foot's velocity).
    let far: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i >= 76 {
                l.replacen(
                    "0.000000 0.950000",
                    if (i - 76) / 2 % 2 == 0 { "10000000 0.950000" } else { "-10000000 0.950000" },
                    1,
                )
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let far = parsed("far.bvh", &far);
    let e = build(&config(r#"{"scale": 1000, "fps": 1000, "mirror": false}"#), std::slice::from_ref(&far))
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("far.bvh: its values times the unit scale 1000 reach") && e.contains("at most 100000 m"), "{e}");
    // At 1 mm per unit the same take jumps 10 km: it builds, and loads.
    let out = build(&config(r#"{"scale": 0.001, "fps": 1000, "mirror": false}"#), &[far]).unwrap();
    format::from_bytes(&format::to_bytes(&out.database)).unwrap();
}

/// A second take whose legs are 10,000× shorter than the reference's: its root scale of 10⁴
/// was written, and the loader refuses anything beyond 10³ ("CLIP root scale"). Its root
/// motion now stays unscaled (with a warning) and the database loads.
#[test]
fn a_leg_ratio_beyond_the_loader_s_root_scale_is_not_applied() {
    let walk = hostile::humanoid_bvh(60);
    let tiny = walk
        .replace("OFFSET 0 -0.42 0", "OFFSET 0 -0.000042 0")
        .replace("OFFSET 0 -0.41 0", "OFFSET 0 -0.000041 0")
        .replace("OFFSET 0.1 -0.05 0", "OFFSET 0.1 -0.000005 0")
        .replace("OFFSET -0.1 -0.05 0", "OFFSET -0.1 -0.000005 0");
    let out =
        build(&config(r#"{"scale": 1, "mirror": false}"#), &[parsed("walk.bvh", &walk), parsed("tiny.bvh", &tiny)])
            .unwrap();
    assert!(
        out.warnings.iter().any(|w| w.contains("tiny.bvh: legs of length") && w.contains("root motion not rescaled")),
        "{:?}",
        out.warnings
    );
    assert!(out.database.clips.iter().all(|c| c.root_scale == 1.0));
    format::from_bytes(&format::to_bytes(&out.database)).unwrap();
}

/// Issue 28, case 2: more feature dimensions than the search takes passed the config checks,
/// built and loaded, then nothing could search it (`mmdb quality` panicked). The loader refuses
/// such a file by `INFO` now, and `check_database` (the builder's last step) says the same.
#[test]
fn a_database_with_more_dimensions_than_the_search_takes_is_refused() {
    let db = hostile::wide_database(128);
    let d = hostile::tiny_database().num_features();
    let dims = d + 128;
    let e = format::from_bytes(&format::to_bytes(&db)).unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "invalid .mmdb: INFO: {dims} feature dimensions; the search takes 1 to 128 (fewer groups, offsets or axes)"
        )
    );
    let e = format::check_database(&db).unwrap_err().to_string();
    assert!(e.contains(&format!("{dims} feature dimensions")), "{e}");
}
