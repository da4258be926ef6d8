//! The builder on the real mocap in `../shared/mocap` (CMU): every file imports, contacts
//! and mirroring behave, resampling and normalization are exact where they should be, and a
//! golden summary catches unintended changes (regenerate with `UPDATE_GOLDEN=1`).

use glam::{Quat, Vec3};
use mmcore::config::BuildConfig;
use mmcore::{build, format, inspect, Database, Source};
use std::path::Path;

use crate::common;
use common::{config, mocap, source};

fn world_positions(db: &Database, frame: usize) -> Vec<Vec3> {
    let mut p = vec![Vec3::ZERO; db.num_joints()];
    let mut r = vec![Quat::IDENTITY; db.num_joints()];
    db.forward_kinematics(frame, &mut p, &mut r);
    p
}

#[test]
fn every_shared_bvh_imports_and_builds_alone() {
    // Every file the shared manifest lists (it grows: never a fixed count), with the unit scale
    // its `units` field states: metres for CMU ASF, centimetre-like for Daz and 100STYLE.
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(mocap().join("manifest.json")).unwrap()).unwrap();
    let entries = manifest.as_array().expect("manifest.json is a list");
    assert!(!entries.is_empty());
    for entry in entries {
        let (folder, name) = (entry["folder"].as_str().unwrap(), entry["file"].as_str().unwrap());
        let units = entry["units"].as_str().unwrap_or_default();
        let s = source(&format!("{folder}/{name}"));
        let out =
            build(&config(r#"{"mirror": false}"#), std::slice::from_ref(&s)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            !out.warnings.iter().any(|w| w.contains("hip height")),
            "{name}: auto scale should find a plausible unit: {:?}",
            out.warnings
        );
        let expected_scale = if units.contains("centimetres") || units.contains("Daz") { 0.01 } else { 1.0 };
        assert_eq!(out.database.clips[0].scale, expected_scale, "{name} ({units})");
        // Round trip through bytes.
        format::check_round_trip(&out.database, &format::from_bytes(&format::to_bytes(&out.database)).unwrap())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    println!("{} shared files built", entries.len());
}

/// In walking each foot is in stance for ~60% of the gait cycle, its forefoot planted from
/// foot-flat to toe-off (~45–50%). The builder's toe-speed rule must agree.
#[test]
fn walking_contacts_are_plausible() {
    let walks = [
        "cmu-asf/cmu_16_15.bvh",
        "cmu-asf/cmu_16_16.bvh",
        "cmu-asf/cmu_16_21.bvh",
        "cmu-asf/cmu_16_22.bvh",
        "cmu-asf/cmu_16_31.bvh",
        "cmu-asf/cmu_16_32.bvh",
        "cmu-asf/cmu_16_47.bvh",
        "cmu-asf/cmu_16_58.bvh",
    ];
    let sources: Vec<Source> = walks.iter().map(|w| source(w)).collect();
    let db = build(&config(r#"{"mirror": false}"#), &sources).unwrap().database;
    let summary = inspect::summary(&db, None);
    // What a page reads at every load (`RawDatabase::header_json`) is the summary less its scans.
    let header = inspect::header(&db, db.toe_height_in_contact());
    for (k, v) in header.as_object().unwrap() {
        assert_eq!(&summary[k], v, "{k}");
    }
    for k in ["feature_range", "contact_share", "num_valid_frames"] {
        assert!(header.get(k).is_none(), "{k} in the header");
    }
    let (left, right) = (summary["contact_share"][0].as_f64().unwrap(), summary["contact_share"][1].as_f64().unwrap());
    println!("walking contact share: left {left:.3}, right {right:.3}; both {:.3}", both_share(&db));
    for share in [left, right] {
        assert!((0.40..0.65).contains(&share), "contact share {share}");
    }
    // Double support exists but is short; flight (no contact) almost never happens in a walk.
    let none = (0..db.num_frames).filter(|&f| db.contacts[2 * f] == 0 && db.contacts[2 * f + 1] == 0).count() as f64
        / db.num_frames as f64;
    assert!(none < 0.1, "walking with neither foot down {none}");
}

fn both_share(db: &Database) -> f64 {
    (0..db.num_frames).filter(|&f| db.contacts[2 * f] == 1 && db.contacts[2 * f + 1] == 1).count() as f64
        / db.num_frames as f64
}

/// Running has a flight phase and short stances (~8 frames at 60 fps): contacts must exist
/// (a too-wide median filter erases them) and be well below walking.
#[test]
fn running_has_less_contact_than_walking() {
    let db =
        build(&config(r#"{"mirror": false}"#), &[source("cmu-asf/cmu_16_35.bvh"), source("cmu-asf/cmu_16_36.bvh")])
            .unwrap()
            .database;
    let share = db.contacts.iter().filter(|&&c| c == 1).count() as f64 / db.contacts.len() as f64;
    println!("running contact share {share:.3}");
    assert!((0.1..0.35).contains(&share), "running contact share {share}");
}

/// The mirrored clip's virtual root is the original's reflected across x = 0 (smoothing is
/// linear, so this is exact up to f32), its facing reflected, and its feet swap contacts.
#[test]
fn mirroring_reflects_the_trajectory_and_swaps_feet() {
    let db = build(&BuildConfig::default(), &[source("cmu-asf/cmu_16_17.bvh")]).unwrap().database;
    let (a, b) = (&db.clips[0], &db.clips[1]);
    assert!(!a.mirrored && b.mirrored && b.name.ends_with("(mirror)"));
    let j = db.num_joints();
    for f in 0..(a.end - a.start) as usize {
        let p = db.local_positions[(a.start as usize + f) * j];
        let m = db.local_positions[(b.start as usize + f) * j];
        assert!((Vec3::new(-p.x, p.y, p.z) - m).length() < 1e-4, "frame {f}: {p} vs {m}");
        let fa = db.local_rotations[(a.start as usize + f) * j] * Vec3::Z;
        let fb = db.local_rotations[(b.start as usize + f) * j] * Vec3::Z;
        assert!((Vec3::new(-fa.x, fa.y, fa.z) - fb).length() < 1e-4, "facing at frame {f}");
    }
    let swapped = (0..(a.end - a.start) as usize)
        .filter(|&f| db.contacts[2 * (a.start as usize + f)] == db.contacts[2 * (b.start as usize + f) + 1])
        .count() as f64
        / (a.end - a.start) as f64;
    assert!(swapped > 0.9, "mirrored contacts should swap feet ({swapped})");
    // A 90° left turn mirrored is a right turn: the final facing's x flips sign.
    let last = |c: &mmcore::database::Clip| db.local_rotations[(c.end as usize - 1) * j] * Vec3::Z;
    assert!(last(a).x * last(b).x < 0.0);
}

/// 120 → 60 fps takes every other source frame exactly; 120 → 50 interpolates between them.
#[test]
fn resampling_is_exact_at_integer_ratios() {
    let s = [source("cmu-asf/cmu_16_15.bvh")];
    let full = build(&config(r#"{"mirror": false, "fps": 120}"#), &s).unwrap().database;
    let half = build(&config(r#"{"mirror": false, "fps": 60}"#), &s).unwrap().database;
    assert_eq!(half.num_frames, (full.num_frames - 1) / 2 + 1);
    for f in (0..half.num_frames).step_by(7) {
        let (a, b) = (world_positions(&half, f), world_positions(&full, 2 * f));
        for j in 1..a.len() {
            // The same source pose, each stored to 16 bits a rotation component (its virtual
            // root, smoothed over a window of frames, differs between the rates): 0.12 mm.
            assert!((a[j] - b[j]).length() < 2e-4, "frame {f} joint {j}: {}", (a[j] - b[j]).length());
        }
    }
    let fifty = build(&config(r#"{"mirror": false, "fps": 50}"#), &s).unwrap().database;
    assert_eq!(fifty.num_frames, ((full.num_frames - 1) as f64 * 50.0 / 120.0).floor() as usize + 1);
    // Frame 1 at 50 fps is source time 0.02 s = source frame 2.4: between frames 2 and 3.
    let (p, a, b) = (world_positions(&fifty, 1), world_positions(&full, 2), world_positions(&full, 3));
    let head = fifty.skeleton.joint_index("head").unwrap();
    let t = (p[head] - a[head]).dot(b[head] - a[head]) / (b[head] - a[head]).length_squared();
    assert!((t - 0.4).abs() < 0.05, "interpolation parameter {t}");
}

/// Takes of another subject (same topology, other bone lengths) get the reference skeleton
/// and root motion scaled by the leg-length ratio; another topology is retargeted (tests/import.rs).
#[test]
fn bone_lengths_are_normalized_and_topology_checked() {
    let out =
        build(&config(r#"{"mirror": false}"#), &[source("cmu-asf/cmu_16_15.bvh"), source("cmu-asf/cmu_127_03.bvh")])
            .unwrap();
    let db = &out.database;
    assert_eq!(db.clips[0].root_scale, 1.0);
    let ratio = db.clips[1].root_scale;
    assert!(ratio != 1.0 && (0.8..1.25).contains(&ratio), "leg ratio {ratio}");
    // Subject 127's frames use subject 16's bone lengths: thigh length equals the skeleton's.
    let femur = db.skeleton.joint_index("ltibia").unwrap();
    let rest = db.skeleton.offsets[femur].length();
    let f = db.clips[1].start as usize + 10;
    assert!((db.local_positions[f * db.num_joints() + femur].length() - rest).abs() < 1e-6);

    let out =
        build(&BuildConfig::default(), &[source("cmu-asf/cmu_16_15.bvh"), source("cmu-daz/cmu_02_01.bvh")]).unwrap();
    assert_eq!(out.retargeted.len(), 1);
    assert_eq!(out.retargeted[0].0, "cmu-daz/cmu_02_01.bvh");
}

/// The virtual root sits on the floor under the hips and faces where the body faces.
#[test]
fn virtual_root_follows_the_hips_on_the_floor() {
    let db = build(&config(r#"{"mirror": false}"#), &[source("cmu-asf/cmu_16_15.bvh")]).unwrap().database;
    let hips = db.skeleton.site("hips").unwrap().joint as usize;
    let j = db.num_joints();
    for f in 0..db.num_frames {
        let root = db.local_positions[f * j];
        assert_eq!(root.y, 0.0);
        let hip_offset = db.local_positions[f * j + hips];
        assert!(
            Vec3::new(hip_offset.x, 0.0, hip_offset.z).length() < 0.15,
            "frame {f}: hips {hip_offset} from the root"
        );
        assert!((0.75..1.05).contains(&hip_offset.y), "hip height {}", hip_offset.y);
    }
    // A straight walk: the trajectory features point forward (+z in character space).
    let g = db.groups.iter().find(|g| g.name == "trajectory_position").unwrap();
    let mid = db.num_frames / 2;
    let raw_z = db.feature(mid)[g.first_dim + 5] * db.feature_scale[g.first_dim + 5] + db.feature_mean[g.first_dim + 5];
    assert!((0.9..2.0).contains(&raw_z), "1 s ahead the root should be ~1.3 m forward, got {raw_z}");
}

/// Golden summary of a small two-subject database: fails when the builder's output moves.
#[test]
fn golden_summary() {
    let db = build(&BuildConfig::default(), &[source("cmu-asf/cmu_16_15.bvh"), source("cmu-asf/cmu_127_14.bvh")])
        .unwrap()
        .database;
    let mut summary = inspect::summary(&db, None);
    summary.as_object_mut().unwrap().remove("size_bytes");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/summary_16_15_127_14.json");
    if std::env::var_os("UPDATE_GOLDEN").is_some() || !path.exists() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, serde_json::to_string_pretty(&summary).unwrap()).unwrap();
    }
    let golden: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let mut diffs = Vec::new();
    compare("", &golden, &summary, &mut diffs);
    assert!(
        diffs.is_empty(),
        "builder output differs from {} (UPDATE_GOLDEN=1 to accept):\n{}",
        path.display(),
        diffs.join("\n")
    );
}

/// Structural equality with a relative float tolerance (libm differs slightly across hosts).
fn compare(at: &str, a: &serde_json::Value, b: &serde_json::Value, diffs: &mut Vec<String>) {
    use serde_json::Value::*;
    match (a, b) {
        (Number(x), Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            if (x - y).abs() > 1e-4 * x.abs().max(y.abs()).max(1e-2) {
                diffs.push(format!("{at}: {x} → {y}"));
            }
        }
        (Array(x), Array(y)) if x.len() == y.len() => {
            x.iter().zip(y).enumerate().for_each(|(i, (x, y))| compare(&format!("{at}[{i}]"), x, y, diffs))
        }
        (Object(x), Object(y)) if x.len() == y.len() => {
            for (k, v) in x {
                match y.get(k) {
                    Some(w) => compare(&format!("{at}.{k}"), v, w, diffs),
                    None => diffs.push(format!("{at}.{k}: missing")),
                }
            }
        }
        _ if a == b => {}
        _ => diffs.push(format!("{at}: {a} → {b}")),
    }
}

/// β_q / β_r scale the pose and trajectory groups' cost without rebuilding, and the brute
/// force returns the k best valid frames in order.
#[test]
fn search_weights_and_masks() {
    use mmcore::search::{brute_force, SearchOptions};
    let db = build(&BuildConfig::default(), &[source("cmu-asf/cmu_16_15.bvh"), source("cmu-asf/cmu_16_35.bvh")])
        .unwrap()
        .database;
    let query = db.feature(40).to_vec();
    let cost = |f: usize, bq: f32, br: f32| -> f32 {
        db.groups
            .iter()
            .flat_map(|g| {
                (g.first_dim..g.first_dim + g.num_dims).map(move |d| (d, if g.is_trajectory { br } else { bq }))
            })
            .map(|(d, w)| w * (query[d] - db.feature(f)[d]).powi(2))
            .sum()
    };
    for (bq, br) in [(1.0, 1.0), (0.0, 1.0), (1.0, 0.0), (2.5, 0.5)] {
        let options =
            SearchOptions { beta_pose: bq, beta_trajectory: br, exclude: Some((20, 61)), ..Default::default() };
        let best = brute_force(&db, &query, &options, 10);
        assert_eq!(best.len(), 10);
        let expected = (0..db.num_frames)
            .filter(|&f| db.valid[f] == 1 && !(20..61).contains(&f))
            .map(|f| cost(f, bq, br))
            .fold(f32::INFINITY, f32::min);
        assert!((best[0].1 - expected).abs() <= 1e-5 * expected.max(1.0), "β=({bq},{br}): {} vs {expected}", best[0].1);
        assert!(best.windows(2).all(|w| w[0].1 <= w[1].1));
        assert!(best.iter().all(|&(f, c)| db.valid[f] == 1
            && !(20..61).contains(&f)
            && (c - cost(f, bq, br)).abs() <= 1e-4 * c.max(1.0)));
    }
    // A mask keeps results inside it.
    let run = &db.clips[2];
    let mask: Vec<bool> = (0..db.num_frames).map(|f| f >= run.start as usize && f < run.end as usize).collect();
    let best = brute_force(&db, &query, &SearchOptions { mask: Some(&mask), ..Default::default() }, 5);
    assert!(!best.is_empty() && best.iter().all(|&(f, _)| mask[f]));
}
