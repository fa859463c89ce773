//! Primitive storage and ray-primitive tests: SoA triangles with the watertight test (scalar, one
//! ray against 8 triangles, and 8 rays against one triangle), the course's analytic spheres, and
//! the primitive id that names either (`prim`).

pub mod prim;
pub mod sphere;
pub mod triangles;
pub mod watertight;

pub use triangles::TriangleSoa;
