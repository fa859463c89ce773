//! BSDF evaluation and sampling for the course materials, in a local shading frame where the
//! normal is +z. Directions `wo` (towards the viewer) and `wi` (towards the light) are unit
//! vectors in that frame.

use std::f32::consts::{FRAC_1_PI, PI};

use crate::math::{exp_nonpositive, ln_unit, sincos_turns, Vec3};
use crate::scene::Material;

/// A sampled incident direction and its weight f * |cos| / pdf.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfSample {
    /// Unit incident direction, in the local shading frame.
    pub wi: Vec3,
    /// f * |cos| / pdf: what the path's throughput is multiplied by.
    pub weight: Vec3,
    /// Solid-angle pdf; 0 for a delta (specular) lobe, where MIS does not apply.
    pub pdf: f32,
}

/// Whether light sampling can ever help at this material (delta lobes have f = 0 almost
/// everywhere, so next-event estimation is skipped for them).
pub fn has_smooth_lobe(m: &Material) -> bool {
    matches!(m, Material::Diffuse { .. } | Material::Microfacet { .. })
}

/// Whether `sample` reads its third number (the lobe choice).
pub fn chooses_lobe(m: &Material) -> bool {
    matches!(m, Material::Glass { .. })
}

/// f(wo, wi) for the smooth lobes; zero for delta lobes and emitters.
pub fn eval(m: &Material, wo: Vec3, wi: Vec3) -> Vec3 {
    match *m {
        Material::Diffuse { albedo } if wo.z > 0.0 && wi.z > 0.0 => albedo * FRAC_1_PI,
        Material::Microfacet { alpha, eta, k } => microfacet_f(alpha, eta, k, wo, wi),
        _ => Vec3::ZERO,
    }
}

/// Solid-angle pdf with which `sample` would pick `wi` (smooth lobes only).
pub fn pdf(m: &Material, wo: Vec3, wi: Vec3) -> f32 {
    match *m {
        Material::Diffuse { .. } if wo.z > 0.0 && wi.z > 0.0 => wi.z * FRAC_1_PI,
        Material::Microfacet { alpha, .. } if wo.z > 0.0 && wi.z > 0.0 => {
            let h = (wo + wi).normalize();
            beckmann_d(alpha, h) * h.z / (4.0 * wo.dot(h))
        }
        _ => 0.0,
    }
}

/// Samples wi given wo and two uniform numbers (and a third for the glass lobe choice).
/// `None` means the path ends here (no valid direction, or an emitter, which reflects nothing).
pub fn sample(m: &Material, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
    match *m {
        Material::Diffuse { albedo } => {
            let wi = cosine_hemisphere(u[0], u[1]);
            (wo.z > 0.0 && wi.z > 0.0).then_some(BsdfSample {
                wi,
                weight: albedo,
                pdf: wi.z * FRAC_1_PI,
            })
        }
        Material::Emission { .. } => None,
        Material::Mirror { reflectance } => {
            (wo.z > 0.0).then_some(BsdfSample { wi: reflect(wo), weight: reflectance, pdf: 0.0 })
        }
        Material::Glass { reflectance, transmittance, ior, .. } => {
            let mirror = BsdfSample { wi: reflect(wo), weight: reflectance, pdf: 0.0 };
            match refract(wo, ior) {
                // Total internal reflection: all light reflects.
                None => Some(mirror),
                // Choose the lobe with the Fresnel probability, so the weight needs no R factor.
                // Schlick of |wo.z| on both sides, as the course does (from inside the physical
                // choice is the outside angle: tests/bsdf.rs, the ignored
                // `glass_reflects_from_inside_with_schlick_of_the_outside_angle`; PERF.md).
                Some(_) if u[2] < schlick(wo.z.abs(), ior) => Some(mirror),
                Some((wt, eta)) => {
                    Some(BsdfSample { wi: wt, weight: transmittance * (eta * eta), pdf: 0.0 })
                }
            }
        }
        Material::Refraction { transmittance, ior, .. } => {
            let (wt, eta) = refract(wo, ior)?;
            Some(BsdfSample { wi: wt, weight: transmittance * (eta * eta), pdf: 0.0 })
        }
        Material::Microfacet { alpha, eta, k } => {
            if wo.z <= 0.0 {
                return None;
            }
            let h = sample_beckmann(alpha, u[0], u[1]);
            let wi = 2.0 * wo.dot(h) * h - wo;
            if wi.z <= 0.0 {
                return None;
            }
            let pdf = beckmann_d(alpha, h) * h.z / (4.0 * wo.dot(h));
            let f = microfacet_f(alpha, eta, k, wo, wi);
            (pdf > 0.0).then(|| BsdfSample { wi, weight: f * wi.z / pdf, pdf })
        }
    }
}

/// Cosine-weighted direction about +z (pdf cos / pi), by Malley's method.
pub fn cosine_hemisphere(u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let (sin_phi, cos_phi) = crate::math::sincos_turns(u2);
    Vec3::new(r * cos_phi, r * sin_phi, (1.0 - u1).max(0.0).sqrt())
}

/// Uniform direction over the +z hemisphere (pdf 1 / (2 pi)). The angle's sine and cosine by
/// `sincos_turns`, as `cosine_hemisphere`, so that shading lanes repeat it bit for bit.
pub fn uniform_hemisphere(u1: f32, u2: f32) -> Vec3 {
    let z = u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (sin_phi, cos_phi) = crate::math::sincos_turns(u2);
    Vec3::new(r * cos_phi, r * sin_phi, z)
}

/// The pdf of `uniform_hemisphere`, 1 / (2 pi) per steradian.
pub const UNIFORM_HEMISPHERE_PDF: f32 = 1.0 / (2.0 * PI);

fn reflect(wo: Vec3) -> Vec3 {
    Vec3::new(-wo.x, -wo.y, wo.z)
}

/// Refracts wo through the interface (outside above +z has index 1, inside `ior`). Returns the
/// transmitted direction and eta = n_wo / n_wi, the index on the viewer's side over the index
/// on the side the path continues into, or `None` on total internal reflection. Radiance
/// scales with n^2 across the interface, so a transmitted sample's weight carries eta^2
/// (1 / ior^2 entering the glass, ior^2 leaving it; pbrt-v4's radiance-mode factor). Before
/// this was fixed the weight carried 1 / eta^2: the factors cancelled for paths that leave
/// the object again, so images were unchanged, but Russian roulette saw throughputs 2.25x too
/// high inside glass (tests/bsdf.rs, `transmission_scales_radiance_by_n_wo_over_n_wi_squared`).
fn refract(wo: Vec3, ior: f32) -> Option<(Vec3, f32)> {
    let entering = wo.z > 0.0;
    let eta = if entering { 1.0 / ior } else { ior };
    let cos_i = wo.z.abs();
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let wt = Vec3::new(-eta * wo.x, -eta * wo.y, if entering { -cos_t } else { cos_t });
    Some((wt, eta))
}

/// Schlick's approximation of the dielectric Fresnel reflectance (as the course uses). The
/// powers are written out as the multiplications `powi` would make (x^5 = x (x^2)^2), so that
/// the glass lanes (`delta_lanes`) repeat them operation for operation, in vector registers.
fn schlick(cos_i: f32, ior: f32) -> f32 {
    let r = (1.0 - ior) / (1.0 + ior);
    let r0 = r * r;
    let x = 1.0 - cos_i;
    let x2 = x * x;
    r0 + (1.0 - r0) * (x * (x2 * x2))
}

/// Beckmann normal distribution D(h).
fn beckmann_d(alpha: f32, h: Vec3) -> f32 {
    if h.z <= 0.0 {
        return 0.0;
    }
    let cos2 = h.z * h.z;
    let tan2 = (1.0 - cos2).max(0.0) / cos2;
    let a2 = alpha * alpha;
    exp_nonpositive(-tan2 / a2) / (PI * a2 * cos2 * cos2)
}

/// Samples a half vector with pdf D(h) cos(theta_h).
fn sample_beckmann(alpha: f32, u1: f32, u2: f32) -> Vec3 {
    let tan2 = -alpha * alpha * ln_unit((1.0 - u1).max(f32::MIN_POSITIVE));
    let cos_t = 1.0 / (1.0 + tan2).sqrt();
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    // The angle 2 pi u2 by `sincos_turns`, which the lanes repeat (libm's `sinf` and `cosf`
    // there cost a call per lane).
    let (sin_phi, cos_phi) = sincos_turns(u2);
    Vec3::new(sin_t * cos_phi, sin_t * sin_phi, cos_t)
}

/// Smith shadowing-masking for Beckmann (rational approximation of Walter et al. 2007).
fn smith_g1(alpha: f32, w: Vec3) -> f32 {
    let cos = w.z;
    if cos <= 0.0 {
        return 0.0;
    }
    let tan = (1.0 - cos * cos).max(0.0).sqrt() / cos;
    if tan == 0.0 {
        return 1.0;
    }
    let a = 1.0 / (alpha * tan);
    if a >= 1.6 {
        return 1.0;
    }
    (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
}

/// The largest conductor index `conductor_fresnel` uses: the reflectance is 1 in f32 well
/// before it, and its square stays finite. A scene's finite index of 2^64 or 3.4e38 squared
/// to infinity, and the ratios below to inf / inf = NaN pixels.
pub(super) const MAX_CONDUCTOR_INDEX: f32 = 1e18;

/// Fresnel reflectance of a conductor with complex index eta + i k, per channel (each part
/// held at `MAX_CONDUCTOR_INDEX`).
fn conductor_fresnel(cos_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
    let c = cos_i.clamp(0.0, 1.0);
    let c2 = Vec3::splat(c * c);
    let (eta, k) =
        (eta.min(Vec3::splat(MAX_CONDUCTOR_INDEX)), k.min(Vec3::splat(MAX_CONDUCTOR_INDEX)));
    let e2k2 = eta * eta + k * k;
    let two_eta_c = 2.0 * c * eta;
    let rs = (e2k2 - two_eta_c + c2) / (e2k2 + two_eta_c + c2);
    let rp = (e2k2 * c2 - two_eta_c + Vec3::ONE) / (e2k2 * c2 + two_eta_c + Vec3::ONE);
    0.5 * (rs + rp)
}

fn microfacet_f(alpha: f32, eta: Vec3, k: Vec3, wo: Vec3, wi: Vec3) -> Vec3 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Vec3::ZERO;
    }
    let h = (wo + wi).normalize();
    let g = smith_g1(alpha, wo) * smith_g1(alpha, wi);
    conductor_fresnel(wi.dot(h), eta, k) * (g * beckmann_d(alpha, h) / (4.0 * wo.z * wi.z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::Pcg32;

    fn mc_albedo(m: &Material, wo: Vec3, n: usize) -> Vec3 {
        let mut rng = Pcg32::new(7, 1);
        let mut sum = Vec3::ZERO;
        for _ in 0..n {
            if let Some(s) = sample(m, wo, [rng.next_f32(), rng.next_f32(), rng.next_f32()]) {
                sum += s.weight;
            }
        }
        sum / n as f32
    }

    #[test]
    fn lambertian_sampling_returns_the_albedo() {
        let m = Material::Diffuse { albedo: Vec3::new(0.2, 0.5, 0.8) };
        let a = mc_albedo(&m, Vec3::new(0.3, 0.1, 0.9).normalize(), 1000);
        assert!((a - Vec3::new(0.2, 0.5, 0.8)).abs().max_element() < 1e-4, "{a}");
    }

    #[test]
    fn sampled_weight_matches_eval_over_pdf() {
        let m = Material::Microfacet {
            alpha: 0.3,
            eta: Vec3::new(0.2, 0.9, 1.1),
            k: Vec3::new(3.9, 2.4, 2.2),
        };
        let wo = Vec3::new(0.4, -0.2, 0.8).normalize();
        let mut rng = Pcg32::new(3, 3);
        for _ in 0..1000 {
            let Some(s) = sample(&m, wo, [rng.next_f32(), rng.next_f32(), 0.0]) else {
                continue;
            };
            let expect = eval(&m, wo, s.wi) * s.wi.z / pdf(&m, wo, s.wi);
            assert!(
                (s.weight - expect).abs().max_element() <= 1e-3 * expect.max_element().max(1.0)
            );
        }
    }

    #[test]
    fn microfacet_conserves_energy() {
        // A conductor with F ~ 1 (huge k) reflects at most all light; at alpha 0.2 almost all.
        let m = Material::Microfacet { alpha: 0.2, eta: Vec3::ONE, k: Vec3::splat(1e3) };
        let a = mc_albedo(&m, Vec3::new(0.3, 0.0, 0.95).normalize(), 200_000);
        assert!(a.max_element() <= 1.02 && a.min_element() > 0.85, "{a}");
    }

    #[test]
    fn conductor_fresnel_of_an_index_whose_square_overflows_is_a_mirror() {
        // 2^64 and 3.4e38 are finite f32s whose squares are not (fuzzed scenes' eta made NaN
        // pixels).
        for huge in [2f32.powi(64), 3.4e38].map(Vec3::splat) {
            for c in [0.0, 0.3, 0.6, 1.0] {
                assert_eq!(conductor_fresnel(c, huge, Vec3::ONE), Vec3::ONE, "cos {c}");
                assert_eq!(conductor_fresnel(c, Vec3::ONE, huge), Vec3::ONE, "cos {c}");
            }
        }
    }

    #[test]
    fn beckmann_pdf_integrates_to_one() {
        // Integrate pdf(wo, wi) over the hemisphere by uniform sampling: expect <= 1 (the part of
        // the lobe below the horizon is lost), close to 1 for a smooth lobe at normal incidence.
        let m = Material::Microfacet { alpha: 0.3, eta: Vec3::ONE, k: Vec3::ONE };
        let wo = Vec3::Z;
        let mut rng = Pcg32::new(5, 5);
        let n = 400_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let wi = uniform_hemisphere(rng.next_f32(), rng.next_f32());
            sum += pdf(&m, wo, wi) / UNIFORM_HEMISPHERE_PDF;
        }
        let integral = sum / n as f32;
        assert!((integral - 1.0).abs() < 0.03, "{integral}");
    }

    #[test]
    fn glass_refracts_by_snell_and_reflects_totally_inside() {
        let ior = 1.5;
        let wo = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
        let (wt, eta) = refract(wo, ior).unwrap();
        assert!((eta - 1.0 / ior).abs() < 1e-6);
        // sin_t = sin_i / ior
        let sin_t = (wt.x * wt.x + wt.y * wt.y).sqrt();
        assert!((sin_t - 0.5 / ior).abs() < 1e-6 && wt.z < 0.0);
        // From inside at a grazing angle: total internal reflection.
        assert!(refract(Vec3::new(0.9, 0.0, -(0.19f32).sqrt()), ior).is_none());
        let g = Material::Glass {
            reflectance: Vec3::ONE,
            transmittance: Vec3::ONE,
            roughness: 0.0,
            ior,
        };
        let s = sample(&g, Vec3::new(0.9, 0.0, -(0.19f32).sqrt()), [0.0, 0.0, 0.99]).unwrap();
        assert!(s.wi.z < 0.0, "TIR reflects back inside");
    }
}
