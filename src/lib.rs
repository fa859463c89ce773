//! A data-oriented SIMD ray-packet path tracer for the CS184 "PathTracer-1" scene format.
//!
//! Data flows one way, and each module imports only those to its left:
//!
//! ```text
//! scene file -> scene (model + COLLADA loader + camera)
//!            -> simd (lane-width-generic f32x4 / f32x8 helpers)
//!            -> geometry (SoA triangles, Möller-Trumbore, spheres)
//!            -> accel (binned-SAH BVH, flat nodes, single-ray and packet traversal)
//!            -> wavefront (generate -> extend -> shade -> shadow -> accumulate)
//!            -> film (linear accumulator) -> image file (PNG tone-mapped, EXR linear)
//! ```

pub mod accel;
pub mod bench;
pub mod convergence;
pub mod error;
pub mod film;
pub mod geometry;
pub mod integrator;
pub mod math;
pub mod metrics;
pub mod procedural;
pub mod render;
pub mod sampler;
pub mod scene;
pub mod simd;
pub mod staged;
pub mod wavefront;

pub use error::{Error, Result};
