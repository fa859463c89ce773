//! Properties of the BSDFs (`pathtracer::integrator::bsdf`) that any correct implementation
//! has, whatever random numbers it draws: these pin the shading across a rewrite.
//!
//! - Smooth lobes (Diffuse, Microfacet): sampled directions follow the pdf that `pdf()`
//!   reports, by a chi-square test (`tests/bsdf_chi2.rs`).
//! - Sample weights equal f cos / pdf; f is reciprocal (the pdf integrating to at most 1 is
//!   checked beside the chi-square tests, with their cubature).
//! - White furnace: the mean sample weight is at most 1 (for dielectrics, once the radiance
//!   scaling of transmission is taken out, reflection and transmission probabilities sum to 1).
//! - Delta lobes (Mirror, Glass, Refraction): `eval` and `pdf` are 0, samples are the mirror
//!   direction or obey Snell's law, with the course's Schlick reflection probability, and
//!   total internal reflection past the critical angle.
//!
//! One `#[ignore]`d test asserts physics that the glass does not have: Schlick's R from inside
//! at the outside angle (the renderer keeps the course's Schlick of |wo.z| on both sides; the
//! physical choice was tried and measured 3% darker on the glass ball against Mitsuba 3's
//! exact-Fresnel reference, not yet understood: PERF.md "Whole renders: bias"). Run it with
//! `-- --ignored`. A second test found the transmission's eta^2 radiance scaling inverted;
//! that bug is fixed.
//!
//! Every test uses a fixed-seed PCG32, so it is deterministic.
//! `cargo test --release --test bsdf -- --nocapture` prints the chi-square p-values.

use pathtracer::integrator::bsdf::{eval, has_smooth_lobe, pdf, sample};
use pathtracer::math::Vec3;
use pathtracer::sampler::Pcg32;
use pathtracer::scene::Material;

mod common;

use common::bsdf::*;

// ------------------------------------------------------------------------------------------
// Weights, pdf normalisation, reciprocity, white furnace.

/// Every sample's weight is f cos / pdf and its pdf is `pdf()`, to 1e-3 relative.
#[test]
fn sample_weight_is_f_cos_over_pdf() {
    let mut rng = Pcg32::new(21, 3);
    for (name, m) in smooth_materials() {
        for (t, p) in WO_ANGLES {
            let wo = dir(t, p);
            let mut taken = 0;
            for _ in 0..100_000 {
                let Some(s) = sample(&m, wo, u3(&mut rng)) else { continue };
                taken += 1;
                let q = pdf(&m, wo, s.wi);
                let f = eval(&m, wo, s.wi);
                assert!(s.pdf > 0.0 && s.pdf != 0.0, "{name}: {s:?}");
                assert!((s.pdf - q).abs() <= 1e-3 * q, "{name} wo {wo}: pdf {} vs {q}", s.pdf);
                let want = f * s.wi.z / q;
                assert!(s.weight.is_finite() && s.weight.min_element() >= 0.0, "{name}: {s:?}");
                assert!(
                    rel_close(s.weight, want, 1e-3),
                    "{name} wo {wo} wi {}: weight {} vs f cos / pdf {want}",
                    s.wi,
                    s.weight
                );
            }
            assert!(taken > 10_000, "{name} wo ({t}, {p}): only {taken} samples");
        }
    }
}

/// f(wo, wi) = f(wi, wo) for random direction pairs: uniform over the sphere (above and across
/// the surface; a sharp lobe is 0 for most of them) and pairs where wi is sampled from wo (so
/// that the lobes' peaks are covered).
#[test]
fn smooth_lobes_are_reciprocal() {
    let mut rng = Pcg32::new(5, 8);
    let random_dir = |rng: &mut Pcg32| {
        let z = 2.0 * rng.next_f32() - 1.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * rng.next_f32();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    };
    for (name, m) in smooth_materials() {
        let mut nonzero = 0;
        for i in 0..20_000 {
            let a = random_dir(&mut rng);
            let b = match i % 2 {
                0 => random_dir(&mut rng),
                _ => sample(&m, a, u3(&mut rng)).map_or_else(|| random_dir(&mut rng), |s| s.wi),
            };
            let (ab, ba) = (eval(&m, a, b), eval(&m, b, a));
            assert!(ab.is_finite() && ab.min_element() >= 0.0, "{name}: f({a}, {b}) = {ab}");
            assert!(rel_close(ab, ba, 1e-4), "{name}: f({a}, {b}) = {ab} but f({b}, {a}) = {ba}");
            if a.z <= 0.0 || b.z <= 0.0 {
                assert_eq!(ab, Vec3::ZERO, "{name}: f across the surface");
            }
            nonzero += (ab.max_element() > 0.0) as u32;
        }
        assert!(nonzero > 5_000, "{name}: only {nonzero} nonzero pairs");
    }
}

/// Mean and standard error of `x` over `n` draws.
fn mean_se(n: usize, mut x: impl FnMut() -> f64) -> (f64, f64) {
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..n {
        let v = x();
        s += v;
        s2 += v * v;
    }
    let mean = s / n as f64;
    let var = (s2 / n as f64 - mean * mean).max(0.0) * n as f64 / (n as f64 - 1.0);
    (mean, (var / n as f64).sqrt())
}

/// White furnace of the smooth lobes: albedo 1, and a conductor whose Fresnel reflectance is
/// ~1 (k = 1e3). The mean sample weight (directional albedo) is at most 1 for every wo, exactly
/// 1 for the Diffuse lobe, and close to 1 for a Beckmann lobe that stays above the horizon.
#[test]
fn white_furnace_smooth_lobes_reflect_at_most_everything() {
    let mut materials = vec![("diffuse".to_string(), Material::Diffuse { albedo: Vec3::ONE })];
    for alpha in ALPHAS {
        materials
            .push((format!("microfacet alpha {alpha}"), microfacet(alpha, [1.0; 3], [1e3; 3])));
    }
    let mut rng = Pcg32::new(9, 9);
    for (name, m) in materials {
        for (t, p) in WO_ANGLES {
            let wo = dir(t, p);
            let (mean, se) = mean_se(400_000, || {
                sample(&m, wo, u3(&mut rng)).map_or(0.0, |s| s.weight.max_element() as f64)
            });
            eprintln!("furnace {name} wo ({t}, {p}): {mean:.5} +- {se:.5}");
            // Walter et al.'s rational Smith G1 is within ~0.4% of the exact one.
            assert!(mean <= 1.0 + 4.0 * se + 5e-3, "{name} wo ({t}, {p}): albedo {mean} > 1");
            match m {
                Material::Diffuse { .. } => assert!((mean - 1.0).abs() < 1e-6, "{name}: {mean}"),
                Material::Microfacet { alpha, .. } if alpha <= 0.2 && t <= 45.0 => {
                    assert!(mean > 0.95, "{name} wo ({t}, {p}): albedo {mean}")
                }
                _ => {}
            }
        }
    }
}

// ------------------------------------------------------------------------------------------
// Delta lobes: Mirror, Glass, Refraction.

const IORS: [f32; 2] = [1.5, 1.33];

/// The course's Schlick approximation R0 + (1 - R0) (1 - cos)^5, R0 = ((1 - ior) / (1 + ior))^2.
fn schlick(cos: f32, ior: f32) -> f32 {
    let r0 = ((1.0 - ior) / (1.0 + ior)).powi(2);
    r0 + (1.0 - r0) * (1.0 - cos).powi(5)
}

fn glass(ior: f32) -> Material {
    Material::Glass { reflectance: Vec3::ONE, transmittance: Vec3::ONE, roughness: 0.0, ior }
}

fn refraction(ior: f32) -> Material {
    Material::Refraction { transmittance: Vec3::ONE, roughness: 0.0, ior }
}

/// Outgoing directions for dielectrics: the WO_ANGLES and 30 degrees (inside, below the critical
/// angle of both IORS) outside, and the same mirrored inside.
fn dielectric_wos() -> Vec<Vec3> {
    let outside: Vec<Vec3> =
        WO_ANGLES.iter().chain(&[(30.0, 200.0)]).map(|&(t, p)| dir(t, p)).collect();
    outside.iter().copied().chain(outside.iter().map(|w| Vec3::new(w.x, w.y, -w.z))).collect()
}

/// The transmitted direction by Snell's law, or None past the critical angle.
fn snell(wo: Vec3, ior: f32) -> Option<Vec3> {
    let ratio = if wo.z > 0.0 { 1.0 / ior } else { ior }; // n_wo / n_wi
    let sin2_t = ratio * ratio * (1.0 - wo.z * wo.z);
    (sin2_t < 1.0)
        .then(|| Vec3::new(-ratio * wo.x, -ratio * wo.y, -wo.z.signum() * (1.0 - sin2_t).sqrt()))
}

fn mirror_dir(wo: Vec3) -> Vec3 {
    Vec3::new(-wo.x, -wo.y, wo.z)
}

#[test]
fn delta_lobes_have_zero_eval_and_pdf_and_no_smooth_lobe() {
    let deltas = [
        Material::Mirror { reflectance: Vec3::ONE },
        glass(1.5),
        glass(1.33),
        refraction(1.5),
        refraction(1.33),
    ];
    let mut rng = Pcg32::new(4, 4);
    for m in deltas {
        assert!(!has_smooth_lobe(&m), "{m:?}");
        for wo in dielectric_wos() {
            // Random directions and the lobes' own specular directions alike.
            let mut wis: Vec<Vec3> = (0..200)
                .map(|_| {
                    let z = 2.0 * rng.next_f32() - 1.0;
                    let r = (1.0 - z * z).sqrt();
                    let phi = std::f32::consts::TAU * rng.next_f32();
                    Vec3::new(r * phi.cos(), r * phi.sin(), z)
                })
                .collect();
            wis.push(mirror_dir(wo));
            wis.extend(IORS.iter().filter_map(|&ior| snell(wo, ior)));
            for wi in wis {
                assert_eq!(eval(&m, wo, wi), Vec3::ZERO, "{m:?} f({wo}, {wi})");
                assert_eq!(pdf(&m, wo, wi), 0.0, "{m:?} pdf({wo}, {wi})");
            }
            for _ in 0..100 {
                if let Some(s) = sample(&m, wo, u3(&mut rng)) {
                    assert!(s.pdf == 0.0, "{m:?}: {s:?}");
                }
            }
        }
    }
    for m in [Material::Diffuse { albedo: Vec3::ONE }, microfacet(0.2, [1.0; 3], [1e3; 3])] {
        assert!(has_smooth_lobe(&m), "{m:?}");
    }
    let emitter = Material::Emission { radiance: Vec3::ONE };
    assert!(!has_smooth_lobe(&emitter));
    assert!(sample(&emitter, Vec3::Z, [0.5; 3]).is_none(), "emitters reflect nothing");
}

#[test]
fn mirror_reflects_about_the_normal_with_its_reflectance() {
    let m = Material::Mirror { reflectance: Vec3::new(0.9, 0.8, 0.7) };
    let mut rng = Pcg32::new(6, 6);
    for (t, p) in WO_ANGLES {
        let wo = dir(t, p);
        for _ in 0..100 {
            let s = sample(&m, wo, u3(&mut rng)).expect("a mirror always reflects from above");
            assert!((s.wi - mirror_dir(wo)).length() < 1e-6, "{wo}: {}", s.wi);
            assert_eq!(s.weight, Vec3::new(0.9, 0.8, 0.7));
        }
    }
}

/// Sampled glass: reflection is the mirror direction with weight `reflectance`, transmission
/// obeys Snell's law, and the reflection probability from outside is Schlick's R at that angle
/// (within 4 binomial standard errors). White glass then keeps all energy: with the radiance
/// scaling of transmission taken out, every sample carries 1, so E = R + (1 - R) = 1.
#[test]
fn glass_reflects_with_schlick_probability_and_refracts_by_snell() {
    let n = 200_000;
    let mut rng = Pcg32::new(12, 12);
    for ior in IORS {
        let m = glass(ior);
        for wo in dielectric_wos() {
            let mut reflected = 0usize;
            let mut scale = None;
            for _ in 0..n {
                let s = sample(&m, wo, u3(&mut rng)).expect("glass always scatters");
                assert!(s.pdf == 0.0);
                if s.wi.z * wo.z > 0.0 {
                    reflected += 1;
                    assert!((s.wi - mirror_dir(wo)).length() < 1e-6, "{wo}: {}", s.wi);
                    assert_eq!(s.weight, Vec3::ONE, "reflection carries the reflectance alone");
                } else {
                    let want = snell(wo, ior).expect("no transmission past the critical angle");
                    assert!((s.wi - want).length() < 1e-5, "ior {ior} {wo}: {} vs {want}", s.wi);
                    assert!((s.wi.length() - 1.0).abs() < 1e-5);
                    // Transmission carries the transmittance times a radiance scaling that is
                    // the same for every sample at this wo (see the tests below).
                    assert!(s.weight.x == s.weight.y && s.weight.y == s.weight.z);
                    let w = s.weight.x;
                    assert!(*scale.get_or_insert(w) == w);
                }
            }
            let p = reflected as f64 / n as f64;
            match snell(wo, ior) {
                None => assert_eq!(reflected, n, "total internal reflection"),
                Some(_) if wo.z > 0.0 => {
                    let r = schlick(wo.z, ior) as f64;
                    let sigma = (r * (1.0 - r) / n as f64).sqrt();
                    eprintln!("glass {ior} wo {wo}: P(reflect) {p:.5} vs Schlick {r:.5}");
                    assert!(
                        (p - r).abs() < 4.0 * sigma + 1e-6,
                        "ior {ior} wo {wo}: P(reflect) {p} vs Schlick {r} (sigma {sigma})"
                    );
                }
                // From inside below the critical angle: `glass_reflects_from_inside_...` below.
                Some(_) => assert!(p < 1.0),
            }
        }
    }
}

/// Total internal reflection: from inside, past the critical angle asin(1 / ior), glass reflects
/// every sample back inside and the transmission-only material returns no sample.
#[test]
fn total_internal_reflection_from_inside_at_grazing_angles() {
    let mut rng = Pcg32::new(13, 13);
    for ior in IORS {
        let critical = (1.0 / ior).asin().to_degrees();
        for theta in [critical + 0.5, 60.0, 75.0, 85.0, 89.0] {
            for phi in [0.0, 130.0] {
                let w = dir(theta, phi);
                let wo = Vec3::new(w.x, w.y, -w.z);
                for _ in 0..1000 {
                    let s = sample(&glass(ior), wo, u3(&mut rng)).unwrap();
                    assert!(s.wi.z < 0.0, "ior {ior} theta {theta}: TIR stays inside");
                    assert!((s.wi - mirror_dir(wo)).length() < 1e-6);
                    assert_eq!(s.weight, Vec3::ONE);
                    assert!(sample(&refraction(ior), wo, u3(&mut rng)).is_none());
                }
            }
        }
        // Just inside the critical angle both still transmit.
        let w = dir(critical - 1.0, 0.0);
        let wo = Vec3::new(w.x, w.y, -w.z);
        assert!(sample(&refraction(ior), wo, [0.5; 3]).is_some_and(|s| s.wi.z > 0.0));
        assert!(sample(&glass(ior), wo, [0.0, 0.0, 0.9999]).is_some_and(|s| s.wi.z > 0.0));
    }
}

/// The transmission-only material: always transmits by Snell's law (no Fresnel reflection).
#[test]
fn refraction_always_transmits_by_snell() {
    let mut rng = Pcg32::new(14, 14);
    for ior in IORS {
        let t = Vec3::new(0.9, 0.7, 0.5);
        let m = Material::Refraction { transmittance: t, roughness: 0.0, ior };
        for wo in dielectric_wos() {
            let Some(want) = snell(wo, ior) else { continue };
            for _ in 0..100 {
                let s = sample(&m, wo, u3(&mut rng)).expect("below the critical angle");
                assert!(s.pdf == 0.0);
                assert!((s.wi - want).length() < 1e-5, "ior {ior} {wo}: {} vs {want}", s.wi);
                let scale = s.weight / t;
                assert!(rel_close(scale, Vec3::splat(scale.x), 1e-6), "{}", s.weight);
            }
        }
    }
}

/// Radiance scaling of transmission, as the renderer has it: the weight is the transmittance
/// times (n_a / n_b)^2 for the two media, and the scalings of entering and of leaving are
/// reciprocal, so a path through a closed dielectric comes out unscaled. With the scaling
/// taken out, white glass and white Refraction carry exactly 1 per sample (R + T = 1, and
/// T = 1 for Refraction): nothing is created.
#[test]
fn transmission_scaling_is_a_ratio_of_indices_squared_and_reciprocal() {
    let mut rng = Pcg32::new(15, 15);
    for ior in IORS {
        for m in [glass(ior), refraction(ior)] {
            for (t, p) in WO_ANGLES {
                let wo = dir(t, p);
                let transmitted = |wo: Vec3, rng: &mut Pcg32| loop {
                    let s = sample(&m, wo, u3(rng)).unwrap();
                    if s.wi.z * wo.z < 0.0 {
                        return s;
                    }
                };
                let enter = transmitted(wo, &mut rng);
                // The reversed path: seen from inside along the transmitted direction, the
                // light comes in from outside along wo.
                let leave = transmitted(enter.wi, &mut rng);
                assert!((leave.wi - wo).length() < 1e-4, "{m:?}: {} vs {wo}", leave.wi);
                let (a, b) = (enter.weight.x, leave.weight.x);
                let ior2 = ior * ior;
                assert!(
                    (a - ior2).abs() < 1e-5 * ior2 || (a - 1.0 / ior2).abs() < 1e-5 / ior2,
                    "{m:?} wo {wo}: scaling {a} is neither ior^2 nor 1 / ior^2"
                );
                assert!((a * b - 1.0).abs() < 1e-5, "{m:?}: entering {a} x leaving {b} != 1");
                // White furnace with the scaling taken out: exactly 1 per sample.
                let energy = (0..10_000)
                    .map(|_| {
                        let s = sample(&m, wo, u3(&mut rng)).unwrap();
                        let scaling = if s.wi.z * wo.z < 0.0 { a } else { 1.0 };
                        (s.weight.max_element() / scaling) as f64
                    })
                    .sum::<f64>()
                    / 10_000.0;
                assert!((energy - 1.0).abs() < 1e-6, "{m:?} wo {wo}: energy {energy}");
            }
        }
    }
}

/// The physical direction of the scaling: radiance over n^2 is invariant across a smooth
/// interface, so radiance seen from outside (n = 1) through glass (n = ior) is the radiance
/// inside times (1 - F) / ior^2 (pbrt's `ft *= Sqr(etaI / etaT)` in radiance mode, etaI on the
/// side of wo). The BSDF's own doc comment defines eta = n_incident / n_transmitted along the
/// light path (ior / 1 for a camera ray entering), and weights by 1 / eta^2.
// BUG: `refract` returns eta = 1 / ior for a ray entering from outside (contradicting its doc
// comment), so the weight is T * ior^2 = 2.25 T at ior 1.5 instead of T / ior^2 = 0.444 T,
// and the inverse when leaving. A path through a closed object cancels it; paths that end
// inside (depth limit, Russian roulette) or see light inside do not.
#[test]
fn transmission_scales_radiance_by_n_wo_over_n_wi_squared() {
    for ior in IORS {
        for m in [glass(ior), refraction(ior)] {
            for wo in dielectric_wos() {
                let Some(want_wi) = snell(wo, ior) else { continue };
                let (n_wo, n_wi) = if wo.z > 0.0 { (1.0, ior) } else { (ior, 1.0) };
                let want = (n_wo / n_wi) * (n_wo / n_wi);
                // u[2] = 0.9999 picks transmission for glass below grazing angles.
                let s = sample(&m, wo, [0.5, 0.5, 0.9999]).unwrap();
                assert!((s.wi - want_wi).length() < 1e-5);
                assert!(
                    (s.weight.x - want).abs() < 1e-5 * want,
                    "ior {ior} wo {wo}: transmission weight {} vs (n_wo / n_wi)^2 = {want}",
                    s.weight.x
                );
            }
        }
    }
}

/// Fresnel reflectance is the same from both sides of an interface (Stokes): from inside at
/// theta_i below the critical angle, glass must reflect with Schlick's R of the angle outside,
/// theta_t (Schlick's formula holds for the cosine on the side of the lower index), so that R
/// rises continuously to 1 at the critical angle.
#[test]
#[ignore = "course convention kept: from inside, the reflection probability is Schlick of the \
            inside angle (0.041 at 40 deg, ior 1.5) instead of the outside angle (0.246)"]
fn glass_reflects_from_inside_with_schlick_of_the_outside_angle() {
    let n = 200_000;
    let mut rng = Pcg32::new(16, 16);
    for ior in IORS {
        let m = glass(ior);
        for wo in dielectric_wos().into_iter().filter(|w| w.z < 0.0) {
            let Some(wt) = snell(wo, ior) else { continue };
            let reflected =
                (0..n).filter(|_| sample(&m, wo, u3(&mut rng)).unwrap().wi.z < 0.0).count();
            let p = reflected as f64 / n as f64;
            let r = schlick(wt.z.abs(), ior) as f64;
            let sigma = (r * (1.0 - r) / n as f64).sqrt();
            assert!(
                (p - r).abs() < 4.0 * sigma + 1e-6,
                "ior {ior} inside wo {wo}: P(reflect) {p:.4} vs Schlick(theta_t) {r:.4}"
            );
        }
        // The critical angle: R must be continuous there.
        let critical = (1.0 / ior).asin().to_degrees();
        let w = dir(critical - 0.2, 0.0);
        let wo = Vec3::new(w.x, w.y, -w.z);
        let reflected = (0..n).filter(|_| sample(&m, wo, u3(&mut rng)).unwrap().wi.z < 0.0).count();
        let p = reflected as f64 / n as f64;
        assert!(p > 0.5, "ior {ior}: 0.2 deg inside the critical angle P(reflect) = {p:.4}");
    }
}
