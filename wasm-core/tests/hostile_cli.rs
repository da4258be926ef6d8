//! The CLI on hostile input and out-of-range flags: usage errors (exit 2) name the flag, bad
//! files (exit 1) name the file and line or section — never a NaN database with exit 0.

use crate::hostile;

use std::path::PathBuf;
use std::process::{Command, Output};

fn mmdb(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mmdb")).args(args).output().expect("run mmdb")
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mmdb-hostile-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn out_of_range_flags_are_usage_errors() {
    let bvh = temp("walk.bvh");
    std::fs::write(&bvh, hostile::humanoid_bvh(60)).unwrap();
    let (bvh, db) = (bvh.to_str().unwrap(), temp("walk.mmdb"));
    let db = db.to_str().unwrap();
    for (flag, value, expected) in [
        ("--fps", "0", "--fps: fps must be between 1 and 1000, found 0"),
        ("--fps", "1e300", "--fps: fps must be between 1 and 1000"),
        ("--fps", "nan", "--fps: fps must be between 1 and 1000, found NaN"),
        ("--scale", "inf", "--scale: scale must be between"),
        ("--scale", "0", "--scale: scale must be between"),
        ("--scale", "1e300", "--scale: scale must be between"),
        ("--scale", "metres", "--scale: 'metres' is not a number or 'auto'"),
    ] {
        let out = mmdb(&["build", bvh, "-o", db, flag, value]);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}: {}", stderr(&out));
        assert!(stderr(&out).contains(expected), "{flag} {value}: {}", stderr(&out));
    }
    let out = mmdb(&["build", bvh, "-o", db, "--fps", "30", "--scale", "0.01"]);
    assert!(out.status.success(), "{}", stderr(&out));
}

#[test]
fn extreme_values_fail_the_build_naming_the_line() {
    let text = hostile::humanoid_bvh(60);
    for (what, from, to, expected) in [
        (
            "1e308",
            "0.000000 0.950000",
            "1e308 0.950000",
            "bad.bvh:77: frame 0: value 1e308 at column 1 is out of range",
        ),
        ("1e39", "0.000000 0.950000", "1e39 0.950000", "bad.bvh:77: frame 0: value 1e39"),
        ("offset 1e300", "OFFSET 0 -0.42 0", "OFFSET 0 -1e300 0", "bad.bvh:12: OFFSET y is -1e300, out of range"),
        (
            "frame time",
            "Frame Time: 0.00833333",
            "Frame Time: 1e-300",
            "bad.bvh:76: 'Frame Time:' must be 0.0001 to 1 seconds",
        ),
    ] {
        let bad = temp("bad.bvh");
        std::fs::write(&bad, text.replacen(from, to, 1)).unwrap();
        let out = mmdb(&["build", bad.to_str().unwrap(), "-o", temp("bad.mmdb").to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(1), "{what}");
        assert!(stderr(&out).contains(expected), "{what}: {}", stderr(&out));
    }
}

/// Search and benchmark flags are range-checked too (a huge -k reserved k result slots).
#[test]
fn search_flags_are_bounded() {
    let path = temp("tiny.mmdb");
    std::fs::write(&path, mmcore::format::to_bytes(&hostile::tiny_database())).unwrap();
    let p = path.to_str().unwrap();
    let out = mmdb(&[
        "search",
        p,
        "--frame",
        "0",
        "-k",
        "18446744073709551615",
        "--exclude-radius",
        "18446744073709551615",
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    for (flag, value) in [("--beta-pose", "nan"), ("--beta-trajectory", "-1"), ("--beta-pose", "inf")] {
        let out = mmdb(&["search", p, "--frame", "0", flag, value]);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}");
        assert!(stderr(&out).contains(&format!("{flag}: must be 0 to 1e6")), "{}", stderr(&out));
    }
    let out = mmdb(&["quality", p, "--seconds", "1e300"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("--seconds: must be more than 0"), "{}", stderr(&out));
}

/// One flipped bit in INFO.fps (checksum recomputed) froze the page; the loader refuses it.
#[test]
fn a_flipped_fps_bit_is_refused_by_inspect() {
    let mut bytes = mmcore::format::to_bytes(&hostile::tiny_database());
    let info = hostile::table(&bytes).iter().find(|e| &e.0 == b"INFO").unwrap().2;
    bytes[info + 8 + 3] ^= 0x20; // exponent bit of 60.0 → 1.1e21 fps
    hostile::refix(&mut bytes);
    let path = temp("flipped.mmdb");
    std::fs::write(&path, &bytes).unwrap();
    let out = mmdb(&["inspect", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("flipped.mmdb: INFO.fps must be between 1 and 1000"), "{}", stderr(&out));
}

/// Found by this suite: a second take whose legs have zero length got root scale
/// `ref_leg / 0 = ∞`, and `mmdb build` wrote a database its own loader refused
/// (`CLIP 'b': root scale inf`). The builder now warns and keeps that take's root motion as is.
#[test]
fn a_take_with_zero_length_legs_is_refused_or_builds_a_loadable_database() {
    let a = hostile::humanoid_bvh(40);
    let mut b = a.clone();
    for offset in
        ["OFFSET 0.1 -0.05 0", "OFFSET -0.1 -0.05 0", "OFFSET 0 -0.42 0", "OFFSET 0 -0.41 0", "OFFSET 0 -0.05 0.12"]
    {
        b = b.replace(offset, "OFFSET 0 0 0");
    }
    let (pa, pb, db) = (temp("a.bvh"), temp("b.bvh"), temp("ab.mmdb"));
    std::fs::write(&pa, a).unwrap();
    std::fs::write(&pb, b).unwrap();
    let out = mmdb(&["build", pa.to_str().unwrap(), pb.to_str().unwrap(), "-o", db.to_str().unwrap(), "--scale", "1"]);
    if out.status.success() {
        let out = mmdb(&["inspect", db.to_str().unwrap()]);
        assert!(out.status.success(), "the builder wrote a database its loader refuses: {}", stderr(&out));
    }
}

/// Found by the builder fuzz target: a small BVH at 1 fps built at 1,000 fps asked the
/// allocator for gigabytes and aborted. The builder now counts the output before allocating.
#[test]
fn a_slow_take_resampled_past_the_size_limit_is_refused_before_allocating() {
    let bvh = hostile::humanoid_bvh(2000).replace("Frame Time: 0.00833333", "Frame Time: 1");
    let (path, db) = (temp("slow.bvh"), temp("slow.mmdb"));
    std::fs::write(&path, bvh).unwrap();
    let out = mmdb(&["build", path.to_str().unwrap(), "-o", db.to_str().unwrap(), "--fps", "1000", "--scale", "1"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("the database would have"), "{}", stderr(&out));
    assert!(!db.exists());
}

/// `name`.mmdb built from 240 frames of `hostile::humanoid_bvh`: a database to replay on.
fn walk_database(name: &str) -> PathBuf {
    let bvh = temp(&format!("{name}.bvh"));
    std::fs::write(&bvh, hostile::humanoid_bvh(240)).unwrap();
    let db = temp(&format!("{name}.mmdb"));
    let out = mmdb(&["build", bvh.to_str().unwrap(), "-o", db.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    db
}

/// Issue 28: `mmdb replay` accepted recordings the page refuses (zero or 10³⁰⁰ quaternions,
/// non-increasing time) and printed NaN metrics; a string in `time` said "time has 345 finite
/// numbers, expected 345". It now reads them with the page's validator (the shared cases are in
/// `tests/corpus/recordings/cases.json`), and a recording it replays gives finite metrics.
#[test]
fn replay_validates_recordings_as_the_page_does() {
    let db = walk_database("replay-walk");
    let recording = |frames: usize, edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v = serde_json::json!({
            "format": "mm-vr-recording", "version": 1, "frames": frames, "meta": {"eyeHeight": 1.6},
            "time": (0..frames).map(|f| f as f64 / 60.0).collect::<Vec<_>>(),
            "position": (0..frames).flat_map(|f| [0.0, 1.6, f as f64 / 60.0, -0.2, 1.0, 0.0, 0.2, 1.0, 0.0]).collect::<Vec<_>>(),
            "rotation": (0..frames * 3).flat_map(|_| [0.0, 0.0, 0.0, 1.0]).collect::<Vec<_>>(),
            "tracked": vec![1; 3 * frames],
        });
        edit(&mut v);
        let path = temp("rec.json");
        std::fs::write(&path, v.to_string()).unwrap();
        mmdb(&["replay", db.to_str().unwrap(), path.to_str().unwrap(), "--yaw", "hmd", "--json"])
    };
    let zero = |v: &mut serde_json::Value| (0..4).for_each(|c| v["rotation"][12 + c] = 0.0.into());
    let huge = |v: &mut serde_json::Value| v["rotation"][15] = 1e300.into();
    let back = |v: &mut serde_json::Value| v["time"][5] = 0.0.into();
    let text = |v: &mut serde_json::Value| v["time"][3] = "0.05".into();
    for (what, edit, expected) in [
        (
            "zero quaternion",
            &zero as &dyn Fn(&mut serde_json::Value),
            "rec.json: rotation of frame 1, tracker 0 is not a unit quaternion (length 0.0000)",
        ),
        (
            "1e300 quaternion",
            &huge,
            "rec.json: rotation of frame 1, tracker 0 is not a unit quaternion (length Infinity)",
        ),
        ("time going back", &back, "rec.json: time must increase: time[5] = 0 after 0.06666666666666667"),
        ("a string in time", &text, "rec.json: \"time\"[3] is not a number"),
    ] {
        let out = recording(120, edit);
        assert_eq!(out.status.code(), Some(1), "{what}: {}", stderr(&out));
        assert!(stderr(&out).contains(expected), "{what}: {}", stderr(&out));
    }
    let out = recording(1, &|_| {});
    assert!(stderr(&out).contains("a replay needs at least 2 frames, the recording has 1"), "{}", stderr(&out));
    let out = recording(120, &|_| {});
    assert!(out.status.success(), "{}", stderr(&out));
    let metrics = String::from_utf8_lossy(&out.stdout);
    // No truth: no root distance; every other metric a number (serde writes NaN as null).
    assert!(metrics.contains("\"root_distance\":null") && metrics.matches("null").count() == 1, "{metrics}");

    // The network's hips (`--hips`): one [x, z] or null per frame; the root aims at them.
    // (`recording` above left a valid 120-frame rec.json behind.)
    let rec = temp("rec.json");
    let hips_run = |hips: &serde_json::Value| {
        let path = temp("hips.json");
        std::fs::write(&path, hips.to_string()).unwrap();
        let (db, rec, hips) = (db.to_str().unwrap(), rec.to_str().unwrap(), path.to_str().unwrap());
        mmdb(&["replay", db, rec, "--yaw", "hmd", "--hips", hips, "--json"])
    };
    let out = hips_run(&serde_json::json!([[0.0, -0.1], [0.0, -0.1], [0.0, -0.1]]));
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("hips.json: 3 hips offsets for 120 frames"), "{}", stderr(&out));
    let out = hips_run(&serde_json::json!([1.0, 2.0]));
    assert!(stderr(&out).contains("hips.json: "), "{}", stderr(&out));
    let mixed: Vec<serde_json::Value> =
        (0..120).map(|f| if f % 2 == 0 { serde_json::json!([0.0, -0.12]) } else { serde_json::Value::Null }).collect();
    let out = hips_run(&serde_json::Value::from(mixed));
    assert!(out.status.success(), "{}", stderr(&out));
    // A null is "not known" (the target is the head centre again, the smoothing starts over):
    // the replay runs through the flicker and every metric stays a number.
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(r["head_gap"]["mean"].as_f64().is_some_and(f64::is_finite), "{r}");
}

/// A recording with body joints replays as the page drives it (issue 23, body tracking): while
/// the hips are tracked the shown hips stand on them (the body-tracking e2e's line: within 3 cm),
/// here 25 cm beside the head the drive would otherwise follow; when the hips are lost the
/// replay falls back to the head, every metric still a number. Without `body`, nothing drives
/// from it.
#[test]
fn replay_drives_from_the_tracked_body_as_the_page_does() {
    let db = walk_database("body-walk");
    let frames = 240;
    let z = |f: usize| 0.5 * f as f64 / 60.0; // walking +Z at 0.5 m/s
    let mut v = serde_json::json!({
        "format": "mm-vr-recording", "version": 1, "frames": frames, "meta": {"eyeHeight": 1.6},
        "time": (0..frames).map(|f| f as f64 / 60.0).collect::<Vec<_>>(),
        "position": (0..frames).flat_map(|f| [0.0, 1.6, z(f), -0.2, 1.0, z(f), 0.2, 1.0, z(f)]).collect::<Vec<_>>(),
        "rotation": (0..frames * 3).flat_map(|_| [0.0, 1.0, 0.0, 0.0]).collect::<Vec<_>>(), // facing +Z
        "tracked": vec![1; 3 * frames],
        // Hips 25 cm to the side of the head, the hip joints ±10 cm across them (facing +Z); the
        // hips lost for the second half.
        "body": {
            "joints": ["hips", "left-upper-leg", "right-upper-leg"],
            "position": (0..frames).flat_map(|f| [0.25, 0.9, z(f), 0.35, 0.9, z(f), 0.15, 0.9, z(f)]).collect::<Vec<_>>(),
            "rotation": (0..frames * 3).flat_map(|_| [0.0, 0.0, 0.0, 1.0]).collect::<Vec<_>>(),
            "tracked": (0..frames).flat_map(|f| [u8::from(f < 120), 1, 1]).collect::<Vec<_>>(),
        },
    });
    let replay = |v: &serde_json::Value| {
        let path = temp("body-rec.json");
        std::fs::write(&path, v.to_string()).unwrap();
        let out = mmdb(&["replay", db.to_str().unwrap(), path.to_str().unwrap(), "--yaw", "hmd", "--json"]);
        assert!(out.status.success(), "{}", stderr(&out));
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
    };
    let r = replay(&v);
    assert_eq!(r["body_frames"], 120, "{r}");
    let hips = r["hips_distance"]["mean"].as_f64().unwrap();
    assert!(hips < 0.03, "shown hips {:.1} cm from the tracked ones", 100.0 * hips);
    // No truth: root_distance is the only null; the rest are numbers after the loss too.
    assert_eq!(r.to_string().matches("null").count(), 1, "{r}");
    v.as_object_mut().unwrap().remove("body");
    let r = replay(&v);
    assert_eq!(r["body_frames"], 0, "{r}");
    assert!(r["hips_distance"].is_null(), "{r}");
}

/// Issue 28, cases 2 and 3 through the CLI: a configuration of 300 feature groups (2,700
/// dimensions) built with exit 0 and `mmdb quality` panicked on the result (exit 101); a BVH
/// with every number ≤ 10⁷ built with `--scale 1000 --fps 1000` exited 0 and its own loader
/// refused the file. Now the first is a config error, a wide file is refused by the loader (no
/// panic), and the second is refused by the build naming the take.
#[test]
fn builds_the_search_or_the_loader_would_refuse_are_refused_by_the_build() {
    let bvh = temp("limits-walk.bvh");
    std::fs::write(&bvh, hostile::humanoid_bvh(120)).unwrap();
    let group =
        |i: usize| format!(r#"{{"name": "g{i}", "kind": "position", "joint": "hips", "offsets": [0, 10, 20]}}"#);
    let config = temp("wide.json");
    std::fs::write(
        &config,
        format!(
            r#"{{"clips": [{{"file": "limits-walk.bvh"}}], "features": [{}]}}"#,
            (0..300).map(group).collect::<Vec<_>>().join(",")
        ),
    )
    .unwrap();
    let db = temp("limits.mmdb");
    let out = mmdb(&["build", "--config", config.to_str().unwrap(), "-o", db.to_str().unwrap()]);
    assert!(
        !out.status.success() && stderr(&out).contains("features: 2700 feature dimensions; the search takes 1 to 128"),
        "{}",
        stderr(&out)
    );
    // A file with 133 dimensions (written by hand): refused by every command that loads it.
    let wide = temp("wide.mmdb");
    std::fs::write(&wide, mmcore::format::to_bytes(&hostile::wide_database(128))).unwrap();
    for command in ["quality", "inspect"] {
        let out = mmdb(&[command, wide.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(1), "{command}: {}", stderr(&out));
        assert!(
            stderr(&out).contains("INFO: 133 feature dimensions; the search takes 1 to 128"),
            "{command}: {}",
            stderr(&out)
        );
    }
    // Every value ≤ 10⁷, the root jumping ±10⁷ units every other frame at 1,000 fps, built at
    // 1,000 m per unit and 1,000 fps: exit 0 and "FNRM: scale of dim 6 is 3.3e12" on load before.
    let text: String = hostile::humanoid_bvh(120)
        .replace("Frame Time: 0.00833333", "Frame Time: 0.001")
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
    let far = temp("far.bvh");
    std::fs::write(&far, text).unwrap();
    let out = mmdb(&["build", far.to_str().unwrap(), "-o", db.to_str().unwrap(), "--scale", "1000", "--fps", "1000"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("its values times the unit scale 1000 reach")
            && stderr(&out).contains("at most 100000 m — check the unit scale (--scale)"),
        "{}",
        stderr(&out)
    );
}
