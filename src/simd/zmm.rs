//! Whole-register moves of 512-bit vectors (see `LaneMemory` in `simd`).

use std::arch::x86_64::{
    __m256d, __m512, __m512d, _mm512_castpd256_pd512, _mm512_castpd512_pd256,
    _mm512_extractf64x4_pd, _mm512_i32gather_ps, _mm512_insertf64x4, _mm512_loadu_ps,
    _mm512_loadu_si512, _mm512_storeu_ps,
};
use std::mem::transmute;

use wide::f32x8;

use super::F32x16;

// SAFETY (every block below): `F32x16` (`wide::f32x16` in this build) and `f32x8` are
// `wide`'s plain-data wrappers of one `__m512` and one `__m256` (repr(C), no padding, every
// bit pattern valid), so transmutes between them and same-sized intrinsic types are bit
// copies; the intrinsics' instruction sets (avx512f, and avx below it) are enabled at
// compile time (`cfg(target_feature = "avx512f")`); and the loads and stores touch the 16
// floats of a slice whose length the slicing has checked.

/// The first 16 values of `s`.
#[inline(always)]
pub fn load(s: &[f32]) -> F32x16 {
    let s = &s[..16];
    unsafe { transmute::<__m512, F32x16>(_mm512_loadu_ps(s.as_ptr())) }
}

/// Writes the 16 lanes to the first 16 values of `out`.
#[inline(always)]
pub fn store(v: F32x16, out: &mut [f32]) {
    let out = &mut out[..16];
    unsafe { _mm512_storeu_ps(out.as_mut_ptr(), transmute::<F32x16, __m512>(v)) }
}

/// `out[i] = base[index[i]]` for 4-byte `T`, every index already checked to be within
/// `base`, and `base` at most 2^31 - 1 elements long (`super::gather16`).
#[inline(always)]
pub fn gather32<T: Copy>(base: &[T], index: &[u32; 16], out: &mut [T; 16]) {
    debug_assert!(std::mem::size_of::<T>() == 4 && base.len() <= i32::MAX as usize);
    debug_assert!(index.iter().all(|&i| (i as usize) < base.len()));
    // SAFETY (besides the module's): every index is below `base.len() <= 2^31 - 1`
    // (checked by `gather16`), so it is a non-negative signed offset too, and each 4-byte
    // load at `base + 4 * index` reads an element of `base`.
    unsafe {
        let offsets = _mm512_loadu_si512(index.as_ptr().cast());
        let v = _mm512_i32gather_ps::<4>(offsets, base.as_ptr().cast::<f32>());
        _mm512_storeu_ps(out.as_mut_ptr().cast::<f32>(), v);
    }
}

/// One vector from two 8-lane halves (lanes 0-7, then 8-15).
#[inline(always)]
pub fn join(lo: f32x8, hi: f32x8) -> F32x16 {
    unsafe {
        let lo = _mm512_castpd256_pd512(transmute::<f32x8, __m256d>(lo));
        let v = _mm512_insertf64x4::<1>(lo, transmute::<f32x8, __m256d>(hi));
        transmute::<__m512d, F32x16>(v)
    }
}

/// The two 8-lane halves of a vector.
#[inline(always)]
pub fn split(v: F32x16) -> (f32x8, f32x8) {
    unsafe {
        let v = transmute::<F32x16, __m512d>(v);
        let lo = transmute::<__m256d, f32x8>(_mm512_castpd512_pd256(v));
        (lo, transmute::<__m256d, f32x8>(_mm512_extractf64x4_pd::<1>(v)))
    }
}
