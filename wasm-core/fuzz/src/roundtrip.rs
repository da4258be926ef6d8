//! The round-trip property (issue 28): anything `build` accepts, `load` accepts, and a character
//! plays — finite output, its root within α of its simulated character. One generator turns any
//! bytes into a build configuration and one or two BVH takes (a humanoid whose units, rate,
//! length, motion, proportions and skeleton vary, with values anywhere inside the BVH limits) and
//! the configuration anywhere around the configuration's limits (fps, scale, windows, mirror,
//! reverse, motion tags, head-height filter, feature groups with any offsets, axes and
//! weights). Used by the AFL target `roundtrip` (`fuzz/src/bin/roundtrip.rs`), by
//! `tests/roundtrip.rs` on every `cargo test` (fixed seeds), and by `mmdb-cases --roundtrip`,
//! which writes cases for the same property in WASM (`tests/unit/roundtrip-wasm.test.ts`).
//! Needs only `mmcore`, so both crates compile it.

use glam::Vec2;
use mmcore::character::{Character, CharacterSettings};
use mmcore::controller::Input;
use mmcore::limits::{MAX_ABS_BVH_VALUE, MAX_MESSAGE_CHARS};
use mmcore::search::SearchIndex;
use mmcore::{build, format, BuildConfig, Bvh, Source};

/// Reads values from the bytes; past the end everything is zero.
struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn byte(&mut self) -> u8 {
        let (b, rest) = self.0.split_first().map_or((0, &[][..]), |(b, r)| (*b, r));
        self.0 = rest;
        b
    }
    /// 0 … 1.
    fn unit(&mut self) -> f64 {
        f64::from(u16::from_le_bytes([self.byte(), self.byte()])) / 65535.0
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// Log-uniform in [lo, hi] (both > 0).
    fn log(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unit()).exp()
    }
    fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[self.byte() as usize % items.len()]
    }
    fn chance(&mut self, per_256: u8) -> bool {
        self.byte() < per_256
    }
}

/// A generated case: the configuration (JSON, as `mmdb build --config` and the page's builder
/// take it) and the BVH takes (name, text).
pub struct Case {
    pub config: String,
    pub takes: Vec<(String, String)>,
}

/// The joints of the generated humanoid: name, parent, rest offset (metres, Y up), whether an
/// arm (dropped in the second skeleton of a retargeting case).
const JOINTS: [(&str, i32, [f64; 3], bool); 16] = [
    ("root", -1, [0.0, 0.0, 0.0], false),
    ("lfemur", 0, [0.1, -0.05, 0.0], false),
    ("ltibia", 1, [0.0, -0.42, 0.0], false),
    ("lfoot", 2, [0.0, -0.41, 0.0], false),
    ("ltoes", 3, [0.0, -0.05, 0.12], false),
    ("rfemur", 0, [-0.1, -0.05, 0.0], false),
    ("rtibia", 5, [0.0, -0.42, 0.0], false),
    ("rfoot", 6, [0.0, -0.41, 0.0], false),
    ("rtoes", 7, [0.0, -0.05, 0.12], false),
    ("lowerback", 0, [0.0, 0.1, 0.0], false),
    ("thorax", 9, [0.0, 0.3, 0.0], false),
    ("head", 10, [0.0, 0.3, 0.0], false),
    ("lhumerus", 10, [0.18, 0.2, 0.0], true),
    ("lradius", 12, [0.3, 0.0, 0.0], true),
    ("rhumerus", 10, [-0.18, 0.2, 0.0], true),
    ("rradius", 14, [-0.3, 0.0, 0.0], true),
];

/// A number as BVH text, inside the BVH limit.
fn v(x: f64) -> String {
    format!("{:.6}", x.clamp(-MAX_ABS_BVH_VALUE, MAX_ABS_BVH_VALUE))
}

/// One take (for a database at `fps`): `frames` frames of a walk (forward speed, sway, leg swing, turning) in `unit` file
/// units per metre, legs × `legs`, with Z up when `z_up`; arms unless `no_arms`; a few values
/// anywhere within ±10⁷ when the bytes say so (a glitch, a teleport, a spinning joint).
fn take(r: &mut Reader, no_arms: bool, fps: f64) -> String {
    let unit = r.pick(&[1.0, 100.0, 1000.0, 39.37, 1.0, 100.0]);
    let legs = if r.chance(24) { r.log(1e-4, 1e4) } else { r.range(0.7, 1.4) };
    let z_up = r.chance(24);
    let frames = if r.chance(16) { 1 + r.byte() as usize * 8 } else { 2 + r.byte() as usize % 160 };
    let frame_time = if r.chance(32) {
        r.pick(&[1.0, 0.5, 1e-4, 1e-3, 0.04])
    } else {
        r.pick(&[1.0 / 120.0, 1.0 / 60.0, 1.0 / 30.0, 0.00833333, 1.0 / 24.0])
    };
    // A slow source resampled to 1,000 fps grows 1,000-fold: keep such takes short, so that a
    // case stays a fraction of a second (`tests/build_limits.rs` has the big builds).
    let frames = if frame_time >= 0.5 { frames.min(30) } else { frames };
    // Likewise a long take at a high database rate: 2,000 frames at 60 fps are 66,000 at
    // 1,000 fps, mirrored and reversed four times that (seconds per case under AFL).
    let frames = if fps > 120.0 { frames.min(400) } else { frames };
    let (speed, swing, turn) = (r.range(-0.5, 3.0), r.range(0.0, 60.0), r.range(-1.0, 1.0));
    let glitches = if r.chance(48) { 1 + r.byte() % 4 } else { 0 };
    let joints: Vec<usize> = (0..JOINTS.len()).filter(|&j| !(no_arms && JOINTS[j].3)).collect();
    let up = |p: [f64; 3]| if z_up { [p[0], -p[2], p[1]] } else { p };
    let mut s = String::from("HIERARCHY\n");
    // Children follow their parent in JOINTS, so nesting closes by depth.
    let depth = |j: usize| {
        let mut d = 0;
        let mut k = JOINTS[j].1;
        while k >= 0 {
            d += 1;
            k = JOINTS[k as usize].1;
        }
        d
    };
    for (i, &j) in joints.iter().enumerate() {
        let (name, parent, offset, _) = JOINTS[j];
        let k = if (1..=8).contains(&j) { legs } else { 1.0 };
        let o = up([offset[0] * unit * k, offset[1] * unit * k, offset[2] * unit * k]);
        let pad = "  ".repeat(depth(j));
        s += &format!(
            "{pad}{} {name}\n{pad}{{\n{pad}  OFFSET {} {} {}\n",
            if parent < 0 { "ROOT" } else { "JOINT" },
            v(o[0]),
            v(o[1]),
            v(o[2])
        );
        s += &format!(
            "{pad}  CHANNELS {}\n",
            if parent < 0 {
                "6 Xposition Yposition Zposition Zrotation Yrotation Xrotation"
            } else {
                "3 Zrotation Yrotation Xrotation"
            }
        );
        let leaf = joints.get(i + 1).is_none_or(|&n| JOINTS[n].1 != j as i32);
        if leaf {
            s += &format!("{pad}  End Site\n{pad}  {{\n{pad}    OFFSET 0 {} 0\n{pad}  }}\n", v(0.05 * unit));
        }
        // Close this joint and every ancestor the next joint is not under.
        let next_depth = joints.get(i + 1).map_or(0, |&n| depth(n));
        if leaf || next_depth <= depth(j) {
            for d in (next_depth..=depth(j)).rev() {
                s += &format!("{}}}\n", "  ".repeat(d));
            }
        }
    }
    s += &format!("MOTION\nFrames: {frames}\nFrame Time: {frame_time}\n");
    let hip = 0.95 * unit * legs.min(10.0);
    for f in 0..frames {
        let t = f as f64 * frame_time;
        let yaw = turn * t * 57.3;
        let (x, z) = ((turn * t).sin() * speed * t * unit, (turn * t).cos() * speed * t * unit);
        let p = up([x, hip, z]);
        let mut row = vec![p[0], p[1], p[2], 0.0, yaw, 0.0];
        for &j in &joints[1..] {
            let side = if JOINTS[j].0.starts_with('l') { 1.0 } else { -1.0 };
            let a = swing * (t * 6.0).sin() * side;
            row.extend(match JOINTS[j].0 {
                "lfemur" | "rfemur" => [0.0, 0.0, a],
                "ltibia" | "rtibia" => [0.0, 0.0, a.max(0.0) * 0.8],
                _ => [0.0, 0.0, 0.0],
            });
        }
        s += &row.iter().map(|&x| v(x)).collect::<Vec<_>>().join(" ");
        s += "\n";
    }
    // Glitches: one value of one frame set anywhere within the BVH limit.
    if glitches > 0 {
        let mut lines: Vec<String> = s.lines().map(String::from).collect();
        let first = lines.len() - frames;
        for _ in 0..glitches {
            let (f, c) = (r.byte() as usize % frames, r.byte() as usize);
            let value = r.pick(&[1e7, -1e7, 3.6e5, 1e3, -720.0, 1e-6]);
            let mut row: Vec<String> = lines[first + f].split(' ').map(String::from).collect();
            let k = c % row.len();
            row[k] = v(value);
            lines[first + f] = row.join(" ");
        }
        s = lines.join("\n") + "\n";
    }
    s
}

/// A feature group spec (JSON) anywhere around the configuration's limits.
fn feature(r: &mut Reader, i: usize) -> String {
    let kind = r.pick(&["position", "velocity", "direction"]);
    let joint = r.pick(&[
        "root",
        "root",
        "hips",
        "left_foot",
        "right_foot",
        "left_toe",
        "head",
        "ltibia",
        "VirtualRoot",
        "nose",
    ]);
    let count = if r.chance(16) { 1 + r.byte() as usize % 80 } else { 1 + r.byte() as usize % 4 };
    let offsets: Vec<String> = (0..count)
        .map(|_| {
            if r.chance(16) { r.range(-10_000.0, 10_000.0).round() as i64 } else { r.range(-30.0, 60.0).round() as i64 }
                .to_string()
        })
        .collect();
    let axes = r.pick(&["", r#", "axes": "xz""#, r#", "axes": "xyz""#]);
    let weight = if r.chance(8) { r.pick(&[0.0, 1e-4, 2e3]) } else { r.log(1e-3, 1e3) };
    let axis = if r.chance(32) {
        format!(r#", "axis": [{}, {}, {}]"#, r.range(-1e3, 1e3), r.range(-2.0, 2.0), r.range(-2.0, 2.0))
    } else {
        String::new()
    };
    format!(
        r#"{{"name": "g{i}", "kind": "{kind}", "joint": "{joint}", "offsets": [{}]{axes}, "weight": {weight}{axis}}}"#,
        offsets.join(", ")
    )
}

/// The case `data` encodes.
pub fn generate(data: &[u8]) -> Case {
    let mut r = Reader(data);
    let mut keys: Vec<String> = Vec::new();
    let fps = if r.chance(48) {
        r.pick(&[1.0, 2.0, 1000.0, 999.5, 240.0])
    } else {
        r.pick(&[30.0, 60.0, 60.0, 24.0, 120.0, 90.0])
    };
    keys.push(format!(r#""fps": {fps}"#));
    keys.push(format!(r#""mirror": {}"#, r.chance(100)));
    if r.chance(48) {
        keys.push(r#""reverse": true"#.into());
    }
    if r.chance(80) {
        keys.push(r#""motion_tags": true"#.into());
    }
    if r.chance(64) {
        keys.push(r#""repair_spikes": false"#.into());
    }
    if r.chance(96) {
        let scale = r.pick(&[1e-6, 1e-3, 0.01, 0.0254, 1.0, 10.0, 1000.0, 0.5]);
        keys.push(format!(r#""scale": {scale}"#));
    }
    if r.chance(24) {
        keys.push(format!(r#""up": "{}""#, r.pick(&["y", "z", "x", "auto"])));
    }
    for key in ["contact_filter", "root_position_window", "root_facing_window"] {
        if r.chance(32) {
            let seconds = if r.chance(64) { r.range(0.0, 60.0) } else { r.range(0.0, 1.0) };
            keys.push(format!(r#""{key}": {seconds}"#));
        }
    }
    if r.chance(24) {
        keys.push(format!(r#""contact_speed": {}"#, r.range(0.0, 100.0)));
    }
    if r.chance(24) {
        keys.push(format!(r#""min_head_height": {}"#, r.range(0.3, 1.0)));
    }
    if r.chance(96) {
        let n = 1 + r.byte() as usize % 6;
        let groups: Vec<String> = (0..n).map(|i| feature(&mut r, i)).collect();
        keys.push(format!(r#""features": [{}]"#, groups.join(", ")));
    }
    let two = r.chance(64);
    let other_skeleton = two && r.chance(128);
    if r.chance(48) {
        let (s, e) = (r.byte() as usize % 8, 8 + r.byte() as usize % 64);
        keys.push(format!(r#""clips": [{{"file": "a.bvh", "frames": [{s}, {e}], "ranges": [{{"frames": [0, 4], "tags": ["idle"]}}]}}]"#));
    }
    let mut takes = vec![("a.bvh".to_string(), take(&mut r, false, fps))];
    if two {
        takes.push(("b.bvh".to_string(), take(&mut r, other_skeleton, fps)));
    }
    Case { config: format!("{{{}}}", keys.join(", ")), takes }
}

/// What a case gave: refused (with the message), or built, loaded and played.
#[derive(Debug, PartialEq)]
pub enum Verdict {
    Refused(String),
    Played { frames: usize },
}

/// Runs the property on the case `data` encodes; panics when it breaks: a build whose database
/// the loader refuses or whose round trip changes it, a database the search cannot index, a
/// character whose pose or root is not finite, whose frame leaves the database, or whose root
/// ends an update more than α from its simulated character.
pub fn check_round_trip(data: &[u8]) -> Verdict {
    let case = generate(data);
    run(&case)
}

/// The property on one case.
pub fn run(case: &Case) -> Verdict {
    let refused = |e: String| {
        assert!(e.chars().count() <= MAX_MESSAGE_CHARS + 40, "a message of {} chars", e.chars().count());
        Verdict::Refused(e)
    };
    let config = match BuildConfig::from_json(&case.config) {
        Ok(c) => c,
        Err(e) => return refused(e.to_string()),
    };
    let mut sources = Vec::new();
    for (name, text) in &case.takes {
        match Bvh::parse(name, text.as_bytes()) {
            Ok(bvh) => sources.push(Source { name: name.clone(), bvh }),
            Err(e) => return refused(e.to_string()),
        }
    }
    let out = match build(&config, &sources) {
        Ok(out) => out,
        Err(e) => return refused(e.to_string()),
    };
    let built = out.database;
    let bytes = format::to_bytes(&built);
    let db = format::from_bytes(&bytes)
        .unwrap_or_else(|e| panic!("the builder wrote a database its loader refuses: {e}\nconfig: {}", case.config));
    assert_eq!(
        (db.num_frames, db.num_joints(), db.num_features(), &db.clips, &db.tags),
        (built.num_frames, built.num_joints(), built.num_features(), &built.clips, &built.tags)
    );
    // What loaded is stable: written and read again it is the same within the format's
    // quantization. (Against the builder's unquantized rotations, an angular velocity of half
    // a turn per frame — a capture glitch — may flip its sign: the same rotation rate.)
    let again = format::from_bytes(&format::to_bytes(&db))
        .unwrap_or_else(|e| panic!("a loaded database written again is refused: {e}"));
    format::check_round_trip(&db, &again).unwrap_or_else(|e| panic!("the round trip changed the database: {e}"));
    let index = SearchIndex::new(&db)
        .unwrap_or_else(|e| panic!("a loaded database the search refuses: {e}\nconfig: {}", case.config));
    let mut c = Character::new(&db, CharacterSettings::default());
    c.set_toe_floor(db.toe_height_in_contact());
    let alpha = c.settings.clamp_distance;
    for step in 0..120 {
        let phase = step / 30;
        let a = step as f32 * 0.05;
        let input = Input {
            direction: Vec2::new(a.sin(), a.cos()) * [1.0, 0.6, 0.0, 1.0][phase % 4],
            facing: Vec2::new(a.cos(), -a.sin()),
            run: phase == 3,
            strafe: phase == 1,
        };
        c.update(&db, &index, &input, 1.0 / 60.0);
        assert!(
            c.world_positions().iter().all(|p| p.is_finite()),
            "non-finite pose at step {step}\nconfig: {}",
            case.config
        );
        assert!(c.world_rotations().iter().all(|q| q.is_finite()), "non-finite rotation at step {step}");
        assert!(c.root_position().is_finite() && c.root_rotation().is_finite(), "non-finite root at step {step}");
        assert!(c.frame() < db.num_frames, "frame {} of {}", c.frame(), db.num_frames);
        let (sim, _) = c.simulation_transform();
        let gap = Vec2::new(c.root_position().x - sim.x, c.root_position().z - sim.z).length();
        let far = c.root_position().abs().max_element().max(sim.abs().max_element());
        assert!(
            gap <= alpha + 1e-3 + 2.0 * far * f32::EPSILON,
            "root {gap} m from the simulation at step {step} (α {alpha})\nconfig: {}",
            case.config
        );
    }
    Verdict::Played { frames: db.num_frames }
}
