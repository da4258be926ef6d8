//! A 4-wide f32 vector on WASM SIMD128 / x86 SSE, scalar elsewhere, for the search kernels and
//! the inertializer's rotation offsets ([`Vec3x4`]: four 3-vectors, component-planar).
//!
//! The backend is chosen at compile time: `core::arch::wasm32` v128 when the WASM build
//! enables `simd128` (scripts/setup.mjs passes `-C target-feature=+simd128`), SSE on x86_64
//! (always present there), and a plain `[f32; 4]` otherwise. Every lane operation is one IEEE
//! operation per lane, so a lane computes bit-for-bit what scalar code computes with the same
//! operations in the same order — the search relies on this to equal the scalar reference
//! exactly.

use std::ops::{Add, AddAssign, Mul, Sub};

#[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
use core::arch::wasm32 as arch;
#[cfg(target_arch = "x86_64")]
use core::arch::x86_64 as arch;

#[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
type Inner = arch::v128;
#[cfg(target_arch = "x86_64")]
type Inner = arch::__m128;
#[cfg(not(any(all(target_arch = "wasm32", target_feature = "simd128"), target_arch = "x86_64")))]
type Inner = Fallback;

/// The scalar stand-in, aligned like the SIMD registers so the memory layout is the same.
#[cfg(not(any(all(target_arch = "wasm32", target_feature = "simd128"), target_arch = "x86_64")))]
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Fallback([f32; 4]);

/// Which backend this build uses: `"simd128"`, `"sse"` or `"scalar"`.
pub const BACKEND: &str = if cfg!(all(target_arch = "wasm32", target_feature = "simd128")) {
    "simd128"
} else if cfg!(target_arch = "x86_64") {
    "sse"
} else {
    "scalar"
};

/// Four f32 lanes, 16-byte aligned. Lane `i` of every operation is the scalar operation on
/// lane `i` of the operands.
#[derive(Clone, Copy)]
#[repr(transparent)]
pub struct F32x4(Inner);

/// The result of a lane comparison: one boolean per lane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mask4(u32);

impl Mask4 {
    /// Bit `i` set when lane `i` is true.
    #[inline(always)]
    pub fn bitmask(self) -> u32 {
        self.0
    }
    /// Whether any lane is true.
    #[inline(always)]
    pub fn any(self) -> bool {
        self.0 != 0
    }
}

impl F32x4 {
    pub const ZERO: Self = Self::from_array([0.0; 4]);
    pub const INFINITY: Self = Self::from_array([f32::INFINITY; 4]);
    pub const NEG_INFINITY: Self = Self::from_array([f32::NEG_INFINITY; 4]);

    /// Lanes from an array, lane `i` = `a[i]`.
    #[inline(always)]
    pub const fn from_array(a: [f32; 4]) -> Self {
        // SAFETY: every backend is 16 plain bytes holding four f32 in lane order.
        F32x4(unsafe { core::mem::transmute::<[f32; 4], Inner>(a) })
    }

    #[inline(always)]
    pub fn to_array(self) -> [f32; 4] {
        // SAFETY: as in `from_array`.
        unsafe { core::mem::transmute::<Inner, [f32; 4]>(self.0) }
    }

    /// The first four values of `slice`.
    ///
    /// # Panics
    /// If `slice` has fewer than 4 elements.
    #[inline(always)]
    pub fn from_slice(slice: &[f32]) -> Self {
        Self::from_array(slice[..4].try_into().unwrap())
    }

    /// Writes the lanes to the first four elements of `slice`.
    ///
    /// # Panics
    /// If `slice` has fewer than 4 elements.
    #[inline(always)]
    pub fn write_to_slice(self, slice: &mut [f32]) {
        slice[..4].copy_from_slice(&self.to_array());
    }

    /// All lanes `v`.
    #[inline(always)]
    pub fn splat(v: f32) -> Self {
        #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
        return F32x4(arch::f32x4_splat(v));
        #[cfg(target_arch = "x86_64")]
        #[allow(unused_unsafe)]
        // SAFETY: SSE is part of the x86_64 baseline.
        return F32x4(unsafe { arch::_mm_set1_ps(v) });
        #[cfg(not(any(all(target_arch = "wasm32", target_feature = "simd128"), target_arch = "x86_64")))]
        return Self::from_array([v; 4]);
    }

    /// Lane-wise minimum. Which operand is returned for NaN or for `-0.0` vs `0.0` is
    /// unspecified (the instructions differ across backends).
    #[inline(always)]
    pub fn min(self, rhs: Self) -> Self {
        #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
        // `pmin` (rhs < self ? rhs : self) is one `minps` on x86 hosts; `f32x4_min` needs
        // extra instructions for its NaN rules, which the search does not need.
        return F32x4(arch::f32x4_pmin(self.0, rhs.0));
        #[cfg(target_arch = "x86_64")]
        #[allow(unused_unsafe)]
        // SAFETY: SSE is part of the x86_64 baseline.
        return F32x4(unsafe { arch::_mm_min_ps(self.0, rhs.0) });
        #[cfg(not(any(all(target_arch = "wasm32", target_feature = "simd128"), target_arch = "x86_64")))]
        return self.zip(rhs, |a, b| if b < a { b } else { a });
    }

    /// Lane-wise maximum; NaN and signed zeros as in [`Self::min`].
    #[inline(always)]
    pub fn max(self, rhs: Self) -> Self {
        #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
        return F32x4(arch::f32x4_pmax(self.0, rhs.0));
        #[cfg(target_arch = "x86_64")]
        #[allow(unused_unsafe)]
        // SAFETY: SSE is part of the x86_64 baseline.
        return F32x4(unsafe { arch::_mm_max_ps(self.0, rhs.0) });
        #[cfg(not(any(all(target_arch = "wasm32", target_feature = "simd128"), target_arch = "x86_64")))]
        return self.zip(rhs, |a, b| if a < b { b } else { a });
    }

    /// Lanes where `self < rhs` (false for NaN).
    #[inline(always)]
    pub fn cmplt(self, rhs: Self) -> Mask4 {
        #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
        return Mask4(arch::i32x4_bitmask(arch::f32x4_lt(self.0, rhs.0)) as u32);
        #[cfg(target_arch = "x86_64")]
        #[allow(unused_unsafe)]
        // SAFETY: SSE is part of the x86_64 baseline.
        return Mask4(unsafe { arch::_mm_movemask_ps(arch::_mm_cmplt_ps(self.0, rhs.0)) } as u32);
        #[cfg(not(any(all(target_arch = "wasm32", target_feature = "simd128"), target_arch = "x86_64")))]
        {
            let (a, b) = (self.to_array(), rhs.to_array());
            Mask4((0..4).fold(0, |m, i| m | (((a[i] < b[i]) as u32) << i)))
        }
    }

    /// Lanes where `self ≤ rhs` (false for NaN).
    #[inline(always)]
    pub fn cmple(self, rhs: Self) -> Mask4 {
        #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
        return Mask4(arch::i32x4_bitmask(arch::f32x4_le(self.0, rhs.0)) as u32);
        #[cfg(target_arch = "x86_64")]
        #[allow(unused_unsafe)]
        // SAFETY: SSE is part of the x86_64 baseline.
        return Mask4(unsafe { arch::_mm_movemask_ps(arch::_mm_cmple_ps(self.0, rhs.0)) } as u32);
        #[cfg(not(any(all(target_arch = "wasm32", target_feature = "simd128"), target_arch = "x86_64")))]
        {
            let (a, b) = (self.to_array(), rhs.to_array());
            Mask4((0..4).fold(0, |m, i| m | (((a[i] <= b[i]) as u32) << i)))
        }
    }

    /// Sum of the lanes, as `(x0 + x1) + (x2 + x3)`.
    #[inline(always)]
    pub fn element_sum(self) -> f32 {
        let a = self.to_array();
        (a[0] + a[1]) + (a[2] + a[3])
    }

    /// Smallest lane (NaN lanes are skipped unless all are NaN).
    #[inline(always)]
    pub fn element_min(self) -> f32 {
        let a = self.to_array();
        a[0].min(a[1]).min(a[2].min(a[3]))
    }

    /// Largest lane (NaN lanes are skipped unless all are NaN).
    #[inline(always)]
    pub fn element_max(self) -> f32 {
        let a = self.to_array();
        a[0].max(a[1]).max(a[2].max(a[3]))
    }

    #[cfg(not(any(all(target_arch = "wasm32", target_feature = "simd128"), target_arch = "x86_64")))]
    #[inline(always)]
    fn zip(self, rhs: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let (a, b) = (self.to_array(), rhs.to_array());
        Self::from_array([f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]), f(a[3], b[3])])
    }
}

/// Implements a binary operator with the wasm32 intrinsic, the SSE intrinsic, or per lane.
macro_rules! lane_op {
    ($trait:ident, $method:ident, $wasm:ident, $sse:ident, $op:tt) => {
        impl $trait for F32x4 {
            type Output = F32x4;
            #[inline(always)]
            fn $method(self, rhs: F32x4) -> F32x4 {
                #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
                return F32x4(arch::$wasm(self.0, rhs.0));
                #[cfg(target_arch = "x86_64")]
                #[allow(unused_unsafe)]
                // SAFETY: SSE is part of the x86_64 baseline.
                return F32x4(unsafe { arch::$sse(self.0, rhs.0) });
                #[cfg(not(any(all(target_arch = "wasm32", target_feature = "simd128"), target_arch = "x86_64")))]
                return self.zip(rhs, |a, b| a $op b);
            }
        }
    };
}

lane_op!(Add, add, f32x4_add, _mm_add_ps, +);
lane_op!(Sub, sub, f32x4_sub, _mm_sub_ps, -);
lane_op!(Mul, mul, f32x4_mul, _mm_mul_ps, *);

/// Whether every value is finite, without a branch per value: `x · 0` is 0 for a finite `x`
/// and NaN for ±∞ or NaN, so the sum of those products is 0 exactly when all are finite (and
/// cannot overflow). Four at a time: a character checks its whole world pose every update,
/// where testing its 224 floats one by one was 4 % of the update's instructions in V8.
pub fn all_finite(values: &[f32]) -> bool {
    let (zero, mut acc) = (F32x4::ZERO, F32x4::ZERO);
    let mut chunks = values.chunks_exact(4);
    for c in chunks.by_ref() {
        acc += F32x4::from_slice(c) * zero;
    }
    let rest = chunks.remainder().iter().fold(0.0, |a, &x| a + x * 0.0);
    acc.element_sum() + rest == 0.0
}

/// Views lane vectors as their floats, lane by lane: element `4·i + l` is lane `l` of `v[i]`.
#[inline(always)]
pub fn as_f32_slice(v: &[F32x4]) -> &[f32] {
    // SAFETY: F32x4 is 16 bytes of four f32 with no padding, alignment 16 ≥ 4, and the length
    // in floats is exactly 4× the length in vectors.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<f32>(), v.len() * 4) }
}

impl AddAssign for F32x4 {
    #[inline(always)]
    fn add_assign(&mut self, rhs: F32x4) {
        *self = *self + rhs;
    }
}

impl Default for F32x4 {
    fn default() -> Self {
        Self::ZERO
    }
}

impl PartialEq for F32x4 {
    /// Lane-wise IEEE equality of all four lanes.
    fn eq(&self, other: &Self) -> bool {
        self.to_array() == other.to_array()
    }
}

impl core::fmt::Debug for F32x4 {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_tuple("F32x4").field(&self.to_array()).finish()
    }
}

impl From<[f32; 4]> for F32x4 {
    fn from(a: [f32; 4]) -> Self {
        Self::from_array(a)
    }
}

/// Four 3-vectors stored component-planar (`x` holds the four x's): four joints' vectors
/// moved by one set of lane operations.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3x4 {
    pub x: F32x4,
    pub y: F32x4,
    pub z: F32x4,
}

impl Vec3x4 {
    pub const ZERO: Vec3x4 = Vec3x4 { x: F32x4::ZERO, y: F32x4::ZERO, z: F32x4::ZERO };

    /// Vector `lane` (0..4).
    #[inline(always)]
    pub fn lane(&self, lane: usize) -> glam::Vec3 {
        glam::Vec3::new(self.x.to_array()[lane], self.y.to_array()[lane], self.z.to_array()[lane])
    }

    /// The four vectors.
    #[inline(always)]
    pub fn to_vec3s(self) -> [glam::Vec3; 4] {
        let (x, y, z) = (self.x.to_array(), self.y.to_array(), self.z.to_array());
        std::array::from_fn(|l| glam::Vec3::new(x[l], y[l], z[l]))
    }

    /// Four vectors into lanes 0..4.
    #[inline(always)]
    pub fn from_vec3s(v: [glam::Vec3; 4]) -> Vec3x4 {
        Vec3x4 {
            x: F32x4::from_array(v.map(|v| v.x)),
            y: F32x4::from_array(v.map(|v| v.y)),
            z: F32x4::from_array(v.map(|v| v.z)),
        }
    }

    /// Sets vector `lane` (0..4); the others are kept.
    pub fn set_lane(&mut self, lane: usize, v: glam::Vec3) {
        for (c, value) in [(&mut self.x, v.x), (&mut self.y, v.y), (&mut self.z, v.z)] {
            let mut a = c.to_array();
            a[lane] = value;
            *c = F32x4::from_array(a);
        }
    }

    /// `x² + y² + z²` per lane, summed left to right.
    #[inline(always)]
    pub fn length_squared(self) -> F32x4 {
        self.x * self.x + self.y * self.y + self.z * self.z
    }
}

impl Add for Vec3x4 {
    type Output = Vec3x4;
    #[inline(always)]
    fn add(self, r: Vec3x4) -> Vec3x4 {
        Vec3x4 { x: self.x + r.x, y: self.y + r.y, z: self.z + r.z }
    }
}

impl Sub for Vec3x4 {
    type Output = Vec3x4;
    #[inline(always)]
    fn sub(self, r: Vec3x4) -> Vec3x4 {
        Vec3x4 { x: self.x - r.x, y: self.y - r.y, z: self.z - r.z }
    }
}

impl Mul<F32x4> for Vec3x4 {
    type Output = Vec3x4;
    #[inline(always)]
    fn mul(self, k: F32x4) -> Vec3x4 {
        Vec3x4 { x: self.x * k, y: self.y * k, z: self.z * k }
    }
}

/// Every lane times one scalar: a [`crate::spring::SpringValue`], so the springs move four
/// vectors with the operations they use on one.
impl Mul<f32> for Vec3x4 {
    type Output = Vec3x4;
    #[inline(always)]
    fn mul(self, k: f32) -> Vec3x4 {
        self * F32x4::splat(k)
    }
}

/// Every lane `v` (as [`F32x4::splat`]), for code written once for lanes and scalars.
impl From<f32> for F32x4 {
    #[inline(always)]
    fn from(v: f32) -> Self {
        Self::splat(v)
    }
}

impl From<F32x4> for [f32; 4] {
    fn from(v: F32x4) -> Self {
        v.to_array()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_finite_finds_any_infinity_or_nan_anywhere() {
        let values: Vec<f32> = (0..23).map(|i| (i as f32 - 11.0) * 1e37).collect();
        assert!(all_finite(&values) && all_finite(&[]) && all_finite(&[f32::MAX, f32::MAX, -0.0]));
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            for at in 0..values.len() {
                let mut v = values.clone();
                v[at] = bad;
                assert!(!all_finite(&v), "{bad} at {at}");
            }
        }
    }

    const A: [f32; 4] = [1.5, -2.0, 3.25, f32::INFINITY];
    const B: [f32; 4] = [0.5, 4.0, -1.0, 2.0];

    fn per_lane(f: impl Fn(f32, f32) -> f32) -> [f32; 4] {
        [f(A[0], B[0]), f(A[1], B[1]), f(A[2], B[2]), f(A[3], B[3])]
    }

    #[test]
    fn layout_is_sixteen_aligned_bytes() {
        assert_eq!(std::mem::size_of::<F32x4>(), 16);
        assert_eq!(std::mem::align_of::<F32x4>(), 16);
    }

    #[test]
    fn arithmetic_matches_scalar_per_lane() {
        let (a, b) = (F32x4::from_array(A), F32x4::from_array(B));
        assert_eq!((a + b).to_array(), per_lane(|x, y| x + y));
        assert_eq!((a - b).to_array(), per_lane(|x, y| x - y));
        assert_eq!((a * b).to_array(), per_lane(|x, y| x * y));
        assert_eq!(a.min(b).to_array(), per_lane(f32::min));
        assert_eq!(a.max(b).to_array(), per_lane(f32::max));
        let mut acc = F32x4::ZERO;
        acc += a;
        acc += b;
        assert_eq!(acc.to_array(), per_lane(|x, y| 0.0 + x + y));
    }

    #[test]
    fn rounding_is_bit_identical_to_scalar() {
        // A chain where every step rounds: lanes must round like scalar f32 (no FMA, no
        // flush to zero), including subnormal results.
        let xs = [0.1f32, 1.0e-20, 3.3333333, 7.0e-39];
        let ys = [0.7f32, 3.0e-19, 1.1, 0.5];
        let v = (F32x4::from_array(xs) - F32x4::from_array(ys)) * F32x4::from_array(xs) * F32x4::from_array(ys)
            + F32x4::splat(1e-30);
        let scalar: Vec<f32> = (0..4).map(|i| (xs[i] - ys[i]) * xs[i] * ys[i] + 1e-30).collect();
        for (l, s) in v.to_array().iter().zip(&scalar) {
            assert_eq!(l.to_bits(), s.to_bits());
        }
    }

    #[test]
    fn splat_slices_and_arrays_round_trip() {
        assert_eq!(F32x4::splat(2.5).to_array(), [2.5; 4]);
        let data = [9.0, 1.0, 2.0, 3.0, 4.0];
        let v = F32x4::from_slice(&data[1..]);
        assert_eq!(v.to_array(), [1.0, 2.0, 3.0, 4.0]);
        let mut out = [0.0; 6];
        v.write_to_slice(&mut out[2..]);
        assert_eq!(out, [0.0, 0.0, 1.0, 2.0, 3.0, 4.0]);
        assert_eq!(<[f32; 4]>::from(F32x4::from(A)), A);
        assert_eq!(F32x4::default(), F32x4::ZERO);
        assert_eq!(F32x4::INFINITY.to_array(), [f32::INFINITY; 4]);
        assert_eq!(F32x4::NEG_INFINITY.to_array(), [f32::NEG_INFINITY; 4]);
        let vs = [F32x4::from_array(A), F32x4::from_array(B)];
        assert_eq!(as_f32_slice(&vs), [A, B].concat());
    }

    #[test]
    #[should_panic]
    fn from_slice_panics_when_short() {
        F32x4::from_slice(&[1.0, 2.0, 3.0]);
    }

    #[test]
    fn compare_gives_a_lane_bitmask() {
        let m = F32x4::from_array(A).cmplt(F32x4::from_array(B));
        // 1.5<0.5 no, -2<4 yes, 3.25<-1 no, inf<2 no
        assert_eq!(m.bitmask(), 0b0010);
        assert!(m.any());
        assert!(!F32x4::splat(1.0).cmplt(F32x4::splat(1.0)).any());
        assert_eq!(F32x4::ZERO.cmplt(F32x4::INFINITY).bitmask(), 0b1111);
        assert_eq!(F32x4::splat(f32::NAN).cmplt(F32x4::INFINITY).bitmask(), 0);
        assert_eq!(F32x4::from_array([1.0, 2.0, f32::NAN, 0.0]).cmple(F32x4::splat(1.0)).bitmask(), 0b1001);
        assert_eq!(F32x4::INFINITY.cmple(F32x4::INFINITY).bitmask(), 0b1111);
    }

    #[test]
    fn horizontal_reductions() {
        let v = F32x4::from_array([1.0, 2.0, 3.0, -4.0]);
        assert_eq!(v.element_sum(), 2.0);
        assert_eq!(v.element_min(), -4.0);
        assert_eq!(v.element_max(), 3.0);
        assert_eq!(F32x4::from_array(A).element_min(), -2.0);
    }

    #[test]
    fn backend_matches_the_target() {
        #[cfg(target_arch = "x86_64")]
        assert_eq!(BACKEND, "sse");
    }
}
