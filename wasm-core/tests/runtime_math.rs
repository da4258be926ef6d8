//! The runtime math on a database built from the real mocap in `../shared/mocap` (CMU walks):
//! inertialized playback with random jumps stays continuous, and foot lock + leg IK plant the
//! feet during contacts.

use glam::{Quat, Vec3};
use mmcore::character::root::RootMotion;
use mmcore::config::BuildConfig;
use mmcore::ik::{knee_bend_direction, leg_ik, FootLock, LegJoints};
use mmcore::inertialize::Inertializer;
use mmcore::kinematics::local_to_model;
use mmcore::{build, Bvh, Database, Source};
use std::path::Path;

fn walk_database() -> Database {
    let sources: Vec<Source> = ["cmu-asf/cmu_16_15.bvh", "cmu-asf/cmu_16_16.bvh", "cmu-asf/cmu_16_21.bvh"]
        .iter()
        .map(|rel| {
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/mocap").join(rel);
            let bytes = std::fs::read(&path)
                .unwrap_or_else(|e| panic!("{}: {e} (is ../shared beside the repo?)", path.display()));
            Source { name: rel.to_string(), bvh: Bvh::parse(rel, &bytes).unwrap() }
        })
        .collect();
    build(&BuildConfig::from_json(r#"{"mirror": false}"#).unwrap(), &sources).unwrap().database
}

/// Owned per-joint pose buffers.
struct Pose {
    pos: Vec<Vec3>,
    vel: Vec<Vec3>,
    rot: Vec<Quat>,
    angvel: Vec<Vec3>,
}

impl Pose {
    fn new(n: usize) -> Pose {
        Pose {
            pos: vec![Vec3::ZERO; n],
            vel: vec![Vec3::ZERO; n],
            rot: vec![Quat::IDENTITY; n],
            angvel: vec![Vec3::ZERO; n],
        }
    }
}

/// One frame of the database: (positions, velocities, rotations, angular velocities), the
/// velocities derived as a character plays the frame.
fn frame(db: &Database, f: usize) -> (&[Vec3], Vec<Vec3>, &[Quat], Vec<Vec3>) {
    let j = db.num_joints();
    let r = f * j..(f + 1) * j;
    let (mut v, mut w) = (vec![Vec3::ZERO; j], vec![Vec3::ZERO; j]);
    db.frame_velocities(f, &mut v, &mut w);
    (&db.local_positions[r.clone()], v, &db.local_rotations[r], w)
}

/// World forward kinematics of local buffers whose joint 0 holds the world root.
fn fk(parents: &[i32], pos: &[Vec3], rot: &[Quat], gp: &mut [Vec3], gr: &mut [Quat]) {
    local_to_model(parents, 0..parents.len(), None, pos, rot, gp, gr);
}

/// SplitMix64 for reproducible jumps.
fn next(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A frame's velocities, derived a block at a time when first asked for, are the ones every
/// frame's at once gives (`pose_velocities`, the recipe the offline tools and checks use) bit for
/// bit, whatever order the frames are asked in: clip ends one-sided, a block across a clip
/// boundary included. Asked again (from the kept block), the same; a clone starts over, the same.
#[test]
fn velocities_derived_when_played_are_every_frames_velocities() {
    let db = walk_database();
    let j = db.num_joints();
    let (all_v, all_w) =
        mmcore::database::pose_velocities(j, db.fps, &db.clips, &db.local_positions, &db.local_rotations);
    let (mut v, mut w) = (vec![Vec3::ZERO; j], vec![Vec3::ZERO; j]);
    let mut state = 58;
    let mut frames: Vec<usize> = (0..db.num_frames).collect();
    for i in (1..frames.len()).rev() {
        frames.swap(i, (next(&mut state) % (i as u64 + 1)) as usize);
    }
    let copy = db.clone();
    for (round, db) in [&db, &db, &copy].into_iter().enumerate() {
        for &f in &frames {
            db.frame_velocities(f, &mut v, &mut w);
            assert_eq!(
                (&v[..], &w[..]),
                (&all_v[f * j..(f + 1) * j], &all_w[f * j..(f + 1) * j]),
                "round {round} frame {f}"
            );
            let k = f % j;
            assert_eq!(db.joint_velocity(f, k), (all_v[f * j + k], all_w[f * j + k]));
        }
    }
    assert!(db.clips.len() >= 3 && db.clips.iter().any(|c| c.start % 32 != 0), "a block spans a clip boundary");
}

#[test]
fn inertialized_playback_is_continuous_across_random_jumps() {
    let db = walk_database();
    let (n, parents) = (db.num_joints(), &db.skeleton.parents);
    let dt = 1.0 / db.fps;
    let halflife = 0.1;
    let valid: Vec<usize> = (0..db.num_frames).filter(|&f| db.valid[f] == 1).collect();
    let mut rng = 42u64;

    let mut inert = Inertializer::new(n);
    let mut current = valid[0];
    // The character's own root motion: plays each take's root motion from where it stands.
    let mut root = RootMotion::default();
    let (mut out, mut check) = (Pose::new(n), Pose::new(n));
    let (mut gp, mut gr, mut prev_gp, mut cut_gp) =
        (vec![Vec3::ZERO; n], vec![Quat::IDENTITY; n], vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
    let (mut max_step, mut max_cut) = (0.0f32, 0.0f32);

    for step in 0..1200 {
        if step > 0 {
            // Jump every 10 frames (as a search would) and at the end of a clip.
            let clip_end = current + 1 >= db.num_frames || db.clip_at(current + 1) != db.clip_at(current);
            if step % 10 == 0 || clip_end {
                let dst = valid[(next(&mut rng) % valid.len() as u64) as usize];
                // Source: the raw frame that was playing; target: the new frame.
                let (sp, sv, sr, sw) = frame(&db, current);
                let (dp, dv, dr, dw) = frame(&db, dst);
                inert.transition(sp, &sv, sr, &sw, dp, &dv, dr, &dw);
                root.transition(&db, dst, true);
                // Key invariant on real data: at the transition the output does not move.
                inert.update(dp, dr, halflife, 0.0, &mut check.pos, &mut check.rot);
                for i in 1..n {
                    assert!((check.pos[i] - out.pos[i]).length() < 1e-5, "joint {i} moved at a transition");
                    assert!(1.0 - check.rot[i].dot(out.rot[i]).abs() < 1e-6, "joint {i} turned at a transition");
                }
                // What a hard cut would do to the world pose (root anchored like the inertializer's).
                let (mut cut_pos, mut cut_rot) = (dp.to_vec(), dr.to_vec());
                (cut_pos[0], cut_rot[0]) = (root.position, root.rotation);
                fk(parents, &cut_pos, &cut_rot, &mut cut_gp, &mut gr);
                max_cut = max_cut.max(cut_gp.iter().zip(&prev_gp).map(|(a, b)| (*a - *b).length()).fold(0.0, f32::max));
                current = dst;
            }
            root.step(&db, current, current + 1, halflife);
            current += 1;
        }
        let (ip, iv, ir, iw) = frame(&db, current);
        inert.update(ip, ir, halflife, dt, &mut out.pos, &mut out.rot);
        inert.velocities(&iv, &iw, &mut out.vel, &mut out.angvel);
        (out.pos[0], out.rot[0]) = (root.position, root.rotation);
        fk(parents, &out.pos, &out.rot, &mut gp, &mut gr);
        if step > 0 {
            let s = gp.iter().zip(&prev_gp).map(|(a, b)| (*a - *b).length()).fold(0.0, f32::max);
            max_step = max_step.max(s);
        }
        for q in &out.rot {
            assert!((q.length() - 1.0).abs() < 1e-4);
        }
        prev_gp.copy_from_slice(&gp);
    }
    // The same measure on the database played straight through (within clips).
    let mut max_data = 0.0f32;
    let mut prev = vec![Vec3::ZERO; n];
    for f in 0..db.num_frames {
        let (p, _, r, _) = frame(&db, f);
        fk(parents, p, r, &mut gp, &mut gr);
        if f > 0 && db.clip_at(f) == db.clip_at(f - 1) {
            max_data = max_data.max(gp.iter().zip(&prev).map(|(a, b)| (*a - *b).length()).fold(0.0, f32::max));
        }
        prev.copy_from_slice(&gp);
    }
    println!("largest per-frame joint move: data {max_data:.3} m, inertialized jumps {max_step:.3} m, hard cuts {max_cut:.3} m");
    // Jumps between random frames (far harsher than search results) may add the decaying offsets'
    // speed to the data's, but nothing like a cut.
    assert!(max_step < 1.5 * max_data, "inertialized playback jumped {max_step} m in one frame");
    assert!(max_cut > 4.0 * max_data, "the test's cuts are not discontinuous enough to mean anything");
}

#[test]
fn foot_lock_and_leg_ik_plant_the_feet_on_real_walks() {
    let db = walk_database();
    let (n, parents) = (db.num_joints(), &db.skeleton.parents);
    let dt = 1.0 / db.fps;
    let legs = [
        LegJoints::from_skeleton(&db.skeleton, "left").unwrap(),
        LegJoints::from_skeleton(&db.skeleton, "right").unwrap(),
    ];
    let (mut gp, mut gr) = (vec![Vec3::ZERO; n], vec![Quat::IDENTITY; n]);
    let mut rot = vec![Quat::IDENTITY; n];
    let toe_of = |leg: &LegJoints, gp: &[Vec3], gr: &[Quat]| gp[leg.toe] + gr[leg.toe] * leg.toe_offset;

    for clip in &db.clips {
        let mut locks = [FootLock::new(), FootLock::new()];
        let mut prev_toe: [Option<Vec3>; 2] = [None, None];
        let mut prev_fixed: [Option<(bool, Vec3)>; 2] = [None, None];
        let (mut slide_before, mut slide_after, mut worst_reach) = (0.0f32, 0.0f32, 0.0f32);
        let (mut step_anim, mut step_fixed) = (0.0f32, 0.0f32);
        for f in clip.start as usize..clip.end as usize {
            let (p, _, r, _) = frame(&db, f);
            rot.copy_from_slice(r);
            fk(parents, p, &rot, &mut gp, &mut gr);
            for (side, leg) in legs.iter().enumerate() {
                // Animated toe (world) and its velocity by finite difference.
                let toe = toe_of(leg, &gp, &gr);
                let vel = prev_toe[side].map_or(Vec3::ZERO, |t| (toe - t) / dt);
                let contact = db.contacts[2 * f + side] == 1;
                let target = locks[side].update(contact, toe, vel, dt, 0.2, 0.12);
                let pole = knee_bend_direction(gp[leg.upper_leg], gp[leg.lower_leg], gp[leg.foot]);
                let reached = leg_ik(leg, parents, &gp, &gr, target, pole, 0.0, 0.01, &mut rot);
                // Re-run FK so the other leg sees the updated pose.
                fk(parents, p, &rot, &mut gp, &mut gr);
                let fixed = toe_of(leg, &gp, &gr);
                assert!((fixed - reached).length() < 1e-4);
                let want = target.with_y(target.y.max(0.0));
                worst_reach = worst_reach.max((fixed - want).length());
                if let (Some(prev), Some((was_locked, prev_fixed))) = (prev_toe[side], prev_fixed[side]) {
                    step_anim = step_anim.max((toe - prev).length());
                    step_fixed = step_fixed.max((fixed - prev_fixed).length());
                    if locks[side].is_locked() && was_locked {
                        slide_before = slide_before.max((toe - prev).length());
                        slide_after = slide_after.max((fixed - prev_fixed).length());
                    }
                }
                prev_toe[side] = Some(toe);
                prev_fixed[side] = Some((locks[side].is_locked(), fixed));
            }
        }
        println!(
            "{}: largest locked toe step {:.2} mm → {:.3} mm after foot lock; worst IK miss {:.3} mm; \
             largest toe step {:.1} mm → {:.1} mm",
            clip.name,
            slide_before * 1e3,
            slide_after * 1e3,
            worst_reach * 1e3,
            step_anim * 1e3,
            step_fixed * 1e3
        );
        // Locking and releasing do not pop: the touched-up toe is never faster than the animation's
        // fastest frame by more than the release blend adds.
        assert!(step_fixed < 1.2 * step_anim, "{}: toe jumped {} m in one frame", clip.name, step_fixed);
        assert!(slide_after < 1e-3, "{}: locked toe still slides {} m per frame", clip.name, slide_after);
        assert!(worst_reach < 0.02, "{}: IK missed the toe target by {} m", clip.name, worst_reach);
    }
}
