//! The closed-mesh test ([`crate::runtime::closed_mesh`]) for the page's avatars.

use wasm_bindgen::prelude::*;

use crate::runtime::closed_mesh::Positions;

/// Whether the triangles `index` (three vertex indices each; empty: the vertices in threes) over
/// `positions` (vertex `i`'s x, y, z at `i * stride`, any positive scale) are a closed surface
/// wound outward.
#[wasm_bindgen]
pub fn is_closed_mesh(positions: &[f32], stride: u32, index: &[u32]) -> bool {
    crate::runtime::closed_mesh::is_closed_mesh(Positions { values: positions, stride: stride as usize }, index)
}
