//! What the integrator reads and writes while the wavefront's shade stage calls it: the
//! render-wide context, the surface at a hit, and the queues it appends to (the queues' SoA
//! columns are in `queues`). The wavefront owns the stage loop and re-exports these.

use super::{EmitterAccel, Integrator, LightSet, RayQueue, ShadowQueue};
use crate::accel::Accel;
use crate::geometry::prim;
use crate::math::{Hit, Ray, Vec3};
use crate::sampler::SamplerKind;
use crate::scene::{Camera, Scene};

/// What every stage reads: immutable for the whole render.
pub struct RenderContext<'a> {
    /// The scene being rendered.
    pub scene: &'a Scene,
    /// `scene.triangle_normals()`, made once per render: shading in lanes gathers one face
    /// normal per triangle where it would gather three corners, and the vertex normals without
    /// going through the vertex indices.
    pub triangle_normals: &'a [Vec3],
    /// The acceleration structure over `scene`'s primitives.
    pub accel: &'a Accel,
    /// The scene's emitters under a structure of their own, for rays that can only add
    /// emission (`EmitterAccel`); `None` where the emitters are a large part of the scene.
    pub emitters: Option<&'a EmitterAccel>,
    /// The camera that generates the primary rays.
    pub camera: &'a Camera,
    /// The integrator the shade stage calls.
    pub integrator: &'a Integrator,
    /// The lights next-event estimation samples (`Integrator::light_set`).
    pub lights: &'a LightSet,
    /// Samples per pixel of the whole render, also when this one takes only some (`samples`).
    pub spp: u32,
    /// The samples of each pixel to take: `0..spp` for a whole render, less for a part of one
    /// (`render::RenderConfig::samples`).
    pub samples: std::ops::Range<u32>,
    /// Direct-light samples (`-l`): draws per non-delta light and for the emitters, or
    /// hemisphere directions per scene light (`-H`).
    pub light_samples: u32,
    /// Extra camera rays per sample on emitter outlines (`--edge-samples`, see
    /// `wavefront::stages::generate`).
    pub edge_samples: u32,
    /// The image rectangle (x0, y0, x1, y1 in pixels) outside which no camera ray can see
    /// emissive geometry, from the emitters' projections (`wavefront::emitter_window`); `None`
    /// when none can be seen anywhere or the render takes no extra camera rays.
    pub emitter_window: Option<[f32; 4]>,
    /// Maximum path depth (`-m`): vertices reached at this depth add only emission and spawn no
    /// rays.
    pub max_depth: u32,
    /// Adaptive sampling: (samples per batch, tolerance), see `PixelStats::converged`.
    pub adaptive: Option<(u32, f32)>,
    /// Seed from which every random number of the render is derived (see `sampler`).
    pub seed: u64,
    /// How random numbers are drawn (`--sampler`).
    pub sampler: SamplerKind,
    /// Packets for coherent queues (see `stages::Coherence`); `false`: single rays only.
    pub packets: bool,
    /// Surface vertices in SIMD lanes where the integrator allows it (`stages::shade`).
    pub shading_lanes: bool,
    /// Light samples of area lights weighed against the BSDF sample at glossy vertices
    /// (`path::weighs_area_lights`); `false`: plain light sampling everywhere (for tests).
    pub glossy_light_mis: bool,
    /// Time the stages of the loop (`wavefront::StageTimes`).
    pub stage_times: bool,
    /// The scene mixes specular and light-sampling surfaces (`Scene::mixes_specular`): the
    /// shade stage then puts each queue's specular vertices after the others
    /// (`wavefront::stages::group_specular`).
    pub mixes_specular: bool,
    /// Smallest offset for spawned rays: 1e-5 of the scene's bounding-box diagonal.
    pub scene_epsilon: f32,
}

impl RenderContext<'_> {
    /// How far a ray spawned at `p` must start from the surface to clear its own rounding
    /// error. A hit point is off by at most about gamma_7 |p| ~ 3.5 ulps of its
    /// largest coordinate (pbrt-v4, 6.8), so the offset is 8 ulps of |p|, and never less than
    /// 1e-5 of the scene's diagonal. Both scale with the scene, so moving a scene far from the
    /// origin or rescaling it changes nothing beyond rounding (tests/stability.rs).
    #[inline]
    pub fn ray_epsilon(&self, p: Vec3) -> f32 {
        const ULPS: f32 = 8.0 * f32::EPSILON;
        (p.abs().max_element() * ULPS).max(self.scene_epsilon)
    }

    /// A spawn point for a ray leaving `p` in direction `dir`: pushed off the surface along the
    /// geometric normal `ng`, to the side the ray leaves through.
    #[inline]
    pub fn offset_origin(&self, p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
        let side = if ng.dot(dir) >= 0.0 { 1.0 } else { -1.0 };
        p + (side * self.ray_epsilon(p)) * ng
    }
}

/// Where the integrator writes the work it creates.
pub struct ShadeOutputs<'q> {
    /// Continuation rays (bounces), traced at the next depth.
    pub next: &'q mut RayQueue,
    /// Shadow rays (any hit): unblocked rays add their radiance to their path.
    pub shadow: &'q mut ShadowQueue,
    /// Emission probes (closest hit) of uniform hemisphere sampling.
    pub probes: &'q mut ShadowQueue,
}

/// What shading needs to know about a hit point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surface {
    /// The hit point.
    pub p: Vec3,
    /// Geometric normal (unit), as wound for triangles, outward for spheres.
    pub ng: Vec3,
    /// Shading normal (unit): interpolated vertex normals for triangles.
    pub ns: Vec3,
    /// The material index (into `Scene::materials`).
    pub material: u32,
    /// The primitive hit (`Hit::prim`).
    pub prim: u32,
    /// The ray parameter of the hit (`Hit::t`).
    pub t: f32,
}

/// The material of primitive `prim` (`Hit::prim`), without reconstructing its surface.
#[inline]
pub fn surface_material(scene: &Scene, prim: u32) -> u32 {
    if prim::is_sphere(prim) {
        scene.spheres[prim::sphere_index(prim) as usize].material
    } else {
        scene.triangle_materials[prim::triangle_index(prim) as usize]
    }
}

/// The emission a ray sees at its hit: a front-facing emitter's radiance, else zero. The
/// material first: only an emitter's hit needs its surface.
#[inline]
pub fn emission_seen(scene: &Scene, ray: &Ray, hit: &Hit) -> Vec3 {
    let emitted = scene.materials[surface_material(scene, hit.prim) as usize].emission();
    if emitted == Vec3::ZERO || Surface::at(scene, ray, hit).ng.dot(ray.dir) >= 0.0 {
        return Vec3::ZERO;
    }
    emitted
}

impl Surface {
    /// Reconstructs the surface that `ray` hit at `hit`: point, normals and material.
    pub fn at(scene: &Scene, ray: &Ray, hit: &Hit) -> Surface {
        let p = ray.at(hit.t);
        if prim::is_sphere(hit.prim) {
            let s = &scene.spheres[prim::sphere_index(hit.prim) as usize];
            let n = ((p - s.center) / s.radius).normalize_or(Vec3::Y);
            return Surface { p, ng: n, ns: n, material: s.material, prim: hit.prim, t: hit.t };
        }
        let i = prim::triangle_index(hit.prim) as usize;
        let [a, b, c] = scene.triangles[i];
        let [pa, pb, pc] = scene.triangle(i);
        let ng = (pb - pa).cross(pc - pa).normalize_or(Vec3::Y);
        let w = 1.0 - hit.u - hit.v;
        let n = &scene.normals;
        let ns =
            (w * n[a as usize] + hit.u * n[b as usize] + hit.v * n[c as usize]).normalize_or(ng);
        Surface { p, ng, ns, material: scene.triangle_materials[i], prim: hit.prim, t: hit.t }
    }
}
