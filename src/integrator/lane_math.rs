//! Arithmetic on `LANES` f32 lanes for `diffuse`: 3-vectors, the shading frame, sine and
//! cosine, and the ray offsets, each repeating the scalar code's operations in its order (the
//! doc line of each names the scalar function), so that lanes and scalar code agree bit for bit.

use std::f32::consts::TAU;

use super::diffuse::LANES;
use crate::math::{
    Vec3, COS_COEFFS, EXP_COEFFS, LN2_PARTS, LN_COEFFS, POW2_STEPS, ROUND_MAGIC, SIN_COEFFS,
};
use crate::simd::{Arith, SimdF32, VFloat};

pub(super) type V = VFloat<LANES>;
pub(super) type Lanes = [f32; LANES];

/// Three coordinates of `LANES` vectors.
#[derive(Clone, Copy)]
pub(super) struct V3 {
    pub(super) x: V,
    pub(super) y: V,
    pub(super) z: V,
}

impl V3 {
    #[inline(always)]
    pub(super) fn load(a: &[Lanes; 3]) -> V3 {
        V3 { x: V::load(&a[0]), y: V::load(&a[1]), z: V::load(&a[2]) }
    }
    #[inline(always)]
    pub(super) fn splat(v: Vec3) -> V3 {
        V3 { x: V::splat(v.x), y: V::splat(v.y), z: V::splat(v.z) }
    }
    #[inline(always)]
    pub(super) fn store(self, out: &mut [Lanes; 3]) {
        self.x.store(&mut out[0]);
        self.y.store(&mut out[1]);
        self.z.store(&mut out[2]);
    }
    #[inline(always)]
    pub(super) fn add(self, o: V3) -> V3 {
        V3 { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
    #[inline(always)]
    pub(super) fn sub(self, o: V3) -> V3 {
        V3 { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
    #[inline(always)]
    pub(super) fn mul(self, o: V3) -> V3 {
        V3 { x: self.x * o.x, y: self.y * o.y, z: self.z * o.z }
    }
    #[inline(always)]
    pub(super) fn scale(self, s: V) -> V3 {
        V3 { x: self.x * s, y: self.y * s, z: self.z * s }
    }
    #[inline(always)]
    pub(super) fn div(self, s: V) -> V3 {
        V3 { x: self.x / s, y: self.y / s, z: self.z / s }
    }
    /// glam's `cross`, in its order of operations.
    #[inline(always)]
    pub(super) fn cross(self, o: V3) -> V3 {
        V3 {
            x: self.y * o.z - o.y * self.z,
            y: self.z * o.x - o.z * self.x,
            z: self.x * o.y - o.x * self.y,
        }
    }
    #[inline(always)]
    pub(super) fn dot(self, o: V3) -> V {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline(always)]
    pub(super) fn select(mask: V, t: V3, f: V3) -> V3 {
        V3 {
            x: V::select(mask, t.x, f.x),
            y: V::select(mask, t.y, f.y),
            z: V::select(mask, t.z, f.z),
        }
    }
    /// glam's `max_element`: `if a > b { a } else { b }`, folded left.
    #[inline(always)]
    pub(super) fn max_element(self) -> V {
        max(max(self.x, self.y), self.z)
    }
    /// A mask of the lanes whose three coordinates are finite.
    #[inline(always)]
    pub(super) fn is_finite(self) -> V {
        let inf = V::splat(f32::INFINITY);
        Arith::abs(self.x).simd_lt(inf)
            & Arith::abs(self.y).simd_lt(inf)
            & Arith::abs(self.z).simd_lt(inf)
    }
    /// Coordinates in the frame (t, b, n), as `Frame::to_local`.
    #[inline(always)]
    pub(super) fn to_local(self, f: &Frame) -> V3 {
        V3 { x: self.dot(f.t), y: self.dot(f.b), z: self.dot(f.n) }
    }
}

/// `if a > b { a } else { b }` per lane.
#[inline(always)]
pub(super) fn max(a: V, b: V) -> V {
    V::select(b.simd_lt(a), a, b)
}

/// `f32::min(a, b)` for lanes that are not NaN.
#[inline(always)]
pub(super) fn min(a: V, b: V) -> V {
    V::select(a.simd_lt(b), a, b)
}

#[inline(always)]
pub(super) fn gt(a: V, b: V) -> V {
    b.simd_lt(a)
}

/// `-x`, exactly (also for zeros).
#[inline(always)]
pub(super) fn neg(x: V) -> V {
    V::splat(-1.0) * x
}

/// The shading frame of `math::orthonormal_basis`, lane by lane.
pub(super) struct Frame {
    pub(super) t: V3,
    pub(super) b: V3,
    pub(super) n: V3,
}

impl Frame {
    #[inline(always)]
    pub(super) fn new(n: V3) -> Frame {
        let one = V::splat(1.0);
        // `1.0f32.copysign(n.z)`: the sign bit of n.z on 1.0.
        let sign = one | (n.z & V::splat(-0.0));
        let a = V::splat(-1.0) / (sign + n.z);
        let b = n.x * n.y * a;
        let t = V3 { x: one + sign * n.x * n.x * a, y: sign * b, z: neg(sign) * n.x };
        let bb = V3 { x: b, y: sign + n.y * n.y * a, z: neg(n.y) };
        Frame { t, b: bb, n }
    }
}

/// `math::sincos_turns` lane by lane: the same operations in the same order.
#[inline(always)]
pub(super) fn sincos_turns(u: V) -> (V, V) {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let step = |edge: f32| V::select(u.simd_ge(V::splat(edge)), one, zero);
    let quadrant = step(0.125) + step(0.375) + step(0.625) + step(0.875);
    let x = (u - quadrant * V::splat(0.25)) * V::splat(TAU);
    let z = x * x;
    let [s1, s2, s3] = SIN_COEFFS.map(V::splat);
    let s = ((s3 * z + s2) * z + s1) * z * x + x;
    let [c1, c2, c3] = COS_COEFFS.map(V::splat);
    let c = ((c3 * z + c2) * z + c1) * z * z - V::splat(0.5) * z + one;
    // Quadrants 1 and 3 swap sine and cosine; 1 and 2 negate the cosine slot, 2 and 3 the sine.
    let odd = quadrant.simd_eq(one) | quadrant.simd_eq(V::splat(3.0));
    let (s, c) = (V::select(odd, c, s), V::select(odd, s, c));
    let neg_sin = quadrant.simd_eq(V::splat(2.0)) | quadrant.simd_eq(V::splat(3.0));
    let neg_cos = quadrant.simd_eq(one) | quadrant.simd_eq(V::splat(2.0));
    (V::select(neg_sin, neg(s), s), V::select(neg_cos, neg(c), c))
}

/// `math::exp_nonpositive` lane by lane: the same operations in the same order.
#[inline(always)]
pub(super) fn exp_nonpositive(x: V) -> V {
    let (zero, one, magic) = (V::splat(0.0), V::splat(1.0), V::splat(ROUND_MAGIC));
    let n = (x * V::splat(std::f32::consts::LOG2_E) + magic) - magic;
    let r = (x - n * V::splat(LN2_PARTS[0])) - n * V::splat(LN2_PARTS[1]);
    let [p0, p1, p2, p3, p4, p5] = EXP_COEFFS.map(V::splat);
    let p = ((((p0 * r + p1) * r + p2) * r + p3) * r + p4) * r + p5;
    let er = (p * (r * r) + r) + one;
    let mut m = min(neg(n), V::splat(126.0));
    let mut scale = one;
    for (k, &power) in POW2_STEPS.iter().enumerate() {
        let step = V::splat((64 >> k) as f32);
        let take = m.simd_ge(step);
        scale = V::select(take, scale * V::splat(power), scale);
        m = V::select(take, m - step, m);
    }
    V::select(x.simd_lt(V::splat(-87.0)), zero, er * scale)
}

/// `math::ln_unit` lane by lane: the same operations in the same order.
#[inline(always)]
pub(super) fn ln_unit(y: V) -> V {
    let (mut m, mut e) = (y, V::splat(0.0));
    for (k, &power) in POW2_STEPS.iter().enumerate() {
        let step = V::splat((64 >> k) as f32);
        let take = m.simd_lt(V::splat(2.0 * power));
        m = V::select(take, m * V::splat(1.0 / power), m);
        e = V::select(take, e - step, e);
    }
    let high = gt(m, V::splat(std::f32::consts::SQRT_2));
    m = V::select(high, m * V::splat(0.5), m);
    e = V::select(high, e + V::splat(1.0), e);
    let x = m - V::splat(1.0);
    let z = x * x;
    let mut p = V::splat(LN_COEFFS[0]);
    for &c in &LN_COEFFS[1..] {
        p = p * x + V::splat(c);
    }
    let y = ((p * x * z + e * V::splat(LN2_PARTS[1])) - V::splat(0.5) * z) + x;
    y + e * V::splat(LN2_PARTS[0])
}

/// `bsdf::cosine_hemisphere`, lane by lane.
#[inline(always)]
pub(super) fn cosine_hemisphere(u1: V, u2: V) -> V3 {
    let r = u1.sqrt();
    let (sin_phi, cos_phi) = sincos_turns(u2);
    V3 { x: r * cos_phi, y: r * sin_phi, z: max(V::splat(1.0) - u1, V::splat(0.0)).sqrt() }
}

/// `bsdf::uniform_hemisphere`, lane by lane.
#[inline(always)]
pub(super) fn uniform_hemisphere(u1: V, u2: V) -> V3 {
    let r = max(V::splat(1.0) - u1 * u1, V::splat(0.0)).sqrt();
    let (sin_phi, cos_phi) = sincos_turns(u2);
    V3 { x: r * cos_phi, y: r * sin_phi, z: u1 }
}

/// The spawn-point offset of `RenderContext::ray_epsilon`, per lane.
#[inline(always)]
pub(super) fn ray_epsilon(p: V3, scene_epsilon: f32) -> V {
    const ULPS: f32 = 8.0 * f32::EPSILON;
    let largest = max(max(Arith::abs(p.x), Arith::abs(p.y)), Arith::abs(p.z));
    max(largest * V::splat(ULPS), V::splat(scene_epsilon))
}

/// `RenderContext::offset_origin`, per lane.
#[inline(always)]
pub(super) fn offset_origin(p: V3, ng: V3, dir: V3, scene_epsilon: f32) -> V3 {
    let one = V::splat(1.0);
    let side = V::select(ng.dot(dir).simd_ge(V::splat(0.0)), one, V::splat(-1.0));
    p.add(ng.scale(side * ray_epsilon(p, scene_epsilon)))
}

/// glam's `normalize_or(fallback)`.
#[inline(always)]
pub(super) fn normalize_or(v: V3, fallback: V3) -> V3 {
    let rcp = V::splat(1.0) / v.dot(v).sqrt();
    let ok = Arith::abs(rcp).simd_lt(V::splat(f32::INFINITY)) & gt(rcp, V::splat(0.0));
    V3::select(ok, v.scale(rcp), fallback)
}
