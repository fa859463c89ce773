//! The course's specular materials (`bsdf`: mirror, glass, refraction) over `LANES` vertices,
//! for `diffuse`'s lanes: their BSDF samples, as `bsdf::sample` computes them, operation for
//! operation, so that lanes and scalar code agree bit for bit (tests/lighting.rs). These
//! vertices sample no lights (`path::shade_hit`: delta lobes have no smooth part), so a sample
//! is all they need.

use super::lane_math::{gt, max, neg, Lanes, V, V3};
use crate::math::Vec3;
use crate::scene::Material;
use crate::simd::{Arith, SimdF32};

/// Per-lane parameters of the specular lanes, as `diffuse::DiffuseLanes` stores them.
#[derive(Default)]
pub(super) struct DeltaParams {
    /// Lanes of each specular material, as bit masks.
    mirror: u32,
    glass: u32,
    refraction: u32,
    reflectance: [Lanes; 3],
    transmittance: [Lanes; 3],
    ior: Lanes,
}

impl DeltaParams {
    /// No specular lanes.
    #[inline]
    pub(super) fn clear(&mut self) {
        (self.mirror, self.glass, self.refraction) = (0, 0, 0);
    }

    /// Lanes that hold a specular vertex.
    #[inline(always)]
    pub(super) fn bits(&self) -> u32 {
        self.mirror | self.glass | self.refraction
    }

    /// Lanes whose material is transmissive: their normals keep the outward side.
    #[inline(always)]
    pub(super) fn transmissive(&self) -> u32 {
        self.glass | self.refraction
    }

    /// Stores lane `l`'s material, if it is specular; whether it was.
    #[inline]
    pub(super) fn set(&mut self, l: usize, m: &Material) -> bool {
        let put = |a: &mut [Lanes; 3], v: Vec3| (a[0][l], a[1][l], a[2][l]) = (v.x, v.y, v.z);
        match *m {
            Material::Mirror { reflectance } => {
                self.mirror |= 1 << l;
                put(&mut self.reflectance, reflectance);
            }
            Material::Glass { reflectance, transmittance, ior, .. } => {
                self.glass |= 1 << l;
                put(&mut self.reflectance, reflectance);
                put(&mut self.transmittance, transmittance);
                self.ior[l] = ior;
            }
            Material::Refraction { transmittance, ior, .. } => {
                self.refraction |= 1 << l;
                put(&mut self.transmittance, transmittance);
                self.ior[l] = ior;
            }
            _ => return false,
        }
        true
    }
}

/// `bsdf::sample` of the specular lanes: the direction and weight (the pdf is 0), and `valid`
/// masking the lanes where it returns one. Lanes that are not specular read nonsense.
pub(super) struct DeltaSample {
    pub(super) wi: V3,
    pub(super) weight: V3,
    pub(super) valid: V,
}

/// `bsdf::sample` for the specular lanes of `d`, with the lobe choice's number `lobe`.
#[inline(always)]
pub(super) fn sample(d: &DeltaParams, wo: V3, lobe: V) -> DeltaSample {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let ior = V::load(&d.ior);
    // `bsdf::refract`.
    let entering = gt(wo.z, zero);
    let eta = V::select(entering, one / ior, ior);
    let cos_i = Arith::abs(wo.z);
    let sin2_t = eta * eta * max(one - cos_i * cos_i, zero);
    let tir = sin2_t.simd_ge(one);
    let cos_t = (one - sin2_t).sqrt();
    let wt =
        V3 { x: neg(eta) * wo.x, y: neg(eta) * wo.y, z: V::select(entering, neg(cos_t), cos_t) };
    // `bsdf::schlick(|wo.z|, ior)`, in the glass lanes.
    let r = (one - ior) / (one + ior);
    let r0 = r * r;
    let x = one - cos_i;
    let x2 = x * x;
    let fresnel = r0 + (one - r0) * (x * (x2 * x2));
    let mirror_lanes = V::from_bitmask(d.mirror);
    let glass_lanes = V::from_bitmask(d.glass);
    let reflect = mirror_lanes | (glass_lanes & (tir | lobe.simd_lt(fresnel)));
    let reflected = V3 { x: neg(wo.x), y: neg(wo.y), z: wo.z };
    let reflectance = V3::load(&d.reflectance);
    let transmitted = V3::load(&d.transmittance).scale(eta * eta);
    // Mirror: `wo.z > 0`; glass: always (total internal reflection reflects); refraction:
    // unless totally reflected.
    let (refraction_lanes, all) = (V::from_bitmask(d.refraction), zero.simd_eq(zero));
    let refracts = V::select(tir, zero, all);
    let valid = V::select(mirror_lanes, entering, V::select(refraction_lanes, refracts, all));
    DeltaSample {
        wi: V3::select(reflect, reflected, wt),
        weight: V3::select(reflect, reflectance, transmitted),
        valid,
    }
}
