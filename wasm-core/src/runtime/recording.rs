//! A tracker recording (docs/vr-recording.md, JSON version 1): its reader and the one validator
//! of its values, shared by the page (`web/src/vr/recording.ts`, through the WASM binding
//! `validate_recording`) and `mmdb replay` (the replay harness, `harness/vr_replay.rs`), so both
//! accept exactly the same recordings and say the same of the others.

use glam::{Quat, Vec2, Vec3};

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
    /// `body`: the joints a body-tracking headset reported, when it did.
    pub body: Option<Body>,
}

/// A recording's body joints (`body`, docs/vr-recording.md): their names, and per frame and
/// joint (`f * joints.len() + j`) the position (room m) and whether the joint was tracked.
#[derive(Clone, Debug, Default)]
pub struct Body {
    pub joints: Vec<String>,
    pub position: Vec<Vec3>,
    pub tracked: Vec<bool>,
}

impl Body {
    /// Index of the joint named `name` (the page's names: `hips`, `left-upper-leg`, …).
    pub fn joint(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j == name)
    }

    /// Joint `j`'s position in frame `f`, when it was tracked then.
    pub fn tracked_position(&self, f: usize, j: usize) -> Option<Vec3> {
        let k = f * self.joints.len() + j;
        self.tracked[k].then(|| self.position[k])
    }
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
        let numbers = |name: &str| numbers_in(o, "", name);
        if o.get("meta").is_some_and(|m| !m.is_object()) {
            return Err("\"meta\" must be an object".into());
        }
        let frames = o.get("frames").and_then(Value::as_f64).ok_or("\"frames\" must be a number")?;
        let truth = match o.get("truth") {
            None => None,
            Some(t) => {
                let t = t.as_object().ok_or("\"truth\" must be an object")?;
                let arr = |name: &str| -> Result<Vec<f64>, String> {
                    let a = t
                        .get(name)
                        .and_then(Value::as_array)
                        .ok_or(format!("\"truth.{name}\" must be an array of numbers"))?;
                    a.iter()
                        .map(|x| x.as_f64().ok_or(format!("\"truth.{name}\" must be an array of numbers")))
                        .collect()
                };
                Some((arr("bodyYaw")?, arr("root")?))
            }
        };
        let time = numbers("time")?;
        let p = numbers("position")?;
        let r = numbers("rotation")?;
        let tracked: Vec<u8> =
            numbers("tracked")?.into_iter().map(|t| if t == 0.0 || t == 1.0 { t as u8 } else { 255 }).collect();
        validate(frames, &time, &p, &r, &tracked, truth.as_ref().map(|(y, r)| (y.as_slice(), r.as_slice())))?;
        let mut body = None;
        if let Some(b) = o.get("body") {
            let b = b.as_object().ok_or("\"body\" must be an object")?;
            let joints =
                b.get("joints").and_then(Value::as_array).ok_or("\"body.joints\" must be an array of names")?;
            if joints.is_empty() || !joints.iter().all(Value::is_string) {
                return Err("\"body.joints\" must be an array of names".into());
            }
            let arr = |name: &str| numbers_in(b, "body.", name);
            let flags: Vec<u8> =
                arr("tracked")?.into_iter().map(|t| if t == 0.0 || t == 1.0 { t as u8 } else { 255 }).collect();
            let position = arr("position")?;
            validate_body(frames, joints.len(), &position, &arr("rotation")?, &flags)?;
            body = Some(Body {
                joints: joints.iter().filter_map(Value::as_str).map(str::to_string).collect(),
                position: position.chunks(3).map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)).collect(),
                tracked: flags.iter().map(|&t| t == 1).collect(),
            });
        }
        let n = time.len();
        if n > crate::limits::MAX_FRAMES {
            return Err(format!("{n} frames, more than {}", crate::limits::MAX_FRAMES));
        }
        Ok(Recording {
            time,
            head_position: (0..n)
                .map(|f| Vec3::new(p[9 * f] as f32, p[9 * f + 1] as f32, p[9 * f + 2] as f32))
                .collect(),
            head_rotation: (0..n)
                .map(|f| {
                    Quat::from_xyzw(r[12 * f] as f32, r[12 * f + 1] as f32, r[12 * f + 2] as f32, r[12 * f + 3] as f32)
                        .normalize()
                })
                .collect(),
            eye_height: o.get("meta").and_then(|m| m["eyeHeight"].as_f64()).map(|e| e as f32),
            truth_yaw: truth.as_ref().map(|(y, _)| y.iter().map(|&x| x as f32).collect()),
            truth_root: truth.as_ref().map(|(_, r)| r.chunks(2).map(|c| Vec2::new(c[0] as f32, c[1] as f32)).collect()),
            body,
        })
    }

    pub fn num_frames(&self) -> usize {
        self.time.len()
    }
}

/// `obj[name]` as numbers, or what is wrong with it as the page says it (`"body.position"[4] is
/// not a number`); `prefix` names the object (`body.`).
fn numbers_in(obj: &serde_json::Map<String, serde_json::Value>, prefix: &str, name: &str) -> Result<Vec<f64>, String> {
    let a = obj
        .get(name)
        .and_then(serde_json::Value::as_array)
        .ok_or(format!("\"{prefix}{name}\" must be an array of numbers"))?;
    a.iter().enumerate().map(|(i, x)| x.as_f64().ok_or(format!("\"{prefix}{name}\"[{i}] is not a number"))).collect()
}

/// Trackers per recorded frame: head, left grip, right grip.
pub const NUM_TRACKERS: usize = 3;

/// The one validator of a recording's values, used by `mmdb replay` ([`Recording::from_json`])
/// and by the page (`validateRecording` in `web/src/vr/recording.ts`, through the WASM binding
/// `validate_recording`): a positive whole frame count; arrays of frames × 1 (time), × 9
/// (positions), × 12 (rotations), × 3 (tracked flags) values; truth (when given) of frames × 1
/// and × 2 finite values; finite times that strictly increase; then the poses ([`check_poses`]).
///
/// # Errors
/// The first thing wrong, as the page says it.
pub fn validate(
    frames: f64,
    time: &[f64],
    position: &[f64],
    rotation: &[f64],
    tracked: &[u8],
    truth: Option<(&[f64], &[f64])>,
) -> Result<(), String> {
    if !(frames >= 1.0 && frames.fract() == 0.0 && frames <= 9_007_199_254_740_991.0) {
        return Err(format!("frames must be a positive integer (got {})", js_number(frames)));
    }
    let expect = |name: &str, length: usize, per: usize| -> Result<(), String> {
        if length as f64 != frames * per as f64 {
            return Err(format!(
                "{name} has {length} values, expected frames × {per} = {}",
                js_number(frames * per as f64)
            ));
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
            return Err(format!(
                "time must increase: time[{f}] = {} after {}",
                js_number(time[f]),
                js_number(time[f - 1])
            ));
        }
    }
    check_poses("", "tracker", NUM_TRACKERS, position, rotation, tracked)
}

/// The body joints of a recording (optional `body`, docs/vr-recording.md): frames × `joints` ×
/// 3 positions, × 4 rotations and × 1 tracked flags, checked as the trackers are.
///
/// # Errors
/// The first thing wrong, as the page says it.
pub fn validate_body(
    frames: f64,
    joints: usize,
    position: &[f64],
    rotation: &[f64],
    tracked: &[u8],
) -> Result<(), String> {
    for (name, length, per) in
        [("position", position.len(), 3), ("rotation", rotation.len(), 4), ("tracked", tracked.len(), 1)]
    {
        if length as f64 != frames * (joints * per) as f64 {
            return Err(format!(
                "body.{name} has {length} values, expected frames × {joints} joints × {per} = {}",
                js_number(frames * (joints * per) as f64)
            ));
        }
    }
    check_poses("body.", "body joint", joints, position, rotation, tracked)
}

/// Flags 0 or 1, finite positions and finite unit quaternions (|q| within 10⁻³ of 1, so a zero
/// or a 10³⁰⁰ quaternion is refused) of `per_frame` poses a frame; lengths already checked.
fn check_poses(
    prefix: &str,
    what: &str,
    per_frame: usize,
    position: &[f64],
    rotation: &[f64],
    tracked: &[u8],
) -> Result<(), String> {
    for k in 0..tracked.len() {
        let (f, t) = (k / per_frame.max(1), k % per_frame.max(1));
        if tracked[k] > 1 {
            return Err(format!("{prefix}tracked[{k}] must be 0 or 1 (got {})", tracked[k]));
        }
        if !position[3 * k..3 * k + 3].iter().all(|v| v.is_finite()) {
            return Err(format!("{prefix}position of frame {f}, {what} {t} is not finite"));
        }
        let q = &rotation[4 * k..4 * k + 4];
        if !q.iter().all(|v| v.is_finite()) {
            return Err(format!("{prefix}rotation of frame {f}, {what} {t} is not finite"));
        }
        let length = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !((length - 1.0).abs() <= 1e-3) {
            return Err(format!(
                "{prefix}rotation of frame {f}, {what} {t} is not a unit quaternion (length {})",
                js_fixed4(length)
            ));
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
        if x > 0.0 {
            "Infinity".into()
        } else {
            "-Infinity".into()
        }
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

#[cfg(test)]
mod tests {
    /// The hostile recordings the page's reader is tested on too (`web/src/vr/recording.test.ts`):
    /// the same verdict and message. `mmdb replay` accepted zero and 10³⁰⁰ quaternions and
    /// non-increasing times (and printed NaN metrics), and said "time has 345 finite numbers,
    /// expected 345" of a string in `time`.
    #[test]
    fn recordings_are_read_as_the_page_reads_them() {
        let doc: serde_json::Value =
            serde_json::from_str(include_str!("../../tests/corpus/recordings/cases.json")).unwrap();
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
