use crate::math::Vec3;

/// The closed set of BSDFs of the course scenes (CGL profile), one variant each.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Material {
    /// Lambertian, f = albedo / pi (profile_COMMON phong `diffuse`, or 0.5 grey).
    Diffuse { albedo: Vec3 },
    /// An emitter: front side radiates `radiance`, reflects nothing.
    Emission { radiance: Vec3 },
    /// A perfect mirror.
    Mirror { reflectance: Vec3 },
    /// A dielectric that reflects and refracts (Fresnel).
    Glass { reflectance: Vec3, transmittance: Vec3, roughness: f32, ior: f32 },
    /// A dielectric that only refracts.
    Refraction { transmittance: Vec3, roughness: f32, ior: f32 },
    /// A rough conductor (Beckmann/GGX `alpha`, complex index eta + i k per RGB channel).
    Microfacet { alpha: f32, eta: Vec3, k: Vec3 },
}

impl Material {
    pub fn kind(&self) -> &'static str {
        match self {
            Material::Diffuse { .. } => "diffuse",
            Material::Emission { .. } => "emission",
            Material::Mirror { .. } => "mirror",
            Material::Glass { .. } => "glass",
            Material::Refraction { .. } => "refraction",
            Material::Microfacet { .. } => "microfacet",
        }
    }

    pub fn emission(&self) -> Vec3 {
        match self {
            Material::Emission { radiance } => *radiance,
            _ => Vec3::ZERO,
        }
    }
}
