//! Motion tags (config `"motion_tags": true`): what the body does, read off the virtual root of
//! every clip — `idle`, `turn_in_place`, `sidestep`, `backward`. The runtime can then treat such
//! stretches specially (`CharacterSettings::idle_exclude_speed`: no standing frames while the
//! user moves) and searches can be restricted to them (`--tag`).
//!
//! Rules (the shared mocap survey's, so durations compare with it): root speed over ±0.25 s;
//! moving (≥ 0.3 m/s) is `sidestep` when the travel direction is 60–120° off the facing and
//! `backward` beyond 120°; in place (< 0.2 m/s) is `turn_in_place` when the facing turns faster
//! than 30°/s over ±0.5 s, else `idle`. Runs shorter than 0.25 s are dropped (flicker at the
//! thresholds).

use glam::{Quat, Vec3};

const MOVING: f32 = 0.3;
const IN_PLACE: f32 = 0.2;
const TURN_RATE: f32 = 30.0 * std::f32::consts::PI / 180.0;
const SPEED_WINDOW: f32 = 0.25;
const TURN_WINDOW: f32 = 0.5;
const MIN_RUN: f32 = 0.25;

/// The tags, in the order [`motion_tags`] reports them.
pub const MOTION_TAGS: [&str; 4] = ["idle", "turn_in_place", "sidestep", "backward"];

/// Per tag of [`MOTION_TAGS`], the `[start, end)` frame ranges (clip-relative) of one clip whose
/// root transforms per frame are `root(f)`.
pub fn motion_tags(num_frames: usize, fps: f32, root: impl Fn(usize) -> (Vec3, Quat)) -> [Vec<(u32, u32)>; 4] {
    let k = ((SPEED_WINDOW * fps).round() as usize).max(1);
    let kt = ((TURN_WINDOW * fps).round() as usize).max(1);
    let last = num_frames.saturating_sub(1);
    let yaw = |f: usize| {
        let d = root(f).1 * Vec3::Z;
        d.x.atan2(d.z)
    };
    let class = |f: usize| -> Option<usize> {
        let (a, b) = (f.saturating_sub(k), (f + k).min(last));
        if b == a {
            return None;
        }
        let v = (root(b).0 - root(a).0) * (fps / (b - a) as f32);
        let speed = (v.x * v.x + v.z * v.z).sqrt();
        if speed >= MOVING {
            let facing = yaw(f);
            let travel = v.x.atan2(v.z);
            let off = ((travel - facing + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU)
                - std::f32::consts::PI)
                .abs()
                .to_degrees();
            return if off > 120.0 {
                Some(3)
            } else if off >= 60.0 {
                Some(2)
            } else {
                None
            };
        }
        if speed < IN_PLACE {
            let (a, b) = (f.saturating_sub(kt), (f + kt).min(last));
            let turn =
                (yaw(b) - yaw(a) + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI;
            let rate = turn.abs() * fps / (b - a).max(1) as f32;
            return Some(if rate > TURN_RATE { 1 } else { 0 });
        }
        None
    };
    let min_run = ((MIN_RUN * fps).round() as usize).max(1);
    let mut out: [Vec<(u32, u32)>; 4] = Default::default();
    let mut f = 0;
    while f < num_frames {
        let c = class(f);
        let mut e = f + 1;
        while e < num_frames && class(e) == c {
            e += 1;
        }
        if let Some(c) = c {
            if e - f >= min_run {
                out[c].push((f as u32, e as u32));
            }
        }
        f = e;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tags_standing_turning_and_stepping_backward_and_sideways() {
        let fps = 60.0;
        // 2 s standing, 2 s turning on the spot at 90°/s, 2 s back at 1 m/s, 2 s right at 0.6 m/s.
        let root = |f: usize| {
            let t = f as f32 / fps;
            let yaw = (t.clamp(2.0, 4.0) - 2.0) * std::f32::consts::FRAC_PI_2;
            let facing = Quat::from_rotation_y(yaw);
            let back = (t.clamp(4.0, 6.0) - 4.0) * 1.0;
            let side = (t.clamp(6.0, 8.0) - 6.0) * 0.6;
            (facing * Vec3::new(-side, 0.0, -back), facing)
        };
        let tags = motion_tags(480, fps, root);
        let covers = |ranges: &[(u32, u32)], a: u32, b: u32| ranges.iter().any(|&(s, e)| s <= a && e >= b);
        assert!(covers(&tags[0], 0, 100), "idle {:?}", tags[0]);
        assert!(covers(&tags[1], 150, 220), "turn {:?}", tags[1]);
        assert!(covers(&tags[3], 270, 340), "backward {:?}", tags[3]);
        assert!(covers(&tags[2], 390, 460), "sidestep {:?}", tags[2]);
    }
}
