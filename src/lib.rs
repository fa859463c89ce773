//! A data-oriented SIMD ray-packet path tracer for the CS184 "PathTracer-1" scene format.
//!
//! # The front door
//!
//! What an embedding program needs is re-exported here: a [`Scene`] ([`Scene::load`] reads a
//! COLLADA file), the acceleration structure [`Accel`] built over it ([`Accel::new`]), rays
//! ([`Ray`]) traced alone ([`Accel::closest_hit`], [`Accel::any_hit`]) or as packets of 4, 8
//! or 16 ([`Accel::closest_hit_packet`], [`Accel::any_hit_packet`]; [`RayPacket`] is the SoA
//! packet itself), the [`Hit`] they return, a [`RenderConfig`] for [`render()`], the image it
//! returns ([`RenderOutput`]) and [`write_image`] to save it. The counting variants
//! ([`Accel::intersect`], [`Accel::occluded`], [`Accel::intersect_packet`], ...) take a
//! [`TraceStats`] that they add their exact work to. Every failure is an [`Error`]: match on
//! its variant, or print it as one line.
//!
//! ```
//! use pathtracer::{Accel, Error, Ray, RenderConfig, Scene, Vec3};
//!
//! # fn main() -> pathtracer::Result<()> {
//! // A scene file: the project's Cornell box (open towards +z), as `pathtracer gen` writes it.
//! let dir = std::env::temp_dir().join(format!("pathtracer-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! let path = dir.join("cornell.dae");
//! std::fs::write(&path, pathtracer::procedural::cornell_box()).unwrap();
//!
//! let scene = Scene::load(&path)?;
//! let accel = Accel::new(&scene);
//!
//! // One ray through the open front hits the back wall at z = -1; one away from the box
//! // hits nothing.
//! let ray = Ray::new(Vec3::new(0.0, 1.5, 3.0), Vec3::NEG_Z);
//! let hit = accel.closest_hit(&ray).expect("the back wall");
//! assert!((ray.at(hit.t).z + 1.0).abs() < 1e-4);
//! assert!(!accel.any_hit(&Ray::new(Vec3::new(0.0, 1.5, 3.0), Vec3::Z)));
//!
//! // Eight rays as one packet: the same answers as one at a time.
//! let rays: Vec<Ray> =
//!     (0..8).map(|i| Ray::new(Vec3::new(-0.7 + 0.2 * i as f32, 1.5, 3.0), Vec3::NEG_Z)).collect();
//! let mut hits = [None; 8];
//! accel.closest_hit_packet::<8>(&rays, &mut hits);
//! for (ray, hit) in rays.iter().zip(&hits) {
//!     assert_eq!(*hit, accel.closest_hit(ray));
//! }
//!
//! // A small image (normal shading by default) saved as PNG.
//! let config = RenderConfig { width: 32, height: 24, ..RenderConfig::default() };
//! let image = pathtracer::render(&scene, &accel, &config)?;
//! assert_eq!(image.pixels.len(), 32 * 24);
//! pathtracer::write_image(&dir.join("cornell.png"), image.width, image.height, &image.pixels)?;
//!
//! // Errors are typed: a missing file is an I/O error naming it.
//! match Scene::load(dir.join("missing.dae")) {
//!     Err(Error::Io { path, .. }) => assert!(path.ends_with("missing.dae")),
//!     other => panic!("expected an I/O error, got {other:?}"),
//! }
//! std::fs::remove_dir_all(&dir).unwrap();
//! # Ok(())
//! # }
//! ```
//!
//! # Layout
//!
//! Data flows one way (scene file -> `scene` -> `accel` -> `wavefront` stages -> `film` -> image
//! file), and imports run one way too: each module imports only modules before it in
//!
//! ```text
//! error        the error enum and `bail!`
//! staged       a command's output files, written all or none (temporaries, signals)
//! math         Vec3, Aabb, Ray, Hit (scalar)
//! simd         lane types and helpers; `simd::isa`: the instruction-set level of this build
//! sampler      PCG32, Sobol, the per-path random numbers
//! scene        the scene model, COLLADA loader, camera (no limits of accel)
//! procedural   generated scenes (COLLADA text)
//! geometry     SoA triangles, the watertight triangle test, spheres, the primitive id (`geometry::prim`)
//! accel        binned-SAH BVH, 8-wide nodes, single-ray and packet traversal, its limits
//! film         image output (PNG tone-mapped, EXR linear)
//! integrator   BSDFs, lights, estimators; the render context, surface and queues they write
//! wavefront    the stage loop: generate -> extend -> shade -> shadow -> accumulate
//! render       tiles over threads, the render configuration; a crop and a range of samples
//! farm         plans of parts, `.ptpart` files of exact sums, the exact merge
//! metrics, convergence, bench, bvh_preview   tools built on whole renders
//! cli          the binary's commands (src/main.rs)
//! ```
//!
//! `.ci/module-order` checks this on every CI run.

#![warn(missing_docs)]

pub mod accel;
pub mod bench;
pub mod bvh_preview;
pub mod convergence;
pub mod error;
pub mod farm;
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

pub use accel::{Accel, AccelKind, BuildParams, RayPacket, TraceStats};
pub use error::{Error, Result};
pub use film::write_image;
pub use integrator::{DirectLighting, Integrator};
pub use math::{Aabb, Hit, Ray, Vec3};
pub use render::{render, RenderConfig, RenderOutput};
pub use sampler::SamplerKind;
pub use scene::{Camera, Scene};
