//! Scalar math used by the loader, the builder and the shading code: axis-aligned boxes and rays.
//! Vectors are `glam::Vec3` (12 bytes, no padding) so they can sit in tightly packed arrays.

mod exact;
mod ray;

pub use exact::ExactRgb;
pub use glam::{Mat4, Vec3};
pub use ray::{fill_no_hits, reset_hits, Hit, Ray};

/// The coordinates of `points` as one flat slice (x, y, z of each in turn), for gathers that
/// index single coordinates.
pub fn flat_coordinates(points: &[Vec3]) -> &[f32] {
    const _: () = assert!(std::mem::size_of::<Vec3>() == 12 && std::mem::align_of::<Vec3>() == 4);
    // SAFETY: `glam::Vec3` is `#[repr(C)] { x: f32, y: f32, z: f32 }` without padding (checked
    // above), so `points` is `3 * len` initialised, suitably aligned f32 values; the borrow of
    // `points` lives as long as the result.
    unsafe { std::slice::from_raw_parts(points.as_ptr().cast::<f32>(), points.len() * 3) }
}

/// An axis-aligned bounding box. The empty box has `min = +inf`, `max = -inf`, so that growing it
/// by any point or box gives that point or box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// The lower corner.
    pub min: Vec3,
    /// The upper corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box (`min = +inf`, `max = -inf`): the identity of `grow` and `union`.
    pub const EMPTY: Aabb =
        Aabb { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };

    /// The smallest box holding `points` (empty for none).
    pub fn from_points(points: &[Vec3]) -> Aabb {
        points.iter().fold(Aabb::EMPTY, |b, &p| b.grow(p))
    }

    /// The smallest box holding this one and `p`.
    #[inline]
    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb { min: self.min.min(p), max: self.max.max(p) }
    }

    /// The smallest box holding this one and `o`.
    #[inline]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    /// Whether the box holds no point (`min > max` on some axis).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// `max - min`, zero for the empty box.
    #[inline]
    pub fn extent(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            self.max - self.min
        }
    }

    /// The midpoint of the corners (not meaningful for the empty box).
    #[inline]
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// The length of the diagonal, 0 for the empty box.
    #[inline]
    pub fn diagonal(&self) -> f32 {
        let d = self.extent().length();
        if d.is_finite() {
            return d;
        }
        // The f32 squares overflow for a box over about 1.8e19 across (the camera's distance
        // and the ray epsilons scale with this length): the same length through f64.
        self.extent().as_dvec3().length() as f32
    }

    /// Half the surface area (the SAH only needs ratios, so the factor 2 is dropped).
    #[inline]
    pub fn half_area(&self) -> f32 {
        let e = self.extent();
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

/// An orthonormal basis (t, b, n) around unit `n` (Duff et al. 2017, branchless).
#[inline]
pub(crate) fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// sin and cos of the angle 2 pi `u`, for `u` in [0, 1) (in turns, so that no range reduction
/// rounds): the quadrant by comparisons, then Cephes' single-precision minimax polynomials on
/// [-pi/4, pi/4] (error below 1.2e-7, measured 8.9e-8). Only +, -, * and comparisons, in an order that
/// `integrator::diffuse` repeats lane by lane, so scalar and SIMD shading agree bit for bit;
/// libm's `sincosf` called once per lane cost 3 % of a render (PERF.md "Whole renders").
#[inline]
pub(crate) fn sincos_turns(u: f32) -> (f32, f32) {
    let quadrant =
        (u >= 0.125) as u32 + (u >= 0.375) as u32 + (u >= 0.625) as u32 + (u >= 0.875) as u32;
    let x = (u - quadrant as f32 * 0.25) * std::f32::consts::TAU;
    let z = x * x;
    let (s, c) = (sin_poly(x, z), cos_poly(z));
    match quadrant & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// sin x = x + x z (s1 + z (s2 + z s3)), z = x^2, on [-pi/4, pi/4] (Cephes `sinf`).
pub(crate) const SIN_COEFFS: [f32; 3] = [-1.666_665_5e-1, 8.332_161e-3, -1.951_529_6e-4];
/// cos x = 1 - z / 2 + z^2 (c1 + z (c2 + z c3)), z = x^2, on [-pi/4, pi/4] (Cephes `cosf`).
pub(crate) const COS_COEFFS: [f32; 3] = [4.166_664_6e-2, -1.388_731_6e-3, 2.443_315_7e-5];

#[inline(always)]
fn sin_poly(x: f32, z: f32) -> f32 {
    let [s1, s2, s3] = SIN_COEFFS;
    ((s3 * z + s2) * z + s1) * z * x + x
}

#[inline(always)]
fn cos_poly(z: f32) -> f32 {
    let [c1, c2, c3] = COS_COEFFS;
    ((c3 * z + c2) * z + c1) * z * z - 0.5 * z + 1.0
}

/// e^x for x <= 0 (x below -87, where e^x is under 2^-125, gives 0; NaN stays NaN): x is
/// n ln 2 plus r, |r| <= ln 2 / 2 (ln 2 in two parts, Cody and Waite), e^r by Cephes' `expf`
/// polynomial, 2^n as the product of the powers 2^-64, ..., 2^-1 that -n's bits pick. Only
/// additions, subtractions, products and comparisons, in an order that
/// `integrator::microfacet_lanes` repeats lane by lane, so that scalar and SIMD shading agree
/// bit for bit in every build; libm's `expf` called lane by lane took 2% of a glossy render
/// (PERF.md "Whole renders"). Relative error under 2.5e-7 (`exp_nonpositive_matches_f64`).
#[inline]
pub(crate) fn exp_nonpositive(x: f32) -> f32 {
    let n = (x * std::f32::consts::LOG2_E + ROUND_MAGIC) - ROUND_MAGIC;
    let r = (x - n * LN2_PARTS[0]) - n * LN2_PARTS[1];
    let [p0, p1, p2, p3, p4, p5] = EXP_COEFFS;
    let p = ((((p0 * r + p1) * r + p2) * r + p3) * r + p4) * r + p5;
    let er = (p * (r * r) + r) + 1.0;
    // At most 126 steps down: the lanes' garbage (infinite -n) stays out of subnormals.
    let mut m = (-n).min(126.0);
    let mut scale = 1.0;
    for (k, &power) in POW2_STEPS.iter().enumerate() {
        let step = (64 >> k) as f32;
        if m >= step {
            scale *= power;
            m -= step;
        }
    }
    if x < -87.0 {
        0.0
    } else {
        er * scale
    }
}

/// ln y for y in [f32::MIN_POSITIVE, 1] (the Beckmann sample's 1 - u): y scaled into [1, 2) by
/// the powers 2^64, ..., 2^1 that it needs (y = m 2^e), m halved above sqrt 2, then Cephes'
/// `logf` polynomial in m - 1 and e ln 2 in two parts. Only additions, subtractions, products
/// and comparisons, as `exp_nonpositive`, so that the lanes repeat it bit for bit in every
/// build; error under 1.5e-7 absolute plus 1.5e-7 relative (`ln_unit_matches_f64`).
#[inline]
pub(crate) fn ln_unit(y: f32) -> f32 {
    let (mut m, mut e) = (y, 0.0f32);
    for (k, &power) in POW2_STEPS.iter().enumerate() {
        let step = (64 >> k) as f32;
        if m < 2.0 * power {
            m *= 1.0 / power;
            e -= step;
        }
    }
    if m > std::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1.0;
    }
    let x = m - 1.0;
    let z = x * x;
    let mut p = LN_COEFFS[0];
    for &c in &LN_COEFFS[1..] {
        p = p * x + c;
    }
    let y = ((p * x * z + e * LN2_PARTS[1]) - 0.5 * z) + x;
    y + e * LN2_PARTS[0]
}

/// ln(1 + x) = x - x^2 / 2 + x^3 P(x) on [sqrt(1/2) - 1, sqrt 2 - 1], P's coefficients highest
/// first (Cephes `logf`).
pub(crate) const LN_COEFFS: [f32; 9] = [
    7.037_683_6e-2,
    -1.151_461e-1,
    1.167_699_9e-1,
    -1.242_014_1e-1,
    1.424_932_3e-1,
    -1.666_805_8e-1,
    2.000_071_5e-1,
    -2.499_999_4e-1,
    3.333_333e-1,
];

/// 1.5 x 2^23: added to and subtracted from a float below 2^22 in magnitude, it rounds it to
/// an integer (ties to even).
pub(crate) const ROUND_MAGIC: f32 = 12_582_912.0;
/// ln 2 = `LN2_PARTS[0] + LN2_PARTS[1]`, the first exact in few bits (Cephes `expf`).
pub(crate) const LN2_PARTS: [f32; 2] = [0.693_359_4, -2.121_944_4e-4];
/// e^r = 1 + r + r^2 (p5 + r (p4 + ...)) on |r| <= ln 2 / 2 (Cephes `expf`).
pub(crate) const EXP_COEFFS: [f32; 6] =
    [1.987_569_1e-4, 1.398_199_9e-3, 8.333_452e-3, 4.166_579_6e-2, 1.666_666_5e-1, 0.5];
/// 2^-64, 2^-32, ..., 2^-1: the factors of 2^n, largest step first.
pub(crate) const POW2_STEPS: [f32; 7] =
    [5.421_011e-20, 2.328_306_4e-10, 1.525_878_9e-5, 3.906_25e-3, 6.25e-2, 0.25, 0.5];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagonal_of_a_box_whose_squares_overflow_f32_is_finite() {
        let b = Aabb { min: Vec3::splat(-1e20), max: Vec3::splat(1e20) };
        let d = b.diagonal();
        assert!((d / (2e20 * 3f32.sqrt()) - 1.0).abs() < 1e-6, "{d}");
        let unit = Aabb { min: Vec3::ZERO, max: Vec3::ONE };
        assert_eq!(unit.diagonal(), Vec3::ONE.length());
        assert_eq!(Aabb::EMPTY.diagonal(), 0.0);
    }

    #[test]
    fn exp_nonpositive_matches_f64() {
        let mut worst = 0.0f64;
        let n = 1 << 20;
        for k in 0..=n {
            let x = -87.0 * k as f32 / n as f32;
            let want = (x as f64).exp();
            worst = worst.max(((exp_nonpositive(x) as f64 - want) / want).abs());
        }
        assert!(worst < 2.5e-7, "worst relative error {worst:e}");
        assert_eq!(exp_nonpositive(0.0), 1.0);
        assert_eq!(exp_nonpositive(-0.0), 1.0);
        assert_eq!(exp_nonpositive(-87.5), 0.0);
        assert_eq!(exp_nonpositive(f32::NEG_INFINITY), 0.0);
        assert!(exp_nonpositive(f32::NAN).is_nan());
        for (k, &p) in POW2_STEPS.iter().enumerate() {
            assert_eq!(p, 2f32.powi(-(64 >> k)), "step {k}");
        }
    }

    #[test]
    fn ln_unit_matches_f64() {
        let check = |y: f32| {
            let (got, want) = (ln_unit(y) as f64, (y as f64).ln());
            assert!(
                (got - want).abs() <= 1.5e-7 + 1.5e-7 * want.abs(),
                "ln({y:e}) = {got:e}, want {want:e}"
            );
        };
        let n = 1 << 20;
        for k in 1..=n {
            check(k as f32 / n as f32);
            check(f32::MIN_POSITIVE * (k as f32 / n as f32 * 1e6 + 1.0));
        }
        for e in -126..=0 {
            for m in [1.0, 1.2, std::f32::consts::SQRT_2, 1.5, 1.999_999_9] {
                check((m * 2f32.powi(e)).min(1.0));
            }
        }
        assert_eq!(ln_unit(1.0), 0.0);
    }

    #[test]
    fn sincos_turns_matches_f64_within_1_2e_7() {
        let n = 1 << 20;
        let mut worst = 0.0f64;
        for k in 0..n {
            let u = k as f32 / n as f32;
            let (s, c) = sincos_turns(u);
            let a = u as f64 * std::f64::consts::TAU;
            worst = worst.max((s as f64 - a.sin()).abs()).max((c as f64 - a.cos()).abs());
        }
        let u = 1.0 - f32::EPSILON / 2.0;
        let (s, c) = sincos_turns(u);
        let a = u as f64 * std::f64::consts::TAU;
        worst = worst.max((s as f64 - a.sin()).abs()).max((c as f64 - a.cos()).abs());
        assert!(worst < 1.2e-7, "worst error {worst:e}");
    }
}
