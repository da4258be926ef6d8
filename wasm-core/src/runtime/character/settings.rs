//! Everything a user can tune on a character, live (the demo's panel, `Character.settings` in
//! the TS API). JSON with the field names below; missing fields keep their defaults, unknown
//! ones are errors (docs/runtime.md lists them with their meaning).

use crate::controller::ControllerSettings;
use crate::search::SearchMethod;

/// [`CharacterSettings::style_bias`]'s default.
pub const DEFAULT_STYLE_BIAS: f32 = 10.0;

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CharacterSettings {
    pub controller: ControllerSettings,
    /// Database frames between searches (10 at 60 fps).
    pub search_interval: u32,
    /// β_q (pose / quality) and β_r (trajectory / responsiveness).
    pub beta_pose: f32,
    pub beta_trajectory: f32,
    /// Frames around the current one a search may not return.
    pub exclude_radius: usize,
    /// Sharp-change triggers: rate of change of the desired velocity (m/s²) and facing (rad/s).
    pub velocity_change_threshold: f32,
    pub rotation_change_threshold: f32,
    pub inertialize: bool,
    pub inertialization_halflife: f32,
    pub adjustment: bool,
    pub adjustment_position_halflife: f32,
    pub adjustment_rotation_halflife: f32,
    /// Adjustment per frame is capped at this × the character's speed × dt, so a standing
    /// character never slides (docs/method.md §6).
    pub adjustment_max_ratio: f32,
    /// …but never below this speed (m/s), so a standing character is still brought back under
    /// its simulated character (a tracked VR user who stands still must find the avatar under
    /// them, not α away); the foot lock turns the drift into a corrective step. 0 = off.
    pub adjustment_min_speed: f32,
    pub clamping: bool,
    /// α: the root never ends farther than this from the simulated character (m).
    pub clamp_distance: f32,
    /// With `clamping`, the root's yaw stays within this angle (rad) of the simulated
    /// character's: the data has little turning on the spot, and a tracked (VR) user who turns
    /// in place must see the avatar turn with them.
    pub clamp_angle: f32,
    /// Database playback rate multiplier.
    pub playback_speed: f32,
    /// All methods return the same frame; AABB is the fast one, the others are for comparison.
    pub search_method: SearchMethod,
    /// Pin toes in contact to the floor with two-bone leg IK (docs/method.md §7).
    pub foot_lock: bool,
    /// A locked toe unlocks when the animation drifts farther than this (m) — or than
    /// `clamp_distance` (α) when clamping, whichever is larger.
    pub foot_lock_unlock_radius: f32,
    /// Plant locked toes at the floor height (see [`super::Character::set_toe_floor`]) rather
    /// than wherever they touched down.
    pub foot_lock_floor: bool,
    /// Blend in and out of a lock (exact half-life; Holden's 0.1 s).
    pub foot_lock_halflife: f32,
    /// Add the root's drag by adjustment and clamping to the query's hips velocity, so a
    /// dragged character does not keep matching standing frames (`query::Query::add_drag`).
    pub query_drag: bool,
    /// While the character is asked to move faster than this (m/s: the simulated character's
    /// velocity), searches skip frames tagged `idle` (built with `"motion_tags": true`), so a
    /// walking user is never matched with standing frames dragged by the clamp. 0 = off.
    pub idle_exclude_speed: f32,
    /// Tracked (VR) drive: the user's head gives where the avatar's *head* should be, and the
    /// root's target is that less the avatar's own head offset from its root (smoothed over
    /// [`super::HEAD_OFFSET_HALFLIFE`]). Off (default): the root's target is the head itself
    /// (MMVR), which puts the hips under the head however the body leans — 15 cm from the real
    /// hips while walking backward or side-stepping; on, side-steps and backward walking follow
    /// better but gestures and stepping about worse (docs/vr.md, "Where the root goes").
    pub tracked_head_offset: bool,
    /// The motion style searches prefer: a frame not tagged `style:<style>` costs `style_bias`
    /// more ([`crate::tag_query`]). The default `neutral` plays stylized clips (`angry`,
    /// `akimbo`, …) only where nothing neutral comes close; a database without styles ignores it.
    pub style: String,
    /// The cost a frame of another style pays (normalized feature units: the default features'
    /// best match costs ~0.5–3; docs/method.md §3 has the measurements). 0 = styles are equal.
    pub style_bias: f32,
    /// Tag queries: searches return only frames carrying every `require_tags` tag and none of
    /// the `exclude_tags`; a frame lacking any of the `prefer_tags` pays `style_bias` like a
    /// frame of another style. Names the database lacks are left out.
    pub require_tags: Vec<String>,
    pub exclude_tags: Vec<String>,
    pub prefer_tags: Vec<String>,
}

impl Default for CharacterSettings {
    fn default() -> Self {
        CharacterSettings {
            controller: ControllerSettings::default(),
            search_interval: 10,
            beta_pose: 1.0,
            beta_trajectory: 1.0,
            exclude_radius: 20,
            velocity_change_threshold: 50.0,
            rotation_change_threshold: 50.0,
            inertialize: true,
            inertialization_halflife: 0.1,
            adjustment: true,
            adjustment_position_halflife: 0.1,
            adjustment_rotation_halflife: 0.2,
            adjustment_max_ratio: 0.5,
            clamping: true,
            clamp_distance: 0.15,
            clamp_angle: std::f32::consts::FRAC_PI_4,
            playback_speed: 1.0,
            search_method: SearchMethod::Aabb,
            foot_lock: true,
            foot_lock_unlock_radius: 0.2,
            adjustment_min_speed: 0.0,
            foot_lock_floor: true,
            foot_lock_halflife: 0.12,
            query_drag: false,
            idle_exclude_speed: 0.0,
            tracked_head_offset: false,
            style: crate::tag_query::NEUTRAL_STYLE.to_string(),
            style_bias: DEFAULT_STYLE_BIAS,
            require_tags: Vec::new(),
            exclude_tags: Vec::new(),
            prefer_tags: Vec::new(),
        }
    }
}

impl CharacterSettings {
    /// These settings with a JSON object's fields applied (`{"beta_pose": 1.5}`).
    ///
    /// # Errors
    /// Not a JSON object, an unknown field, or a value of the wrong type.
    pub fn patched(&self, json: &str) -> Result<CharacterSettings, String> {
        let patch: serde_json::Value = serde_json::from_str(json).map_err(|e| format!("settings: {e}"))?;
        let patch = patch.as_object().ok_or("settings: expected a JSON object")?;
        let mut current = serde_json::to_value(self).map_err(|e| e.to_string())?;
        let obj = current.as_object_mut().ok_or("settings: expected a JSON object")?;
        for (k, v) in patch {
            obj.insert(k.clone(), v.clone());
        }
        let settings: CharacterSettings = serde_json::from_value(current).map_err(|e| format!("settings: {e}"))?;
        settings.validate()?;
        Ok(settings)
    }

    /// Checks every value is a number in its range (a NaN or a `playback_speed` of 1e30 would
    /// stall or poison the character).
    ///
    /// # Errors
    /// The first field out of range, with its value and the range.
    pub fn validate(&self) -> Result<(), String> {
        let c = &self.controller;
        let half = (1e-3, 10.0);
        let checks: [(&str, f32, (f32, f32)); 26] = [
            ("controller.walk.forward", c.walk.forward, (0.0, 20.0)),
            ("controller.walk.side", c.walk.side, (0.0, 20.0)),
            ("controller.walk.backward", c.walk.backward, (0.0, 20.0)),
            ("controller.run.forward", c.run.forward, (0.0, 20.0)),
            ("controller.run.side", c.run.side, (0.0, 20.0)),
            ("controller.run.backward", c.run.backward, (0.0, 20.0)),
            ("controller.velocity_halflife", c.velocity_halflife, half),
            ("controller.rotation_halflife", c.rotation_halflife, half),
            ("search_interval", self.search_interval as f32, (1.0, 600.0)),
            ("beta_pose", self.beta_pose, (0.0, 1000.0)),
            ("beta_trajectory", self.beta_trajectory, (0.0, 1000.0)),
            ("exclude_radius", self.exclude_radius as f32, (0.0, 1.0e6)),
            ("velocity_change_threshold", self.velocity_change_threshold, (0.0, 1.0e6)),
            ("rotation_change_threshold", self.rotation_change_threshold, (0.0, 1.0e6)),
            ("inertialization_halflife", self.inertialization_halflife, half),
            ("adjustment_position_halflife", self.adjustment_position_halflife, half),
            ("adjustment_rotation_halflife", self.adjustment_rotation_halflife, half),
            ("adjustment_max_ratio", self.adjustment_max_ratio, (0.0, 100.0)),
            ("adjustment_min_speed", self.adjustment_min_speed, (0.0, 100.0)),
            ("clamp_distance", self.clamp_distance, (0.0, 1000.0)),
            ("clamp_angle", self.clamp_angle, (0.0, std::f32::consts::PI)),
            ("playback_speed", self.playback_speed, (1e-3, 10.0)),
            ("foot_lock_unlock_radius", self.foot_lock_unlock_radius, (0.0, 10.0)),
            ("foot_lock_halflife", self.foot_lock_halflife, half),
            ("idle_exclude_speed", self.idle_exclude_speed, (0.0, 100.0)),
            ("style_bias", self.style_bias, (0.0, 1.0e6)),
        ];
        for (name, value, (lo, hi)) in checks {
            if !(value >= lo && value <= hi) {
                return Err(format!("settings: {name} is {value}, expected a number in [{lo}, {hi}]"));
            }
        }
        // Tag names are compared on every search: keep them few and short.
        let lists = [
            ("require_tags", &self.require_tags),
            ("exclude_tags", &self.exclude_tags),
            ("prefer_tags", &self.prefer_tags),
        ];
        for (name, list) in lists {
            if list.len() > crate::tag_query::MAX_QUERY_TAGS {
                return Err(format!(
                    "settings: {name} has {} tags, at most {}",
                    list.len(),
                    crate::tag_query::MAX_QUERY_TAGS
                ));
            }
        }
        let names = lists.iter().flat_map(|(n, l)| l.iter().map(move |t| (*n, t))).chain([("style", &self.style)]);
        for (field, tag) in names {
            if tag.len() > crate::limits::MAX_NAME_BYTES {
                return Err(format!(
                    "settings: {field} has a name of {} bytes, at most {}",
                    tag.len(),
                    crate::limits::MAX_NAME_BYTES
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tag_queries_and_styles_are_checked() {
        let s = CharacterSettings::default();
        assert_eq!(s.style, "neutral");
        let ok = s.patched(r#"{"style": "angry", "style_bias": 3, "require_tags": ["walk"], "exclude_tags": ["run"], "prefer_tags": []}"#).unwrap();
        assert_eq!((ok.style.as_str(), ok.style_bias, ok.require_tags.len()), ("angry", 3.0, 1));
        let many = format!(r#"{{"exclude_tags": [{}]}}"#, vec!["\"t\""; 65].join(","));
        for (json, expected) in [
            (many.as_str(), "exclude_tags has 65 tags, at most 64"),
            (r#"{"style_bias": -1}"#, "style_bias is -1"),
            (r#"{"style_bias": 1e30}"#, "expected a number in [0, 1000000]"),
            (r#"{"require_tags": "walk"}"#, "settings: invalid type"),
        ] {
            let e = s.patched(json).unwrap_err();
            assert!(e.contains(expected), "{json}: {e}");
        }
        let long = format!(r#"{{"style": "{}"}}"#, "x".repeat(300));
        assert!(s.patched(&long).unwrap_err().contains("style has a name of 300 bytes"));
    }
}
