//! The `mmdb` command line as a user runs it: build (files and config), inspect, search,
//! exit codes and messages for bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn mmdb(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mmdb")).args(args).output().expect("run mmdb")
}

fn mocap(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/mocap").join(rel).to_string_lossy().into_owned()
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mmdb-cli-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn stdout_json(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "mmdb failed: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn build_inspect_and_search() {
    let db = temp("two.mmdb");
    let db = db.to_str().unwrap();
    let built = stdout_json(&mmdb(&[
        "build",
        &mocap("cmu-asf/cmu_16_15.bvh"),
        &mocap("cmu-asf/cmu_16_17.bvh"),
        "-o",
        db,
        "--json",
    ]));
    let inspected = stdout_json(&mmdb(&["inspect", db, "--json"]));
    assert_eq!(built["num_frames"], inspected["num_frames"]);
    assert_eq!(inspected["clips"].as_array().unwrap().len(), 4, "2 takes + their mirrors");
    assert_eq!(inspected["num_features"], 27);
    let text = String::from_utf8(mmdb(&["inspect", db]).stdout).unwrap();
    assert!(text.contains("cmu_16_17 (mirror)") && text.contains("trajectory_direction"), "{text}");

    // A frame's own features: excluded ±20 around it, the best match lies outside that window.
    let found = stdout_json(&mmdb(&["search", db, "--frame", "100", "-k", "3", "--json"]));
    let results = found["results"].as_array().unwrap();
    assert_eq!(results.len(), 3);
    let costs: Vec<f64> = results.iter().map(|r| r["cost"].as_f64().unwrap()).collect();
    assert!(costs.windows(2).all(|w| w[0] <= w[1]), "sorted by cost: {costs:?}");
    for r in results {
        let f = r["frame"].as_i64().unwrap();
        assert!(!(80..=120).contains(&f), "frame {f} is inside the exclusion window");
    }
    // A query equal to frame 100's stored (normalized) features finds frame 100 at cost 0.
    let dump = stdout_json(&mmdb(&["dump", db]));
    let row: Vec<String> =
        dump["features"].as_array().unwrap()[100 * 27..101 * 27].iter().map(|v| v.to_string()).collect();
    for method in ["aabb", "simd", "scalar"] {
        let own = stdout_json(&mmdb(&[
            "search",
            db,
            "--query",
            &row.join(","),
            "--normalized",
            "--method",
            method,
            "--json",
        ]));
        assert_eq!(own["results"][0]["frame"], 100, "{method}");
        assert_eq!(own["results"][0]["cost"], 0.0);
    }
}

#[test]
fn build_from_config_with_tags_and_ranges() {
    let config = temp("config.json");
    std::fs::write(
        &config,
        format!(
            r#"{{"fps": 30, "mirror": false, "clips": [
                {{"file": "{}", "tags": ["walk"], "ranges": [{{"frames": [0, 120], "tags": ["start"]}}]}},
                {{"file": "{}", "frames": [100, 200], "tags": ["turn"]}}
            ]}}"#,
            mocap("cmu-asf/cmu_16_1?.bvh").replace('\\', "/"),
            mocap("cmu-asf/cmu_16_27.bvh").replace('\\', "/")
        ),
    )
    .unwrap();
    let db = temp("config.mmdb");
    let info =
        stdout_json(&mmdb(&["build", "--config", config.to_str().unwrap(), "-o", db.to_str().unwrap(), "--json"]));
    assert_eq!(info["fps"], 30.0);
    let clips = info["clips"].as_array().unwrap();
    assert_eq!(clips.len(), 10, "cmu_16_11..19 via the wildcard + 16_27");
    assert_eq!(clips.last().unwrap()["name"], "cmu_16_27[100-200]");
    let tags: Vec<&str> = info["tags"].as_array().unwrap().iter().map(|t| t["name"].as_str().unwrap()).collect();
    assert_eq!(tags, ["start", "turn", "walk"]);
    // 120 source frames at 120 fps = 1 s = 30 frames at 30 fps, in each of the 9 walk clips.
    assert_eq!(info["tags"][0]["frames"], 9 * 30);
    // The tag restricts the search.
    let found =
        stdout_json(&mmdb(&["search", db.to_str().unwrap(), "--frame", "5", "--tag", "turn", "-k", "5", "--json"]));
    let turn = &clips.last().unwrap();
    for r in found["results"].as_array().unwrap() {
        let f = r["frame"].as_u64().unwrap();
        assert!(f >= turn["start"].as_u64().unwrap() && f < turn["end"].as_u64().unwrap());
    }
}

#[test]
fn bad_input_exits_non_zero_with_a_clear_message() {
    let bad = temp("bad.bvh");
    std::fs::write(&bad, "HIERARCHY\nROOT hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xrotation Yrotation Wrotation\n}\n")
        .unwrap();
    let out = mmdb(&["build", bad.to_str().unwrap(), "-o", temp("x.mmdb").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.bvh:5: expected a channel name"), "{err}");

    let out = mmdb(&["inspect", bad.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("wrong magic"));

    let config = temp("typo.json");
    std::fs::write(&config, "{\"fps\": 60,\n \"mirorr\": false}").unwrap();
    let out = mmdb(&["build", "--config", config.to_str().unwrap(), "-o", temp("y.mmdb").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("typo.json") && err.contains("unknown field `mirorr`") && err.contains("line 2"), "{err}");

    let out = mmdb(&["build", "-o"]);
    assert_eq!(out.status.code(), Some(2), "usage errors exit 2");
    assert!(String::from_utf8_lossy(&out.stderr).contains("usage:"));

    let out = mmdb(&["search", "nope.mmdb", "--frame", "1"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("nope.mmdb"));
}
