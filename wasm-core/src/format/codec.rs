//! The encodings of the big per-frame arrays (docs/mmdb-format.md, "Pose arrays"): what the
//! runtime reads, in fewer bytes, and laid out so that HTTP compression finds the redundancy
//! that is there (poses change slowly from frame to frame).
//!
//! - `PANM`: local positions only for the joints whose position ever differs from the skeleton's
//!   rest offset (the virtual root and the hips in a mocap database), exact f32.
//! - `QROT`: local rotations quantized to 16 bits per component (error bound below), stored
//!   component-planar (joint, component, frame) as the miss of a constant-velocity prediction
//!   from the two frames before (wrapping arithmetic, so decoding is exact), zigzag-coded and
//!   split into a low-byte and a high-byte plane: small numbers brotli packs well (version 2:
//!   plain first-order deltas).
//! - `FSHF` (version 2, and version 3 where deriving would cost too much): the feature matrix,
//!   exact f32, byte-planar (plane b = byte b of every value, values dimension-major): the
//!   sign/exponent plane of a slowly varying feature is nearly constant.
//! - Velocities and (version 3) features are not stored: a played frame's velocities come from
//!   [`crate::database::Database::frame_velocities`], the features from
//!   [`crate::database::Database::compute_features`].

use glam::{Quat, Vec3};

/// Quantization step of a rotation component: `c = round(x · 32767)`, `x ≈ c / 32767`.
pub const ROTATION_SCALE: f32 = 32767.0;

/// Largest angle (rad) between a unit quaternion and its decoded quantization. Rounding alone
/// puts each component off by at most ½/32767, so the whole by at most |δ| = √4·½/32767, and
/// the rotation angle, twice the part of δ orthogonal to q, by at most 2|δ| = 2/32767; the
/// stabilizing steps of [`quantize_rotation`] (1 % of rotations) move a component by one more
/// unit, for which 3/32767 ≈ 9.2e-5 rad (0.0052°) leaves room (a million random rotations:
/// worst 6.9e-5 rad, `quantization_is_stable_and_within_the_bound`).
pub const MAX_ROTATION_ERROR: f64 = 3.0 / 32767.0;

/// The angle between two rotations, in f64 (glam's f32 `angle_between` takes `acos` of a
/// dot product near 1 and cannot resolve angles below ~1e-3 rad).
pub fn angle(a: Quat, b: Quat) -> f64 {
    let d = a.as_dquat().conjugate() * b.as_dquat();
    2.0 * d.xyz().length().min(1.0).asin()
}

/// Joints whose local position differs (bit for bit) from `offsets[j]` in some frame.
pub fn animated_joints(positions: &[Vec3], offsets: &[Vec3]) -> Vec<u32> {
    let j = offsets.len();
    (0..j)
        .filter(|&k| positions.iter().skip(k).step_by(j.max(1)).any(|p| p.to_array() != offsets[k].to_array()))
        .map(|k| k as u32)
        .collect()
}

/// `PANM`: `u32` count `A`, `A` strictly increasing `u32` joint indices (`animated`, from
/// [`animated_joints`] over every frame, derived ones included), then `F×A×3` f32.
pub fn encode_positions(positions: &[Vec3], offsets: &[Vec3], animated: &[u32]) -> Vec<u8> {
    let j = offsets.len().max(1);
    let frames = positions.len() / j;
    let mut out = Vec::with_capacity(4 + 4 * animated.len() + 12 * frames * animated.len());
    out.extend_from_slice(&(animated.len() as u32).to_le_bytes());
    for &k in animated {
        out.extend_from_slice(&k.to_le_bytes());
    }
    for f in 0..frames {
        for &k in animated {
            for c in positions[f * j + k as usize].to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    out
}

/// Decodes `PANM` into `F×J` positions, the other joints at their rest offsets, and which
/// joints it animates.
///
/// # Errors
/// A message naming the field: a count or index out of range, indices out of order, or a
/// length that is not what the count implies.
pub fn decode_positions(data: &[u8], frames: usize, offsets: &[Vec3]) -> Result<(Vec<Vec3>, Vec<bool>), String> {
    let j = offsets.len();
    let word = |i: usize| data.get(4 * i..4 * i + 4).map(|b| u32::from_le_bytes(b.try_into().unwrap_or_default()));
    let count = word(0).ok_or("PANM: shorter than its joint count")? as usize;
    if count > j {
        return Err(format!("PANM: {count} animated joints but the skeleton has {j}"));
    }
    let expected = frames.checked_mul(count).and_then(|n| n.checked_mul(12)).and_then(|n| n.checked_add(4 + 4 * count));
    if expected != Some(data.len()) {
        return Err(format!(
            "PANM is {} bytes; {count} animated joints over {frames} frames need {}",
            data.len(),
            4 + 4 * count + 12 * frames * count
        ));
    }
    let mut animated = Vec::with_capacity(count);
    for i in 0..count {
        let k = word(1 + i).unwrap_or(u32::MAX) as usize;
        if k >= j || animated.last().is_some_and(|&last| k <= last) {
            return Err(format!("PANM: animated joint {i} is {k}; indices must increase and be below {j}"));
        }
        animated.push(k);
    }
    let mut positions = Vec::with_capacity(frames * j);
    for _ in 0..frames {
        positions.extend_from_slice(offsets);
    }
    let values: &[u8] = &data[4 + 4 * count..];
    for (i, chunk) in values.chunks_exact(12).enumerate() {
        let (f, a) = (i / count, i % count);
        let c = |o: usize| f32::from_le_bytes(chunk[o..o + 4].try_into().unwrap_or_default());
        positions[f * j + animated[a]] = Vec3::new(c(0), c(4), c(8));
    }
    let mut mask = vec![false; j];
    animated.iter().for_each(|&k| mask[k] = true);
    Ok((positions, mask))
}

/// `QROT`: `F×J×4` i16, component-planar and delta-coded (see the module comment).
pub fn encode_rotations(rotations: &[Quat], joints: usize) -> Vec<u8> {
    let frames = rotations.len() / joints.max(1);
    let n = rotations.len() * 4;
    let mut out = vec![0u8; n * 2];
    let mut i = 0;
    for k in 0..joints {
        for c in 0..4 {
            let (mut previous, mut before) = (0i16, 0i16);
            for f in 0..frames {
                let q = quantize_rotation(rotations[f * joints + k])[c];
                // What the two frames before predict (constant velocity), and the zigzag code of
                // the miss: small misses of either sign become small unsigned numbers.
                let residual = q.wrapping_sub(previous.wrapping_mul(2)).wrapping_add(before);
                let code = ((residual << 1) ^ (residual >> 15)) as u16;
                (out[i], out[n + i]) = (code as u8, (code >> 8) as u8);
                (before, previous, i) = (previous, q, i + 1);
            }
        }
    }
    out
}

/// The 16-bit components `QROT` stores for a unit quaternion: `round(x · 32767)`, then, while
/// that is not what its own decoded rotation quantizes to, the quantization of the decoded
/// rotation (at most [`STABLE_STEPS`] times). A stable value decodes to a rotation that
/// quantizes back to it, so a database written, read and written again keeps the same bits —
/// and the features derived from its poses (`crate::pose_features`) stay the same too.
pub fn quantize_rotation(q: Quat) -> [i16; 4] {
    let round =
        |q: Quat| q.to_array().map(|x| (x * ROTATION_SCALE).round().clamp(-ROTATION_SCALE, ROTATION_SCALE) as i16);
    let mut c = round(q);
    for _ in 0..STABLE_STEPS {
        let next = round(dequantize_rotation(c));
        // Only the last unit moves for a unit quaternion; anything more is not one, and is
        // written as it is (the reader then names it).
        if next == c || next.iter().zip(&c).any(|(a, b)| (a - b).abs() > 1) {
            break;
        }
        c = next;
    }
    c
}

/// Most re-quantizations [`quantize_rotation`] tries before it keeps what it has.
pub const STABLE_STEPS: usize = 4;

/// The unit quaternion 16-bit components stand for: `normalize(c)` (the decoder's rule).
pub fn dequantize_rotation(c: [i16; 4]) -> Quat {
    Quat::from_array(c.map(f32::from)).normalize()
}

/// Decodes `QROT` into normalized `F×J` quaternions: version 3's second-order zigzag code in
/// two byte planes (`second_order`), or version 2's first-order deltas.
///
/// # Errors
/// A length that is not `F·J·8` bytes, or a decoded quaternion whose length is not 1 within
/// the tolerance (`|‖c‖²/32767² − 1| > tolerance`): corruption, not quantization.
pub fn decode_rotations(
    data: &[u8],
    frames: usize,
    joints: usize,
    tolerance: f32,
    second_order: bool,
) -> Result<Vec<Quat>, String> {
    let n = frames.checked_mul(joints).ok_or("QROT: counts overflow")?;
    if n.checked_mul(8) != Some(data.len()) {
        return Err(format!(
            "QROT is {} bytes; {frames} frames × {joints} joints need {}",
            data.len(),
            n.saturating_mul(8)
        ));
    }
    // Frame-outer: the 4·J running sums advance together, so the output is written in order
    // while the input is read as 4·J sequential streams (the planar order is for compression,
    // not for this loop; the transposed loop writes one component per cache line and is ~3×
    // slower here).
    let planes = joints * 4;
    // Little-endian i16s (the crate refuses to build big-endian); copied only when the section
    // is not 2-byte aligned in memory.
    let owned;
    let values: &[i16] = if second_order {
        // Back to residuals: byte planes joined, zigzag undone.
        let (low, high) = data.split_at(n * 4);
        owned = low
            .iter()
            .zip(high)
            .map(|(&l, &h)| {
                let code = u16::from(l) | (u16::from(h) << 8);
                ((code >> 1) as i16) ^ -((code & 1) as i16)
            })
            .collect::<Vec<i16>>();
        &owned
    } else {
        match bytemuck::try_cast_slice(data) {
            Ok(v) => v,
            Err(_) => {
                owned = bytemuck::pod_collect_to_vec::<u8, i16>(data);
                &owned
            }
        }
    };
    let mut sums = vec![0i16; planes];
    let mut before = vec![0i16; if second_order { planes } else { 0 }];
    let scale2 = ROTATION_SCALE * ROTATION_SCALE;
    let mut rotations = Vec::with_capacity(n);
    for f in 0..frames {
        for k in 0..joints {
            let mut c = [0f32; 4];
            for (j, value) in c.iter_mut().enumerate() {
                let p = 4 * k + j;
                let d = values[p * frames + f];
                if second_order {
                    let c = d.wrapping_add(sums[p].wrapping_mul(2)).wrapping_sub(before[p]);
                    (before[p], sums[p]) = (sums[p], c);
                } else {
                    sums[p] = sums[p].wrapping_add(d);
                }
                *value = sums[p] as f32;
            }
            let q = Quat::from_array(c);
            if (q.length_squared() / scale2 - 1.0).abs() > tolerance {
                return Err(format!(
                    "QROT: frame {f} joint {k} is not a unit quaternion ({:?} / 32767)",
                    c.map(|x| x as i16)
                ));
            }
            rotations.push(q.normalize());
        }
    }
    Ok(rotations)
}

/// `FSHF`: the `F×D` feature matrix as 4 byte planes of its dimension-major values.
pub fn shuffle_features(features: &[f32], dims: usize) -> Vec<u8> {
    let frames = features.len() / dims.max(1);
    let n = features.len();
    let mut out = vec![0u8; n * 4];
    for d in 0..dims {
        for f in 0..frames {
            let bytes = features[f * dims + d].to_le_bytes();
            let i = d * frames + f;
            for (b, byte) in bytes.iter().enumerate() {
                out[b * n + i] = *byte;
            }
        }
    }
    out
}

/// Decodes `FSHF` into the `F×D` feature matrix.
///
/// # Errors
/// A length that is not `F·D·4` bytes.
pub fn unshuffle_features(data: &[u8], frames: usize, dims: usize) -> Result<Vec<f32>, String> {
    let n = frames.checked_mul(dims).ok_or("FSHF: counts overflow")?;
    if n.checked_mul(4) != Some(data.len()) {
        return Err(format!(
            "FSHF is {} bytes; {frames} frames × {dims} dims need {}",
            data.len(),
            n.saturating_mul(4)
        ));
    }
    let mut features = vec![0.0f32; n];
    for d in 0..dims {
        for f in 0..frames {
            let i = d * frames + f;
            features[f * dims + d] = f32::from_le_bytes([data[i], data[n + i], data[2 * n + i], data[3 * n + i]]);
        }
    }
    Ok(features)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    #[test]
    fn rotations_round_trip_within_the_quantization_bound() {
        let mut rng = Rng(7);
        let (frames, joints) = (50, 3);
        let rotations: Vec<Quat> = (0..frames * joints)
            .map(|_| {
                Quat::from_xyzw(
                    rng.uniform(-1.0, 1.0),
                    rng.uniform(-1.0, 1.0),
                    rng.uniform(-1.0, 1.0),
                    rng.uniform(-1.0, 1.0),
                )
                .normalize()
            })
            .collect();
        let decoded = decode_rotations(&encode_rotations(&rotations, joints), frames, joints, 1e-3, true).unwrap();
        for (a, b) in rotations.iter().zip(&decoded) {
            assert!(angle(*a, *b) <= MAX_ROTATION_ERROR, "{a} vs {b}: {} rad", angle(*a, *b));
        }
    }

    /// The stable quantization: over a million random rotations, every one within the bound of
    /// its original, and its decoded rotation quantizes back to the same 16-bit values (so a
    /// database written, read and written again keeps its bits).
    #[test]
    fn quantization_is_stable_and_within_the_bound() {
        let mut rng = Rng(11);
        let (mut worst, mut unstable, mut moved) = (0.0f64, 0, 0);
        for _ in 0..1_000_000 {
            let q = Quat::from_xyzw(
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
            )
            .normalize();
            let c = quantize_rotation(q);
            let first = q.to_array().map(|x| (x * ROTATION_SCALE).round() as i16);
            moved += (c != first) as usize;
            let back = dequantize_rotation(c);
            worst = worst.max(angle(q, back));
            unstable += (quantize_rotation(back) != c) as usize;
        }
        println!("stable quantization: worst {worst:e} rad (bound {MAX_ROTATION_ERROR:e}), {moved} of 1e6 moved from the first rounding, {unstable} unstable");
        assert!(worst <= MAX_ROTATION_ERROR, "{worst}");
        assert_eq!(unstable, 0);
    }

    #[test]
    fn positions_keep_only_what_moves_exactly() {
        let offsets = [Vec3::ZERO, Vec3::Y, Vec3::X];
        let positions: Vec<Vec3> = (0..4).flat_map(|f| [Vec3::new(f as f32, 0.0, 0.5), Vec3::Y, Vec3::X]).collect();
        let bytes = encode_positions(&positions, &offsets, &animated_joints(&positions, &offsets));
        assert_eq!(bytes.len(), 4 + 4 + 4 * 12);
        assert_eq!(decode_positions(&bytes, 4, &offsets).unwrap(), (positions, vec![true, false, false]));
    }

    #[test]
    fn features_round_trip_bit_exact() {
        let features: Vec<f32> =
            (0..35).map(|i| (i as f32 * 0.37).sin() * 1e3).chain([f32::MIN_POSITIVE, -0.0]).collect();
        assert_eq!(unshuffle_features(&shuffle_features(&features, 37), 1, 37).unwrap(), features);
        let features: Vec<f32> = (0..36).map(|i| i as f32 - 7.5).collect();
        assert_eq!(unshuffle_features(&shuffle_features(&features, 4), 9, 4).unwrap(), features);
    }
}
