//! Repair of single- to three-frame rotation glitches of optical mocap (a joint flips to
//! another Euler solution or to the rest pose and back: CMU 16_15 starts with the humerus at
//! rest, 16_16 flips a thumb for two frames).

use super::poses::Poses;
use glam::DQuat;

/// Longest run of glitched frames [`repair_spikes`] bridges.
const MAX_SPIKE_FRAMES: usize = 3;
/// A spike leaves by more than this (rad) …
const SPIKE_DEPARTURE: f64 = 0.5;
/// … and the frames on either side of it agree within this per bridged frame (rad).
const SPIKE_BRIDGE_PER_FRAME: f64 = 0.1;

/// A glitch *leaves and comes back*: the frames on either side agree while the frames between
/// are far from both — which real fast motion never does, as it does not return. Glitched
/// frames are replaced by slerp across them (or by the first good frame at a take's start).
/// Returns the repaired (joint, frame) pairs.
pub fn repair_spikes(poses: &mut Poses) -> Vec<(usize, usize)> {
    let (n, num_joints) = (poses.num_frames(), poses.num_joints);
    let rotations = &mut poses.rotations;
    let angle = |a: DQuat, b: DQuat| 2.0 * a.dot(b).abs().min(1.0).acos();
    let mut repaired = Vec::new();
    for j in 0..num_joints {
        let q = |f: usize, r: &[DQuat]| r[f * num_joints + j];
        // A glitched start: frames 0..k far from frame k, which agrees with frame k+1.
        for k in 1..=MAX_SPIKE_FRAMES.min(n.saturating_sub(2)) {
            let good = q(k, rotations);
            if angle(good, q(k + 1, rotations)) < SPIKE_BRIDGE_PER_FRAME
                && (0..k).all(|f| angle(q(f, rotations), good) > SPIKE_DEPARTURE)
            {
                for f in 0..k {
                    rotations[f * num_joints + j] = good;
                    repaired.push((j, f));
                }
                break;
            }
        }
        let mut f = 1;
        while f + 1 < n {
            let before = q(f - 1, rotations);
            if angle(q(f, rotations), before) > SPIKE_DEPARTURE {
                for len in 1..=MAX_SPIKE_FRAMES {
                    let after_frame = f + len;
                    if after_frame >= n {
                        break;
                    }
                    let after = q(after_frame, rotations);
                    let bridged = angle(before, after) < SPIKE_BRIDGE_PER_FRAME * (len + 1) as f64;
                    if bridged
                        && (f..after_frame).all(|g| {
                            angle(q(g, rotations), before) > SPIKE_DEPARTURE
                                && angle(q(g, rotations), after) > SPIKE_DEPARTURE
                        })
                    {
                        for g in f..after_frame {
                            let u = (g + 1 - f) as f64 / (len + 1) as f64;
                            rotations[g * num_joints + j] = before.slerp(after, u);
                            repaired.push((j, g));
                        }
                        f = after_frame;
                        break;
                    }
                }
            }
            f += 1;
        }
    }
    repaired
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn poses(angles: impl Iterator<Item = f64>) -> Poses {
        let mut p = Poses::default();
        p.clear(1);
        for a in angles {
            p.push(DVec3::ZERO, DQuat::from_rotation_z(a));
        }
        p
    }

    #[test]
    fn spikes_that_leave_and_return_are_repaired_and_fast_motion_is_not() {
        // Smooth motion at 0.05 rad/frame, a 2-frame flip at 10, a bad first frame.
        let mut frames = poses((0..30).map(|f| 0.05 * f as f64));
        frames.rotations[0] = DQuat::from_rotation_z(2.5);
        frames.rotations[10] = DQuat::from_rotation_z(3.0);
        frames.rotations[11] = DQuat::from_rotation_z(-2.0);
        let repaired = repair_spikes(&mut frames);
        assert_eq!(repaired, vec![(0, 0), (0, 10), (0, 11)]);
        for (f, r) in frames.rotations.iter().enumerate() {
            let expected = DQuat::from_rotation_z(0.05 * if f == 0 { 1.0 } else { f as f64 });
            assert!(r.angle_between(expected) < 1e-6, "frame {f}");
        }
        // A fast, real swing (0.8 rad/frame that does not come back) is left alone.
        let mut swing = poses((0..10).map(|f| if f < 5 { 0.0 } else { 0.8 * (f - 4) as f64 }));
        assert!(repair_spikes(&mut swing).is_empty());
    }
}
