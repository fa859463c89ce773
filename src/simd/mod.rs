//! Lane-width-generic SIMD over `wide::f32x4`, `wide::f32x8` and [`F32x16`] (two `f32x8`
//! halves), in the spirit of Embree's `vfloat<N>`: kernels are written once against
//! [`SimdF32`] and instantiated per width, so the 4-, 8- and 16-wide packet paths (and the
//! scalar triangle test, through the arithmetic traits alone) share one body of code.
//!
//! Masks are float vectors whose lanes are all-ones or all-zeros bits, as `wide`'s comparisons
//! return them.

pub mod isa;

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};

#[cfg(target_feature = "avx512f")]
use wide::u32x16;
use wide::{f32x4, f32x8, u32x4, u32x8};

/// The arithmetic shared by f32 and the lane types: what the generic triangle-test core
/// needs (so one function serves scalar and SIMD tests).
pub trait Arith: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> {
    /// Absolute value (lane by lane for the SIMD types).
    fn abs(self) -> Self;
}

impl Arith for f32 {
    #[inline(always)]
    fn abs(self) -> f32 {
        f32::abs(self)
    }
}

/// The operations the traversal and triangle kernels need from a vector of `W` f32 lanes.
pub trait SimdF32:
    Arith + Div<Output = Self> + BitAnd<Output = Self> + BitOr<Output = Self> + std::fmt::Debug
{
    /// Lanes.
    const W: usize;
    /// All lanes set to `x`.
    fn splat(x: f32) -> Self;
    /// The first `W` values of `s` (`s.len() >= W`).
    fn load(s: &[f32]) -> Self;
    /// The value of lane `i` (`i < W`). By reference, so that a lane of a vector in memory
    /// (a packet's terms) is one load: taken by value, each vector was first copied to the
    /// stack (PERF.md, "The packets' hand-over reads lanes in place").
    fn lane(&self, i: usize) -> f32;
    /// Writes the lanes to the first `W` values of `out` (`out.len() >= W`).
    fn store(self, out: &mut [f32]);
    /// The vector at `v`, read in one load: a plain copy of a 512-bit vector in memory is two
    /// 256-bit moves (`LaneMemory`), and a 512-bit load of the copy then waits for both.
    fn copied(v: &Self) -> Self;
    /// The mask of lanes where `self == b`.
    fn simd_eq(self, b: Self) -> Self;
    /// The mask of lanes where `self != b`.
    fn simd_ne(self, b: Self) -> Self;
    /// The mask of lanes where `self < b`.
    fn simd_lt(self, b: Self) -> Self;
    /// The mask of lanes where `self <= b`.
    fn simd_le(self, b: Self) -> Self;
    /// The mask of lanes where `self >= b`.
    fn simd_ge(self, b: Self) -> Self;
    /// `minps` semantics (the second operand when either is NaN); the kernels never feed it
    /// NaN for finite input.
    fn fast_min(self, b: Self) -> Self;
    /// `maxps` semantics (the second operand when either is NaN), as `fast_min`.
    fn fast_max(self, b: Self) -> Self;
    /// `self * a + b`: fused (one rounding) in the builds with FMA (`isa::Isa::Avx2` and up),
    /// a multiply and an add in the baseline build; at every width alike within a build, so
    /// that lanes of any width agree. Only the box tests use it, and their margins
    /// (`accel::packet::SLACK`, `BOX_INFLATE`) are wider than the second rounding, so hits do
    /// not depend on the build (`tests/isa.rs`).
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// `mask ? t : f` per lane.
    fn select(mask: Self, t: Self, f: Self) -> Self;
    /// Correctly rounded square root per lane (as `f32::sqrt`).
    fn sqrt(self) -> Self;
    /// Bit `i` set iff lane `i` of the mask is set.
    fn bitmask(self) -> u32;

    /// All-ones in the first `n` lanes.
    #[inline(always)]
    fn first_lanes(n: usize) -> Self {
        Self::from_bitmask(if n >= 32 { !0 } else { (1u32 << n) - 1 })
    }

    /// The mask whose lane `i` is set iff bit `i` of `bits` is.
    fn from_bitmask(bits: u32) -> Self;

    /// Transposes `n <= W` rows of 8 values (`row(i)`) into 8 columns: lane `i` of column `k`
    /// is value `k` of row `i` (0 for lanes `n..W`). Gathers 32-byte ray records into a packet
    /// with shuffles instead of 8 W scalar moves.
    fn columns8(n: usize, row: impl Fn(usize) -> [f32; 8]) -> [Self; 8];

    /// The inverse of `columns8`: writes `W` rows of 8 values to `out` (`out.len() >= W`), row
    /// `i` holding lane `i` of each column, by transposes rather than 8 W lane extractions.
    fn rows8(cols: [Self; 8], out: &mut [[f32; 8]]);

    /// The smallest lane of each of 8 vectors (`fast_min` semantics), with one transpose and
    /// seven vector minima rather than eight lane-by-lane folds.
    fn min_of_rows(rows: [Self; 8]) -> [f32; 8];

    /// The largest lane of each of 8 vectors (`fast_max` semantics), as `min_of_rows`.
    fn max_of_rows(rows: [Self; 8]) -> [f32; 8];
}

/// The most cache lines a `T` can touch: its size plus how far into a line it can start (a
/// multiple of its alignment), rounded up to whole lines.
pub(crate) const fn lines_spanned<T>() -> usize {
    let align = std::mem::align_of::<T>();
    let lead = 64_usize.saturating_sub(align);
    (lead + std::mem::size_of::<T>()).div_ceil(64)
}

/// Starts loading every cache line of the `T` at `p` (which need not be dereferenceable): a
/// fixed number of prefetches, the most lines a `T` can span, so the loop unrolls and has no
/// branch (a loop to the object's last line cost about 20 instructions per call; PERF.md,
/// "Instructions per ray on Zen 3"). The last may fall just past the object when it starts
/// early in a line.
#[inline(always)]
pub fn prefetch<T>(p: *const T) {
    let first = p as usize & !63;
    for k in 0..lines_spanned::<T>() {
        let line = first.wrapping_add(64 * k);
        #[cfg(target_arch = "x86_64")]
        // SAFETY: a prefetch is a hint that never faults or reads into the program, whatever
        // the address; `sse` is part of the x86_64 baseline.
        unsafe {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            _mm_prefetch::<_MM_HINT_T0>(line as *const i8)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let _ = line;
    }
}

/// All bits set: a true mask lane.
pub const TRUE: f32 = f32::from_bits(!0);

/// `out[i] = base[index[i]]` for 16 indices, if every index is within `base`; otherwise
/// `false`, with `out` unchanged. One AVX-512 gather per call where the build has AVX-512
/// (the 16 loads of a shading chunk's surfaces then overlap), a plain loop below it.
#[inline(always)]
pub fn gather16<T: Copy + Default>(base: &[T], index: &[u32; 16], out: &mut [T; 16]) -> bool {
    if index.iter().fold(0, |m, &i| m.max(i)) as usize >= base.len() {
        return false;
    }
    // The gather's offsets are signed 32-bit: slices past 2^31 - 1 elements take the loop.
    #[cfg(target_feature = "avx512f")]
    if std::mem::size_of::<T>() == 4 && base.len() <= i32::MAX as usize {
        zmm::gather32(base, index, out);
        return true;
    }
    for (o, &i) in out.iter_mut().zip(index) {
        *o = base[i as usize];
    }
    true
}

macro_rules! impl_simd_f32 {
    ($t:ident, $u:ident, $w:literal) => {
        impl Arith for $t {
            #[inline(always)]
            fn abs(self) -> Self {
                $t::abs(self)
            }
        }

        impl SimdF32 for $t {
            const W: usize = $w;
            #[inline(always)]
            fn splat(x: f32) -> Self {
                $t::splat(x)
            }
            #[inline(always)]
            fn load(s: &[f32]) -> Self {
                <$t as LaneMemory>::load_lanes(s)
            }
            #[inline(always)]
            fn lane(&self, i: usize) -> f32 {
                self.as_array()[i]
            }
            #[inline(always)]
            fn store(self, out: &mut [f32]) {
                <$t as LaneMemory>::store_lanes(self, out)
            }
            #[inline(always)]
            fn copied(v: &Self) -> Self {
                <$t as LaneMemory>::load_lanes(v.as_array())
            }
            #[inline(always)]
            fn simd_eq(self, b: Self) -> Self {
                $t::simd_eq(self, b)
            }
            #[inline(always)]
            fn simd_ne(self, b: Self) -> Self {
                $t::simd_ne(self, b)
            }
            #[inline(always)]
            fn simd_lt(self, b: Self) -> Self {
                $t::simd_lt(self, b)
            }
            #[inline(always)]
            fn simd_le(self, b: Self) -> Self {
                $t::simd_le(self, b)
            }
            #[inline(always)]
            fn simd_ge(self, b: Self) -> Self {
                $t::simd_ge(self, b)
            }
            #[inline(always)]
            fn fast_min(self, b: Self) -> Self {
                $t::fast_min(self, b)
            }
            #[inline(always)]
            fn fast_max(self, b: Self) -> Self {
                $t::fast_max(self, b)
            }
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                $t::mul_add(self, a, b)
            }
            #[inline(always)]
            fn select(mask: Self, t: Self, f: Self) -> Self {
                mask.select(t, f)
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                $t::sqrt(self)
            }
            #[inline(always)]
            fn bitmask(self) -> u32 {
                self.to_bitmask()
            }
            #[inline(always)]
            fn columns8(n: usize, row: impl Fn(usize) -> [f32; 8]) -> [Self; 8] {
                <$t as Columns8>::columns8_impl(n.min($w), row)
            }
            #[inline(always)]
            fn rows8(cols: [Self; 8], out: &mut [[f32; 8]]) {
                <$t as Columns8>::rows8_impl(cols, &mut out[..$w])
            }
            #[inline(always)]
            fn from_bitmask(bits: u32) -> Self {
                // Each lane ANDs the bits with its own power of two and compares, in integer
                // lanes: a few register instructions, where building the mask from 16 scalar
                // lanes went through memory (2.8% of a CBspheres_lambertian `-m 5` render).
                let lane_bits = $u::new(std::array::from_fn(|i| 1u32 << i));
                $t::from_bits(($u::splat(bits) & lane_bits).simd_eq(lane_bits))
            }
            #[inline(always)]
            fn min_of_rows(rows: [Self; 8]) -> [f32; 8] {
                <$t as Columns8>::fold_rows(rows, $t::fast_min)
            }
            #[inline(always)]
            fn max_of_rows(rows: [Self; 8]) -> [f32; 8] {
                <$t as Columns8>::fold_rows(rows, $t::fast_max)
            }
        }
    };
}

/// Moving lanes between a vector and memory. Through arrays (`wide`'s `new`, `as_array`) the
/// compiler copies a 512-bit vector as two 256-bit halves (LLVM's 256-bit preference on
/// x86-64-v4), and a 512-bit load right after such a copy waits for both stores. So the
/// 512-bit vector moves whole; the narrower ones keep the arrays.
trait LaneMemory: Sized {
    fn load_lanes(s: &[f32]) -> Self;
    fn store_lanes(self, out: &mut [f32]);
}

macro_rules! impl_lane_memory_by_arrays {
    ($t:ident, $w:literal) => {
        impl LaneMemory for $t {
            #[inline(always)]
            fn load_lanes(s: &[f32]) -> Self {
                let a: [f32; $w] = s[..$w].try_into().expect("slice holds W lanes");
                $t::new(a)
            }
            #[inline(always)]
            fn store_lanes(self, out: &mut [f32]) {
                out[..$w].copy_from_slice(self.as_array());
            }
        }
    };
}

impl_lane_memory_by_arrays!(f32x4, 4);
impl_lane_memory_by_arrays!(f32x8, 8);
impl_simd_f32!(f32x4, u32x4, 4);
impl_simd_f32!(f32x8, u32x8, 8);

/// Sixteen lanes: one 512-bit register in builds with AVX-512 (`wide::f32x16`), two `f32x8`
/// halves below that (`halves::F32x16`), as Embree runs its 16-wide packets on 8-wide
/// hardware. Every operation is lane by lane the 8-wide one, so each lane computes bit for
/// bit what it computes in an 8-wide packet, in either form.
#[cfg(not(target_feature = "avx512f"))]
pub use halves::F32x16;
#[cfg(target_feature = "avx512f")]
pub use wide::f32x16 as F32x16;

#[cfg(target_feature = "avx512f")]
impl_simd_f32!(F32x16, u32x16, 16);

#[cfg(target_feature = "avx512f")]
impl LaneMemory for F32x16 {
    #[inline(always)]
    fn load_lanes(s: &[f32]) -> Self {
        zmm::load(s)
    }
    #[inline(always)]
    fn store_lanes(self, out: &mut [f32]) {
        zmm::store(self, out)
    }
}

/// Whole-register moves of 512-bit vectors (see `LaneMemory`).
#[cfg(target_feature = "avx512f")]
mod zmm;

#[cfg(target_feature = "avx512f")]
impl Columns8 for F32x16 {
    #[inline(always)]
    fn columns8_impl(n: usize, row: impl Fn(usize) -> [f32; 8]) -> [F32x16; 8] {
        let lo = f32x8::columns8(n.min(8), &row);
        let hi = f32x8::columns8(n.saturating_sub(8), |i| row(i + 8));
        std::array::from_fn(|k| join16(lo[k], hi[k]))
    }

    #[inline(always)]
    fn rows8_impl(cols: [F32x16; 8], out: &mut [[f32; 8]]) {
        let halves = cols.map(split16);
        f32x8::rows8(halves.map(|h| h.0), &mut out[..8]);
        f32x8::rows8(halves.map(|h| h.1), &mut out[8..16]);
    }

    #[inline(always)]
    fn fold_rows(rows: [F32x16; 8], f: impl Fn(F32x16, F32x16) -> F32x16) -> [f32; 8] {
        // Fold the two 8-lane halves of each row into one 16-lane vector's halves first.
        let folded = rows.map(|r| {
            let (lo, hi) = split16(r);
            let (lo, hi) = (join16(lo, lo), join16(hi, hi));
            split16(f(lo, hi)).0
        });
        let c = f32x8::transpose(folded);
        let g = |a: f32x8, b: f32x8| split16(f(join16(a, a), join16(b, b))).0;
        g(g(g(c[0], c[1]), g(c[2], c[3])), g(g(c[4], c[5]), g(c[6], c[7]))).to_array()
    }
}

/// One 16-lane vector from two 8-lane halves (lanes 0-7, then 8-15).
#[cfg(target_feature = "avx512f")]
#[inline(always)]
fn join16(lo: f32x8, hi: f32x8) -> F32x16 {
    zmm::join(lo, hi)
}

/// The two 8-lane halves of a 16-lane vector.
#[cfg(target_feature = "avx512f")]
#[inline(always)]
fn split16(v: F32x16) -> (f32x8, f32x8) {
    zmm::split(v)
}

/// Sixteen lanes as two `f32x8` halves, for builds without AVX-512.
#[cfg(not(target_feature = "avx512f"))]
mod halves {
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};

    use wide::f32x8;

    use super::{Arith, SimdF32};

    /// Sixteen lanes as two `f32x8` halves (see `simd::F32x16`).
    #[derive(Clone, Copy, Debug)]
    pub struct F32x16 {
        lo: f32x8,
        hi: f32x8,
    }

    macro_rules! halves_binop {
        ($trait:ident, $f:ident) => {
            impl $trait for F32x16 {
                type Output = F32x16;
                #[inline(always)]
                fn $f(self, b: F32x16) -> F32x16 {
                    F32x16 { lo: self.lo.$f(b.lo), hi: self.hi.$f(b.hi) }
                }
            }
        };
    }
    halves_binop!(Add, add);
    halves_binop!(Sub, sub);
    halves_binop!(Mul, mul);
    halves_binop!(Div, div);
    halves_binop!(BitAnd, bitand);
    halves_binop!(BitOr, bitor);

    impl F32x16 {
        /// Applies the 8-wide `f` to both halves.
        #[inline(always)]
        fn zip(self, b: F32x16, f: impl Fn(f32x8, f32x8) -> f32x8) -> F32x16 {
            F32x16 { lo: f(self.lo, b.lo), hi: f(self.hi, b.hi) }
        }
    }

    /// Two-operand `SimdF32` methods of `F32x16` as the `f32x8` method on each half.
    macro_rules! lanewise {
    ($($f:ident),*) => {
        $(
            #[inline(always)]
            fn $f(self, b: Self) -> Self {
                self.zip(b, |x, y| x.$f(y))
            }
        )*
    };
}

    impl Arith for F32x16 {
        #[inline(always)]
        fn abs(self) -> Self {
            F32x16 { lo: self.lo.abs(), hi: self.hi.abs() }
        }
    }

    impl SimdF32 for F32x16 {
        const W: usize = 16;
        #[inline(always)]
        fn splat(x: f32) -> Self {
            F32x16 { lo: f32x8::splat(x), hi: f32x8::splat(x) }
        }
        #[inline(always)]
        fn load(s: &[f32]) -> Self {
            F32x16 { lo: f32x8::load(s), hi: f32x8::load(&s[8..]) }
        }
        #[inline(always)]
        fn lane(&self, i: usize) -> f32 {
            if i < 8 {
                self.lo.as_array()[i]
            } else {
                self.hi.as_array()[i - 8]
            }
        }
        #[inline(always)]
        fn store(self, out: &mut [f32]) {
            self.lo.store(out);
            self.hi.store(&mut out[8..]);
        }
        #[inline(always)]
        fn copied(v: &Self) -> Self {
            *v
        }
        lanewise!(simd_eq, simd_ne, simd_lt, simd_le, simd_ge, fast_min, fast_max);
        #[inline(always)]
        fn mul_add(self, a: Self, b: Self) -> Self {
            F32x16 { lo: self.lo.mul_add(a.lo, b.lo), hi: self.hi.mul_add(a.hi, b.hi) }
        }
        #[inline(always)]
        fn select(mask: Self, t: Self, f: Self) -> Self {
            F32x16 { lo: mask.lo.select(t.lo, f.lo), hi: mask.hi.select(t.hi, f.hi) }
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            F32x16 { lo: self.lo.sqrt(), hi: self.hi.sqrt() }
        }
        #[inline(always)]
        fn bitmask(self) -> u32 {
            self.lo.bitmask() | self.hi.bitmask() << 8
        }
        #[inline(always)]
        fn from_bitmask(bits: u32) -> Self {
            F32x16 { lo: f32x8::from_bitmask(bits & 0xff), hi: f32x8::from_bitmask(bits >> 8) }
        }
        #[inline(always)]
        fn columns8(n: usize, row: impl Fn(usize) -> [f32; 8]) -> [Self; 8] {
            let lo = f32x8::columns8(n.min(8), &row);
            let hi = f32x8::columns8(n.saturating_sub(8), |i| row(i + 8));
            std::array::from_fn(|k| F32x16 { lo: lo[k], hi: hi[k] })
        }
        #[inline(always)]
        fn rows8(cols: [Self; 8], out: &mut [[f32; 8]]) {
            f32x8::rows8(cols.map(|c| c.lo), &mut out[..8]);
            f32x8::rows8(cols.map(|c| c.hi), &mut out[8..16]);
        }
        #[inline(always)]
        fn min_of_rows(rows: [Self; 8]) -> [f32; 8] {
            f32x8::min_of_rows(rows.map(|r| r.lo.fast_min(r.hi)))
        }
        #[inline(always)]
        fn max_of_rows(rows: [Self; 8]) -> [f32; 8] {
            f32x8::max_of_rows(rows.map(|r| r.lo.fast_max(r.hi)))
        }
    }
}

impl Columns8 for f32x8 {
    #[inline(always)]
    fn columns8_impl(n: usize, row: impl Fn(usize) -> [f32; 8]) -> [f32x8; 8] {
        // Written out: through `std::array::from_fn` the rows were built out of line, in a
        // call that checked `i < n` row by row (1% of a CBbunny `-m 5` render).
        let r = |i: usize| if i < n { f32x8::new(row(i)) } else { f32x8::ZERO };
        f32x8::transpose([r(0), r(1), r(2), r(3), r(4), r(5), r(6), r(7)])
    }

    #[inline(always)]
    fn rows8_impl(cols: [f32x8; 8], out: &mut [[f32; 8]]) {
        for (o, r) in out.iter_mut().zip(f32x8::transpose(cols)) {
            *o = r.to_array();
        }
    }

    #[inline(always)]
    fn fold_rows(rows: [f32x8; 8], f: impl Fn(f32x8, f32x8) -> f32x8) -> [f32; 8] {
        // Column k of the transpose holds lane k of every row.
        let c = f32x8::transpose(rows);
        f(f(f(c[0], c[1]), f(c[2], c[3])), f(f(c[4], c[5]), f(c[6], c[7]))).to_array()
    }
}

impl Columns8 for f32x4 {
    #[inline(always)]
    fn columns8_impl(n: usize, row: impl Fn(usize) -> [f32; 8]) -> [f32x4; 8] {
        let (mut lo, mut hi) = ([f32x4::ZERO; 4], [f32x4::ZERO; 4]);
        for i in 0..n.min(4) {
            let r = row(i);
            lo[i] = f32x4::new([r[0], r[1], r[2], r[3]]);
            hi[i] = f32x4::new([r[4], r[5], r[6], r[7]]);
        }
        let (a, b) = (f32x4::transpose(lo), f32x4::transpose(hi));
        [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]]
    }

    #[inline(always)]
    fn rows8_impl(cols: [f32x4; 8], out: &mut [[f32; 8]]) {
        let (a, b) = (
            f32x4::transpose([cols[0], cols[1], cols[2], cols[3]]),
            f32x4::transpose([cols[4], cols[5], cols[6], cols[7]]),
        );
        for (i, o) in out.iter_mut().enumerate() {
            let (lo, hi) = (a[i].to_array(), b[i].to_array());
            *o = [lo[0], lo[1], lo[2], lo[3], hi[0], hi[1], hi[2], hi[3]];
        }
    }

    #[inline(always)]
    fn fold_rows(rows: [f32x4; 8], f: impl Fn(f32x4, f32x4) -> f32x4) -> [f32; 8] {
        let half = |r: [f32x4; 4]| {
            let c = f32x4::transpose(r);
            f(f(c[0], c[1]), f(c[2], c[3])).to_array()
        };
        let (a, b) = (
            half([rows[0], rows[1], rows[2], rows[3]]),
            half([rows[4], rows[5], rows[6], rows[7]]),
        );
        [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]]
    }
}

/// The width-specific transpose behind `SimdF32::columns8`.
trait Columns8: Sized {
    fn columns8_impl(n: usize, row: impl Fn(usize) -> [f32; 8]) -> [Self; 8];
    fn rows8_impl(cols: [Self; 8], out: &mut [[f32; 8]]);
    /// Folds each of 8 vectors' lanes with `f` (after a transpose, one vector op per step).
    fn fold_rows(rows: [Self; 8], f: impl Fn(Self, Self) -> Self) -> [f32; 8];
}

/// Maps a packet width to its lane type: `Lanes<4>` is `f32x4`, `Lanes<8>` is `f32x8`. Public
/// APIs take the width as a const generic (`intersect_packet::<8>`), kernels the lane type.
pub struct Lanes<const W: usize>;

/// A packet width with a lane type (implemented by `Lanes<4>`, `Lanes<8>` and `Lanes<16>`).
pub trait LaneWidth {
    /// The lane type of this width.
    type F: SimdF32;
}

impl LaneWidth for Lanes<4> {
    type F = f32x4;
}

impl LaneWidth for Lanes<8> {
    type F = f32x8;
}

impl LaneWidth for Lanes<16> {
    type F = F32x16;
}

/// The lane type of width `W`.
pub type VFloat<const W: usize> = <Lanes<W> as LaneWidth>::F;

#[cfg(test)]
mod tests;
