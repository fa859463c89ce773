//! Integrators are hooks called by the wavefront's shade stage: given a hit (or a miss) they add
//! radiance to the path and may queue continuation rays, shadow rays and emission probes. They
//! never trace rays themselves, so every integrator shares the same queues and traversal.
//!
//! What they read and write is defined here, before the wavefront that drives them:
//! `context.rs` (`RenderContext`, `Surface` at a hit, `ShadeOutputs`: the queues shading
//! appends to) and `queues.rs` (the SoA columns of the path state and the ray queues). The
//! wavefront re-exports them and owns only the stage loop and its scratch space.

pub mod bsdf;
mod context;
mod delta_lanes;
pub mod diffuse;
mod diffuse_out;
mod emitter_accel;
mod glossy_lanes;
mod lane_math;
mod light_lanes;
pub mod lights;
mod microfacet_lanes;
mod path;
mod queues;
mod rectangle;

pub use context::{emission_seen, surface_material, RenderContext, ShadeOutputs, Surface};
pub use emitter_accel::EmitterAccel;
pub use lights::LightSet;
pub use path::{is_glossy, weighs_area_lights, DirectLighting, DrawLayout};
pub(crate) use queues::FILL as PATH_FILL;
pub use queues::{PathState, RayQueue, ShadowQueue};

use crate::math::{Ray, Vec3};
use crate::sampler::{DrawBatch, Numbers};

/// The closed set of integrators.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Integrator {
    /// Shading normal as colour 0.5 n + 0.5; misses are black. No secondary rays.
    Normals,
    /// Direct lighting (`-m 1`) or path tracing (`-m N`), with the given direct-light estimator.
    Path(DirectLighting),
}

impl Integrator {
    /// The integrator's name, as `--shading` takes it: `normals`, `hemisphere`, `light` or `mis`.
    pub fn name(&self) -> &'static str {
        match self {
            Integrator::Normals => "normals",
            Integrator::Path(DirectLighting::Hemisphere) => "hemisphere",
            Integrator::Path(DirectLighting::LightSampling) => "light",
            Integrator::Path(DirectLighting::Mis) => "mis",
        }
    }

    /// The lights this integrator samples.
    pub fn light_set(&self, scene: &crate::scene::Scene) -> LightSet {
        match self {
            Integrator::Path(DirectLighting::Mis) => LightSet::emissive_geometry(scene),
            _ => LightSet::course(scene),
        }
    }

    /// Whether vertices on surfaces (all but emitters) go through `diffuse::shade_diffuse`,
    /// `LANES` at a time, instead of `shade_hit` (see `diffuse::applies`).
    pub fn shades_diffuse_in_lanes(&self, ctx: &RenderContext) -> bool {
        match *self {
            Integrator::Path(direct) => diffuse::applies(ctx, direct),
            Integrator::Normals => false,
        }
    }

    /// Whether a hit on an emitter by a ray of depth `depth` (whose BSDF sample had pdf
    /// `prev_bsdf_pdf`) adds nothing and ends the path, so that shading may skip it
    /// (`path::emission_counts`).
    pub fn ignores_emitter_hit(&self, depth: u32, prev_bsdf_pdf: f32) -> bool {
        match *self {
            Integrator::Path(direct) => !path::emission_counts(direct, depth, prev_bsdf_pdf),
            Integrator::Normals => false,
        }
    }

    /// Whether a hit on a surface that emits nothing, by a ray of depth `depth`, adds nothing
    /// and ends the path, so that shading may skip it without reconstructing the surface:
    /// path vertices at `max_depth` only add emission (`path::shade_hit`). Under MIS every
    /// last-depth BSDF ray (at `-m 1`, one per camera hit) ends this way unless it meets an
    /// emitter.
    pub fn ignores_surface_hit(&self, depth: u32, max_depth: u32) -> bool {
        match *self {
            Integrator::Path(_) => depth >= max_depth,
            Integrator::Normals => false,
        }
    }

    /// The estimator of direct light, for integrators that have one.
    pub fn direct_lighting(&self) -> Option<DirectLighting> {
        match *self {
            Integrator::Path(direct) => Some(direct),
            Integrator::Normals => None,
        }
    }

    /// Plans the random numbers every vertex reached by a ray of depth `depth` may use.
    pub fn plan_draws(&self, ctx: &RenderContext, depth: u32, batch: &mut DrawBatch) -> DrawLayout {
        match *self {
            Integrator::Normals => {
                batch.plan(depth);
                DrawLayout::default()
            }
            Integrator::Path(direct) => path::plan_draws(direct, ctx, depth, batch),
        }
    }

    /// Shades the vertex of path `path` where a ray of depth `depth` hit `surface`: updates the
    /// path's state in `paths` and queues its shadow rays, emission probes and continuation ray
    /// in `out`. `numbers` are the vertex's planned random numbers and their layout
    /// (`plan_draws`).
    #[allow(clippy::too_many_arguments)]
    pub fn shade_hit(
        &self,
        ctx: &RenderContext,
        depth: u32,
        ray: &Ray,
        surface: &Surface,
        path: u32,
        paths: &mut PathState,
        numbers: (&DrawLayout, Numbers),
        out: &mut ShadeOutputs,
    ) {
        match *self {
            Integrator::Normals => {
                paths.radiance[path as usize] = 0.5 * surface.ns + Vec3::splat(0.5);
            }
            Integrator::Path(direct) => {
                path::shade_hit(direct, ctx, depth, ray, surface, path, paths, numbers, out)
            }
        }
    }
}
