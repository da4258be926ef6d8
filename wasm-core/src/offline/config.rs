//! Database build configuration, read from JSON (`mmdb build --config`, the in-page builder).
//! Unknown keys are errors, so a typo never silently falls back to a default.

use crate::database::{Axes, FeatureKind};
use crate::error::{Error, Result};
use crate::limits::{
    check_feature_dims, check_fps, check_scale, num, quote, MAX_FEATURE_OFFSET, MAX_SPEED, MAX_WEIGHT,
    MAX_WINDOW_FRAMES, MAX_WINDOW_SECONDS, MIN_WEIGHT,
};
use serde::Deserialize;
use std::collections::HashMap;

/// How source units become metres.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum Scale {
    /// Metres per source unit.
    Fixed(f64),
    /// `"auto"`: the unit (m, cm, mm, inch) that puts the standing hip height nearest 0.95 m.
    Auto(AutoScale),
}

#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AutoScale {
    Auto,
}

/// Which world axis is up in the source.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    /// Detected from the motion (hips → head, feet → hips).
    #[default]
    Auto,
    Y,
    Z,
    X,
}

/// Everything that decides how a database is built. `Default` is the product's defaults.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BuildConfig {
    /// What the database is for, in words (a pinned benchmark recipe says where its list came
    /// from); the build ignores it. The one free-text field, so that a typo elsewhere stays an error.
    pub description: Option<String>,
    /// Database frame rate; sources are resampled to it.
    pub fps: f64,
    /// Add a left/right mirrored copy of every clip.
    pub mirror: bool,
    /// Repair 1–3 frame rotation glitches of the capture (see `builder::repair_spikes`).
    pub repair_spikes: bool,
    pub scale: Scale,
    pub up: UpAxis,
    /// Source file whose skeleton the others are normalized onto (default: the first).
    pub reference: Option<String>,
    /// Role → joint name overrides (`{"left_toe": "LeftToe_End"}`), see `joint_map::ROLES`.
    pub roles: HashMap<String, String>,
    /// Toe speed below which a foot is in contact (m/s). The thesis starts from 0.15; on CMU
    /// data a planted forefoot still moves 0.1–0.3 m/s in runs (roll and capture slide), so
    /// 0.15 misses most running stances (see docs/database.md for the measurements).
    pub contact_speed: f64,
    /// Median filter radius for contacts, seconds (3 frames at 60 fps, Holden's window of 6):
    /// wider windows erase running stances, which last only ~8 frames at 60 fps.
    pub contact_filter: f64,
    /// Savitzky–Golay windows for the virtual root, seconds (31 and 61 frames at 60 fps).
    pub root_position_window: f64,
    pub root_facing_window: f64,
    /// Feature groups; `None` = the 27-float locomotion set (docs/method.md §2).
    pub features: Option<Vec<FeatureSpec>>,
    pub clips: Vec<ClipSpec>,
    /// Add a time-reversed copy of every clip (per clip: `ClipSpec::reverse`).
    pub reverse: bool,
    /// Tag what the body does from the virtual root: `idle`, `turn_in_place`, `sidestep`,
    /// `backward` (`builder::tags`).
    pub motion_tags: bool,
    /// Frames whose head is lower than this share of the skeleton's standing (rest) head height
    /// are never searched — played only on the way from a frame that was: a tracked (VR) avatar
    /// takes its bend from its user's head (`character::crouch`), not from the data. Clips tagged
    /// `crouch` are crouch data: their low frames stay searchable, tagged `crouched`, which the
    /// runtime searches only while its character crouches.
    pub min_head_height: Option<f64>,
    /// A 100STYLE `Frame_Cuts.csv` (path relative to the config): each `<Style>_<TYPE>.bvh`
    /// without its own `frames` uses the usable window the CSV gives (read by the CLI into
    /// [`BuildConfig::cuts`]).
    pub frame_cuts: Option<String>,
    /// Also write the database's first part (`<out>.first.mmdb`): a few clips a page can start
    /// on while the rest downloads (`crate::first_part`).
    pub first_part: Option<crate::first_part::FirstPartSpec>,
    /// Frame windows per source file name, from `frame_cuts` (`crate::frame_cuts::parse`).
    #[serde(skip)]
    pub cuts: HashMap<String, [usize; 2]>,
}

impl Default for BuildConfig {
    fn default() -> Self {
        BuildConfig {
            description: None,
            fps: 60.0,
            mirror: true,
            repair_spikes: true,
            scale: Scale::Auto(AutoScale::Auto),
            up: UpAxis::Auto,
            reference: None,
            roles: HashMap::new(),
            contact_speed: 0.3,
            contact_filter: 0.05,
            root_position_window: 0.5,
            root_facing_window: 1.0,
            features: None,
            clips: Vec::new(),
            reverse: false,
            motion_tags: false,
            min_head_height: None,
            frame_cuts: None,
            first_part: None,
            cuts: HashMap::new(),
        }
    }
}

/// One feature group as configured. `joint` is a role (`left_foot`, `hips`), a joint name, or
/// `root` for the virtual root (trajectory).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FeatureSpec {
    pub name: String,
    pub kind: FeatureKind,
    pub joint: String,
    #[serde(default = "default_offsets")]
    pub offsets: Vec<i32>,
    /// Default: `xz` for the root, `xyz` otherwise.
    pub axes: Option<Axes>,
    #[serde(default = "default_weight")]
    pub weight: f32,
    /// Direction axis in joint space (default forward, +Z).
    #[serde(default = "default_axis")]
    pub axis: [f32; 3],
}

impl FeatureSpec {
    /// Whether the group is on the virtual root (a trajectory group).
    pub fn on_root(&self) -> bool {
        self.joint == "root" || self.joint == crate::builder::VIRTUAL_ROOT
    }

    /// The dimensions the group adds: its offsets times its axes (`xz` on the root by default,
    /// `xyz` elsewhere).
    pub fn num_dims(&self) -> usize {
        let axes = self.axes.unwrap_or(if self.on_root() { Axes::Xz } else { Axes::Xyz });
        self.offsets.len().saturating_mul(axes.num_dims())
    }
}

fn default_offsets() -> Vec<i32> {
    vec![0]
}
fn default_weight() -> f32 {
    1.0
}
fn default_axis() -> [f32; 3] {
    [0.0, 0.0, 1.0]
}

/// Source files and how to cut and tag them. `file` is relative to the config file and may
/// use `*`/`?` in its last component.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipSpec {
    pub file: String,
    /// Tags for the whole clip.
    #[serde(default)]
    pub tags: Vec<String>,
    /// `[start, end)` in source frames; default the whole take.
    pub frames: Option<[usize; 2]>,
    /// Tags for sub-ranges, in source frames.
    #[serde(default)]
    pub ranges: Vec<RangeSpec>,
    /// Per-file overrides.
    pub scale: Option<Scale>,
    pub mirror: Option<bool>,
    /// Add a time-reversed copy (walking played backward is a plausible back-step).
    pub reverse: Option<bool>,
    /// Whole-clip tags of the reversed copy (default: `tags`), e.g. `["backward"]`.
    pub reverse_tags: Option<Vec<String>>,
    /// The clip's motion style (`angry`, `akimbo`, …): tagged `style:<style>`. Once any clip
    /// of a database has one, every clip without one is `style:neutral` (`crate::tag_query`).
    pub style: Option<String>,
    /// This clip's virtual-root smoothing window (s; default the configuration's
    /// `root_position_window`): step-together side-steps move the hips in bursts, and a longer
    /// window gives their root the steady velocity a user's stick asks for.
    pub root_position_window: Option<f64>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RangeSpec {
    pub frames: [usize; 2],
    pub tags: Vec<String>,
}

impl BuildConfig {
    /// Parses a JSON configuration; the error names the line, column and key.
    pub fn from_json(text: &str) -> Result<BuildConfig> {
        // Where first: a long message (an unknown key lists every known one) is cut at its end.
        let config: BuildConfig = serde_json::from_str(text).map_err(|e| {
            let what = e.to_string();
            let what = what.rsplit_once(" at line ").map_or(what.as_str(), |(w, _)| w).to_string();
            Error::config(format!("line {}, column {}: {what}", e.line(), e.column()))
        })?;
        config.validate()?;
        Ok(config)
    }

    /// Checks every value against [`crate::limits`]: call it again after changing fields
    /// (the CLI's `--fps` and `--scale` do) before building.
    ///
    /// # Errors
    /// [`Error::Config`] naming the key: `fps` outside 1…1000, a fixed `scale` outside
    /// 10⁻⁶…10³, a negative, non-finite or too long window or speed (a window is also at most
    /// [`MAX_WINDOW_FRAMES`] database frames), a feature weight outside 10⁻³…10³, empty or
    /// out-of-range feature offsets, more feature dimensions than the search takes
    /// ([`crate::limits::MAX_FEATURE_DIMS`]), an empty clip frame range.
    pub fn validate(&self) -> Result<()> {
        check_fps(self.fps).map_err(Error::config)?;
        if let Scale::Fixed(s) = self.scale {
            check_scale(s).map_err(|m| Error::config(format!("{m} (or \"auto\")")))?;
        }
        for (key, v, max) in [
            ("contact_speed", self.contact_speed, MAX_SPEED),
            ("contact_filter", self.contact_filter, MAX_WINDOW_SECONDS),
            ("root_position_window", self.root_position_window, MAX_WINDOW_SECONDS),
            ("root_facing_window", self.root_facing_window, MAX_WINDOW_SECONDS),
        ] {
            if !(0.0..=max).contains(&v) {
                return Err(Error::config(format!("{key} must be 0 to {max}, found {}", num(v))));
            }
        }
        for (key, v) in [
            ("contact_filter", self.contact_filter),
            ("root_position_window", self.root_position_window),
            ("root_facing_window", self.root_facing_window),
        ] {
            if v * self.fps > MAX_WINDOW_FRAMES {
                return Err(Error::config(format!(
                    "{key} of {} s is {} frames at {} fps; at most {MAX_WINDOW_FRAMES} frames",
                    num(v),
                    num(v * self.fps),
                    num(self.fps)
                )));
            }
        }
        if let Some(r) = self.min_head_height {
            if !(r > 0.0 && r <= 1.0) {
                return Err(Error::config(format!(
                    "min_head_height must be above 0 and at most 1 (a share of the standing head height), found {}",
                    num(r)
                )));
            }
        }
        if let Some(part) = &self.first_part {
            part.validate()?;
        }
        for f in self.features.iter().flatten() {
            let name = quote(&f.name);
            if !(MIN_WEIGHT..=MAX_WEIGHT).contains(&f.weight) {
                return Err(Error::config(format!(
                    "feature '{name}': weight must be {MIN_WEIGHT} to {MAX_WEIGHT}, found {}",
                    num(f.weight)
                )));
            }
            if f.offsets.is_empty() {
                return Err(Error::config(format!("feature '{name}': offsets must not be empty")));
            }
            if let Some(o) = f.offsets.iter().find(|o| o.unsigned_abs() > MAX_FEATURE_OFFSET as u32) {
                return Err(Error::config(format!(
                    "feature '{name}': offset {o} is beyond ±{MAX_FEATURE_OFFSET} frames"
                )));
            }
            if !f.axis.iter().all(|a| a.is_finite() && a.abs() <= 1e3) {
                return Err(Error::config(format!("feature '{name}': axis must be finite, found {:?}", f.axis)));
            }
        }
        if let Some(features) = &self.features {
            check_feature_dims(features.iter().map(FeatureSpec::num_dims).fold(0usize, usize::saturating_add))
                .map_err(|m| Error::config(format!("features: {m}")))?;
        }
        for c in &self.clips {
            if let Some(Scale::Fixed(s)) = c.scale {
                check_scale(s).map_err(|m| Error::config(format!("clip '{}': {m}", quote(&c.file))))?;
            }
            if let Some([s, e]) = c.frames {
                if e <= s {
                    return Err(Error::config(format!("clip '{}': frames [{s}, {e}] is empty", quote(&c.file))));
                }
            }
            if let Some(w) = c.root_position_window {
                if !(0.0..=MAX_WINDOW_SECONDS).contains(&w) {
                    return Err(Error::config(format!(
                        "clip '{}': root_position_window must be 0 to {MAX_WINDOW_SECONDS}, found {}",
                        quote(&c.file),
                        num(w)
                    )));
                }
            }
            if let Some(style) = &c.style {
                let ok = (1..=64).contains(&style.len())
                    && style.bytes().all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_' || b == b'-');
                if !ok {
                    return Err(Error::config(format!(
                        "clip '{}': style '{}' must be 1 to 64 of a-z, 0-9, '_' and '-'",
                        quote(&c.file),
                        quote(style)
                    )));
                }
            }
        }
        Ok(())
    }

    /// The style tag of a source's clips (`style:<name>`), or `None` when no clip of the
    /// configuration has a style.
    pub fn style_tag(&self, file_name: &str) -> Option<String> {
        self.clips.iter().any(|c| c.style.is_some()).then(|| {
            let style =
                self.clip_spec(file_name).and_then(|c| c.style.as_deref()).unwrap_or(crate::tag_query::NEUTRAL_STYLE);
            format!("{}{style}", crate::tag_query::STYLE_PREFIX)
        })
    }

    /// The frame window `frame_cuts` gives a source file, if any.
    pub fn frame_cuts_of(&self, file_name: &str) -> Option<[usize; 2]> {
        let base = file_name.rsplit(['/', '\\']).next().unwrap_or(file_name);
        self.cuts.get(base).or_else(|| self.cuts.get(split_clip(base).0)).copied()
    }

    /// The spec for a source file: the first clip entry whose `file` pattern matches its name
    /// (compared on the last path component). One clip of a glTF file (`walks.glb#Walk`) matches
    /// a pattern for itself (`walks.glb#W*`) or for its file (`walks.glb`).
    pub fn clip_spec(&self, file_name: &str) -> Option<&ClipSpec> {
        let base = |p: &str| p.rsplit(['/', '\\']).next().unwrap_or(p).to_string();
        let name = base(file_name);
        self.clips.iter().find(|c| source_matches(&base(&c.file), &name))
    }
}

/// A source name split into its file and, for one clip of a glTF file, the clip's name:
/// `walks.glb#Walk` → (`walks.glb`, `Walk`).
pub fn split_clip(name: &str) -> (&str, Option<&str>) {
    match name.split_once('#') {
        Some((file, clip)) => (file, Some(clip)),
        None => (name, None),
    }
}

/// Whether a config's file `pattern` names the source `name` (a file name; a glTF clip is named
/// by its file too unless the pattern names clips).
pub fn source_matches(pattern: &str, name: &str) -> bool {
    wildcard_match(pattern, name) || (!pattern.contains('#') && wildcard_match(pattern, split_clip(name).0))
}

/// `*` (any run) and `?` (any one character) matching on a file name.
pub fn wildcard_match(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    let (mut pi, mut ni, mut star, mut mark) = (0, 0, None, 0);
    while ni < n.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == n[ni]) {
            pi += 1;
            ni += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some(pi);
            mark = ni;
            pi += 1;
        } else if let Some(s) = star {
            pi = s + 1;
            mark += 1;
            ni = mark;
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_rejects_typos() {
        let c =
            BuildConfig::from_json(r#"{"fps": 30, "scale": "auto", "clips": [{"file": "a/*.bvh", "tags": ["walk"]}]}"#)
                .unwrap();
        assert_eq!(c.fps, 30.0);
        assert!(c.mirror);
        assert!(c.clip_spec("x/y/a_1.bvh").is_some());
        let e = BuildConfig::from_json("{\n \"mirorr\": true}").unwrap_err().to_string();
        assert!(e.contains("unknown field `mirorr`") && e.contains("line 2"), "{e}");
        let e = BuildConfig::from_json(r#"{"scale": -1}"#).unwrap_err().to_string();
        assert!(e.contains("scale must be between"), "{e}");
        assert_eq!(BuildConfig::from_json(r#"{"scale": 0.01}"#).unwrap().scale, Scale::Fixed(0.01));
    }

    /// Issue 28: 300 groups (2,700 dims) or 10,000 trajectory offsets passed the checks and built
    /// a database that loaded but could not be searched.
    #[test]
    fn feature_dimensions_beyond_the_search_are_refused() {
        let group =
            |i: usize| format!(r#"{{"name": "g{i}", "kind": "position", "joint": "hips", "offsets": [0, 10, 20]}}"#);
        let many = format!(r#"{{"features": [{}]}}"#, (0..300).map(group).collect::<Vec<_>>().join(","));
        let e = BuildConfig::from_json(&many).unwrap_err().to_string();
        assert!(e.contains("features: 2700 feature dimensions; the search takes 1 to 128"), "{e}");
        let offsets: Vec<String> = (0..10_000).map(|o| (o % 10_000).to_string()).collect();
        let long = format!(
            r#"{{"features": [{{"name": "t", "kind": "position", "joint": "root", "offsets": [{}]}}]}}"#,
            offsets.join(",")
        );
        let e = BuildConfig::from_json(&long).unwrap_err().to_string();
        assert!(e.contains("20000 feature dimensions"), "{e}");
        // 128 exactly is fine: 64 root offsets × xz.
        let offsets: Vec<String> = (0..64).map(|o| o.to_string()).collect();
        let edge = format!(
            r#"{{"features": [{{"name": "t", "kind": "position", "joint": "root", "offsets": [{}]}}]}}"#,
            offsets.join(",")
        );
        assert!(BuildConfig::from_json(&edge).is_ok());
    }

    #[test]
    fn wildcards() {
        assert!(wildcard_match("cmu_16_*.bvh", "cmu_16_15.bvh"));
        assert!(wildcard_match("cmu_1?_15.bvh", "cmu_16_15.bvh"));
        assert!(!wildcard_match("cmu_16_*.bvh", "cmu_127_15.bvh"));
        assert!(wildcard_match("*", "anything"));
    }

    /// Values that built a database full of NaN (or none at all) are refused by key.
    #[test]
    fn out_of_range_values_name_the_key() {
        for (json, expected) in [
            (r#"{"fps": 0}"#, "fps must be between 1 and 1000, found 0"),
            (r#"{"fps": 1e300}"#, "fps must be between"),
            (r#"{"scale": 1e300}"#, "scale must be between"),
            (r#"{"scale": 1e-300}"#, "scale must be between"),
            (r#"{"root_facing_window": 1e300}"#, "root_facing_window must be 0 to 60"),
            (r#"{"contact_speed": -1}"#, "contact_speed must be 0 to"),
            (r#"{"min_head_height": 0}"#, "min_head_height must be above 0 and at most 1"),
            (r#"{"min_head_height": 1.5}"#, "min_head_height must be above 0 and at most 1"),
            (
                r#"{"features": [{"name": "a", "kind": "position", "joint": "root", "weight": 1e30}]}"#,
                "feature 'a': weight must be",
            ),
            (
                r#"{"features": [{"name": "a", "kind": "position", "joint": "root", "offsets": []}]}"#,
                "offsets must not be empty",
            ),
            (
                r#"{"features": [{"name": "a", "kind": "position", "joint": "root", "offsets": [2147483647]}]}"#,
                "beyond ±10000",
            ),
            (r#"{"clips": [{"file": "a.bvh", "scale": 0}]}"#, "clip 'a.bvh': scale must be between"),
            (
                r#"{"fps": 1000, "root_facing_window": 60}"#,
                "root_facing_window of 60 s is 60000 frames at 1000 fps; at most 1000 frames",
            ),
            (r#"{"fps": 1000, "contact_filter": 2}"#, "contact_filter of 2 s is 2000 frames"),
            (
                r#"{"clips": [{"file": "a.bvh", "style": "Angry"}]}"#,
                "clip 'a.bvh': style 'Angry' must be 1 to 64 of a-z",
            ),
            (r#"{"clips": [{"file": "a.bvh", "style": ""}]}"#, "style '' must be 1 to 64"),
            (
                r#"{"clips": [{"file": "a.bvh", "root_position_window": 61}]}"#,
                "clip 'a.bvh': root_position_window must be 0 to 60",
            ),
        ] {
            let e = BuildConfig::from_json(json).unwrap_err().to_string();
            assert!(e.contains(expected), "{json}: {e}");
        }
    }
}
