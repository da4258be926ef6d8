//! The database's per-frame arrays, allocated once for every take and split into disjoint
//! per-clip slices that the takes fill independently (on all cores natively; WASM has one
//! thread) — the result is identical either way.

use glam::{Quat, Vec3};

/// Database arrays for all frames.
#[derive(Default)]
pub struct Accumulator {
    pub num_frames: usize,
    pub positions: Vec<Vec3>,
    pub rotations: Vec<Quat>,
    pub contacts: Vec<u8>,
}

impl Accumulator {
    /// The arrays for `num_frames` frames. The allocation is fallible: where memory runs out
    /// (wasm32's 4 GiB, shared with the page's other objects) the build gets an error, not an
    /// abort (a trap in WASM).
    ///
    /// # Errors
    /// The bytes that could not be had.
    pub fn new(num_frames: usize, num_joints: usize) -> Result<Accumulator, String> {
        fn filled<T: Clone>(n: usize, value: T) -> Result<Vec<T>, String> {
            let mut v = Vec::new();
            v.try_reserve_exact(n).map_err(|_| {
                format!(
                    "out of memory: {:.1} MB for the database's arrays could not be allocated",
                    (n * std::mem::size_of::<T>()) as f64 / 1e6
                )
            })?;
            v.resize(n, value);
            Ok(v)
        }
        Ok(Accumulator {
            num_frames,
            positions: filled(num_frames * num_joints, Vec3::ZERO)?,
            rotations: filled(num_frames * num_joints, Quat::IDENTITY)?,
            contacts: filled(num_frames * 2, 0)?,
        })
    }

    pub fn rows(&mut self) -> Rows<'_> {
        Rows { positions: &mut self.positions, rotations: &mut self.rotations, contacts: &mut self.contacts }
    }
}

/// Mutable views of consecutive database frames, written by one clip.
pub struct Rows<'a> {
    pub positions: &'a mut [Vec3],
    pub rotations: &'a mut [Quat],
    pub contacts: &'a mut [u8],
}

impl<'a> Rows<'a> {
    /// The same rows, borrowed for a shorter while.
    pub fn reborrow(&mut self) -> Rows<'_> {
        Rows { positions: self.positions, rotations: self.rotations, contacts: self.contacts }
    }

    /// The first `frames` frames, and the rest.
    pub fn split_at(self, frames: usize, joints: usize) -> (Rows<'a>, Rows<'a>) {
        let (p, p2) = self.positions.split_at_mut(frames * joints);
        let (r, r2) = self.rotations.split_at_mut(frames * joints);
        let (c, c2) = self.contacts.split_at_mut(frames * 2);
        (Rows { positions: p, rotations: r, contacts: c }, Rows { positions: p2, rotations: r2, contacts: c2 })
    }
}
