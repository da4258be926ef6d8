//! The quality harness: deterministic scripted inputs simulated at a fixed dt, measuring how
//! well the character follows its controller and how clean its motion is (issue 3).

use crate::character::{Character, CharacterSettings};
use crate::controller::{Input, Path};
use crate::database::Database;
pub use crate::skating::{SkatingMeter, ON_FLOOR};
use glam::{Quat, Vec2, Vec3};
use serde::Serialize;

/// A named input script: the input at time `t` (seconds), or a path to follow.
pub struct Script {
    pub name: &'static str,
    pub input: fn(f32) -> Input,
    pub path: Option<fn() -> Path>,
}

fn walk(direction: Vec2) -> Input {
    Input { direction, ..Default::default() }
}

/// The scripts: straight walk, run, zig-zag, circles, stop-and-go, strafe (walking side-steps,
/// 3 s each way), back-pedal (walking backward, facing forward), turning on the spot (the facing
/// turns a quarter every 2 s, no travel), and a 4 m path square.
pub fn scripts() -> Vec<Script> {
    vec![
        Script { name: "straight walk", input: |_| walk(Vec2::Y), path: None },
        Script { name: "run", input: |_| Input { run: true, ..walk(Vec2::Y) }, path: None },
        Script {
            name: "zig-zag",
            input: |t| walk(if (t / 2.0) as i32 % 2 == 0 { Vec2::new(0.7, 0.7) } else { Vec2::new(-0.7, 0.7) }),
            path: None,
        },
        Script { name: "circles", input: |t| walk(Vec2::new((0.6 * t).sin(), (0.6 * t).cos())), path: None },
        Script { name: "stop-and-go", input: |t| walk(if t % 5.0 < 3.0 { Vec2::Y } else { Vec2::ZERO }), path: None },
        Script {
            name: "strafe",
            input: |t| Input {
                direction: if (t / 3.0) as i32 % 2 == 0 { Vec2::X } else { -Vec2::X },
                facing: Vec2::Y,
                strafe: true,
                run: false,
            },
            path: None,
        },
        Script {
            name: "back-pedal",
            input: |t| Input {
                direction: if t % 6.0 < 4.0 { -Vec2::Y } else { Vec2::ZERO },
                facing: Vec2::Y,
                strafe: true,
                run: false,
            },
            path: None,
        },
        Script {
            name: "turn on the spot",
            input: |t| {
                let quarter = (t / 2.0).floor() * std::f32::consts::FRAC_PI_2;
                Input {
                    direction: Vec2::ZERO,
                    facing: Vec2::new(quarter.sin(), quarter.cos()),
                    strafe: true,
                    run: false,
                }
            },
            path: None,
        },
        Script {
            name: "path square",
            input: |_| Input::default(),
            path: Some(|| {
                let square =
                    [Vec3::ZERO, Vec3::new(0.0, 0.0, 4.0), Vec3::new(-4.0, 0.0, 4.0), Vec3::new(-4.0, 0.0, 0.0)];
                Path::new(&square, &[1.5; 4], true).unwrap()
            }),
        },
    ]
}

/// What one script measured.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub script: String,
    pub seconds: f32,
    /// Root ↔ simulated character distance on the ground (m).
    pub mean_distance: f32,
    pub max_distance: f32,
    /// For path scripts: the largest distance of the root from the path (m).
    pub max_path_distance: Option<f32>,
    /// Foot skating, m per second of animation, summed over both toes:
    /// `s = d_xz·(2 − 2^(h/H))` for frames with toe height h < H.
    pub skating: f32,
    /// The same with the foot lock switched off (the rest of the settings unchanged).
    pub skating_without_lock: f32,
    pub searches_per_second: f32,
    pub transitions_per_second: f32,
    /// Largest angular speed of any joint between consecutive output poses (rad/s).
    pub max_angular_speed: f32,
    /// Pop detector: the largest ratio, over joints, of the output's angular speed to the
    /// fastest that joint ever turns in the database. Above 1 the character moved a joint
    /// faster than any recorded motion did.
    pub pop_ratio: f32,
    /// Distance the root travelled (m), to see that it moved at all.
    pub travelled: f32,
}

/// Runs `script` for `seconds` at time step `dt` and measures it (and once more without the
/// foot lock, for the skating comparison).
pub fn run(db: &Database, settings: &CharacterSettings, script: &Script, seconds: f32, dt: f32) -> Report {
    let unlocked = CharacterSettings { foot_lock: false, ..settings.clone() };
    let without = simulate(db, &unlocked, script, seconds, dt);
    Report { skating_without_lock: without.skating, ..simulate(db, settings, script, seconds, dt) }
}

fn simulate(db: &Database, settings: &CharacterSettings, script: &Script, seconds: f32, dt: f32) -> Report {
    let index = crate::search::SearchIndex::new(db).expect("a searchable database");
    let mut character = Character::new(db, settings.clone());
    character.set_toe_floor(db.toe_height_in_contact());
    let path = script.path.map(|p| p());
    if let Some(p) = &path {
        let (start, velocity) = p.sample(0.0);
        let facing = crate::controller::yaw_facing(velocity).unwrap_or(Quat::IDENTITY);
        character.teleport(db, start, facing);
        character.set_path(Some(p.clone()));
    }
    let j = db.num_joints();
    let mut previous_rotations = vec![Quat::IDENTITY; j];
    let joint_limits = joint_max_angular_speeds(db);
    let mut pop_ratio = 0.0f32;
    let steps = (seconds / dt).round() as usize;
    let (mut sum_distance, mut max_distance, mut max_path, mut max_speed, mut travelled) =
        (0.0, 0.0f32, 0.0f32, 0.0f32, 0.0);
    let mut last_root = character.root_position();
    for step in 0..steps {
        let t = step as f32 * dt;
        character.update(db, &index, &(script.input)(t), dt);
        let root = character.root_position();
        let sim = character.simulation.position;
        let distance = Vec2::new(root.x - sim.x, root.z - sim.z).length();
        sum_distance += distance;
        max_distance = max_distance.max(distance);
        if let Some(p) = &path {
            max_path = max_path.max(p.distance_to(root));
        }
        travelled += (root - last_root).length();
        last_root = root;
        if step > 0 {
            for k in 1..j {
                let (q, p) = (character.pose_rotations()[k], previous_rotations[k]);
                let speed = crate::spring::quat_abs(q * p.inverse()).to_scaled_axis().length() / dt;
                max_speed = max_speed.max(speed);
                pop_ratio = pop_ratio.max(speed / joint_limits[k].max(1.0));
            }
        }
        previous_rotations.copy_from_slice(character.pose_rotations());
    }
    let stats = character.stats;
    Report {
        script: script.name.to_string(),
        seconds,
        mean_distance: sum_distance / steps as f32,
        max_distance,
        max_path_distance: path.as_ref().map(|_| max_path),
        skating: character.skating().distance / seconds,
        skating_without_lock: f32::NAN,
        searches_per_second: stats.searches as f32 / seconds,
        transitions_per_second: stats.transitions as f32 / seconds,
        max_angular_speed: max_speed,
        pop_ratio,
        travelled,
    }
}

/// The fastest each joint turns anywhere in the database (rad/s): what recorded motion
/// reaches (after the builder's spike repair), the yardstick of the pop detector. Joint 0 is 0.
pub fn joint_max_angular_speeds(db: &Database) -> Vec<f32> {
    let j = db.num_joints();
    let (mut max, mut v, mut w) = (vec![0.0f32; j], vec![Vec3::ZERO; j], vec![Vec3::ZERO; j]);
    for f in 0..db.num_frames {
        db.frame_velocities(f, &mut v, &mut w);
        for k in 1..j {
            max[k] = max[k].max(w[k].length());
        }
    }
    max
}

/// The harness as a text table (`mmdb quality`).
pub fn table(reports: &[Report]) -> String {
    let mut out = String::from(
        "script          root↔sim mean/max (m)  path max (m)  skating lock/no lock (cm/s)  searches/s  transitions/s  max ω (rad/s)\n",
    );
    for r in reports {
        out += &format!(
            "{:<15} {:>9.3} / {:<9.3} {:>12} {:>13.2} / {:<11.2} {:>10.1} {:>14.2} {:>14.1}\n",
            r.script,
            r.mean_distance,
            r.max_distance,
            r.max_path_distance.map_or("-".to_string(), |d| format!("{d:.3}")),
            100.0 * r.skating,
            100.0 * r.skating_without_lock,
            r.searches_per_second,
            r.transitions_per_second,
            r.max_angular_speed
        );
    }
    out
}

/// How well `db` can play what `other` shows: for every valid frame of `other` (inside `mask`),
/// its features (pose and trajectory) as a query on `db` — renormalized from `other`'s
/// normalization to `db`'s — and the cost of the best match. Low means `db` holds that motion.
///
/// # Errors
/// The two databases' feature layouts differ.
pub fn coverage(db: &Database, other: &Database, mask: Option<&[bool]>) -> Result<Vec<f32>, String> {
    let same = db.groups.len() == other.groups.len()
        && db
            .groups
            .iter()
            .zip(&other.groups)
            .all(|(a, b)| a.name == b.name && a.num_dims == b.num_dims && a.first_dim == b.first_dim);
    if !same {
        return Err("coverage: the databases' feature layouts differ".into());
    }
    let index = crate::search::SearchIndex::new(db).map_err(|e| e.to_string())?;
    let d = db.num_features();
    let mut query = vec![0.0f32; d];
    let mut costs = Vec::new();
    let options = crate::search::SearchOptions::default();
    for f in 0..other.num_frames {
        if other.valid[f] == 0 || mask.is_some_and(|m| !m[f]) {
            continue;
        }
        let x = other.feature(f);
        for k in 0..d {
            let raw = x[k] * other.feature_scale[k] + other.feature_mean[k];
            query[k] = (raw - db.feature_mean[k]) / db.feature_scale[k];
        }
        if let Some((_, cost)) = index.search(crate::search::SearchMethod::Aabb, &query, &options, f32::INFINITY) {
            costs.push(cost);
        }
    }
    Ok(costs)
}

/// Mean, median and 90th percentile of `values` (NaN when empty).
pub fn summarize(values: &[f32]) -> (f32, f32, f32) {
    if values.is_empty() {
        return (f32::NAN, f32::NAN, f32::NAN);
    }
    let mut v = values.to_vec();
    v.sort_by(f32::total_cmp);
    let q = |p: f32| v[((v.len() - 1) as f32 * p).round() as usize];
    (v.iter().sum::<f32>() / v.len() as f32, q(0.5), q(0.9))
}
