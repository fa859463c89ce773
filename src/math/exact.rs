//! An exact, order-independent per-pixel sum of radiance samples.
//!
//! A pixel's samples used to be added in f32 one after the other; such a sum depends on the
//! order and on where it starts, so the samples `0..k` and `k..n` rendered apart (by two
//! machines) could not be added back to the bytes of one render. Here each f32 sample is
//! turned into a fixed-point integer with `FRAC_BITS` fractional bits, and the integers are
//! added in `i128`: integer addition is associative, so any split of a pixel's samples, added
//! in any order, gives the same sum, and the mean is rounded once at the end.
//!
//! The conversion is exact for every f32 of magnitude in [2^-33, 2^40) (about 1.2e-10 to
//! 1.1e12): their last mantissa bit is worth at least 2^-56. Smaller magnitudes are truncated
//! to a multiple of 2^-56, larger ones clamped to 2^40; the sum wraps (still associatively) only
//! past 2^71, e.g. 2^31 samples of 2^40. Non-finite samples (inf, NaN) are kept aside in an
//! f32 that only ever adds non-finite values, an associative operation too (inf + inf = inf,
//! inf - inf = NaN, NaN + x = NaN), and decide the mean when present.

use crate::math::{flat_coordinates, Vec3};

/// Fractional bits of the fixed-point samples.
pub const FRAC_BITS: u32 = 56;
/// Largest magnitude a sample keeps; larger finite samples are clamped to it.
pub const MAX_SAMPLE: f32 = (1u64 << 40) as f32;

/// The exact sum of a pixel's RGB samples.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ExactRgb {
    /// Fixed-point sums (value x 2^FRAC_BITS), wrapping.
    pub fixed: [i128; 3],
    /// The sum of the non-finite samples only: 0 while there are none.
    pub special: [f32; 3],
}

impl ExactRgb {
    /// Adds one sample.
    #[inline]
    pub fn add(&mut self, rgb: [f32; 3]) {
        for (c, &v) in rgb.iter().enumerate() {
            if v.is_finite() {
                self.fixed[c] = self.fixed[c].wrapping_add(to_fixed(v));
            } else {
                self.special[c] += v;
            }
        }
    }

    /// Adds the samples `rgb` one after the other, as `add` does each: the same sum. Runs of up
    /// to `RUN` samples whose channels are all finite and below `SMALL` in magnitude (nearly
    /// all of them) take a branch-free path: their fixed-point values stay under 2^59, so up to
    /// 16 of them add up in an `i64` without overflow, and the pixel's `i128` sums are touched
    /// once per run (PERF.md, "Whole renders"). The run's channels are read as one flat array
    /// of 48 numbers and summed per channel by `channel_sums`: integer sums, so the same sum in
    /// any order.
    pub fn add_all(&mut self, rgb: &[Vec3]) {
        for run in rgb.chunks(RUN) {
            let flat = flat_coordinates(run);
            // A shorter run is padded with zeros, which add nothing: every run then takes the
            // one fixed-size path below.
            let mut padded = [0.0f32; 3 * RUN];
            let flat: &[f32; 3 * RUN] = match flat.try_into() {
                Ok(full) => full,
                Err(_) => {
                    padded[..flat.len()].copy_from_slice(flat);
                    &padded
                }
            };
            let small = flat.iter().fold(true, |all, x| all & (x.abs() < SMALL));
            if !small {
                run.iter().for_each(|v| self.add(v.to_array()));
                continue;
            }
            for (c, sum) in channel_sums(flat).into_iter().enumerate() {
                self.fixed[c] = self.fixed[c].wrapping_add(sum as i128);
            }
        }
    }

    /// Adds another pixel's sum (another range of its samples).
    pub fn merge(&mut self, o: &ExactRgb) {
        for c in 0..3 {
            self.fixed[c] = self.fixed[c].wrapping_add(o.fixed[c]);
            self.special[c] += o.special[c];
        }
    }

    /// The mean of `count` samples (0 for none), rounded once from the exact sum.
    pub fn mean(&self, count: u32) -> [f32; 3] {
        let n = count.max(1) as f64;
        let scale = 1.0 / SCALE;
        std::array::from_fn(|c| {
            if self.special[c] != 0.0 {
                self.special[c]
            } else {
                (self.fixed[c] as f64 * scale / n) as f32
            }
        })
    }
}

/// 2^FRAC_BITS.
const SCALE: f64 = (1u64 << FRAC_BITS) as f64;
/// Samples below this magnitude are under 2^(3 + FRAC_BITS) = 2^59 in fixed point...
const SMALL: f32 = 8.0;
/// ... so that this many of them sum to under 2^63.
const RUN: usize = 16;
const _: () = assert!(FRAC_BITS + 3 + RUN.ilog2() < 64 && SMALL == 8.0 && RUN == 16);

/// The fixed-point sums of the three channels of `RUN` RGB samples, all of magnitude under
/// `SMALL` (so finite). The values are added in halves, 48 -> 24 -> 12 -> 6 -> 3 numbers: each
/// half is a whole number of RGB triples long, so a number's channel stays its position mod 3,
/// and every step is one vertical add of fixed-size arrays, which stay in registers. (Added
/// lane by lane in groups of 24, then strided per channel, the compiler kept the group's lanes
/// on the stack in some builds, and each add waited on the store before it.)
#[inline(always)]
fn channel_sums(flat: &[f32; 3 * RUN]) -> [i64; 3] {
    // SAFETY: |x| < SMALL = 8 (the caller checked the whole run, which also rules out NaN), so
    // x 2^FRAC_BITS is finite and under 2^59 in magnitude, within i64; the conversion truncates
    // toward zero as `as` and `to_fixed` do. Unlike `as`, it needs no saturation, so it
    // vectorises (AVX-512DQ). 16 such values add up to under 2^63.
    let fixed: [i64; 3 * RUN] =
        std::array::from_fn(|k| unsafe { (flat[k] as f64 * SCALE).to_int_unchecked::<i64>() });
    let h24: [i64; 24] = std::array::from_fn(|k| fixed[k] + fixed[k + 24]);
    let h12: [i64; 12] = std::array::from_fn(|k| h24[k] + h24[k + 12]);
    let h6: [i64; 6] = std::array::from_fn(|k| h12[k] + h12[k + 6]);
    [h6[0] + h6[3], h6[1] + h6[4], h6[2] + h6[5]]
}

#[inline]
fn to_fixed(v: f32) -> i128 {
    // Exact: a power-of-two scale of an f32 fits an f64, and is an integer from 2^-33 up;
    // below, the cast truncates toward zero. Samples under 128 (nearly all) take the one-
    // instruction f64 -> i64 conversion; larger ones the (slower) f64 -> i128 one.
    let x = v.clamp(-MAX_SAMPLE, MAX_SAMPLE) as f64 * SCALE;
    if x.abs() < 9.0e18 {
        x as i64 as i128
    } else {
        x as i128
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sum(values: &[f32]) -> ExactRgb {
        let mut s = ExactRgb::default();
        for &v in values {
            s.add([v, -v, v * 0.5]);
        }
        s
    }

    #[test]
    fn any_split_merges_to_the_same_sum() {
        let values: Vec<f32> =
            (0..200).map(|i| ((i * 7919) % 1000) as f32 * 1.37e-3 + 1e-9 * i as f32).collect();
        let whole = sum(&values);
        for k in [0, 1, 17, 199, 200] {
            let mut a = sum(&values[..k]);
            a.merge(&sum(&values[k..]));
            assert_eq!(a, whole);
            let mut b = sum(&values[k..]);
            b.merge(&sum(&values[..k]));
            assert_eq!(b.mean(200), whole.mean(200));
        }
    }

    /// `add_all` gives the sum `add` gives, with runs that are all small, runs with a large
    /// or non-finite sample, and runs longer than `RUN`.
    #[test]
    fn add_all_equals_adding_one_by_one() {
        // A small LCG: `math` comes before `sampler` in the module order.
        let mut state = 12345u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        for len in [0, 1, 5, 16, 17, 40, 100] {
            for spice in
                [None, Some(9.5f32), Some(-8.0), Some(f32::INFINITY), Some(f32::NAN), Some(7.999)]
            {
                let mut v: Vec<Vec3> = (0..len)
                    .map(|_| {
                        Vec3::from_array(std::array::from_fn(|_| (next() - 0.3) * 15.9 * next()))
                    })
                    .collect();
                if let (Some(x), true) = (spice, len > 3) {
                    v[3].y = x;
                }
                let mut a = ExactRgb::default();
                v.iter().for_each(|s| a.add(s.to_array()));
                let mut b = ExactRgb::default();
                b.add_all(&v);
                assert_eq!(a.fixed, b.fixed, "len {len} spice {spice:?}");
                assert_eq!(a.special.map(f32::to_bits), b.special.map(f32::to_bits));
            }
        }
    }

    #[test]
    fn mean_is_exact_where_f32_sums_drift() {
        let mut s = ExactRgb::default();
        for _ in 0..3 {
            s.add([0.1, 1e8, 1.0]);
        }
        s.add([0.1, 1.0, 1.0]);
        let m = s.mean(4);
        assert_eq!(m[0], 0.1);
        assert_eq!(m[2], 1.0);
        assert_eq!(m[1], ((3.0 * 1e8f64 + 1.0) / 4.0) as f32);
        assert_eq!(ExactRgb::default().mean(0), [0.0; 3]);
    }

    #[test]
    fn non_finite_samples_decide_the_mean() {
        let mut s = sum(&[1.0, 2.0]);
        s.add([f32::INFINITY, f32::NEG_INFINITY, f32::NAN]);
        let m = s.mean(3);
        assert_eq!(m[0], f32::INFINITY);
        assert_eq!(m[1], f32::NEG_INFINITY);
        assert!(m[2].is_nan());
        let mut t = sum(&[1.0]);
        t.add([f32::INFINITY, f32::INFINITY, 0.0]);
        t.add([f32::NEG_INFINITY, f32::INFINITY, 0.0]);
        assert!(t.mean(3)[0].is_nan());
        assert_eq!(t.mean(3)[1], f32::INFINITY);
    }
}
