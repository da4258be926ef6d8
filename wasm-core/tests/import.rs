//! Importing any humanoid BVH with no configuration (issue 14): roles from topology and geometry
//! when names fail or lie, units and up axis from the motion whatever the rest pose, skeletons of
//! another topology retargeted into one database with a bounded error, 100STYLE frame windows,
//! and time reversal.

use glam::{DQuat, DVec3, EulerRot, Quat, Vec3};
use mmcore::bvh::{BvhJoint, Channel};
use mmcore::config::BuildConfig;
use mmcore::roles::Role;
use mmcore::{build, format, Bvh, Database, Source};

use crate::common;
use common::{config, source};

/// `bvh` with new joint names.
fn renamed(bvh: &Bvh, name: impl Fn(usize, &str) -> String) -> Bvh {
    let mut b = bvh.clone();
    for (j, joint) in b.joints.iter_mut().enumerate() {
        joint.name = name(j, &bvh.joints[j].name);
    }
    b
}

/// The same motion written with other offsets and local transforms: `offset(j, o)` and
/// `end(j, e)` map the rest skeleton, `local(j, t, q)` each frame's local transform. Every joint
/// gets `Zrotation Yrotation Xrotation` (joints with position channels keep all three).
fn rewritten(
    bvh: &Bvh,
    offset: impl Fn(usize, DVec3) -> DVec3,
    end: impl Fn(usize, DVec3) -> DVec3,
    local: impl Fn(usize, DVec3, DQuat) -> (DVec3, DQuat),
) -> Bvh {
    let mut joints = Vec::new();
    let mut first = 0;
    for (j, b) in bvh.joints.iter().enumerate() {
        let positions = b.channels.iter().any(|c| matches!(c, Channel::PosX | Channel::PosY | Channel::PosZ));
        let channels = if positions {
            vec![Channel::PosX, Channel::PosY, Channel::PosZ, Channel::RotZ, Channel::RotY, Channel::RotX]
        } else {
            vec![Channel::RotZ, Channel::RotY, Channel::RotX]
        };
        joints.push(BvhJoint {
            name: b.name.clone(),
            parent: b.parent,
            offset: offset(j, b.offset),
            first_channel: first,
            end_site: b.end_site.map(|e| end(j, e)),
            channels,
        });
        first += joints[j].channels.len();
    }
    let mut values = Vec::with_capacity(bvh.num_frames * first);
    for f in 0..bvh.num_frames {
        for (j, joint) in joints.iter().enumerate() {
            let (t, q) = bvh.local_transform(f, j);
            let (t, q) = local(j, t, q);
            if joint.channels.len() == 6 {
                values.extend([t.x, t.y, t.z]);
            }
            let (z, y, x) = q.to_euler(EulerRot::ZYX);
            values.extend([z.to_degrees(), y.to_degrees(), x.to_degrees()]);
        }
    }
    let out = Bvh {
        joints,
        num_channels: first,
        num_frames: bvh.num_frames,
        frame_time: bvh.frame_time,
        values,
        role_hints: Vec::new(),
    };
    // The writer's Euler convention is the reader's: a frame reads back as written.
    let (t, q) = out.local_transform(7, 3);
    let (t0, q0) = bvh.local_transform(7, 3);
    let (t1, q1) = local(3, t0, q0);
    assert!((t - t1).length() < 1e-9 && q.dot(q1).abs() > 1.0 - 1e-12, "euler round trip");
    out
}

/// World positions of every joint in every frame.
fn world(db: &Database) -> Vec<Vec3> {
    let j = db.num_joints();
    let (mut p, mut r) = (vec![Vec3::ZERO; j], vec![Quat::IDENTITY; j]);
    let mut all = Vec::with_capacity(db.num_frames * j);
    for f in 0..db.num_frames {
        db.forward_kinematics(f, &mut p, &mut r);
        all.extend_from_slice(&p);
    }
    all
}

fn max_distance(a: &[Vec3], b: &[Vec3]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| x.distance(*y)).fold(0.0, f32::max)
}

fn site(db: &Database, role: Role) -> i32 {
    db.skeleton.site(role.name()).unwrap().joint
}

#[test]
fn a_100style_file_builds_with_no_config() {
    let out = build(&BuildConfig::default(), &[source("100style/Angry_BW.bvh")]).unwrap();
    let db = &out.database;
    assert!(!out.warnings.iter().any(|w| w.contains("hip height") || w.contains("contact")), "{:?}", out.warnings);
    assert_eq!(db.clips[0].scale, 0.01);
    let name = |role: Role| db.skeleton.names[site(db, role) as usize].clone();
    for (role, joint) in [
        (Role::Hips, "Hips"),
        (Role::LeftUpperLeg, "LeftHip"),
        (Role::LeftLowerLeg, "LeftKnee"),
        (Role::LeftFoot, "LeftAnkle"),
        (Role::LeftToe, "LeftToe"),
        (Role::RightFoot, "RightAnkle"),
        (Role::Head, "Head"),
        (Role::LeftHand, "LeftWrist"),
        (Role::RightUpperArm, "RightShoulder"),
    ] {
        assert_eq!(name(role), joint, "{}", role.name());
    }
}

/// CMU joints renamed to `Bone0…Bone30`: topology and geometry find every role the names
/// found, limbs pair up for mirroring, and the database is the named one's, value for value.
#[test]
fn a_renamed_cmu_file_builds_with_no_config() {
    let original = source("cmu-asf/cmu_16_15.bvh");
    let named = build(&BuildConfig::default(), std::slice::from_ref(&original)).unwrap().database;
    let anonymous = Source { name: "bones.bvh".into(), bvh: renamed(&original.bvh, |j, _| format!("Bone{j}")) };
    let db = build(&BuildConfig::default(), &[anonymous]).unwrap().database;
    for role in Role::ALL {
        assert_eq!(site(&db, role), site(&named, role), "{}", role.name());
    }
    assert_eq!(db.local_rotations, named.local_rotations, "mirrored clips differ: limb pairs");
    assert_eq!(db.features, named.features);
    assert_eq!(db.contacts, named.contacts);
}

/// Names that lie (left and right swapped) lose to the geometry: the left foot is the one on
/// the body's left, and the database is the truthfully named one's.
#[test]
fn geometry_wins_over_wrong_names() {
    let original = source("cmu-asf/cmu_16_15.bvh");
    let named = build(&BuildConfig::default(), std::slice::from_ref(&original)).unwrap().database;
    let swap = |_: usize, n: &str| match n.chars().next() {
        Some('l') => format!("r{}", &n[1..]),
        Some('r') if n != "root" => format!("l{}", &n[1..]),
        _ => n.to_string(),
    };
    let liar = Source { name: "liar.bvh".into(), bvh: renamed(&original.bvh, swap) };
    let db = build(&BuildConfig::default(), &[liar]).unwrap().database;
    assert_eq!(db.skeleton.names[site(&db, Role::LeftFoot) as usize], "rfoot");
    for role in Role::ALL {
        assert_eq!(site(&db, role), site(&named, role), "{}", role.name());
    }
    assert_eq!(db.features, named.features);
}

#[test]
fn a_skeleton_that_is_not_a_humanoid_is_refused_naming_the_part() {
    let chain = "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n JOINT B\n {\n  OFFSET 0 1 0\n  CHANNELS 3 Zrotation Yrotation Xrotation\n  End Site\n  {\n   OFFSET 0 1 0\n  }\n }\n}\nMOTION\nFrames: 2\nFrame Time: 0.0333\n0 1 0 0 0 0 0 0 0\n0 1 0 0 0 0 0 0 0\n";
    let s = Source { name: "snake.bvh".into(), bvh: Bvh::parse("snake.bvh", chain.as_bytes()).unwrap() };
    let e = build(&BuildConfig::default(), &[s]).err().unwrap().to_string();
    assert!(e.contains("snake.bvh: not a humanoid skeleton: no pair of matching limbs (legs)"), "{e}");
    // Legs but no arms: CMU's legs only, renamed.
    let cmu = source("cmu-asf/cmu_16_15.bvh").bvh;
    let mut legs = renamed(&cmu, |j, _| format!("J{j}"));
    legs.joints.truncate(11); // root, two legs
    let channels: usize = legs.joints.iter().map(|j| j.channels.len()).sum();
    legs.values = (0..cmu.num_frames).flat_map(|f| cmu.frame(f)[..channels].to_vec()).collect();
    legs.num_channels = channels;
    let e = build(&BuildConfig::default(), &[Source { name: "legs.bvh".into(), bvh: legs }]).err().unwrap().to_string();
    assert!(e.contains("legs.bvh: not a humanoid skeleton") && e.contains("no second") && e.contains("arms"), "{e}");
}

/// Up axis and units come from the motion: the same take written Z-up, X-up, or in
/// centimetres with a rest pose whose legs point up (as Unity humanoid exports do) builds the
/// same database (world positions within 0.1 mm).
#[test]
fn units_and_up_axis_come_from_the_motion() {
    let original = source("cmu-asf/cmu_16_15.bvh");
    let reference = build(&config(r#"{"mirror": false}"#), std::slice::from_ref(&original)).unwrap().database;
    let expected = world(&reference);
    let bvh = &original.bvh;
    let turned = |r: DQuat| rewritten(bvh, |_, o| r * o, |_, e| r * e, |_, t, q| (r * t, r * q * r.conjugate()));
    let half_pi = std::f64::consts::FRAC_PI_2;
    for (axis, rotation) in [("Z", DQuat::from_rotation_x(half_pi)), ("X", DQuat::from_rotation_z(-half_pi))] {
        let s = Source { name: format!("{axis}-up.bvh"), bvh: turned(rotation) };
        let out = build(&config(r#"{"mirror": false}"#), &[s]).unwrap();
        assert!(
            out.warnings.iter().any(|w| w.contains(&format!("the motion is {axis}-up; rotated to Y-up"))),
            "{:?}",
            out.warnings
        );
        let d = max_distance(&world(&out.database), &expected);
        assert!(d < 1e-4, "{axis}-up: {d} m from the Y-up build");
    }
    // Legs up at rest, centimetres: below each upper leg offsets flip (F = 180° about X) and
    // rotations compensate, so every frame's world pose is the original's.
    let flip = DQuat::from_rotation_x(std::f64::consts::PI);
    let legs: Vec<usize> =
        ["lfemur", "rfemur"].iter().map(|n| bvh.joints.iter().position(|j| j.name == *n).unwrap()).collect();
    let below = |j: usize| {
        let mut k = j;
        while let Some(p) = bvh.joints[k].parent {
            if legs.contains(&p) {
                return true;
            }
            k = p;
        }
        false
    };
    let unity = rewritten(
        bvh,
        |j, o| 100.0 * if below(j) { flip * o } else { o },
        |j, e| 100.0 * if below(j) || legs.contains(&j) { flip * e } else { e },
        |j, t, q| {
            let q = if legs.contains(&j) {
                q * flip.conjugate()
            } else if below(j) {
                flip * q * flip.conjugate()
            } else {
                q
            };
            (100.0 * if below(j) { flip * t } else { t }, q)
        },
    );
    let out = build(&config(r#"{"mirror": false}"#), &[Source { name: "unity.bvh".into(), bvh: unity }]).unwrap();
    assert!(!out.warnings.iter().any(|w| w.contains("hip height")), "{:?}", out.warnings);
    assert_eq!(out.database.clips[0].scale, 0.01);
    let d = max_distance(&world(&out.database), &expected);
    assert!(d < 1e-4, "legs-up rest: {d} m from the original build");
}

/// One database from three skeletons: CMU ASF (the reference), 100STYLE (Xsens) and CMU Daz.
/// The retargeted ankles land where the scaled source's are, the head within a few cm; the
/// backward walk still walks backward, with plausible contacts.
#[test]
fn a_mixed_skeleton_database_builds_with_bounded_error() {
    let mut cfg = config(r#"{"clips": [{"file": "Angry_BW.bvh", "tags": ["backward"]}]}"#);
    cfg.cuts.insert("Angry_BW.bvh".into(), [535, 1500]);
    let out = build(
        &cfg,
        &[source("cmu-asf/cmu_16_15.bvh"), source("100style/Angry_BW.bvh"), source("cmu-daz/cmu_02_01.bvh")],
    )
    .unwrap();
    for note in out.retarget_notes() {
        println!("{note}");
    }
    assert_eq!(out.retargeted.len(), 2);
    for (name, r) in &out.retargeted {
        assert!(r.feet.mean < 0.005 && r.feet.max < 0.02, "{name}: ankles {:?}", r.feet);
        assert!(r.head.mean < 0.06 && r.head.max < 0.08, "{name}: head {:?}", r.head);
        assert!(r.hands.mean < 0.15, "{name}: hands {:?}", r.hands);
        assert!((0.9..1.1).contains(&r.leg_ratio), "{name}: leg ratio {}", r.leg_ratio);
    }
    // 100STYLE's toe joint sits at the ball of a 21.5 cm foot, CMU's at 12.5 cm: the toes differ
    // by the foot length, not by direction.
    let style = &out.retargeted[0].1;
    assert!(style.toes.max < 0.1, "toes {:?}", style.toes);
    let db = &out.database;
    let clip = db.clips.iter().find(|c| c.name == "Angry_BW[535-1500]").unwrap();
    let (s, e) = (clip.start as usize, clip.end as usize);
    assert_eq!(e - s, 965);
    let j = db.num_joints();
    let back: f32 = (s..e).map(|f| (db.local_rotations[f * j].inverse() * db.joint_velocity(f, 0).0).z).sum::<f32>()
        / (e - s) as f32;
    assert!(back < -0.6, "the backward walk moves at {back} m/s along its facing");
    for side in 0..2 {
        let share = (s..e).filter(|&f| db.contacts[2 * f + side] != 0).count() as f32 / (e - s) as f32;
        assert!((0.3..0.75).contains(&share), "100STYLE contact share {share}");
    }
    assert!(db
        .tags
        .iter()
        .any(|t| t.name == "backward" && t.ranges.iter().any(|&(a, b)| a <= s as u32 && b >= e as u32)));
    // What the .mmdb keeps of a retargeted database: everything `check_round_trip` requires.
    format::check_round_trip(db, &format::from_bytes(&format::to_bytes(db)).unwrap()).unwrap();
}

/// Walking played backward: the reversed copy's frames are the original's in reverse order,
/// velocities negated, contacts recomputed (and equal, reversed: the rule is on toe speed).
#[test]
fn reversed_copies_play_the_take_backward() {
    let cfg = config(
        r#"{"mirror": false, "clips": [{"file": "*", "reverse": true, "tags": ["walk"], "reverse_tags": ["backward"]}]}"#,
    );
    let db = build(&cfg, &[source("cmu-asf/cmu_16_15.bvh")]).unwrap().database;
    assert_eq!(db.clips.len(), 2);
    assert_eq!(db.clips[1].name, "cmu_16_15 (reversed)");
    let (n, j) = (db.clips[0].end as usize, db.num_joints());
    for f in 0..n {
        let g = n + (n - 1 - f);
        assert_eq!(db.local_positions[f * j..(f + 1) * j], db.local_positions[g * j..(g + 1) * j]);
        assert_eq!(db.contacts[2 * f..2 * f + 2], db.contacts[2 * g..2 * g + 2]);
        let (v, w) = (db.joint_velocity(f, 1).0, db.joint_velocity(g, 1).0);
        assert!((v + w).length() < 1e-4, "frame {f}: hips velocity {v} vs reversed {w}");
    }
    let tag = |name: &str| db.tags.iter().find(|t| t.name == name).unwrap().ranges.clone();
    assert_eq!(tag("walk"), vec![(0, n as u32)]);
    assert_eq!(tag("backward"), vec![(n as u32, 2 * n as u32)]);
    // Through the .mmdb (no velocities stored: they are derived from the poses, per clip): the
    // reversed clip, its name (the only mark of a reversal) and tag survive, and its derived
    // velocities are still the original's negated.
    let loaded = format::from_bytes(&format::to_bytes(&db)).unwrap();
    format::check_round_trip(&db, &loaded).unwrap();
    assert_eq!(loaded.clips[1].name, "cmu_16_15 (reversed)");
    assert_eq!(
        (loaded.clips[1].source_start, loaded.clips[1].source_fps),
        (db.clips[0].source_start, db.clips[0].source_fps)
    );
    for f in 0..n {
        let g = n + (n - 1 - f);
        let (v, w) = (loaded.joint_velocity(f, 1).0, loaded.joint_velocity(g, 1).0);
        assert!((v + w).length() < 1e-3, "loaded frame {f}: hips velocity {v} vs reversed {w}");
    }
}
