//! Retargeting (docs/method.md §8) on a real database: onto a copy of the database's own
//! skeleton whose bones have other rest rotations, in another joint order, scaled, it reproduces
//! the source's world pose; one bent source joint bends only its avatar twin; the hips map by
//! the ratio of heights about the planted toe heights.

use glam::{Quat, Vec3};
use mmcore::character::{Character, CharacterSettings};
use mmcore::config::BuildConfig;
use mmcore::controller::Input;
use mmcore::kinematics::local_to_model;
use mmcore::retarget::{Retargeter, TargetSkeleton};
use mmcore::roles::{Role, Roles};
use mmcore::search::SearchIndex;
use mmcore::{build, Bvh, Database, Source};
use std::path::Path;

fn database() -> Database {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/mocap/cmu-asf");
    let sources: Vec<Source> = ["cmu_16_15.bvh", "cmu_16_35.bvh"]
        .iter()
        .map(|name| Source {
            bvh: Bvh::parse(name, &std::fs::read(dir.join(name)).unwrap()).unwrap(),
            name: name.to_string(),
        })
        .collect();
    build(&BuildConfig::default(), &sources).unwrap().database
}

/// The database's skeleton without its virtual root (the avatar's joints `k` ↔ database `k + 1`),
/// listed in `order`, scaled by `scale`, each bone's rest rotation `twist(k)` (its offset turned
/// so the rest geometry is unchanged).
struct Copy {
    parents: Vec<i32>,
    rotations: Vec<Quat>,
    positions: Vec<Vec3>,
    roles: Roles,
    /// Avatar joint of each database joint (none for the virtual root).
    of_db: Vec<Option<usize>>,
}

fn copy(db: &Database, order: &[usize], scale: f32, twist: impl Fn(usize) -> Quat) -> Copy {
    let n = db.num_joints() - 1;
    let mut slot = vec![0usize; n];
    for (k, &j) in order.iter().enumerate() {
        slot[j] = k;
    }
    // World rest rotation of joint j is twist(j); locals follow from the parents'.
    let (mut parents, mut rotations, mut positions) = (vec![-1; n], vec![Quat::IDENTITY; n], vec![Vec3::ZERO; n]);
    for j in 0..n {
        let p = db.skeleton.parents[j + 1] - 1;
        let parent_world = if p < 0 { Quat::IDENTITY } else { twist(p as usize) };
        parents[slot[j]] = if p < 0 { -1 } else { slot[p as usize] as i32 };
        rotations[slot[j]] = parent_world.inverse() * twist(j);
        positions[slot[j]] = parent_world.inverse() * (db.skeleton.offsets[j + 1] * scale);
    }
    let mut roles = Roles::default();
    for site in &db.skeleton.sites {
        if let (Some(role), true) = (Role::from_name(&site.name), site.joint > 0 && site.offset == Vec3::ZERO) {
            roles.set(role, Some(slot[site.joint as usize - 1]));
        }
    }
    let of_db = (0..db.num_joints()).map(|j| (j > 0).then(|| slot[j - 1])).collect();
    Copy { parents, rotations, positions, roles, of_db }
}

fn retargeter(db: &Database, c: &Copy, align: bool) -> Retargeter {
    let target = TargetSkeleton {
        parents: &c.parents,
        rest_local_rotations: &c.rotations,
        rest_local_positions: &c.positions,
        roles: c.roles,
        root_parent_rotation: Quat::IDENTITY,
    };
    Retargeter::new(db, &target, align, db.toe_height_in_contact()).unwrap()
}

/// World positions of the avatar for local rotations and the hips translation (its FK, in parent-first order).
fn avatar_world(c: &Copy, local: &[Quat], hips_joint: usize, hips: Vec3) -> Vec<Vec3> {
    let n = c.parents.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&k| {
        let (mut d, mut j) = (0, k as i32);
        while j >= 0 {
            d += 1;
            j = c.parents[j as usize];
        }
        d
    });
    let mut position = vec![0usize; n];
    for (i, &k) in order.iter().enumerate() {
        position[k] = i;
    }
    let parents: Vec<i32> =
        order.iter().map(|&k| if c.parents[k] < 0 { -1 } else { position[c.parents[k] as usize] as i32 }).collect();
    let mut lp: Vec<Vec3> = order.iter().map(|&k| c.positions[k]).collect();
    lp[position[hips_joint]] = hips;
    let lr: Vec<Quat> = order.iter().map(|&k| local[k]).collect();
    let (mut wp, mut wr) = (vec![Vec3::ZERO; n], vec![Quat::IDENTITY; n]);
    local_to_model(&parents, 0..n, None, &lp, &lr, &mut wp, &mut wr);
    (0..n).map(|k| wp[position[k]]).collect()
}

/// Whether an ancestor of database joint `j` (below the hips) has no role and turns in the data.
fn below_a_moving_unmapped_joint(db: &Database, c: &Copy, j: usize) -> bool {
    let mapped = |k: usize| c.roles.iter().any(|(_, a)| Some(a) == c.of_db[k]);
    let moves = |k: usize| {
        (1..db.num_frames)
            .any(|f| db.local_rotations[f * db.num_joints() + k].dot(db.local_rotations[k]).abs() < 1.0 - 1e-6)
    };
    let mut k = db.skeleton.parents[j];
    while k > 1 {
        if !mapped(k as usize) && moves(k as usize) {
            return true;
        }
        k = db.skeleton.parents[k as usize];
    }
    false
}

#[test]
fn a_twisted_reordered_copy_of_the_skeleton_gets_the_same_pose_scaled() {
    let db = database();
    let index = SearchIndex::new(&db).unwrap();
    let n = db.num_joints() - 1;
    // Reverse the joint order where allowed (children listed before parents) and give every
    // bone a different rest rotation.
    let order: Vec<usize> = (0..n).rev().collect();
    let twist = |j: usize| {
        Quat::from_euler(glam::EulerRot::YXZ, 0.3 * j as f32, -0.2 * (j % 5) as f32, 0.7 - 0.1 * j as f32).normalize()
    };
    for scale in [1.0f32, 0.8] {
        let c = copy(&db, &order, scale, twist);
        // Plain T-pose method: on the same geometry, alignment changes nothing anyway.
        let mut r = retargeter(&db, &c, false);
        assert!((r.hips_scale - scale).abs() < 1e-4, "hips scale {} for a copy scaled {scale}", r.hips_scale);
        let mut character = Character::new(&db, CharacterSettings::default());
        let mut local = vec![Quat::IDENTITY; n];
        let mut worst = 0.0f32;
        for step in 0..600 {
            let input = Input {
                direction: glam::Vec2::new((step as f32 * 0.01).sin(), 1.0),
                run: step > 300,
                ..Input::default()
            };
            character.update(&db, &index, &input, 1.0 / 60.0);
            let world = character.world_positions();
            let hips = world[r.source_hips];
            let hips_local = r.apply(character.world_rotations(), hips, 0.0, &mut local);
            let avatar = avatar_world(&c, &local, r.target_hips, hips_local);
            // Every role's joint where the database's is, scaled, heights about the planted toe
            // heights — except below a joint of no role that moves (CMU's second neck joint:
            // it keeps its rest, so the head turns right but sits a little elsewhere).
            for j in c.roles.iter().map(|(_, k)| order[k] + 1).filter(|&j| !below_a_moving_unmapped_joint(&db, &c, j)) {
                let a = avatar[c.of_db[j].unwrap()];
                let s = world[j];
                let expected = Vec3::new(s.x * scale, (s.y - r.source_floor) * scale + r.target_floor, s.z * scale);
                worst = worst.max((a - expected).length());
            }
        }
        println!("copy scaled {scale}: worst joint {:.2e} m from the scaled database pose", worst);
        assert!(worst < 1e-4, "joints off by {worst} m");
    }
}

#[test]
fn a_bent_elbow_bends_only_the_avatar_forearm() {
    let db = database();
    let n = db.num_joints() - 1;
    let c = copy(&db, &(0..n).collect::<Vec<_>>(), 1.0, |j| Quat::from_rotation_z(0.2 * j as f32));
    let mut r = retargeter(&db, &c, false);
    let j = db.num_joints();
    // The rest pose: all identity world rotations.
    let rest = vec![Quat::IDENTITY; j];
    let mut rest_local = vec![Quat::IDENTITY; n];
    r.apply(&rest, Vec3::new(0.0, 1.0, 0.0), 0.0, &mut rest_local);
    for k in 0..n {
        assert!(rest_local[k].dot(c.rotations[k]).abs() > 1.0 - 1e-6, "joint {k} not at rest");
    }
    // The left elbow (lower arm) bent 90°: it and everything below it turn in the world.
    let elbow = db.skeleton.site("left_lower_arm").unwrap().joint as usize;
    let bend = Quat::from_axis_angle(Vec3::new(0.3, -0.5, 0.8).normalize(), std::f32::consts::FRAC_PI_2);
    let mut pose = rest.clone();
    for k in 1..j {
        let mut a = k as i32;
        while a >= 0 && a as usize != elbow {
            a = db.skeleton.parents[a as usize];
        }
        if a >= 0 {
            pose[k] = bend;
        }
    }
    let mut local = vec![Quat::IDENTITY; n];
    r.apply(&pose, Vec3::new(0.0, 1.0, 0.0), 0.0, &mut local);
    for k in 0..n {
        let changed = local[k].dot(rest_local[k]).abs() < 1.0 - 1e-6;
        assert_eq!(
            changed,
            k == c.of_db[elbow].unwrap(),
            "joint {} ({}) changed: {changed}",
            k,
            db.skeleton.names[k + 1]
        );
    }
}

#[test]
fn hips_map_by_the_ratio_of_heights_about_the_planted_toes() {
    let db = database();
    let n = db.num_joints() - 1;
    let c = copy(&db, &(0..n).collect::<Vec<_>>(), 0.9, |_| Quat::IDENTITY);
    let mut r = retargeter(&db, &c, true);
    assert!((r.hips_scale - 0.9).abs() < 1e-3, "hips scale {}", r.hips_scale);
    let toe = db.toe_height_in_contact().unwrap();
    assert!((r.source_floor - toe).abs() < 1e-6);
    let mut local = vec![Quat::IDENTITY; n];
    let hips = r.apply(&vec![Quat::IDENTITY; db.num_joints()], Vec3::new(0.5, 0.9, -2.0), 0.0, &mut local);
    assert!((hips.x - 0.5 * 0.9).abs() < 1e-5 && (hips.z + 2.0 * 0.9).abs() < 1e-5);
    assert!((hips.y - ((0.9 - r.source_floor) * 0.9 + r.target_floor)).abs() < 1e-5);
    // A grounding lift moves the hips up by exactly that much.
    let lifted = r.apply(&vec![Quat::IDENTITY; db.num_joints()], Vec3::new(0.5, 0.9, -2.0), 0.02, &mut local);
    assert!((lifted.y - hips.y - 0.02).abs() < 1e-6);
}
