//! The scene's lights, as the loader places them.

use crate::math::Vec3;

/// Scene lights (COLLADA `instance_light`). They are not geometry: only light sampling reaches
/// them. See SCENE_FORMAT.md for how each is placed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Light {
    /// A one-sided rectangle: points `position + u * dim_x + v * dim_y`, u, v in [-1/2, 1/2],
    /// radiating `radiance` into the half-space that unit `direction` points to.
    Area {
        /// The rectangle's centre.
        position: Vec3,
        /// Unit normal of the lit side.
        direction: Vec3,
        /// The rectangle's first side, as a vector.
        dim_x: Vec3,
        /// The rectangle's second side, as a vector.
        dim_y: Vec3,
        /// Emitted radiance.
        radiance: Vec3,
    },
    /// A point light without distance falloff (course semantics): `radiance` arrives unscaled.
    Point {
        /// Where the light is.
        position: Vec3,
        /// Radiance arriving from it.
        radiance: Vec3,
    },
    /// Light from unit direction `direction` (pointing towards the light).
    Directional {
        /// Unit direction towards the light.
        direction: Vec3,
        /// Radiance arriving from it.
        radiance: Vec3,
    },
    /// A uniform sky over the upper (+Y) hemisphere.
    Ambient {
        /// Radiance arriving from every upward direction.
        radiance: Vec3,
    },
}

impl Light {
    /// The light's kind as a word (`area`, `point`, `directional`, `ambient`), for messages
    /// and the scene summary.
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
