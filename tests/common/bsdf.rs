//! The materials, directions and small helpers the BSDF tests share (`tests/bsdf.rs`,
//! `tests/bsdf_chi2.rs`).

use pathtracer::math::Vec3;
use pathtracer::sampler::Pcg32;
use pathtracer::scene::Material;

/// Aluminium and silver as the course's `CBspheres_microfacet_al_ag.dae` has them, and a
/// near-perfect conductor (Fresnel reflectance ~1).
pub const CONDUCTORS: [(&str, [f32; 3], [f32; 3]); 3] = [
    ("al", [1.3352, 1.0109, 0.68955], [7.3398, 6.6157, 5.6471]),
    ("ag", [0.059193, 0.059881, 0.047366], [4.1283, 3.5892, 2.8132]),
    ("perfect", [1.0, 1.0, 1.0], [1e3, 1e3, 1e3]),
];
pub const ALPHAS: [f32; 3] = [0.05, 0.2, 0.5];

/// (theta, phi) in degrees of the outgoing directions above the surface: the normal, 45
/// degrees, grazing, and one off the x axis (so that a lobe mirrored about the wrong axis
/// shows).
pub const WO_ANGLES: [(f32, f32); 4] = [(0.0, 0.0), (45.0, 0.0), (85.0, 0.0), (60.0, 130.0)];

pub fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

pub fn microfacet(alpha: f32, eta: [f32; 3], k: [f32; 3]) -> Material {
    Material::Microfacet { alpha, eta: Vec3::from_array(eta), k: Vec3::from_array(k) }
}

/// Every smooth material of the course with a name.
pub fn smooth_materials() -> Vec<(String, Material)> {
    let mut out =
        vec![("diffuse".to_string(), Material::Diffuse { albedo: Vec3::new(0.2, 0.5, 0.8) })];
    for alpha in ALPHAS {
        for (name, eta, k) in CONDUCTORS {
            out.push((format!("microfacet {name} alpha {alpha}"), microfacet(alpha, eta, k)));
        }
    }
    out
}

/// Chi-square tests run in this file (the smooth materials x the directions), for Bonferroni.
pub const CHI2_TESTS: usize = (1 + ALPHAS.len() * CONDUCTORS.len()) * WO_ANGLES.len();
pub const SIGNIFICANCE: f64 = 1e-2 / CHI2_TESTS as f64;

pub fn u3(rng: &mut Pcg32) -> [f32; 3] {
    [rng.next_f32(), rng.next_f32(), rng.next_f32()]
}

pub fn rel_close(a: Vec3, b: Vec3, rel: f32) -> bool {
    (a - b).abs().max_element() <= rel * a.abs().max(b.abs()).max_element()
}
