//! Deterministic random numbers (SplitMix64, Steele et al. 2014) for property tests and
//! seeded scenarios: reproducible everywhere, no dependency.

use glam::{Quat, Vec3, Vec4};

/// A SplitMix64 generator; the field is the state (any seed is fine).
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (n > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// Uniform in [0, 1), 24 bits.
    pub fn unit_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit_f32()
    }

    /// Roughly standard normal (sum of four uniforms, unit variance).
    pub fn normal(&mut self) -> f32 {
        ((0..4).map(|_| self.unit_f32()).sum::<f32>() - 2.0) * 3f32.sqrt()
    }

    /// Uniform in the cube [−r, r]³.
    pub fn vec3(&mut self, r: f32) -> Vec3 {
        Vec3::new(self.uniform(-r, r), self.uniform(-r, r), self.uniform(-r, r))
    }

    /// A uniformly distributed direction.
    pub fn unit_vector(&mut self) -> Vec3 {
        loop {
            let v = self.vec3(1.0);
            if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                return v.normalize();
            }
        }
    }

    /// A uniformly distributed rotation (normalized point of the 4-ball).
    pub fn quat(&mut self) -> Quat {
        loop {
            let v = Vec4::new(
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
            );
            let l = v.length();
            if l > 0.1 && l <= 1.0 {
                return Quat::from_vec4(v / l);
            }
        }
    }

    /// A rotation about a random axis by an angle uniform in ±3.1 rad.
    pub fn axis_angle_quat(&mut self) -> Quat {
        Quat::from_axis_angle(self.unit_vector(), self.uniform(-3.1, 3.1))
    }
}
