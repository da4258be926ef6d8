//! A take's local joint transforms while it is being built: frame-major SoA arrays in f64
//! (metres, Y up), so the database's FK reproduces the source within ~1e-6 m once stored as f32.

use glam::{DQuat, DVec3};

#[derive(Clone, Debug, Default)]
pub struct Poses {
    pub num_joints: usize,
    pub positions: Vec<DVec3>,
    pub rotations: Vec<DQuat>,
}

impl Poses {
    pub fn num_frames(&self) -> usize {
        self.positions.len().checked_div(self.num_joints).unwrap_or(0)
    }

    /// Empties the arrays, keeping their memory, for `num_joints` joints per frame.
    pub fn clear(&mut self, num_joints: usize) {
        self.num_joints = num_joints;
        self.positions.clear();
        self.rotations.clear();
    }

    /// Empties the arrays for `frames` frames of `num_joints` joints, with exactly that
    /// capacity when they must grow (the build's memory estimate counts on it:
    /// `limits::BuildFootprint`).
    pub fn reset(&mut self, num_joints: usize, frames: usize) {
        self.clear(num_joints);
        self.positions.reserve_exact(frames * num_joints);
        self.rotations.reserve_exact(frames * num_joints);
    }

    pub fn push(&mut self, position: DVec3, rotation: DQuat) {
        self.positions.push(position);
        self.rotations.push(rotation);
    }

    /// Joint `j` of frame `f`.
    pub fn at(&self, f: usize, j: usize) -> (DVec3, DQuat) {
        let i = f * self.num_joints + j;
        (self.positions[i], self.rotations[i])
    }
}
