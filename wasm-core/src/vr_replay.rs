//! A VR session replayed natively (docs/vr.md, "Replays"): a tracker recording
//! (docs/vr-recording.md, JSON version 1) drives a character through the tracked drive exactly as
//! the VR page's frame recipe does (`web/src/vr/tracked-drive.ts`) — head velocity differentiated
//! over the real frame time and lightly smoothed, the head centre 0.10 m behind the eyes on the
//! floor, the body yaw from a given source (the orientation network's output computed by
//! `training/replay.py`, the recording's truth, or HMD forward), the crouch (`Character::set_crouch`), the VR
//! settings — and measures what the replay bench measures: user↔avatar root distance (against
//! the recording's truth), the head gap α clamps, foot skating and the update time.
//!
//! It is for the runtime's numbers without a browser; the page's own bench adds rendering,
//! retargeting, arm IK and the network's run. `MMDB_REPLAY_TRACE=1` prints, every 0.5 s, the
//! root's and the head's offset from the true root (along and across the true facing) and the
//! clip playing — how the root distance in docs/vr.md was taken apart.

use crate::character::{Character, CharacterSettings, Tracked};
use crate::controller::Input;
use crate::skating::ON_FLOOR;
use crate::database::Database;
use crate::search::SearchIndex;
use glam::{Quat, Vec2, Vec3};

/// HMD (eyes) → head centre, m backward along the heading (`HMD_TO_HEAD_CENTRE` of the page).
pub const HMD_TO_HEAD_CENTRE: f32 = 0.1;
/// The page's head-velocity smoothing half-life and dt limits (`web/src/vr/trackers.ts`).
const VELOCITY_HALFLIFE: f32 = 0.03;
const MAX_DT: f32 = 0.1;
const RESET_AFTER: f32 = 0.5;

/// The VR page's runtime settings: the one file the page reads too (`VR_SETTINGS` in
/// `web/src/vr/tracked-drive.ts`, whose comment says why each value).
const VR_SETTINGS_JSON: &str = include_str!("../../web/src/vr/vr-settings.json");

/// The VR page's runtime settings, α apart.
pub fn vr_settings() -> CharacterSettings {
    CharacterSettings::default().patched(VR_SETTINGS_JSON).expect("web/src/vr/vr-settings.json is valid settings (tested)")
}

/// The parts of a recording the replay uses.
#[derive(Clone, Debug, Default)]
pub struct Recording {
    pub time: Vec<f64>,
    pub head_position: Vec<Vec3>,
    pub head_rotation: Vec<Quat>,
    /// `meta.eyeHeight`: the calibrated standing eye height (m).
    pub eye_height: Option<f32>,
    /// `truth.bodyYaw` and `truth.root` (x, z) when the recording was made from mocap.
    pub truth_yaw: Option<Vec<f32>>,
    pub truth_root: Option<Vec<Vec2>>,
}

impl Recording {
    /// Reads the JSON encoding (version 1) exactly as the page does (`decodeRecording` in
    /// `web/src/vr/recording.ts`): the same shape checks in the same order with the same
    /// messages, then [`validate`], the one validator both use (the page through WASM).
    ///
    /// # Errors
    /// What is wrong and where (`"time"[3] is not a number`, `time must increase: …`, `rotation
    /// of frame 2, tracker 0 is not a unit quaternion (length 0.0000)`).
    pub fn from_json(text: &str) -> Result<Recording, String> {
        use serde_json::Value;
        let v: Value = serde_json::from_str(text).map_err(|e| format!("not JSON ({e})"))?;
        let o = v.as_object().ok_or("expected a JSON object")?;
        let shown = |x: Option<&Value>| x.map_or("undefined".to_string(), |x| crate::limits::quote(&x.to_string()));
        if o.get("format").and_then(Value::as_str) != Some("mm-vr-recording") {
            return Err(format!("\"format\" must be \"mm-vr-recording\" (got {})", shown(o.get("format"))));
        }
        if o.get("version").and_then(Value::as_f64) != Some(1.0) {
            return Err(format!("unsupported version {} (this page reads version 1)", shown(o.get("version"))));
        }
        let numbers = |name: &str| -> Result<Vec<f64>, String> {
            let a = o.get(name).and_then(Value::as_array).ok_or(format!("\"{name}\" must be an array of numbers"))?;
            a.iter().enumerate().map(|(i, x)| x.as_f64().ok_or(format!("\"{name}\"[{i}] is not a number"))).collect()
        };
        if o.get("meta").is_some_and(|m| !m.is_object()) {
            return Err("\"meta\" must be an object".into());
        }
        let frames = o.get("frames").and_then(Value::as_f64).ok_or("\"frames\" must be a number")?;
        let truth = match o.get("truth") {
            None => None,
            Some(t) => {
                let t = t.as_object().ok_or("\"truth\" must be an object")?;
                let arr = |name: &str| -> Result<Vec<f64>, String> {
                    let a = t.get(name).and_then(Value::as_array).ok_or(format!("\"truth.{name}\" must be an array of numbers"))?;
                    a.iter().map(|x| x.as_f64().ok_or(format!("\"truth.{name}\" must be an array of numbers"))).collect()
                };
                Some((arr("bodyYaw")?, arr("root")?))
            }
        };
        let time = numbers("time")?;
        let p = numbers("position")?;
        let r = numbers("rotation")?;
        let tracked: Vec<u8> = numbers("tracked")?.into_iter().map(|t| if t == 0.0 || t == 1.0 { t as u8 } else { 255 }).collect();
        validate(frames, &time, &p, &r, &tracked, truth.as_ref().map(|(y, r)| (y.as_slice(), r.as_slice())))?;
        let n = time.len();
        if n > crate::limits::MAX_FRAMES {
            return Err(format!("{n} frames, more than {}", crate::limits::MAX_FRAMES));
        }
        Ok(Recording {
            time,
            head_position: (0..n).map(|f| Vec3::new(p[9 * f] as f32, p[9 * f + 1] as f32, p[9 * f + 2] as f32)).collect(),
            head_rotation: (0..n).map(|f| Quat::from_xyzw(r[12 * f] as f32, r[12 * f + 1] as f32, r[12 * f + 2] as f32, r[12 * f + 3] as f32).normalize()).collect(),
            eye_height: o.get("meta").and_then(|m| m["eyeHeight"].as_f64()).map(|e| e as f32),
            truth_yaw: truth.as_ref().map(|(y, _)| y.iter().map(|&x| x as f32).collect()),
            truth_root: truth.as_ref().map(|(_, r)| r.chunks(2).map(|c| Vec2::new(c[0] as f32, c[1] as f32)).collect()),
        })
    }

    pub fn num_frames(&self) -> usize {
        self.time.len()
    }
}

/// Trackers per recorded frame: head, left grip, right grip.
pub const NUM_TRACKERS: usize = 3;

/// The one validator of a recording's values, used by `mmdb replay` ([`Recording::from_json`])
/// and by the page (`validateRecording` in `web/src/vr/recording.ts`, through the WASM binding
/// `validate_recording`): a positive whole frame count; arrays of frames × 1 (time), × 9
/// (positions), × 12 (rotations), × 3 (tracked flags) values; truth (when given) of frames × 1
/// and × 2 finite values; finite times that strictly increase; tracked flags 0 or 1; finite
/// positions; finite unit quaternions (|q| within 10⁻³ of 1, so a zero or a 10³⁰⁰ quaternion
/// is refused).
///
/// # Errors
/// The first thing wrong, as the page says it.
pub fn validate(frames: f64, time: &[f64], position: &[f64], rotation: &[f64], tracked: &[u8], truth: Option<(&[f64], &[f64])>) -> Result<(), String> {
    if !(frames >= 1.0 && frames.fract() == 0.0 && frames <= 9_007_199_254_740_991.0) {
        return Err(format!("frames must be a positive integer (got {})", js_number(frames)));
    }
    let expect = |name: &str, length: usize, per: usize| -> Result<(), String> {
        if length as f64 != frames * per as f64 {
            return Err(format!("{name} has {length} values, expected frames × {per} = {}", js_number(frames * per as f64)));
        }
        Ok(())
    };
    expect("time", time.len(), 1)?;
    expect("position", position.len(), NUM_TRACKERS * 3)?;
    expect("rotation", rotation.len(), NUM_TRACKERS * 4)?;
    expect("tracked", tracked.len(), NUM_TRACKERS)?;
    if let Some((yaw, root)) = truth {
        expect("truth.bodyYaw", yaw.len(), 1)?;
        expect("truth.root", root.len(), 2)?;
        if !yaw.iter().all(|v| v.is_finite()) {
            return Err("truth.bodyYaw has a non-finite value".into());
        }
        if !root.iter().all(|v| v.is_finite()) {
            return Err("truth.root has a non-finite value".into());
        }
    }
    for f in 0..time.len() {
        if !time[f].is_finite() {
            return Err(format!("time[{f}] is not a finite number"));
        }
        if f > 0 && !(time[f] > time[f - 1]) {
            return Err(format!("time must increase: time[{f}] = {} after {}", js_number(time[f]), js_number(time[f - 1])));
        }
        for t in 0..NUM_TRACKERS {
            let k = f * NUM_TRACKERS + t;
            if tracked[k] > 1 {
                return Err(format!("tracked[{k}] must be 0 or 1 (got {})", tracked[k]));
            }
            if !position[3 * k..3 * k + 3].iter().all(|v| v.is_finite()) {
                return Err(format!("position of frame {f}, tracker {t} is not finite"));
            }
            let q = &rotation[4 * k..4 * k + 4];
            if !q.iter().all(|v| v.is_finite()) {
                return Err(format!("rotation of frame {f}, tracker {t} is not finite"));
            }
            let length = q.iter().map(|v| v * v).sum::<f64>().sqrt();
            if !((length - 1.0).abs() <= 1e-3) {
                return Err(format!("rotation of frame {f}, tracker {t} is not a unit quaternion (length {})", js_fixed4(length)));
            }
        }
    }
    Ok(())
}

/// A number the way JavaScript's `String(x)` writes the usual ones (`3`, `0.5`, `NaN`,
/// `Infinity`), so both callers of [`validate`] say the same.
fn js_number(x: f64) -> String {
    if x.is_nan() {
        "NaN".into()
    } else if x.is_infinite() {
        if x > 0.0 { "Infinity".into() } else { "-Infinity".into() }
    } else {
        crate::limits::num(x)
    }
}

/// `x.toFixed(4)` of JavaScript for the lengths [`validate`] reports.
fn js_fixed4(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.4}")
    } else {
        js_number(x)
    }
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
    /// Avatar root ↔ head centre on the floor (what α clamps), m.
    pub head_gap: Stats,
    /// Share of frames with the root clamped at α (head gap ≥ 0.98 α).
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
/// (radians, 0 = +Z; NaN keeps the previous one) and `settings` (α is set from `alpha`).
pub fn replay(db: &Database, index: &SearchIndex, recording: &Recording, yaw: &[f32], alpha: f32, settings: &CharacterSettings) -> ReplayReport {
    let n = recording.num_frames();
    assert_eq!(yaw.len(), n, "one yaw per frame");
    // Calibration: the avatar's eyes at the user's (the database skeleton's head joint height at
    // rest stands for the avatar's eye height, as the page does without an avatar).
    let db_eye = db.rest_head_height().unwrap_or(1.6);
    let eye = recording.eye_height.unwrap_or(db_eye);
    let scale = eye / db_eye;
    let settings = CharacterSettings { clamp_distance: alpha / scale, ..settings.clone() };
    let mut c = Character::new(db, settings);
    let toe_floor = db.toe_height_in_contact().unwrap_or(0.0);
    c.set_toe_floor(db.toe_height_in_contact());
    let toes: Vec<(usize, Vec3)> = ["left_toe", "right_toe"].iter().filter_map(|r| db.skeleton.site(r)).map(|s| (s.joint as usize, s.offset)).collect();

    let head_floor = |f: usize| {
        let p = recording.head_position[f];
        let h = heading_yaw(recording.head_rotation[f]);
        Vec2::new(p.x - HMD_TO_HEAD_CENTRE * h.sin(), p.z - HMD_TO_HEAD_CENTRE * h.cos())
    };
    let start = head_floor(0);
    let start_yaw = recording.truth_yaw.as_ref().map_or(heading_yaw(recording.head_rotation[0]), |t| t[0]);
    c.teleport(db, Vec3::new(start.x / scale, 0.0, start.y / scale), Quat::from_rotation_y(start_yaw));

    let (mut velocity, mut body_yaw) = (Vec3::ZERO, start_yaw);
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
        let floor = head_floor(f);
        // Crouch: the head centre's drop — the HMD plus R·(0, 0, d), whose height is the HMD's
        // plus d·2(yz − wx), so pitching the head does not move it — split by the headset's
        // pitch (asin of its view axis's y, −2(yz − wx)) into hips drop and torso bend
        // (`TrackedDrive.update` of the page).
        let q = recording.head_rotation[f];
        let up = 2.0 * (q.y * q.z - q.w * q.x);
        let centre = recording.head_position[f].y + HMD_TO_HEAD_CENTRE * up;
        let pitch = (-up).clamp(-1.0, 1.0).asin();
        let started = std::time::Instant::now();
        c.set_tracked(Tracked { position: Vec3::new(floor.x / scale, 0.0, floor.y / scale), velocity: Vec3::new(velocity.x, 0.0, velocity.z) / scale, yaw: body_yaw });
        c.set_crouch((eye - centre) / scale, pitch);
        c.update(db, index, &Input::default(), dt);
        times.push(started.elapsed().as_secs_f32() * 1e3);
        let now = c.foot_stepping();
        steps += (0..2).filter(|&k| now[k] && !stepping[k]).count();
        stepping = now;
        let root = c.root_position() * scale;
        let gap = Vec2::new(root.x - floor.x, root.z - floor.y).length();
        gaps.push(gap);
        clamped += (gap >= 0.98 * alpha) as usize;
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
                    recording.time[f], e.dot(fw), e.dot(lt), h.dot(fw), h.dot(lt), velocity.length(), clip.name, c.frame()
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
                    legacy += Vec2::new(now[k].x - before[k].x, now[k].z - before[k].z).length() * (2.0 - (h / ON_FLOOR).exp2());
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

    /// The hostile recordings the page's reader is tested on too (`web/src/vr/recording.test.ts`):
    /// the same verdict and message. `mmdb replay` accepted zero and 10³⁰⁰ quaternions and
    /// non-increasing times (and printed NaN metrics), and said "time has 345 finite numbers,
    /// expected 345" of a string in `time`.
    #[test]
    fn recordings_are_read_as_the_page_reads_them() {
        let doc: serde_json::Value = serde_json::from_str(include_str!("../tests/corpus/recordings/cases.json")).unwrap();
        let cases = doc["cases"].as_array().unwrap();
        assert!(cases.len() >= 20);
        for c in cases {
            let (name, text) = (c["name"].as_str().unwrap(), c["text"].as_str().unwrap());
            match (super::Recording::from_json(text), c["expect"].as_str()) {
                (Ok(r), None) => assert!(r.head_rotation.iter().all(|q| q.is_finite()), "{name}"),
                (Err(e), Some(expected)) => assert_eq!(e, expected, "{name}"),
                (Ok(_), Some(expected)) => panic!("{name}: accepted, expected {expected:?}"),
                (Err(e), None) => panic!("{name}: refused ({e}), expected to be read"),
            }
        }
    }
}
