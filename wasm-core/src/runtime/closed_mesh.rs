//! Whether a triangle mesh is a closed surface wound outward: the test that lets an avatar's
//! double-sided materials draw front faces only (`web/src/avatar/closed-mesh.ts` says when and
//! why). Here rather than in the page's script because it runs while a page loads, when script
//! is not yet optimized: the shipped avatar's ~13k triangles took 11-19 ms of the page's main
//! thread in script, before its first frame.
//!
//! Closed: after welding vertices at equal positions (seams split them), each edge is shared by
//! exactly two triangles running it in opposite directions. Outward: the signed volume
//! (Σ p0 · (p1 × p2) over the triangles, 6 × the volume enclosed) is positive.

/// The positions of a mesh's vertices: vertex `i` at `values[i * stride..][..3]` (x, y, z, in
/// any positive scale: a quantized mesh's integers as they are), `stride` ≥ 3 (an interleaved
/// attribute's buffer as it is).
#[derive(Clone, Copy)]
pub struct Positions<'a> {
    pub values: &'a [f32],
    pub stride: usize,
}

impl Positions<'_> {
    /// How many vertices the values hold.
    fn len(&self) -> usize {
        if self.stride < 3 || self.values.len() < 3 {
            return 0;
        }
        (self.values.len() - 3) / self.stride + 1
    }

    fn get(&self, i: usize) -> [f32; 3] {
        let p = &self.values[i * self.stride..i * self.stride + 3];
        [p[0], p[1], p[2]]
    }
}

/// Whether the triangles over `positions` are a closed, consistently wound surface whose front
/// faces point out. `index`: three vertex indices per triangle; empty, the vertices taken in
/// threes. Anything malformed (too few triangles, an index past the vertices, a stride under 3)
/// is not closed.
pub fn is_closed_mesh(positions: Positions, index: &[u32]) -> bool {
    let n = positions.len();
    let count = if index.is_empty() { n } else { index.len() };
    if n < 4 || count < 12 || count % 3 != 0 || index.iter().any(|&i| i as usize >= n) {
        return false;
    }
    let welded = weld(positions, n);
    let corner = |k: usize| if index.is_empty() { k } else { index[k] as usize };
    // Edges in an open-addressed table keyed by their two ends (low, high), with the directions
    // they were run in: a closed, consistently wound surface runs each edge once each way, so
    // every key ends with both directions and none is run twice the same way. Counting keys and
    // keys with both directions answers without a pass over the table. Fibonacci hashing (the
    // product's high bits): the low bits of a product of small ids cluster under linear probing.
    let size = table_size(count); // more slots than keys (at most one per corner): never full
    let (mask, shift) = (size - 1, 32 - size.trailing_zeros());
    let mut low = vec![u32::MAX; size];
    let mut high = vec![0u32; size];
    let mut runs = vec![0u8; size];
    let (mut keys, mut paired) = (0usize, 0usize);
    let mut volume = 0.0f64;
    for t in (0..count).step_by(3) {
        let (i0, i1, i2) = (corner(t), corner(t + 1), corner(t + 2));
        let (a, b, c) = (welded[i0], welded[i1], welded[i2]);
        if a == b || b == c || c == a {
            continue; // degenerate: no area, never seen
        }
        for (p, q) in [(a, b), (b, c), (c, a)] {
            let (lo, hi, run) = if p < q { (p, q, 1u8) } else { (q, p, 2u8) };
            let mut h = (lo.wrapping_mul(0x9e37_79b1) ^ hi).wrapping_mul(0x85eb_ca77) >> shift;
            while low[h as usize] != u32::MAX && (low[h as usize] != lo || high[h as usize] != hi) {
                h = (h + 1) & mask as u32;
            }
            let h = h as usize;
            if low[h] == u32::MAX {
                (low[h], high[h], runs[h]) = (lo, hi, run);
                keys += 1;
            } else if runs[h] & run != 0 {
                return false; // the same edge run the same way twice
            } else {
                runs[h] |= run;
                paired += 1;
            }
        }
        let p = |i: usize| positions.get(i).map(f64::from);
        let ([x0, y0, z0], [x1, y1, z1], [x2, y2, z2]) = (p(i0), p(i1), p(i2));
        volume += x0 * (y1 * z2 - z1 * y2) + y0 * (z1 * x2 - x1 * z2) + z0 * (x1 * y2 - y1 * x2);
    }
    paired == keys && volume > 0.0 // an edge run one way only: a hole or a flipped triangle
}

/// A power of two at least twice `n` and at least 16 (open addressing stays short).
fn table_size(n: usize) -> usize {
    (2 * n).next_power_of_two().max(16)
}

/// An id per vertex of the first `n`, equal for vertices at the same position (a UV or normal
/// seam splits one): the first vertex with its bits. `+ 0.0` turns −0 into +0 (equal positions,
/// equal bits).
fn weld(positions: Positions, n: usize) -> Vec<u32> {
    let bits = |i: usize| positions.get(i).map(|v| (v + 0.0).to_bits());
    let size = table_size(n);
    let (mask, shift) = (size - 1, 32 - size.trailing_zeros());
    let mut first = vec![u32::MAX; size];
    let mut id = vec![0u32; n];
    let mut ids = 0u32;
    for i in 0..n {
        let [x, y, z] = bits(i);
        let mut h =
            ((x.wrapping_mul(0x9e37_79b1) ^ y).wrapping_mul(0x85eb_ca77) ^ z).wrapping_mul(0xc2b2_ae3d) >> shift;
        while first[h as usize] != u32::MAX && bits(first[h as usize] as usize) != [x, y, z] {
            h = (h + 1) & mask as u32;
        }
        let h = h as usize;
        if first[h] == u32::MAX {
            first[h] = i as u32;
            id[i] = ids;
            ids += 1;
        } else {
            id[i] = id[first[h] as usize];
        }
    }
    id
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube, each face its own four vertices (as seams split a model), wound outward.
    fn cube() -> (Vec<f32>, Vec<u32>) {
        let corners = |axis: usize, side: f32| -> [[f32; 3]; 4] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut out = [[0.0; 3]; 4];
            for (k, (a, b)) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)].into_iter().enumerate() {
                out[k][axis] = side;
                out[k][u] = a;
                out[k][v] = b;
            }
            if side == 0.0 {
                out.reverse(); // the far side of the axis faces the other way
            }
            out
        };
        let (mut positions, mut index) = (vec![], vec![]);
        for axis in 0..3 {
            for side in [0.0, 1.0] {
                let base = (positions.len() / 3) as u32;
                positions.extend(corners(axis, side).iter().flatten());
                index.extend([0, 1, 2, 0, 2, 3].map(|k| base + k));
            }
        }
        (positions, index)
    }

    fn xyz(values: &[f32]) -> Positions<'_> {
        Positions { values, stride: 3 }
    }

    #[test]
    fn a_cube_is_closed_and_outward() {
        let (p, i) = cube();
        assert!(is_closed_mesh(xyz(&p), &i));
        // Unindexed: the same triangles, their corners copied.
        let flat: Vec<f32> = i.iter().flat_map(|&k| p[3 * k as usize..3 * k as usize + 3].to_vec()).collect();
        assert!(is_closed_mesh(xyz(&flat), &[]));
        // In a quantized file's integers (any positive scale) and moved off the origin.
        let q: Vec<f32> = p.iter().map(|v| (v * 32767.0 + 5.0).round()).collect();
        assert!(is_closed_mesh(xyz(&q), &i));
        // Interleaved, four values a vertex (a quantized file pads its positions so), the last
        // vertex without its padding.
        let mut padded: Vec<f32> = p.chunks(3).flat_map(|v| [v[0], v[1], v[2], 9.0]).collect();
        padded.pop();
        assert!(is_closed_mesh(Positions { values: &padded, stride: 4 }, &i));
    }

    #[test]
    fn open_inside_out_flipped_and_malformed_are_not() {
        let (p, i) = cube();
        assert!(!is_closed_mesh(xyz(&p), &i[6..])); // a face missing
        let inward: Vec<u32> = i.chunks(3).flat_map(|t| [t[0], t[2], t[1]]).collect();
        assert!(!is_closed_mesh(xyz(&p), &inward)); // wound inward
        let mut flipped = i.clone();
        flipped.swap(1, 2); // one triangle against its neighbours
        assert!(!is_closed_mesh(xyz(&p), &flipped));
        let mut past = i.clone();
        past[4] = 1000; // an index past the vertices: no panic, not closed
        assert!(!is_closed_mesh(xyz(&p), &past));
        assert!(!is_closed_mesh(xyz(&p), &i[..9])); // too few triangles
        assert!(!is_closed_mesh(xyz(&p[..6]), &[])); // too few vertices
        assert!(!is_closed_mesh(Positions { values: &p, stride: 2 }, &i)); // not a stride
        assert!(!is_closed_mesh(Positions { values: &p, stride: 0 }, &i));
        let nan: Vec<f32> = p.iter().map(|_| f32::NAN).collect();
        assert!(!is_closed_mesh(xyz(&nan), &i)); // no volume
    }
}
