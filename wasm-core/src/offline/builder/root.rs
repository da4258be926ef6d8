//! The virtual root (docs/method.md §1): the hips projected on the floor, facing the hips'
//! forward axis projected on the floor, both smoothed over time (Savitzky–Golay, cubic) so the
//! trajectory ignores the hips' sway.

use crate::smoothing::savitzky_golay;
use glam::{DQuat, DVec3};

/// Writes one root transform per frame into `root` from the hips' world transforms
/// (`hips_world(f)`); `forward_rest` is the hips' forward axis in their rest frame, windows in
/// seconds. `xz` and `facing` are scratch.
#[allow(clippy::too_many_arguments)]
pub fn virtual_root(
    num_frames: usize,
    hips_world: impl Fn(usize) -> (DVec3, DQuat),
    forward_rest: DVec3,
    fps: f64,
    position_window: f64,
    facing_window: f64,
    xz: &mut Vec<f64>,
    facing: &mut Vec<f64>,
    root: &mut Vec<(DVec3, DQuat)>,
) {
    xz.clear();
    facing.clear();
    let mut last = DVec3::Z;
    for f in 0..num_frames {
        let (p, q) = hips_world(f);
        xz.extend([p.x, p.z]);
        let d = q * forward_rest;
        last = DVec3::new(d.x, 0.0, d.z).try_normalize().unwrap_or(last);
        facing.extend([last.x, last.z]);
    }
    let window = |seconds: f64| 2 * (seconds * fps / 2.0).round() as usize + 1;
    savitzky_golay(xz, 2, window(position_window), 3);
    savitzky_golay(facing, 2, window(facing_window), 3);
    root.clear();
    root.extend((0..num_frames).map(|f| {
        let (x, z) = (facing[2 * f], facing[2 * f + 1]);
        let yaw = if x == 0.0 && z == 0.0 { 0.0 } else { x.atan2(z) };
        (DVec3::new(xz[2 * f], 0.0, xz[2 * f + 1]), DQuat::from_rotation_y(yaw))
    }));
}
