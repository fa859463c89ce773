//! The course's microfacet BSDF (`bsdf`: Beckmann distribution, Smith shadowing, conductor
//! Fresnel) over `LANES` vertices, for `diffuse`'s lanes. Each function repeats its scalar
//! namesake's operations in its order, so that lanes and scalar code agree bit for bit
//! (tests/lighting.rs): `exp`, `ln` and the sampled angle's sine and cosine are our own
//! polynomials in both (`math::exp_nonpositive`, `math::ln_unit`, `math::sincos_turns`). A
//! branch of the scalar code is a select here: every lane computes every case and keeps the one
//! its scalar twin takes.

use std::f32::consts::PI;

use super::bsdf::MAX_CONDUCTOR_INDEX;
use super::lane_math::{exp_nonpositive, gt, ln_unit, max, min, sincos_turns, Lanes, V, V3};
use crate::math::Vec3;
use crate::simd::SimdF32;

/// The microfacet parameters of the lanes that hold a microfacet vertex (`mask`); the other
/// lanes (diffuse or unused) hold whatever was there, and their results are not used.
pub(super) struct MicrofacetLanes {
    pub(super) mask: V,
    pub(super) alpha: V,
    pub(super) eta: V3,
    pub(super) k: V3,
}

/// Per-lane parameters as `diffuse::DiffuseLanes` stores them.
#[derive(Default)]
pub(super) struct MicrofacetParams {
    /// Lanes that hold a microfacet vertex, as a bit mask.
    pub(super) mask: u32,
    alpha: Lanes,
    eta: [Lanes; 3],
    k: [Lanes; 3],
}

impl MicrofacetParams {
    /// Stores lane `l`'s parameters.
    #[inline]
    pub(super) fn set(&mut self, l: usize, alpha: f32, eta: Vec3, k: Vec3) {
        self.mask |= 1 << l;
        self.alpha[l] = alpha;
        for (a, v) in [(&mut self.eta, eta), (&mut self.k, k)] {
            (a[0][l], a[1][l], a[2][l]) = (v.x, v.y, v.z);
        }
    }

    /// The parameters as lanes, when any lane is microfacet.
    #[inline(always)]
    pub(super) fn lanes(&self) -> Option<MicrofacetLanes> {
        (self.mask != 0).then(|| MicrofacetLanes {
            mask: V::from_bitmask(self.mask),
            alpha: V::load(&self.alpha),
            eta: V3::load(&self.eta),
            k: V3::load(&self.k),
        })
    }
}

/// `bsdf::beckmann_d`.
#[inline(always)]
fn beckmann_d(m: &MicrofacetLanes, h: V3) -> V {
    let alpha = m.alpha;
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let cos2 = h.z * h.z;
    let tan2 = max(one - cos2, zero) / cos2;
    let a2 = alpha * alpha;
    let d = exp_nonpositive(V::splat(-1.0) * tan2 / a2) / (V::splat(PI) * a2 * cos2 * cos2);
    V::select(h.z.simd_le(zero), zero, d)
}

/// `bsdf::smith_g1`.
#[inline(always)]
fn smith_g1(alpha: V, w: V3) -> V {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let cos = w.z;
    let tan = max(one - cos * cos, zero).sqrt() / cos;
    let a = one / (alpha * tan);
    let g = (V::splat(3.535) * a + V::splat(2.181) * a * a)
        / (one + V::splat(2.276) * a + V::splat(2.577) * a * a);
    let g = V::select(a.simd_ge(V::splat(1.6)), one, g);
    let g = V::select(tan.simd_eq(zero), one, g);
    V::select(cos.simd_le(zero), zero, g)
}

/// `bsdf::conductor_fresnel`.
#[inline(always)]
fn conductor_fresnel(cos_i: V, eta: V3, k: V3) -> V3 {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    // `f32::clamp(0.0, 1.0)`.
    let c = V::select(cos_i.simd_lt(zero), zero, cos_i);
    let c = V::select(gt(c, one), one, c);
    let c2 = c * c;
    let two_c = V::splat(2.0) * c;
    let max_index = V::splat(MAX_CONDUCTOR_INDEX);
    let channel = |eta: V, k: V| {
        let (eta, k) = (min(eta, max_index), min(k, max_index));
        let e2k2 = eta * eta + k * k;
        let two_eta_c = two_c * eta;
        let rs = (e2k2 - two_eta_c + c2) / (e2k2 + two_eta_c + c2);
        let rp = (e2k2 * c2 - two_eta_c + one) / (e2k2 * c2 + two_eta_c + one);
        V::splat(0.5) * (rs + rp)
    };
    V3 { x: channel(eta.x, k.x), y: channel(eta.y, k.y), z: channel(eta.z, k.z) }
}

/// glam's `normalize`: `v * (1 / |v|)`.
#[inline(always)]
fn normalize(v: V3) -> V3 {
    v.scale(V::splat(1.0) / v.dot(v).sqrt())
}

/// `bsdf::microfacet_f` without its test of `wo.z` and `wi.z` (callers select on it).
#[inline(always)]
fn f_facing(m: &MicrofacetLanes, wo: V3, wi: V3) -> V3 {
    let h = normalize(wo.add(wi));
    let g = smith_g1(m.alpha, wo) * smith_g1(m.alpha, wi);
    let s = g * beckmann_d(m, h) / (V::splat(4.0) * wo.z * wi.z);
    conductor_fresnel(wi.dot(h), m.eta, m.k).scale(s)
}

/// `bsdf::eval` of a microfacet material at lanes where `wo.z > 0` and `wi.z > 0`
/// (`facing`), zero elsewhere.
#[inline(always)]
pub(super) fn eval(m: &MicrofacetLanes, wo: V3, wi: V3, facing: V) -> V3 {
    V3::select(facing, f_facing(m, wo, wi), V3::splat(Vec3::ZERO))
}

/// `beckmann_d(h) h.z / (4 wo.h)`: the solid-angle pdf of the sampled `wi` whose half
/// vector is `h`.
#[inline(always)]
fn pdf_of_half(m: &MicrofacetLanes, wo: V3, h: V3) -> V {
    beckmann_d(m, h) * h.z / (V::splat(4.0) * wo.dot(h))
}

/// `bsdf::pdf` of a microfacet material at lanes that are `facing` (as `eval`), zero
/// elsewhere.
#[inline(always)]
pub(super) fn pdf(m: &MicrofacetLanes, wo: V3, wi: V3, facing: V) -> V {
    let h = normalize(wo.add(wi));
    V::select(facing, pdf_of_half(m, wo, h), V::splat(0.0))
}

/// A sampled direction, as `bsdf::sample` returns it for a microfacet material: `valid`
/// masks the lanes where it returns one.
pub(super) struct MicrofacetSample {
    pub(super) wi: V3,
    pub(super) weight: V3,
    pub(super) pdf: V,
    pub(super) valid: V,
}

/// `bsdf::sample` of a microfacet material from the numbers `u1`, `u2`.
#[inline(always)]
pub(super) fn sample(m: &MicrofacetLanes, wo: V3, u1: V, u2: V) -> MicrofacetSample {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    // `bsdf::sample_beckmann`.
    let ln = ln_unit(max(one - u1, V::splat(f32::MIN_POSITIVE)));
    let tan2 = V::splat(-1.0) * m.alpha * m.alpha * ln;
    let cos_t = one / (one + tan2).sqrt();
    let sin_t = max(one - cos_t * cos_t, zero).sqrt();
    let (sin_phi, cos_phi) = sincos_turns(u2);
    let h = V3 { x: sin_t * cos_phi, y: sin_t * sin_phi, z: cos_t };
    let wi = h.scale(V::splat(2.0) * wo.dot(h)).sub(wo);
    let pdf = pdf_of_half(m, wo, h);
    let f = f_facing(m, wo, wi);
    MicrofacetSample {
        wi,
        weight: f.scale(wi.z).div(pdf),
        pdf,
        valid: gt(wo.z, zero) & gt(wi.z, zero) & gt(pdf, zero),
    }
}
