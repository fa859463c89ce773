//! Primitive storage and ray-primitive tests: SoA triangles with Möller-Trumbore (scalar, one
//! ray against 8 triangles, and 8 rays against one triangle), and the course's analytic spheres.

pub mod moller_trumbore;
pub mod sphere;
pub mod triangles;

pub use triangles::TriangleSoa;
