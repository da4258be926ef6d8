//! The closed-mesh test ([`crate::runtime::closed_mesh`]) for the page's avatars.

use wasm_bindgen::prelude::*;

/// Whether the triangles `index` (three vertex indices each; empty: the vertices in threes) over
/// `positions` (x, y, z per vertex, any positive scale) are a closed surface wound outward.
#[wasm_bindgen]
pub fn is_closed_mesh(positions: &[f32], index: &[u32]) -> bool {
    crate::runtime::closed_mesh::is_closed_mesh(positions, index)
}
