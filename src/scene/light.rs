use crate::math::Vec3;

/// Scene lights (COLLADA `instance_light`). They are not geometry: only light sampling reaches
/// them. See SCENE_FORMAT.md for how each is placed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    /// A one-sided rectangle: points `position + u * dim_x + v * dim_y`, u, v in [-1/2, 1/2],
    /// radiating `radiance` into the half-space that unit `direction` points to.
    Area { position: Vec3, direction: Vec3, dim_x: Vec3, dim_y: Vec3, radiance: Vec3 },
    /// A point light without distance falloff (course semantics): `radiance` arrives unscaled.
    Point { position: Vec3, radiance: Vec3 },
    /// Light from unit direction `direction` (pointing towards the light).
    Directional { direction: Vec3, radiance: Vec3 },
    /// A uniform sky over the upper (+Y) hemisphere.
    Ambient { radiance: Vec3 },
}

impl Light {
    pub fn kind(&self) -> &'static str {
        match self {
            Light::Area { .. } => "area",
            Light::Point { .. } => "point",
            Light::Directional { .. } => "directional",
            Light::Ambient { .. } => "ambient",
        }
    }

    /// Delta lights cannot be found by sampling directions (uniform hemisphere sampling).
    pub fn is_delta(&self) -> bool {
        matches!(self, Light::Point { .. } | Light::Directional { .. })
    }
}
