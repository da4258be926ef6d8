//! The default databases (`databases/*.json`) built from the shared mocap: what they hold, how
//! the character plays them (the quality harness's skating targets), and the VR tracked drive
//! following a straight walk at every speed from 0.3 to 2.0 m/s.

use glam::{Quat, Vec2, Vec3};
use mmcore::character::{Character, CharacterSettings, Tracked};
use mmcore::config::BuildConfig;
use mmcore::controller::Input;
use mmcore::naturalness::{self, Motion};
use mmcore::search::SearchIndex;
use mmcore::{build, format, quality, vr_replay, Bvh, Database, Source};
use std::path::Path;
use std::sync::OnceLock;

/// Builds `databases/<name>.json` as `mmdb build --config` does (its files are plain paths).
fn build_default(name: &str) -> (Database, Vec<String>) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../databases");
    let mut config =
        BuildConfig::from_json(&std::fs::read_to_string(dir.join(format!("{name}.json"))).unwrap()).unwrap();
    if let Some(csv) = &config.frame_cuts {
        config.cuts = mmcore::frame_cuts::parse(&std::fs::read_to_string(dir.join(csv)).unwrap()).unwrap();
    }
    let sources: Vec<Source> = config
        .clips
        .iter()
        .map(|c| {
            let path = dir.join(&c.file);
            let bytes = std::fs::read(&path)
                .unwrap_or_else(|e| panic!("{}: {e} (is ../shared beside the repo?)", path.display()));
            Source { name: c.file.clone(), bvh: Bvh::parse(&c.file, &bytes).unwrap() }
        })
        .collect();
    let out = build(&config, &sources).unwrap();
    let notes = out.retarget_notes();
    (out.database, notes)
}

fn locomotion() -> &'static (Database, Vec<String>) {
    static DB: OnceLock<(Database, Vec<String>)> = OnceLock::new();
    DB.get_or_init(|| build_default("locomotion"))
}

fn vr() -> &'static (Database, Vec<String>) {
    static DB: OnceLock<(Database, Vec<String>)> = OnceLock::new();
    DB.get_or_init(|| build_default("vr"))
}

fn seconds_tagged(db: &Database, tag: &str) -> f32 {
    db.tags
        .iter()
        .find(|t| t.name == tag)
        .map_or(0.0, |t| t.ranges.iter().map(|(s, e)| (e - s) as f32).sum::<f32>() / db.fps)
}

/// Every page loads the desktop database: it stays near its size (19,474 frames before it gained
/// backward walking, side-steps, idle and turning on the spot; 24,688 with them from 100STYLE's
/// angry and akimbo clips; ~34,000 with ACCAD's neutral ones and the stylized clips kept as
/// opt-in styles, docs/database.md "Styles").
#[test]
fn the_default_databases_hold_every_way_of_moving() {
    for (name, (db, notes), max_frames, tags) in [
        (
            "locomotion",
            locomotion(),
            36_000,
            &["walk", "run", "turn", "backward", "sidestep", "idle", "turn_in_place"][..],
        ),
        // VR: 28,230 frames since it holds ACCAD's crouch takes (1,962 frames with the mirrors).
        ("vr", vr(), 29_000, &["walk", "backward", "sidestep", "idle", "turn_in_place", "gesture", "crouched"][..]),
    ] {
        println!("{name}: {} frames, {} clips", db.num_frames, db.clips.len());
        for note in notes {
            println!("  {note}");
        }
        assert!(db.num_frames <= max_frames, "{name}: {} frames", db.num_frames);
        for tag in tags {
            let s = seconds_tagged(db, tag);
            println!("  {tag}: {s:.1} s");
            assert!(s >= 2.0, "{name}: only {s:.1} s tagged {tag}");
        }
        assert!(!notes.is_empty(), "{name}: 100STYLE takes are retargeted");
        // Retargeted clips and motion tags survive the .mmdb (version 2) as the shipped files.
        let bytes = format::to_bytes(db);
        println!("  .mmdb: {:.1} MB", bytes.len() as f64 / 1e6);
        format::check_round_trip(db, &format::from_bytes(&bytes).unwrap()).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

/// The VR database (`min_head_height` 0.9) searches a frame whose head is below 90 % of its
/// standing height only if it is crouch data (tagged `crouched` by the builder: ACCAD's crouch
/// takes): bending over is its user's (`character::crouch`), so CMU 02's washing, 14's laughing
/// bent over and boxing crouches are only played on the way. A character on it plays crouched
/// frames while its hips are dropped into a crouch, and never while it stands.
#[test]
fn the_vr_database_searches_upright_frames_and_crouch_data_only_when_crouching() {
    let db = &vr().0;
    let index = &SearchIndex::new(db).unwrap();
    let head = db.skeleton.site("head").unwrap().joint as usize;
    let rest = db.rest_positions();
    let floor = rest.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    let limit = 0.9 * (rest[head].y - floor);
    let crouched = db.tags.iter().find(|t| t.name == mmcore::tag_query::CROUCHED_TAG).expect("a crouched tag");
    let is_crouched = |f: usize| crouched.ranges.iter().any(|&(s, e)| (s as usize..e as usize).contains(&f));
    let j = db.num_joints();
    let (mut p, mut r) = (vec![Vec3::ZERO; j], vec![Quat::IDENTITY; j]);
    let (mut low, mut searchable, mut low_invalid, mut low_crouched) = (0, 0, 0, 0);
    for f in 0..db.num_frames {
        db.forward_kinematics(f, &mut p, &mut r);
        let is_low = p[head].y < limit;
        if db.valid[f] != 0 {
            searchable += 1;
            low += (is_low && !is_crouched(f)) as usize;
            low_crouched += (is_low && is_crouched(f)) as usize;
        } else {
            low_invalid += is_low as usize;
        }
    }
    println!("vr: {searchable} searchable frames ({low_crouched} crouch data), {low_invalid} with the head below 90 % left out");
    assert_eq!(low, 0, "{low} searchable frames with the head below 90 % outside the crouch data");
    assert!(low_crouched > 300, "only {low_crouched} crouched frames");
    assert!(low_invalid > 500, "only {low_invalid} low frames: the data should hold bending (CMU 02, 14)");
    assert!(searchable > 20_000);

    // Standing 3 s, hips dropped by 45 % of the standing hips height for 3 s, standing 3 s.
    let mut c = Character::new(db, CharacterSettings::default());
    let hips_height = rest[(0..j).find(|&k| db.skeleton.parents[k] == 0).unwrap()].y - floor;
    let (mut upright, mut upright_crouched, mut down, mut down_crouched) = (0, 0, 0, 0);
    for step in 0..540 {
        let crouching = (180..360).contains(&step);
        c.set_hips_drop(if crouching { 0.45 * hips_height } else { 0.0 });
        c.update(db, index, &Input::default(), 1.0 / 60.0);
        let now = is_crouched(c.frame());
        if crouching && step >= 210 {
            down += 1;
            down_crouched += now as usize;
        } else if !crouching && !(360..390).contains(&step) {
            upright += 1;
            upright_crouched += now as usize;
        }
    }
    println!("crouching: {down_crouched} of {down} frames crouch data; standing: {upright_crouched} of {upright}");
    assert_eq!(upright_crouched, 0);
    assert!(down_crouched * 10 >= down * 9, "{down_crouched} of {down}");
}

/// A tracked user crouching 0.5 m and standing up again as the VR e2e's script does (head down
/// over 0.8 s, held, up over 0.6 s, eased): while the head rises the shown hips never sink
/// below where the crouch left them (the crouch data's pose still fading out when the character
/// leaves it is not lowered again by the whole IK drop: it dipped 26 cm, `Legs::crouch_weight`),
/// and they are back within 8 cm of standing 0.1 s after the head is.
#[test]
fn standing_up_from_a_crouch_never_dips_the_hips() {
    let db = &vr().0;
    let index = &SearchIndex::new(db).unwrap();
    let hips = (0..db.num_joints()).find(|&k| db.skeleton.parents[k] == 0).unwrap();
    let ease = |x: f32| {
        let x = x.clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    };
    let mut c = Character::new(db, CharacterSettings::default());
    let (mut standing, mut held, mut lowest_rising, mut up) = (0.0f32, f32::INFINITY, f32::INFINITY, 0.0f32);
    for step in 0..(60 * 5) {
        let t = step as f32 / 60.0;
        let drop = 0.5 * (ease((t - 1.0) / 0.8) - ease((t - 3.0) / 0.6));
        c.set_crouch(drop, 0.0);
        c.update(db, index, &Input::default(), 1.0 / 60.0);
        let y = c.world_positions()[hips].y;
        assert!(y.is_finite(), "NaN at {t:.3} s");
        if (0.8..1.0).contains(&t) {
            standing = standing.max(y);
        } else if (2.5..3.0).contains(&t) {
            held = held.min(y);
        } else if (3.0..3.6).contains(&t) {
            lowest_rising = lowest_rising.min(y);
        } else if (3.69..3.71).contains(&t) {
            up = y;
        }
    }
    println!("hips: standing {standing:.3} m, crouched {held:.3}, lowest while rising {lowest_rising:.3}, 0.1 s after {up:.3}");
    assert!(held < standing - 0.3, "the crouch lowered the hips only to {held} from {standing}");
    assert!(lowest_rising > held - 0.02, "standing up, the hips sank to {lowest_rising} from {held}");
    assert!(up > standing - 0.08, "0.1 s after standing up the hips are at {up}, standing {standing}");
}

/// The quality harness on the desktop database (issue 14): the foot lock removes at least half
/// of the strafing skate and 60% over all scripts.
#[test]
fn the_foot_lock_holds_while_strafing_and_overall() {
    let db = &locomotion().0;
    let settings = CharacterSettings::default();
    let (mut locked, mut unlocked) = (0.0, 0.0);
    for script in quality::scripts() {
        let r = quality::run(db, &settings, &script, 60.0, 1.0 / 60.0);
        println!(
            "{:<16} root {:.3} m, skating {:.2} / {:.2} cm/s",
            r.script,
            r.mean_distance,
            100.0 * r.skating,
            100.0 * r.skating_without_lock
        );
        locked += r.skating;
        unlocked += r.skating_without_lock;
        if r.script == "strafe" {
            assert!(
                r.skating <= 0.5 * r.skating_without_lock,
                "strafe: {} vs {} without the lock",
                r.skating,
                r.skating_without_lock
            );
        }
        if r.script == "back-pedal" || r.script == "strafe" {
            assert!(r.mean_distance < 0.06, "{}: root {} m behind the simulation", r.script, r.mean_distance);
        }
    }
    println!("all scripts: {:.2} / {:.2} cm/s", 100.0 * locked, 100.0 * unlocked);
    assert!(locked <= 0.4 * unlocked, "all scripts: {locked} vs {unlocked} without the lock");
}

/// The quality harness is chaotic run to run (one search decides a clip), so it is judged over
/// five runs (`search_interval` 8–12), medians of the sums: with the foot lock the neutral
/// database skates no more than the stylized one it replaced did (44.5 cm/s, issue 29 allows
/// +10 %) — 54.3 before the corrective step became a timed swing with the other foot holding
/// its lock meanwhile, 33.6 after. Stop-and-go, where a body starting faster than the data's
/// starts dragged one foot 30–60 cm along the floor while the other stepped: 16.0 → 3.4.
#[test]
fn the_quality_harness_skates_less_than_the_stylized_database_did() {
    let db = &locomotion().0;
    let (mut totals, mut stop_and_go) = (Vec::new(), Vec::new());
    for interval in 8..=12 {
        let settings = CharacterSettings { search_interval: interval, ..CharacterSettings::default() };
        let mut total = 0.0;
        for script in quality::scripts() {
            let r = quality::run(db, &settings, &script, 60.0, 1.0 / 60.0);
            total += 100.0 * r.skating;
            if r.script == "stop-and-go" {
                stop_and_go.push(100.0 * r.skating);
            }
        }
        totals.push(total);
    }
    let median = |v: &mut Vec<f32>| {
        v.sort_by(f32::total_cmp);
        v[v.len() / 2]
    };
    println!("all scripts per run {totals:.1?} cm/s, stop-and-go {stop_and_go:.1?}");
    let (total, stop) = (median(&mut totals), median(&mut stop_and_go));
    assert!(total <= 1.1 * 44.5, "all scripts: median {total:.1} cm/s (the stylized database: 44.5)");
    assert!(stop <= 8.0, "stop-and-go: median {stop:.1} cm/s");
}

/// The foot lock's rule for a dragged body, on real data: while one foot is in the air on a
/// corrective step, the other keeps its lock however far the body pulls (the step lands within
/// `ik::STEP_TIME`), so the feet take turns instead of one sliding back under the body.
#[test]
fn a_locked_foot_holds_while_the_other_steps() {
    let db = &locomotion().0;
    let index = SearchIndex::new(db).unwrap();
    let floor = db.toe_height_in_contact().unwrap();
    let dt = 1.0 / 60.0;
    let (mut held, mut steps) = (0, 0);
    for script in quality::scripts().iter().filter(|s| s.path.is_none()) {
        let mut c = Character::new(db, CharacterSettings::default());
        c.set_toe_floor(Some(floor));
        let mut before = (c.foot_locked(), c.foot_stepping(), c.foot_airborne());
        for step in 0..1800 {
            c.update(db, &index, &(script.input)(step as f32 * dt), dt);
            let (locked, stepping, airborne) = (c.foot_locked(), c.foot_stepping(), c.foot_airborne());
            for side in 0..2 {
                let other = 1 - side;
                steps += (stepping[side] && !before.1[side]) as usize;
                // The other foot in the air on its step (after the last update), this one locked
                // and still in contact: it must still be locked.
                if before.2[other] && before.0[side] && c.contacts()[side] != 0 {
                    held += 1;
                    assert!(
                        locked[side],
                        "{}: t {:.2} s, foot {side} let go while the other stepped",
                        script.name,
                        step as f32 * dt
                    );
                }
            }
            before = (locked, stepping, airborne);
        }
    }
    println!("{steps} corrective steps, {held} frames a foot held while the other stepped");
    assert!(steps > 20 && held > 100, "{steps} steps, {held} held frames: the scripts no longer drag the feet");
}

/// A user walking perfectly straight at any speed from 0.3 to 2.0 m/s (VR settings, α = 0.2 m):
/// after 4 s the avatar keeps within a few cm of the head, never at α. Before the VR database
/// (the desktop one has no walk slower than ~1 m/s), some speeds left it standing at the clamp,
/// dragged a full α behind with both feet sliding.
#[test]
fn the_tracked_drive_follows_a_straight_walk_at_every_speed() {
    let db = &vr().0;
    let index = SearchIndex::new(db).unwrap();
    let alpha = 0.2;
    let variants = [
        vr_replay::vr_settings(),
        CharacterSettings {
            adjustment_max_ratio: 0.5,
            adjustment_min_speed: 0.0,
            beta_trajectory: 1.0,
            ..vr_replay::vr_settings()
        },
    ];
    for (v, base) in variants.iter().enumerate() {
        for (direction, hz) in [(0.0f32, 72.0f32), (2.3, 90.0)] {
            for speed in [0.3f32, 0.45, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8, 2.0] {
                let settings = CharacterSettings { clamp_distance: alpha, ..base.clone() };
                let mut c = Character::new(db, settings);
                c.set_toe_floor(db.toe_height_in_contact());
                let (dt, velocity) = (1.0 / hz, Vec3::new(direction.sin(), 0.0, direction.cos()) * speed);
                let mut head = Vec3::ZERO;
                let (mut sum, mut count, mut max) = (0.0, 0, 0.0f32);
                for step in 0..(10.0 * hz) as usize {
                    head += velocity * dt;
                    c.set_tracked(Tracked { position: head, velocity, yaw: direction, body: false });
                    c.update(db, &index, &Input::default(), dt);
                    if step as f32 * dt > 4.0 {
                        let r = c.root_position();
                        let d = Vec2::new(r.x - head.x, r.z - head.z).length();
                        sum += d;
                        count += 1;
                        max = max.max(d);
                    }
                }
                let mean = sum / count as f32;
                println!("settings {v}, direction {direction}, {hz} Hz, {speed} m/s: mean {mean:.3} m, max {max:.3} m");
                assert!(
                    mean < 0.05 && max < 0.8 * alpha,
                    "settings {v}, {speed} m/s at {hz} Hz: mean {mean} m, max {max} m behind the head"
                );
            }
        }
    }
}

/// Format version 3 on the default database (docs/mmdb-format.md): the builder keeps its
/// rotations as the file stores them, so the loaded database is the built one bit for bit —
/// poses, and the features and velocities derived from them; each rotation is within the
/// documented 2/32767 rad of its unquantized value's bound, every world position within 1 mm,
/// and 2,000 searches give the same frames and costs.
#[test]
fn format_version_3_keeps_the_default_database() {
    use mmcore::format::{self, codec};
    use mmcore::rng::Rng;
    use mmcore::search::{SearchMethod, SearchOptions};
    let (db, _) = locomotion();
    let bytes = format::to_bytes(db);
    let loaded = format::from_bytes(&bytes).unwrap();
    format::check_round_trip(db, &loaded).unwrap();
    assert!(loaded == *db, "the loaded database differs from the built one");
    let worst_rotation =
        db.local_rotations.iter().zip(&loaded.local_rotations).map(|(a, b)| codec::angle(*a, *b)).fold(0.0, f64::max);
    let j = db.num_joints();
    let (mut p0, mut r0, mut p1, mut r1) =
        (vec![Vec3::ZERO; j], vec![glam::Quat::IDENTITY; j], vec![Vec3::ZERO; j], vec![glam::Quat::IDENTITY; j]);
    let mut worst_position = 0.0f32;
    for f in 0..db.num_frames {
        db.forward_kinematics(f, &mut p0, &mut r0);
        loaded.forward_kinematics(f, &mut p1, &mut r1);
        worst_position = p0.iter().zip(&p1).map(|(a, b)| a.distance(*b)).fold(worst_position, f32::max);
    }
    let (a, b) = (SearchIndex::new(db).unwrap(), SearchIndex::new(&loaded).unwrap());
    let mut rng = Rng(2_000);
    let mut query = vec![0.0f32; db.num_features()];
    let mut same = 0;
    for _ in 0..2_000 {
        let source = rng.below(db.num_frames);
        let noise = [0.0, 0.1, 1.0][rng.below(3)];
        query.iter_mut().zip(db.feature(source)).for_each(|(q, &x)| *q = x + noise * rng.normal());
        let options = SearchOptions {
            beta_pose: rng.uniform(0.0, 2.0),
            beta_trajectory: rng.uniform(0.0, 2.0),
            ..Default::default()
        };
        let (x, y) = (
            a.search(SearchMethod::Aabb, &query, &options, f32::INFINITY),
            b.search(SearchMethod::Aabb, &query, &options, f32::INFINITY),
        );
        assert_eq!(x.map(|(f, c)| (f, c.to_bits())), y.map(|(f, c)| (f, c.to_bits())));
        same += 1;
    }
    println!(
        "format v3 on the default database: {:.2} MB; worst rotation error {worst_rotation:.2e} rad (bound {:.2e}), worst world position {:.3} mm; {same}/2000 searches identical",
        bytes.len() as f64 / 1e6,
        codec::MAX_ROTATION_ERROR,
        worst_position * 1e3
    );
    assert!(worst_rotation <= codec::MAX_ROTATION_ERROR);
    assert!(worst_position <= 1e-3, "{worst_position} m");
}

/// The default character looks like a calm person (docs/database.md, "Styles"): with the default
/// settings at most 2 % of the frames come from stylized clips while standing, walking,
/// side-stepping and walking backward (60 s each), the head looks within 15° of level on
/// average while standing, and the hands hang below the hips (hands on hips is a style);
/// choosing a style makes at least 80 % of the frames that style's where the database has it.
#[test]
fn the_default_character_is_neutral_and_styles_are_opt_in() {
    let dt = 1.0 / 60.0;
    for (name, db, settings) in
        [("locomotion", &locomotion().0, CharacterSettings::default()), ("vr", &vr().0, vr_replay::vr_settings())]
    {
        let reports: Vec<_> =
            Motion::ALL.iter().map(|&m| naturalness::measure(db, &settings, m, 60.0, dt).unwrap()).collect();
        println!("{name}, default settings:\n{}", naturalness::table(&reports));
        for r in &reports {
            assert!(
                r.other_style_share <= 0.02,
                "{name} {}: {:.1} % of frames stylized",
                r.motion.name(),
                100.0 * r.other_style_share
            );
            assert!(
                r.hands_above_hips_mean < 0.0,
                "{name} {}: hands {:.2} m above the hips",
                r.motion.name(),
                r.hands_above_hips_mean
            );
        }
        let idle = &reports[0];
        assert!(idle.head_pitch_mean.abs() <= 15.0, "{name} idle: head pitch {:.1}°", idle.head_pitch_mean);
    }
    // The desktop database keeps 100STYLE's angry clips (idle, forward, backward, sideways) as
    // an opt-in style.
    let db = &locomotion().0;
    let styles: Vec<&str> = mmcore::tag_query::styles(db).collect();
    assert!(styles.contains(&"neutral") && styles.contains(&"angry") && styles.contains(&"akimbo"), "{styles:?}");
    let angry = CharacterSettings { style: "angry".into(), ..CharacterSettings::default() };
    let reports: Vec<_> = Motion::ALL.iter().map(|&m| naturalness::measure(db, &angry, m, 60.0, dt).unwrap()).collect();
    println!("locomotion, style angry:\n{}", naturalness::table(&reports));
    for r in &reports {
        assert!(r.style_share >= 0.8, "angry {}: only {:.1} % of frames angry", r.motion.name(), 100.0 * r.style_share);
    }
}

/// The first part a page starts on (`first_part` in both configs, docs/mmdb-format.md `PART`):
/// a small share of the bytes, every frame the whole's frame exactly, and a character moved
/// from the part to the whole mid-motion shows no jump — at 25 moments of a walk with turns,
/// side-steps and stops, the update across the move is measured against the same character's
/// other updates: the root within 1 cm of its motion the update before, no joint moving (in
/// the root's space) more than the most any other update moves it.
#[test]
fn the_first_part_moves_to_the_whole_without_a_jump() {
    use mmcore::first_part;
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../databases");
    for (name, (built, _)) in [("locomotion", locomotion()), ("vr", vr())] {
        let config =
            BuildConfig::from_json(&std::fs::read_to_string(dir.join(format!("{name}.json"))).unwrap()).unwrap();
        let spec = config.first_part.expect("the default databases have a first part");
        let whole_bytes = format::to_bytes(built);
        let checksum = u32::from_le_bytes(whole_bytes[24..28].try_into().unwrap());
        let clips = first_part::choose(built, &spec).unwrap();
        let fly = first_part::FirstPartSpec { seconds: 60.0, tags: vec!["fly".into()], exclude: vec![] };
        let e = first_part::choose(built, &fly).unwrap_err().to_string();
        assert!(e.contains("no tag 'fly' in the database (it has backward,"), "{e}");
        let part_bytes = format::to_bytes(&first_part::cut(built, &clips, &format!("{name}.mmdb"), checksum).unwrap());
        // What a page has: both files as loaded (rotations quantized, velocities derived).
        let whole = format::from_bytes(&whole_bytes).unwrap();
        let part = format::from_bytes(&part_bytes).unwrap();
        let p = part.part.clone().expect("PART read back");
        assert_eq!(
            (p.whole.as_str(), p.whole_frames, p.whole_checksum),
            (&*format!("{name}.mmdb"), whole.num_frames as u32, checksum)
        );
        let share = part_bytes.len() as f64 / whole_bytes.len() as f64;
        println!(
            "{name}: first part {} of {} clips, {:.1} s, {:.2} of {:.2} MB ({:.1} %)",
            part.clips.len(),
            whole.clips.len(),
            part.duration(),
            part_bytes.len() as f64 / 1e6,
            whole_bytes.len() as f64 / 1e6,
            100.0 * share
        );
        assert!(share < 0.15, "{name}: the first part is {:.1} % of the whole", 100.0 * share);
        for tag in ["idle", "walk", "sidestep", "backward"] {
            assert!(
                seconds_tagged(&part, tag) >= 2.0,
                "{name}: the first part has {:.1} s of {tag}",
                seconds_tagged(&part, tag)
            );
        }
        // Every part frame is the whole's frame, bit for bit.
        let (j, d) = (whole.num_joints(), whole.num_features());
        for f in 0..part.num_frames {
            let w = p.whole_frame(f).unwrap();
            assert_eq!(
                part.local_rotations[f * j..(f + 1) * j],
                whole.local_rotations[w * j..(w + 1) * j],
                "{name} frame {f}"
            );
            assert_eq!(part.local_positions[f * j..(f + 1) * j], whole.local_positions[w * j..(w + 1) * j]);
            // The velocities a character plays the frame with: the same in both.
            let velocities = |db: &Database, f: usize| {
                let (mut v, mut w) = (vec![Vec3::ZERO; j], vec![Vec3::ZERO; j]);
                db.frame_velocities(f, &mut v, &mut w);
                (v, w)
            };
            assert_eq!(velocities(&part, f), velocities(&whole, w), "{name} frame {f}");
            assert_eq!(part.features[f * d..(f + 1) * d], whole.features[w * d..(w + 1) * d]);
            assert_eq!(
                (&part.contacts[2 * f..2 * f + 2], part.valid[f]),
                (&whole.contacts[2 * w..2 * w + 2], whole.valid[w])
            );
        }
        assert_eq!(p.whole_frame(part.num_frames), None);
        // A new character stands as it would on the whole: the same first frame.
        let settings = CharacterSettings::default();
        let start = mmcore::character::start_frame(&part, &settings);
        assert_eq!(p.whole_frame(start), Some(mmcore::character::start_frame(&whole, &settings)), "{name}");

        let (part_index, whole_index) = (SearchIndex::new(&part).unwrap(), SearchIndex::new(&whole).unwrap());
        // 12 s: stand, walk, turn, side-step, back, stop — a new input every 1.5 s.
        let inputs = [(0.0, 0.0), (0.0, 1.0), (0.7, 0.7), (1.0, 0.0), (0.0, -1.0), (0.0, 0.0), (-1.0, 0.0), (0.0, 1.0)];
        let input_at = |u: usize| {
            let (x, z) = inputs[(u / 90) % inputs.len()];
            Input { direction: Vec2::new(x, z), facing: Vec2::Y, run: false, strafe: (u / 90) % 4 == 3 }
        };
        // Per update: root displacement, and the largest joint displacement in the root's space.
        let step = |c: &Character, before: &(Vec3, Quat, Vec<Vec3>)| {
            let (root, rot) = (c.root_position(), c.root_rotation());
            let local = |p: Vec3, r: Vec3, q: Quat| q.inverse() * (p - r);
            let joint = c
                .world_positions()
                .iter()
                .zip(&before.2)
                .map(|(&a, &b)| (local(a, root, rot) - local(b, before.0, before.1)).length())
                .fold(0.0f32, f32::max);
            ((root - before.0).length(), joint)
        };
        let snapshot = |c: &Character| (c.root_position(), c.root_rotation(), c.world_positions().to_vec());
        let mut worst = (0.0f32, 0.0f32, 0.0f32);
        for k in (20..720).step_by(28) {
            let mut c = Character::new(&part, settings.clone());
            let (mut moves, mut joints) = (Vec::new(), Vec::new());
            let mut swap_at = None;
            for u in 0..k + 60 {
                let before = snapshot(&c);
                if u == k {
                    let frame = c.frame();
                    c.enter_whole(&p);
                    assert_eq!(c.frame(), p.whole_frame(frame).unwrap());
                    swap_at = Some(u);
                }
                let on_whole = swap_at.is_some();
                let (db, index) = if on_whole { (&whole, &whole_index) } else { (&part, &part_index) };
                c.update(db, index, &input_at(u), 1.0 / 60.0);
                let (m, j) = step(&c, &before);
                moves.push(m);
                joints.push(j);
            }
            let (m, j) = (moves[k], joints[k]);
            let root_jump = (m - moves[k - 1]).abs();
            let others = joints.iter().enumerate().filter(|&(u, _)| u != k).map(|(_, &v)| v).fold(0.0f32, f32::max);
            worst = (worst.0.max(root_jump), worst.1.max(j), worst.2.max(others));
            assert!(
                root_jump < 0.01,
                "{name}, moved at update {k}: the root moved {m} m against {} the update before",
                moves[k - 1]
            );
            assert!(j <= others, "{name}, moved at update {k}: a joint moved {j} m in the root's space, at most {others} in other updates");
        }
        println!(
            "{name}: across the move, root change at most {:.2} mm, joints at most {:.1} mm (other updates: up to {:.1} mm)",
            1e3 * worst.0,
            1e3 * worst.1,
            1e3 * worst.2
        );
    }
}
