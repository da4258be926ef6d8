//! Where a tracked head's drop goes (docs/vr.md, "Crouching and bending over"): a VR user whose
//! head is lower than when standing either bends the knees (the hips go down) or bends at the
//! waist (the torso pitches forward, the hips stay up and move back). The height alone cannot
//! tell them apart; the headset's pitch can. Bent over, the face points at the floor; crouched,
//! it looks ahead.
//!
//! The rule, fitted on the orientation network's training people and checked on its held-out
//! ones (docs/vr.md gives the numbers). A head drop `d` first passes the dead band: `e = d − b`
//! (eased in below 2b). The torso may bend by up to
//! `θ_max = clamp(BEND_GAIN · (BEND_START_PITCH − pitch), 0, MAX_BEND)`; a torso of length `L`
//! (hips → head) bent by θ lowers the head by `L (1 − cos θ)`, so the spine takes
//! `s = min(max(e − b, 0), L (1 − cos θ_max))` — nothing of the first b, or a walk's head bob
//! looking down would rock the torso (3 cm is a 19° bend) — and the hips the rest `e − s`. The
//! bend is `θ = acos(1 − s / L)`.

/// Crouch dead band (m): the body goes down d − b once the head is d > 2b below its standing
/// height, easing in quadratically (d²/4b) below that, so a walk's head bob (±2 cm) does not bob
/// the hips twice. The torso bends only beyond a further b.
pub const CROUCH_DEADBAND: f32 = 0.03;
/// Headset pitch (rad, negative: looking down) below which the torso may start to bend: walking
/// upright, people look about 10° down (fitted: `training/orientation/crouch_fit.py`).
pub const BEND_START_PITCH: f32 = -10.0 * std::f32::consts::PI / 180.0;
/// Torso bend allowed per radian of headset pitch below [`BEND_START_PITCH`] (fitted with it).
pub const BEND_GAIN: f32 = 2.0;
/// Most the torso bends (rad).
pub const MAX_BEND: f32 = 80.0 * std::f32::consts::PI / 180.0;

/// How a head drop splits: the hips' drop (m) and the torso's forward bend (rad).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Crouch {
    pub hips_drop: f32,
    pub bend: f32,
}

/// The split of a head `head_drop` m below its standing height, with the headset pitched `pitch`
/// rad (negative: down), for a torso `torso` m from hips to head (0: the skeleton cannot bend, the
/// hips take it all). Not-finite inputs count as 0 (no drop, level, no torso).
pub fn split(head_drop: f32, pitch: f32, torso: f32) -> Crouch {
    let d = if head_drop.is_finite() { head_drop } else { 0.0 };
    if d <= 0.0 {
        return Crouch::default();
    }
    let pitch = if pitch.is_finite() { pitch } else { 0.0 };
    let torso = if torso.is_finite() && torso > 0.0 { torso } else { 0.0 };
    let b = CROUCH_DEADBAND;
    let e = if d < 2.0 * b { d * d / (4.0 * b) } else { d - b };
    let most = (BEND_GAIN * (BEND_START_PITCH - pitch)).clamp(0.0, MAX_BEND);
    let spine = (e - b).max(0.0).min(torso * (1.0 - most.cos()));
    let bend = if spine > 0.0 { (1.0 - spine / torso).clamp(-1.0, 1.0).acos() } else { 0.0 };
    Crouch { hips_drop: e - spine, bend }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEG: f32 = std::f32::consts::PI / 180.0;

    #[test]
    fn looking_ahead_the_hips_take_the_drop() {
        let c = split(0.3, -5.0 * DEG, 0.6);
        assert_eq!(c.bend, 0.0);
        assert!((c.hips_drop - 0.27).abs() < 1e-6, "{c:?}");
        // The dead band eases in: half of it at 2b is b.
        assert!((split(0.06, 0.0, 0.6).hips_drop - 0.03).abs() < 1e-6);
        assert!((split(0.03, 0.0, 0.6).hips_drop - 0.0075).abs() < 1e-6);
    }

    #[test]
    fn looking_at_the_floor_the_torso_bends() {
        // Face down (−75°): θ_max = 2·65° = 130° → 80°; the spine could take 0.6·(1 − cos 80°) =
        // 0.496 m, so a 0.36 m drop (0.33 past the dead band) is bend beyond the first 3 cm:
        // θ = acos(1 − 0.3/0.6) = 60°, the hips 0.03 m.
        let c = split(0.36, -75.0 * DEG, 0.6);
        assert!((c.bend - 60.0 * DEG).abs() < 1e-3, "{c:?}");
        assert!((c.hips_drop - CROUCH_DEADBAND).abs() < 1e-5, "{c:?}");
        // A deeper drop than the bend allows: the hips take the rest.
        let c = split(0.7, -75.0 * DEG, 0.6);
        assert!((c.bend - MAX_BEND).abs() < 1e-4, "{c:?}");
        let spine = 0.6 * (1.0 - MAX_BEND.cos());
        assert!((c.hips_drop - (0.7 - spine - CROUCH_DEADBAND)).abs() < 1e-5, "{c:?}");
        // A walk's bob looking down (a head 6 cm low at −40°) does not bend.
        assert_eq!(split(0.06, -40.0 * DEG, 0.6).bend, 0.0);
    }

    #[test]
    fn the_bend_grows_with_the_pitch_and_the_head_drop_is_kept() {
        let torso = 0.55;
        let mut last = -1.0;
        for pitch in [-10.0, -20.0, -30.0, -45.0, -60.0, -90.0] {
            let c = split(0.25, pitch * DEG, torso);
            assert!(c.bend >= last, "{pitch}: {c:?}");
            last = c.bend;
            // What the spine does not take, the hips do (beyond the dead band).
            let spine = torso * (1.0 - c.bend.cos());
            assert!((c.hips_drop + spine - (0.25 - CROUCH_DEADBAND)).abs() < 1e-5, "{pitch}: {c:?}");
        }
        assert_eq!(split(0.25, -10.0 * DEG, torso).bend, 0.0);
    }

    #[test]
    fn garbage_is_no_crouch_and_no_torso_is_no_bend() {
        for (d, p, l) in [(f32::NAN, 0.0, 0.6), (-0.2, -1.0, 0.6), (f32::INFINITY, -1.0, 0.6), (0.0, -1.0, 0.6)] {
            assert_eq!(split(d, p, l), Crouch::default(), "{d} {p} {l}");
        }
        let c = split(0.3, f32::NAN, 0.6);
        assert_eq!(c.bend, 0.0);
        for l in [0.0, f32::NAN, -1.0] {
            let c = split(0.3, -1.2, l);
            assert_eq!(c.bend, 0.0);
            assert!((c.hips_drop - 0.27).abs() < 1e-6);
        }
    }
}
