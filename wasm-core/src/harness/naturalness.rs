//! The naturalness harness: does the default character look like a calm person? Scripted
//! input (standing, walking, side-stepping, walking backward) on a database, measuring what a
//! visitor notices in the first seconds rather than what the quality harness measures
//! (distance, skating): how often the frame playing comes from a stylized clip, where the head
//! looks while standing, and how far the hands are from the hips while walking (hands on hips
//! is a style, not a walk). `mmdb naturalness` prints it; `tests/databases.rs` holds the
//! default databases to it (docs/database.md, "Styles").

use crate::character::{Character, CharacterSettings};
use crate::controller::Input;
use crate::database::Database;
use crate::search::SearchIndex;
use crate::tag_query::{frame_tag_bits, tag_bit, STYLE_PREFIX};
use glam::{Vec2, Vec3};
use serde::Serialize;

/// What a script asks the character to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Motion {
    Idle,
    Walk,
    Strafe,
    Backward,
}

impl Motion {
    pub const ALL: [Motion; 4] = [Motion::Idle, Motion::Walk, Motion::Strafe, Motion::Backward];

    pub fn name(self) -> &'static str {
        match self {
            Motion::Idle => "idle",
            Motion::Walk => "walk",
            Motion::Strafe => "strafe",
            Motion::Backward => "backward",
        }
    }

    /// The stick at time `t`: nothing; forward; side-steps 3 s each way facing ahead; backward
    /// facing ahead.
    pub fn input(self, t: f32) -> Input {
        match self {
            Motion::Idle => Input::default(),
            Motion::Walk => Input { direction: Vec2::Y, ..Input::default() },
            Motion::Strafe => Input {
                direction: if (t / 3.0) as i32 % 2 == 0 { Vec2::X } else { -Vec2::X },
                facing: Vec2::Y,
                strafe: true,
                run: false,
            },
            Motion::Backward => Input { direction: -Vec2::Y, facing: Vec2::Y, strafe: true, run: false },
        }
    }
}

/// One script's measurements.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub motion: Motion,
    pub seconds: f32,
    /// Share of updates whose frame comes from a clip of another style than the settings'
    /// (`style:<name>` tags; 0 on a database without styles).
    pub other_style_share: f32,
    /// Share of updates whose frame carries the settings' style tag (1 without styles).
    pub style_share: f32,
    /// Mean pitch of the head's forward axis above the horizontal (degrees; negative looks down).
    pub head_pitch_mean: f32,
    /// Mean distance of each hand from the hips (m), over both hands.
    pub hands_to_hips_mean: f32,
    /// Mean height of the hands above the hips joint (m; negative below): arms hanging at the
    /// sides put the wrists ~0.1–0.2 m below it, hands on the hips near 0.
    pub hands_above_hips_mean: f32,
}

/// Runs `motion` for `seconds` at `dt` with `settings` and measures it.
///
/// # Errors
/// A database that cannot be searched or lacks the head, hands or hips roles.
pub fn measure(
    db: &Database,
    settings: &CharacterSettings,
    motion: Motion,
    seconds: f32,
    dt: f32,
) -> Result<Report, String> {
    let index = SearchIndex::new(db).map_err(|e| e.to_string())?;
    let site = |role: &str| db.skeleton.site_joint(role).ok_or_else(|| format!("the skeleton has no {role} role"));
    let (head, hips, hands) = (site("head")?, site("hips")?, [site("left_hand")?, site("right_hand")?]);
    let bits = frame_tag_bits(db);
    let styles: u64 = db
        .tags
        .iter()
        .filter(|t| t.name.starts_with(STYLE_PREFIX))
        .filter_map(|t| tag_bit(db, &t.name))
        .fold(0, |a, b| a | b);
    let own = tag_bit(db, &format!("{STYLE_PREFIX}{}", settings.style)).unwrap_or(0);
    let mut character = Character::new(db, settings.clone());
    character.set_toe_floor(db.toe_height_in_contact());
    let steps = (seconds / dt).round().max(1.0) as usize;
    let (mut other, mut same, mut pitch, mut hands_distance, mut hands_height) =
        (0usize, 0usize, 0.0f64, 0.0f64, 0.0f64);
    for step in 0..steps {
        character.update(db, &index, &motion.input(step as f32 * dt), dt);
        let frame_bits = bits[character.frame()];
        other += (frame_bits & styles & !own != 0) as usize;
        same += (own == 0 || frame_bits & own != 0) as usize;
        // The rest pose faces +Z, head included: its forward axis is the head's rotation of +Z.
        let forward = character.world_rotations()[head] * Vec3::Z;
        pitch += forward.y.clamp(-1.0, 1.0).asin().to_degrees() as f64;
        let w = character.world_positions();
        hands_distance += hands.iter().map(|&h| w[h].distance(w[hips]) as f64).sum::<f64>() / 2.0;
        hands_height += hands.iter().map(|&h| (w[h].y - w[hips].y) as f64).sum::<f64>() / 2.0;
    }
    let n = steps as f64;
    Ok(Report {
        motion,
        seconds,
        other_style_share: (other as f64 / n) as f32,
        style_share: (same as f64 / n) as f32,
        head_pitch_mean: (pitch / n) as f32,
        hands_to_hips_mean: (hands_distance / n) as f32,
        hands_above_hips_mean: (hands_height / n) as f32,
    })
}

/// A text table of reports.
pub fn table(reports: &[Report]) -> String {
    let mut s = String::from("motion     other style  own style  head pitch  hands↔hips  hands above hips\n");
    for r in reports {
        s += &format!(
            "{:<10} {:>10.1}% {:>9.1}% {:>9.1}° {:>9.2} m {:>14.2} m\n",
            r.motion.name(),
            100.0 * r.other_style_share,
            100.0 * r.style_share,
            r.head_pitch_mean,
            r.hands_to_hips_mean,
            r.hands_above_hips_mean
        );
    }
    s
}
