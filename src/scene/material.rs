//! The scene's materials: the course's closed set of BSDFs.

use crate::math::Vec3;

/// The closed set of BSDFs of the course scenes (CGL profile), one variant each.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Material {
    /// Lambertian, f = albedo / pi (profile_COMMON phong `diffuse`, or 0.5 grey).
    Diffuse {
        /// Reflectance per RGB channel.
        albedo: Vec3,
    },
    /// An emitter: front side radiates `radiance`, reflects nothing.
    Emission {
        /// Emitted radiance.
        radiance: Vec3,
    },
    /// A perfect mirror.
    Mirror {
        /// Reflectance per RGB channel.
        reflectance: Vec3,
    },
    /// A dielectric that reflects and refracts (Fresnel).
    Glass {
        /// Tint of the reflected light.
        reflectance: Vec3,
        /// Tint of the refracted light.
        transmittance: Vec3,
        /// As the file gives it; shading treats the surface as smooth.
        roughness: f32,
        /// Index of refraction.
        ior: f32,
    },
    /// A dielectric that only refracts.
    Refraction {
        /// Tint of the refracted light.
        transmittance: Vec3,
        /// As the file gives it; shading treats the surface as smooth.
        roughness: f32,
        /// Index of refraction.
        ior: f32,
    },
    /// A rough conductor (Beckmann/GGX `alpha`, complex index eta + i k per RGB channel).
    Microfacet {
        /// Surface roughness.
        alpha: f32,
        /// Real part of the index of refraction, per channel.
        eta: Vec3,
        /// Imaginary part (absorption), per channel.
        k: Vec3,
    },
}

impl Material {
    /// The material's kind as a word (`diffuse`, `glass`, ...), for messages and the scene
    /// summary.
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

    /// Whether the material scatters only into single directions (mirror, glass, refraction):
    /// its vertices sample no lights.
    pub fn is_specular(&self) -> bool {
        matches!(
            self,
            Material::Mirror { .. } | Material::Glass { .. } | Material::Refraction { .. }
        )
    }

    /// The radiance the material emits: `radiance` for [`Material::Emission`], else zero.
    pub fn emission(&self) -> Vec3 {
        match self {
            Material::Emission { radiance } => *radiance,
            _ => Vec3::ZERO,
        }
    }
}
