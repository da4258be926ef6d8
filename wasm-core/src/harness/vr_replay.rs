//! A VR session replayed natively (docs/vr.md, "Replays"): a tracker recording
//! (docs/vr-recording.md, JSON version 1) drives a character through the tracked drive exactly as
//! the VR page's frame recipe does (`web/src/vr/tracked-drive.ts`) — head velocity differentiated
//! over the real frame time and lightly smoothed, the head centre 0.10 m behind the eyes on the
//! floor, the body yaw from a given source (the orientation network's output computed by
//! `training/replay.py`, the recording's truth, or HMD forward), the root's target at the hips
//! the network predicts when given (else the head centre), the crouch (`Character::set_crouch`), the VR
//! settings — and measures what the replay bench measures: user↔avatar root distance (against
//! the recording's truth), the head gap α clamps, foot skating and the update time.
//!
//! A recording with body joints (a body-tracking headset, docs/vr-recording.md `body`) drives as
//! the page does then: while the hips are tracked the root's target is their floor point, the
//! body yaw the hip joints' (else the shoulders') facing, α at most [`BODY_ALPHA`]; frames
//! without tracked hips fall back to the head and the given yaw source.
//!
//! It is for the runtime's numbers without a browser; the page's own bench adds rendering,
//! retargeting, arm IK and the network's run. `MMDB_REPLAY_TRACE=1` prints, every 0.5 s, the
//! root's and the head's offset from the true root (along and across the true facing) and the
//! clip playing — how the root distance in docs/vr.md was taken apart.

use crate::character::drive::{DriveInput, DriveMode};
use crate::character::{Character, CharacterSettings, Tracked};
use crate::database::Database;
use crate::recording::{Body, Recording};
use crate::search::SearchIndex;
use crate::skating::ON_FLOOR;
use glam::{Quat, Vec2, Vec3};

/// HMD (eyes) → head centre, m backward along the heading (`HMD_TO_HEAD_CENTRE` of the page).
pub const HMD_TO_HEAD_CENTRE: f32 = 0.1;
/// The farthest a predicted hips point may lie from the head centre, m (`MAX_HIPS_OFFSET`).
pub const MAX_HIPS_OFFSET: f32 = 0.5;
/// Smoothing of the predicted hips in the body's frame, half-life s (`HIPS_OFFSET_HALFLIFE`).
const HIPS_OFFSET_HALFLIFE: f32 = 0.2;
/// The share of the predicted hips offset the root's target takes (`HIPS_GAIN`).
pub const HIPS_GAIN: f32 = 0.5;

/// The page's `TrackedDrive.aimRoot`: the predicted hips offset (room m from the head centre,
/// world axes; non-finite: none) smoothed in the frame of the body yaw `yaw` — `local` carries it
/// (NaN: none yet) — and the offset to add to the head centre: [`HIPS_GAIN`] of it, at most
/// [`MAX_HIPS_OFFSET`] long.
fn aim_root(local: &mut Vec2, offset: Vec2, yaw: f32, dt: f32) -> Vec2 {
    let (s, c) = yaw.sin_cos();
    if offset.is_finite() {
        // Into the body's frame (rotate_y by −yaw), then toward it at the half-life.
        let l = Vec2::new(c * offset.x - s * offset.y, s * offset.x + c * offset.y);
        let k = 1.0 - (-dt.max(0.0) / HIPS_OFFSET_HALFLIFE).exp2();
        *local = if local.is_nan() { l } else { *local + (l - *local) * k };
    } else {
        *local = Vec2::NAN;
    }
    let l = if local.is_nan() { Vec2::ZERO } else { HIPS_GAIN * *local };
    Vec2::new(c * l.x + s * l.y, c * l.y - s * l.x).clamp_length_max(MAX_HIPS_OFFSET)
}
/// The page's head-velocity smoothing half-life and dt limits (`web/src/vr/trackers.ts`).
const VELOCITY_HALFLIFE: f32 = 0.03;
const MAX_DT: f32 = 0.1;
const RESET_AFTER: f32 = 0.5;
/// α while the body is tracked, m (`BODY_ALPHA` of the page).
pub const BODY_ALPHA: f32 = 0.1;
/// Smoothing of the tracked hips' ground velocity, half-life s (`HIPS_VELOCITY_HALFLIFE`).
const HIPS_VELOCITY_HALFLIFE: f32 = 0.05;
/// Joint pairs a facing is read from, left then right: the hip joints, else the shoulders
/// (`FACING_PAIRS` over the page's `BODY_JOINTS` names).
const FACING_PAIRS: [(&str, &str); 2] = [("left-upper-leg", "right-upper-leg"), ("left-arm-upper", "right-arm-upper")];

/// The tracked hips as the page follows them (`TrackedDrive.bodyYaw`): their floor point and
/// smoothed ground velocity (room m, m/s) and whether the last frame had them; the recording's
/// indices of the hips and of the facing pairs it has.
struct TrackedHips {
    floor: Vec2,
    velocity: Vec2,
    had: bool,
    hips: Option<usize>,
    pairs: Vec<(usize, usize)>,
}

impl TrackedHips {
    fn new(body: &Body) -> TrackedHips {
        let pairs = FACING_PAIRS.iter().filter_map(|&(l, r)| Some((body.joint(l)?, body.joint(r)?))).collect();
        TrackedHips { floor: Vec2::ZERO, velocity: Vec2::ZERO, had: false, hips: body.joint("hips"), pairs }
    }

    /// Frame `f`'s hips floor point, their velocity and the body facing (rad, 0 = +Z: forward =
    /// (left − right) × up over the first pair both tracked); None without tracked hips or a
    /// pair. Moves the floor point and velocity on (from `head_velocity` when the hips were not
    /// tracked the frame before).
    fn update(&mut self, body: &Body, f: usize, dt: f32, head_velocity: Vec3) -> Option<(Vec2, Vec2, f32)> {
        let Some(hips) = self.hips.and_then(|h| body.tracked_position(f, h)) else {
            self.had = false;
            return None;
        };
        let at = Vec2::new(hips.x, hips.z);
        if self.had && dt > 0.0 {
            let k = 1.0 - (-dt / HIPS_VELOCITY_HALFLIFE).exp2();
            self.velocity += ((at - self.floor) / dt - self.velocity) * k;
        } else {
            self.velocity = Vec2::new(head_velocity.x, head_velocity.z);
        }
        self.floor = at;
        self.had = true;
        self.pairs.iter().find_map(|&(l, r)| {
            let d = body.tracked_position(f, l)? - body.tracked_position(f, r)?;
            (d.x * d.x + d.z * d.z >= 1e-6).then(|| (self.floor, self.velocity, (-d.z).atan2(d.x)))
        })
    }
}

/// The VR page's runtime settings: the one file the page reads too (`VR_SETTINGS` in
/// `web/src/vr/tracked-drive.ts`, whose comment says why each value).
const VR_SETTINGS_JSON: &str = include_str!("../../../settings/vr-settings.json");

/// The VR page's runtime settings, α apart.
pub fn vr_settings() -> CharacterSettings {
    CharacterSettings::default()
        .patched(VR_SETTINGS_JSON)
        .expect("settings/vr-settings.json is valid settings (tested)")
}

/// Heading yaw of an HMD rotation: where its view (−Z) points on the floor, the up axis filling
/// in when looking straight down or up (`headingYaw` of the page, docs/orientation-model.md).
pub fn heading_yaw(q: Quat) -> f32 {
    let f = q * Vec3::NEG_Z;
    let u = q * Vec3::Y;
    (f.x - f.y * u.x).atan2(f.z - f.y * u.z)
}

/// Mean, median, 95th percentile and maximum.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Stats {
    pub mean: f32,
    pub median: f32,
    pub p95: f32,
    pub max: f32,
}

impl Stats {
    pub fn of(values: &[f32]) -> Stats {
        if values.is_empty() {
            return Stats { mean: f32::NAN, median: f32::NAN, p95: f32::NAN, max: f32::NAN };
        }
        let mut v = values.to_vec();
        v.sort_by(f32::total_cmp);
        let q = |p: f32| v[((v.len() - 1) as f32 * p).round() as usize];
        Stats { mean: v.iter().sum::<f32>() / v.len() as f32, median: q(0.5), p95: q(0.95), max: v[v.len() - 1] }
    }
}

/// What one replay measured (room metres).
#[derive(Clone, Debug, serde::Serialize)]
pub struct ReplayReport {
    pub frames: usize,
    pub seconds: f32,
    pub alpha: f32,
    /// Avatar root ↔ the recording's true root on the floor (m), when the recording has truth.
    pub root_distance: Option<Stats>,
    /// Avatar root ↔ what α clamps it to on the floor (m): the predicted hips (else the head
    /// centre), or the tracked hips on the frames the body drove.
    pub head_gap: Stats,
    /// Frames driven from the tracked body (a recording with body joints).
    pub body_frames: usize,
    /// On those frames: the shown hips ↔ the tracked hips on the floor (m) — what the runtime's
    /// hips follow (`Legs::follow_hips`) beyond the root's α. Left out without a tracked body.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hips_distance: Option<Stats>,
    /// Share of frames with the root clamped at α (gap ≥ 0.98 of the α in effect).
    pub clamped_share: f32,
    /// Planted-toe sliding on the floor (`skating::SkatingMeter`), cm/s.
    pub skating: f32,
    /// Corrective steps (a foot the drag pulled out of its lock stepping back, `ik::FootLock`)
    /// per second, both feet.
    pub steps_per_second: f32,
    /// The legacy measure the VR bench published before the contact-flag one (55–62 cm/s on the
    /// held-in recordings): `d_xz·(2 − 2^(h/H))` per toe while its height h above the database's
    /// planted toe height is under H = 3.3 cm, cm/s.
    pub skating_toe_height: f32,
    /// Runtime update time (ms), native.
    pub update_ms: Stats,
    /// Room metres per database metre (calibration).
    pub scale: f32,
}

/// Replays `recording` on `db` at α = `alpha` (room m) with the body yaw `yaw[f]` per frame
/// (radians, 0 = +Z; NaN keeps the previous one), the hips `hips[f]` per frame when given (where
/// the orientation network puts them: room metres from the head centre on the floor, (x, z); a
/// non-finite one: the head centre itself, as the page does) and `settings` (α is set from `alpha`).
pub fn replay(
    db: &Database,
    index: &SearchIndex,
    recording: &Recording,
    yaw: &[f32],
    hips_offsets: Option<&[Vec2]>,
    alpha: f32,
    settings: &CharacterSettings,
) -> ReplayReport {
    let n = recording.num_frames();
    assert_eq!(yaw.len(), n, "one yaw per frame");
    assert!(hips_offsets.is_none_or(|h| h.len() == n), "one hips offset per frame");
    // Calibration: the avatar's eyes at the user's (the database skeleton's head joint height at
    // rest stands for the avatar's eye height, as the page does without an avatar).
    let db_eye = db.rest_head_height().unwrap_or(1.6);
    let eye = recording.eye_height.unwrap_or(db_eye);
    let scale = eye / db_eye;
    let settings = CharacterSettings { clamp_distance: alpha / scale, ..settings.clone() };
    let mut c = Character::new(db, settings);
    let toe_floor = db.toe_height_in_contact().unwrap_or(0.0);
    c.set_toe_floor(db.toe_height_in_contact());
    let toes: Vec<(usize, Vec3)> = ["left_toe", "right_toe"]
        .iter()
        .filter_map(|r| db.skeleton.site(r))
        .map(|s| (s.joint as usize, s.offset))
        .collect();

    let head_floor = |f: usize| {
        let p = recording.head_position[f];
        let h = heading_yaw(recording.head_rotation[f]);
        Vec2::new(p.x - HMD_TO_HEAD_CENTRE * h.sin(), p.z - HMD_TO_HEAD_CENTRE * h.cos())
    };
    let start = head_floor(0);
    let start_yaw = recording.truth_yaw.as_ref().map_or(heading_yaw(recording.head_rotation[0]), |t| t[0]);
    c.teleport(db, Vec3::new(start.x / scale, 0.0, start.y / scale), Quat::from_rotation_y(start_yaw));

    let (mut velocity, mut body_yaw) = (Vec3::ZERO, start_yaw);
    let mut hips_local = Vec2::NAN;
    let mut hips = recording.body.as_ref().map(TrackedHips::new);
    let mut body_frames = 0usize;
    let mut hips_distances = Vec::new();
    let hips_joint = db.skeleton.site("hips").map(|s| s.joint as usize);
    let (mut distances, mut gaps, mut times) = (Vec::with_capacity(n), Vec::with_capacity(n), Vec::with_capacity(n));
    let (mut clamped, mut legacy) = (0usize, 0.0f32);
    let mut previous_toes: Option<[Vec3; 2]> = None;
    let (mut steps, mut stepping) = (0usize, [false; 2]);
    for f in 0..n {
        let raw_dt = if f == 0 { 0.0 } else { (recording.time[f] - recording.time[f - 1]) as f32 };
        let dt = raw_dt.clamp(0.0, MAX_DT);
        if f > 0 && raw_dt > 0.0 && raw_dt <= RESET_AFTER {
            let v = (recording.head_position[f] - recording.head_position[f - 1]) / raw_dt;
            velocity += (v - velocity) * (1.0 - (-raw_dt / VELOCITY_HALFLIFE).exp2());
        } else {
            velocity = Vec3::ZERO;
        }
        if yaw[f].is_finite() {
            body_yaw = yaw[f];
        }
        let tracked = match (&recording.body, &mut hips) {
            (Some(b), Some(h)) => h.update(b, f, dt, velocity),
            _ => None,
        };
        let head = head_floor(f);
        let offset = aim_root(&mut hips_local, hips_offsets.map_or(Vec2::NAN, |h| h[f]), body_yaw, dt);
        // The root's target: the tracked hips while the body drives, else the predicted hips
        // (the head centre without a prediction).
        let (floor, target_velocity, yaw_now, alpha_now) = match tracked {
            Some((at, v, y)) => (at, v, y, alpha.min(BODY_ALPHA)),
            None => (head + offset, Vec2::new(velocity.x, velocity.z), body_yaw, alpha),
        };
        body_frames += tracked.is_some() as usize;
        // Crouch: the head centre's drop — the HMD plus R·(0, 0, d), whose height is the HMD's
        // plus d·2(yz − wx), so pitching the head does not move it — split by the headset's
        // pitch (asin of its view axis's y, −2(yz − wx)) into hips drop and torso bend
        // (`TrackedDrive.update` of the page).
        let q = recording.head_rotation[f];
        let up = 2.0 * (q.y * q.z - q.w * q.x);
        let centre = recording.head_position[f].y + HMD_TO_HEAD_CENTRE * up;
        let pitch = (-up).clamp(-1.0, 1.0).asin();
        let started = std::time::Instant::now();
        // The page's drive value: its crouch split first (`Character.setCrouch`), then the
        // whole value handed over at the update.
        let crouch = c.set_crouch((eye - centre) / scale, pitch);
        let drive = DriveInput {
            mode: DriveMode::Tracked,
            tracked: Tracked {
                position: Vec3::new(floor.x / scale, 0.0, floor.y / scale),
                velocity: Vec3::new(target_velocity.x, 0.0, target_velocity.y) / scale,
                yaw: yaw_now,
                body: tracked.is_some(),
            },
            hips_drop: crouch.hips_drop,
            bend: crouch.bend,
            clamp_distance: alpha_now / scale,
            ..Default::default()
        };
        c.set_drive(&drive);
        c.update(db, index, &drive.input, dt);
        times.push(started.elapsed().as_secs_f32() * 1e3);
        let now = c.foot_stepping();
        steps += (0..2).filter(|&k| now[k] && !stepping[k]).count();
        stepping = now;
        let root = c.root_position() * scale;
        if let (Some(_), Some(j)) = (tracked, hips_joint) {
            let shown = c.world_positions()[j] * scale;
            hips_distances.push(Vec2::new(shown.x - floor.x, shown.z - floor.y).length());
        }
        let gap = Vec2::new(root.x - floor.x, root.z - floor.y).length();
        gaps.push(gap);
        clamped += (gap >= 0.98 * alpha_now) as usize;
        if let Some(truth) = &recording.truth_root {
            distances.push(Vec2::new(root.x - truth[f].x, root.z - truth[f].y).length());
            if std::env::var_os("MMDB_REPLAY_TRACE").is_some() && f % 36 == 0 {
                let clip = &db.clips[db.clip_at(c.frame())];
                let ty = recording.truth_yaw.as_ref().map_or(0.0, |t| t[f]);
                let (fw, lt) = (Vec2::new(ty.sin(), ty.cos()), Vec2::new(ty.cos(), -ty.sin()));
                let e = Vec2::new(root.x, root.z) - truth[f];
                let h = floor - truth[f];
                eprintln!(
                    "t {:5.2} root-truth fwd {:+.2} lat {:+.2} | head-truth fwd {:+.2} lat {:+.2} | v {:.2} {} [{}]",
                    recording.time[f],
                    e.dot(fw),
                    e.dot(lt),
                    h.dot(fw),
                    h.dot(lt),
                    velocity.length(),
                    clip.name,
                    c.frame()
                );
            }
        }
        // Legacy skating: toes under `ON_FLOOR` (3.3 cm, room units) above the planted toe height slide,
        // weighted by their height.
        let (p, r) = (c.world_positions(), c.world_rotations());
        let now = [0, 1].map(|k| toes.get(k).map_or(Vec3::ZERO, |&(j, o)| (p[j] + r[j] * o) * scale));
        if let Some(before) = previous_toes {
            for k in 0..2 {
                let h = (now[k].y - toe_floor * scale).max(0.0);
                if h < ON_FLOOR {
                    legacy += Vec2::new(now[k].x - before[k].x, now[k].z - before[k].z).length()
                        * (2.0 - (h / ON_FLOOR).exp2());
                }
            }
        }
        previous_toes = Some(now);
    }
    let seconds = (recording.time[n - 1] - recording.time[0]) as f32;
    ReplayReport {
        frames: n,
        seconds,
        alpha,
        root_distance: recording.truth_root.as_ref().map(|_| Stats::of(&distances)),
        head_gap: Stats::of(&gaps),
        body_frames,
        hips_distance: (body_frames > 0).then(|| Stats::of(&hips_distances)),
        clamped_share: clamped as f32 / n as f32,
        skating: 100.0 * c.skating().distance * scale / seconds,
        steps_per_second: steps as f32 / seconds,
        skating_toe_height: 100.0 * legacy / seconds,
        update_ms: Stats::of(&times),
        scale,
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_vr_settings_file_is_valid_settings() {
        let s = super::vr_settings();
        assert!(s.clamping && s.adjustment_max_ratio > 0.0);
    }
}
