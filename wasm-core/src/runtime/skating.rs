//! Foot skating as the runtime measures it on its own shown pose (the HUD's figure, the foot
//! lock's floor height) and as every harness measures it (`quality`, `vr_replay`): one meter, in
//! the runtime, so the runtime needs nothing from its harnesses.

use glam::{Vec2, Vec3};

/// Foot skating, the one measure of the product (quality harness, VR replay bench, tests): the
/// horizontal distance each shown toe travels in frames where the frame playing says that foot
/// is planted (its contact flag) and the toe is on the floor (less than [`ON_FLOOR`] above the
/// planted toe height, when the character knows it), summed over both toes, in metres.
///
/// Why contacts and not toe height alone (Holden's `2 − 2^(h/H)` weight below H = 3.3 cm): with
/// the height measured from the planted toe height, a normal walk's swing (toe clearance 1–3 cm)
/// counts as skating (~40 cm/s on a clean straight walk); measured from y = 0, CMU toes (2–4 cm
/// above the floor when planted) almost never count. The contact flag says when a foot should
/// be still; the height, whether it is: a foot the lock lifts to step back under a dragged body
/// (`ik::FootLock`) is stepping, not sliding.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SkatingMeter {
    previous: Option<[Vec3; 2]>,
    /// Distance so far (m).
    pub distance: f32,
}

/// A toe higher than this above the planted toe height (m) is off the floor: Holden's H.
pub const ON_FLOOR: f32 = 0.033;

impl SkatingMeter {
    /// Forgets the previous toes and the distance (after a teleport).
    pub fn reset(&mut self) {
        *self = SkatingMeter::default();
    }

    /// Adds one frame: the toes now (world, Y up), the contact flags of the frame playing and the
    /// planted toe height (`None`: every toe in contact counts).
    pub fn update(&mut self, toes: [Vec3; 2], contacts: [u8; 2], floor: Option<f32>) {
        if let Some(previous) = self.previous {
            for side in 0..2 {
                let on_floor = floor.is_none_or(|h| toes[side].y - h < ON_FLOOR);
                if contacts[side] != 0 && on_floor {
                    let (a, b) = (toes[side], previous[side]);
                    self.distance += Vec2::new(a.x - b.x, a.z - b.z).length();
                }
            }
        }
        self.previous = Some(toes);
    }
}
