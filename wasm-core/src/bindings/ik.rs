//! `RawTwoBoneIk`: the runtime's two-bone IK ([`crate::ik::two_bone_ik`]) for the avatar's arms
//! in TS. Inputs and outputs are preallocated buffers viewed from TS: nothing is allocated per call.

use crate::ik::two_bone_ik;
use glam::{Quat, Vec3};
use wasm_bindgen::prelude::*;

#[wasm_bindgen]
pub struct RawTwoBoneIk {
    /// a, b, c (root, middle, end positions), target, pole: 15 f32.
    input: [f32; 15],
    /// World deltas r_a, r_b (x, y, z, w each): 8 f32.
    output: [f32; 8],
}

#[wasm_bindgen]
impl RawTwoBoneIk {
    #[wasm_bindgen(constructor)]
    pub fn new() -> RawTwoBoneIk {
        RawTwoBoneIk { input: [0.0; 15], output: [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0] }
    }

    /// 15 f32 written by TS before [`Self::solve`]: root, middle and end joint positions, the
    /// target, the pole direction (world).
    pub fn input_ptr(&mut self) -> *mut f32 {
        self.input.as_mut_ptr()
    }
    /// 8 f32 after [`Self::solve`]: the world rotation deltas of the root and middle joints.
    pub fn output_ptr(&self) -> *const f32 {
        self.output.as_ptr()
    }

    /// Solves with reach margin `eps` (m). Non-finite inputs give identities.
    pub fn solve(&mut self, eps: f32) {
        let v = |k: usize| Vec3::from_slice(&self.input[3 * k..3 * k + 3]);
        let (r_a, r_b) = if self.input.iter().all(|x| x.is_finite()) {
            two_bone_ik(v(0), v(1), v(2), v(3), v(4), eps.max(0.0))
        } else {
            (Quat::IDENTITY, Quat::IDENTITY)
        };
        self.output[..4].copy_from_slice(&r_a.to_array());
        self.output[4..].copy_from_slice(&r_b.to_array());
    }
}

impl Default for RawTwoBoneIk {
    fn default() -> Self {
        Self::new()
    }
}
