//! The lighting integrators as one shading hook: direct lighting (`-m 1`) and global
//! illumination (`-m N`) with three estimators of direct light.
//!
//! At a path vertex reached by a ray of depth k (camera rays have k = 0):
//! 1. Emission of a front-facing emitter is added when k = 0 (the course's zero bounce, weighted
//!    by the path's `zero_bounce_weight` where extra camera rays share it), when
//!    the previous bounce was specular (no light sampling happened there), and, weighted by
//!    MIS, in the emissive-geometry mode. Otherwise it is the direct estimator's job, so no
//!    emitter is counted twice.
//! 2. If k < max_depth, direct light: light sampling queues shadow rays, uniform hemisphere
//!    sampling queues emission probes (closest-hit rays that add what they see), MIS queues
//!    shadow rays to points on emissive geometry. At glossy vertices light sampling weighs the
//!    area lights' samples against the BSDF sample, which queues a shadow ray of its own where
//!    its direction meets an area light (`weighs_area_lights`); that vertex samples its BSDF
//!    also at the last depth.
//! 3. If k + 1 < max_depth (or = max_depth under MIS, for the BSDF half of the MIS pair, and at
//!    specular vertices, whose next hit may see an emitter) a BSDF sample continues the path,
//!    with Russian roulette (survival probability = the path throughput's largest channel) from
//!    the ray of depth `RR_START_DEPTH` on.

use super::bsdf::{self, BsdfSample, UNIFORM_HEMISPHERE_PDF};
use super::lights::{sample_scene_light, LightSample};
use super::rectangle::Rectangle;
use super::{PathState, RenderContext, ShadeOutputs, Surface};
use crate::math::{orthonormal_basis, Ray, Vec3};
use crate::sampler::{Decision, DrawBatch, Numbers};
use crate::scene::{Light, Material};

/// How direct light is estimated at each path vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DirectLighting {
    /// `-H`: uniform hemisphere directions; only emissive geometry is found.
    Hemisphere,
    /// The course default: sample the scene lights (`-l` samples per area light).
    LightSampling,
    /// Emissive geometry is the light: area sampling and BSDF sampling combined by MIS.
    Mis,
}

/// Bounces before Russian roulette may end a path: rays of depth 5 and deeper (Mitsuba's
/// `rr_depth` default). Starting at 3 traced 25% fewer rays but left 22% more noise at
/// `-m 5` (PERF.md "Whole renders": 12% worse in noise^2 x rays).
pub(super) const RR_START_DEPTH: u32 = 5;

/// A local shading frame: normal `n`, tangents `t`, `b`.
struct Frame {
    t: Vec3,
    b: Vec3,
    n: Vec3,
}

impl Frame {
    fn new(n: Vec3) -> Frame {
        let (t, b) = orthonormal_basis(n);
        Frame { t, b, n }
    }
    fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
    fn to_world(&self, v: Vec3) -> Vec3 {
        v.x * self.t + v.y * self.b + v.z * self.n
    }
}

/// Everything the direct-light estimators need at one vertex.
struct Vertex<'a> {
    p: Vec3,
    /// Geometric normal on the side of the incoming ray.
    ng: Vec3,
    frame: Frame,
    wo: Vec3,
    material: &'a Material,
    throughput: Vec3,
    /// Depth of the ray that reached this vertex (camera rays: 0).
    depth: u32,
    /// This vertex's random numbers, laid out as `DrawLayout` says.
    numbers: Numbers<'a>,
}

/// Where each decision's numbers sit among a vertex's planned draws (`plan_draws`).
#[derive(Debug, Clone, Copy, Default)]
pub struct DrawLayout {
    /// The direct-light draws: scene lights in order (`-l` each, 1 per delta light), then the
    /// emitter draws (MIS); or the hemisphere draws (`-H`).
    pub(super) light: usize,
    pub(super) emitter: usize,
    pub(super) bsdf: usize,
    /// Lobe choice and roulette, when either can apply at this depth.
    pub(super) lobe: Option<usize>,
}

/// Plans the decisions a vertex reached by a ray of depth `depth` may take, in the order the
/// shading code reads them.
pub fn plan_draws(
    direct: DirectLighting,
    ctx: &RenderContext,
    depth: u32,
    batch: &mut DrawBatch,
) -> DrawLayout {
    batch.plan(depth);
    let mut layout = DrawLayout::default();
    if depth >= ctx.max_depth {
        return layout;
    }
    let n = ctx.light_samples;
    layout.light = batch.stride();
    match direct {
        DirectLighting::Hemisphere => {
            batch.add(Decision::Hemisphere, hemisphere_draws(ctx));
        }
        DirectLighting::LightSampling | DirectLighting::Mis => {
            for (li, light) in ctx.lights.scene_lights.iter().enumerate() {
                batch.add(Decision::SceneLight(li as u32), if light.is_delta() { 1 } else { n });
            }
        }
    }
    layout.emitter = batch.stride();
    if direct == DirectLighting::Mis && ctx.lights.has_emitters() {
        batch.add(Decision::Emitter, n);
    }
    // The continuation's numbers, unless no vertex at this depth continues (`shade_hit`): at
    // the last depth only MIS and specular vertices do. Each decision draws from its own
    // sequence, so leaving one out changes no other number; it saved half the draws of a
    // `-m 1` render (PERF.md, "Whole renders").
    layout.bsdf = batch.stride();
    if !any_vertex_continues(direct, ctx, depth) {
        return layout;
    }
    batch.add(Decision::Bsdf, 1);
    let any_lobe_choice = ctx.scene.materials.iter().any(bsdf::chooses_lobe);
    if depth + 1 >= RR_START_DEPTH || any_lobe_choice {
        layout.lobe = Some(batch.add(Decision::LobeAndRoulette, 1));
    }
    layout
}

/// Whether a vertex reached by a ray of depth `depth < max_depth` may continue the path: as
/// `shade_hit` decides, before the last depth always, at it under MIS and at specular
/// surfaces (emitters never continue).
fn any_vertex_continues(direct: DirectLighting, ctx: &RenderContext, depth: u32) -> bool {
    let specular =
        |m: &Material| !bsdf::has_smooth_lobe(m) && !matches!(m, Material::Emission { .. });
    depth + 1 < ctx.max_depth
        || direct == DirectLighting::Mis
        || ctx.scene.materials.iter().any(specular)
        || (weighs_area_lights(direct, ctx) && ctx.scene.materials.iter().any(is_glossy))
}

/// Whether light samples of the scene's area lights are weighed against the BSDF sample at
/// glossy vertices (`is_glossy`): under light sampling, when the scene has one (MIS samples the
/// emissive geometry instead, `LightSet::emissive_geometry`). Light sampling alone finds a
/// smooth conductor's reflection of a large light only in rare, bright samples; BSDF sampling
/// finds it. Both estimate the same light, so the image converges to the same result (PERF.md,
/// "Glossy vertices weigh light samples against the BSDF").
pub fn weighs_area_lights(direct: DirectLighting, ctx: &RenderContext) -> bool {
    direct == DirectLighting::LightSampling
        && ctx.glossy_light_mis
        && ctx.lights.scene_lights.iter().any(|l| matches!(l, Light::Area { .. }))
}

/// The surfaces whose light samples are weighed against their BSDF sample: microfacet
/// conductors. Diffuse ones keep plain light sampling, whose noise a BSDF sample hardly lowers.
pub fn is_glossy(m: &Material) -> bool {
    matches!(m, Material::Microfacet { .. })
}

/// Uniform hemisphere sampling takes `-l` directions per scene light (at least one light).
pub(super) fn hemisphere_draws(ctx: &RenderContext) -> u32 {
    ctx.scene.lights.len().max(1) as u32 * ctx.light_samples
}

#[allow(clippy::too_many_arguments)]
pub fn shade_hit(
    direct: DirectLighting,
    ctx: &RenderContext,
    depth: u32,
    ray: &Ray,
    surface: &Surface,
    path: u32,
    paths: &mut PathState,
    numbers: (&DrawLayout, Numbers),
    out: &mut ShadeOutputs,
) {
    let (layout, numbers) = numbers;
    let pi = path as usize;
    let material = &ctx.scene.materials[surface.material as usize];
    let cos_out = -surface.ng.dot(ray.dir);

    if let Material::Emission { radiance } = *material {
        if cos_out > 0.0 {
            let (prev_pdf, zero_bounce) = (paths.bsdf_pdf[pi], paths.zero_bounce_weight[pi]);
            let w = emission_weight(direct, ctx, depth, surface, cos_out, prev_pdf, zero_bounce);
            paths.radiance[pi] += w * paths.throughput[pi] * radiance;
        }
        return; // Emitters reflect nothing.
    }
    if depth >= ctx.max_depth {
        return;
    }

    // Reflective materials are two-sided: turn the normals towards the viewer. Dielectrics keep
    // the outward normal so that the BSDF knows whether the ray enters or leaves.
    let transmissive = matches!(material, Material::Glass { .. } | Material::Refraction { .. });
    let flip = !transmissive && cos_out < 0.0;
    let sign = if flip { -1.0 } else { 1.0 };
    let ng = sign * surface.ng;
    let mut ns = sign * surface.ns;
    if !transmissive && ns.dot(-ray.dir) <= 0.0 {
        // Interpolated normals can face away at silhouettes; fall back to the true normal.
        ns = ng;
    }
    let frame = Frame::new(ns);
    let v = Vertex {
        p: surface.p,
        ng,
        wo: frame.to_local(-ray.dir),
        frame,
        material,
        throughput: paths.throughput[pi],
        depth,
        numbers,
    };

    let weigh = is_glossy(material) && weighs_area_lights(direct, ctx);
    if bsdf::has_smooth_lobe(material) {
        match direct {
            DirectLighting::LightSampling => sample_scene_lights(ctx, &v, layout, weigh, path, out),
            DirectLighting::Hemisphere => queue_hemisphere_probes(ctx, &v, layout, path, out),
            DirectLighting::Mis => sample_emissive_geometry(ctx, &v, layout, path, out),
        }
    }

    // At the last vertex a path still continues where the ray it spawns can add emission:
    // under MIS (the BSDF half of the pair) and after a specular bounce (which light sampling
    // cannot replace), as a path tracer of max depth m + 1 segments does.
    let last = depth + 1 == ctx.max_depth;
    let continues = depth + 1 < ctx.max_depth
        || (last && (direct == DirectLighting::Mis || !bsdf::has_smooth_lobe(material)));
    if !continues && !weigh {
        return;
    }
    let (sample, roulette) = sample_bsdf(&v, layout);
    let Some(s) = sample else {
        return;
    };
    if weigh {
        queue_area_lights_hit(ctx, &v, &s, path, out);
    }
    if continues {
        continue_path(ctx, &v, s, roulette, path, paths, out);
    }
}

/// Whether emission seen at a vertex reached by a ray of depth `depth` (whose BSDF sample had
/// pdf `prev_bsdf_pdf`, 0 after a specular bounce) can count at all: seen by the camera or
/// after a specular bounce, or under MIS (weighted); after other bounces light and hemisphere
/// sampling have counted the emitters already (SCENE_FORMAT.md).
pub(super) fn emission_counts(direct: DirectLighting, depth: u32, prev_bsdf_pdf: f32) -> bool {
    depth == 0 || prev_bsdf_pdf == 0.0 || direct == DirectLighting::Mis
}

/// The MIS / course weight of emission seen at a path vertex (see the module docs); seen by
/// the camera, the path's `zero_bounce` weight (1, or its share with extra camera rays).
fn emission_weight(
    direct: DirectLighting,
    ctx: &RenderContext,
    depth: u32,
    surface: &Surface,
    cos_l: f32,
    prev_bsdf_pdf: f32,
    zero_bounce: f32,
) -> f32 {
    if !emission_counts(direct, depth, prev_bsdf_pdf) {
        return 0.0;
    }
    if depth == 0 {
        return zero_bounce;
    }
    if prev_bsdf_pdf == 0.0 {
        return 1.0; // After a specular bounce.
    }
    // MIS; rays are unit length, so the hit distance is the ray parameter.
    let light_pdf = ctx.lights.emitter_pdf(ctx.scene, surface.prim, surface.t, cos_l);
    power_heuristic(1.0, prev_bsdf_pdf, ctx.light_samples as f32, light_pdf)
}

/// Veach's power heuristic (beta = 2) for nf samples of pdf f against ng samples of pdf g.
fn power_heuristic(nf: f32, f: f32, ng: f32, g: f32) -> f32 {
    let (a, b) = (nf * f, ng * g);
    if a == 0.0 && b == 0.0 {
        return 0.0;
    }
    a * a / (a * a + b * b)
}

/// Course light sampling: every scene light, `-l` samples for non-delta lights, 1 for delta.
/// `weigh`: area lights' samples weighed against the BSDF sample (`weighs_area_lights`).
fn sample_scene_lights(
    ctx: &RenderContext,
    v: &Vertex,
    layout: &DrawLayout,
    weigh: bool,
    path: u32,
    out: &mut ShadeOutputs,
) {
    let mut slot = layout.light;
    for light in &ctx.lights.scene_lights {
        let n = if light.is_delta() { 1 } else { ctx.light_samples };
        let rectangle = area_rectangle(light).filter(|_| weigh);
        for _ in 0..n {
            let u = v.numbers.get(slot);
            slot += 1;
            let Some(ls) = sample_scene_light(light, v.p, v.frame.n, u) else {
                continue;
            };
            let scale = match rectangle {
                Some((r, _)) => {
                    let bsdf_pdf = bsdf::pdf(v.material, v.wo, v.frame.to_local(ls.wi));
                    power_heuristic(n as f32, r.solid_angle_pdf(&ls), 1.0, bsdf_pdf) / n as f32
                }
                None => 1.0 / n as f32,
            };
            queue_shadow_ray(ctx, v, &ls, scale, path, out);
        }
    }
}

/// An area light's rectangle and radiance.
pub(super) fn area_rectangle(light: &Light) -> Option<(Rectangle, Vec3)> {
    match *light {
        Light::Area { position, direction, dim_x, dim_y, radiance } => {
            Some((Rectangle::new(position, direction, dim_x, dim_y), radiance))
        }
        _ => None,
    }
}

/// The BSDF half of the glossy vertex's weighing (`weighs_area_lights`): where the BSDF
/// sample's direction meets an area light, a shadow ray to that point carries the light that
/// BSDF sampling finds there, weighed by the power heuristic against the light's `-l` samples.
fn queue_area_lights_hit(
    ctx: &RenderContext,
    v: &Vertex,
    s: &BsdfSample,
    path: u32,
    out: &mut ShadeOutputs,
) {
    if !(s.pdf > 0.0 && s.pdf < f32::INFINITY) {
        return;
    }
    let dir = v.frame.to_world(s.wi).normalize();
    for (r, radiance) in ctx.lights.scene_lights.iter().filter_map(area_rectangle) {
        if let Some(hit) = r.hit_by(radiance, v.p, v.frame.n, dir) {
            let w = power_heuristic(1.0, s.pdf, ctx.light_samples as f32, hit.pdf);
            // As a light sample drawn with the BSDF's pdf: the same shadow ray and estimate.
            queue_shadow_ray(ctx, v, &LightSample { pdf: s.pdf, ..hit }, w, path, out);
        }
    }
}

/// Emissive geometry sampled by area (`-l` samples), MIS-weighted against BSDF sampling; plus
/// the scene's point, directional and sky lights as in course mode.
fn sample_emissive_geometry(
    ctx: &RenderContext,
    v: &Vertex,
    layout: &DrawLayout,
    path: u32,
    out: &mut ShadeOutputs,
) {
    // The CGL area lights are left out here (`LightSet::emissive_geometry`): nothing to weigh.
    sample_scene_lights(ctx, v, layout, false, path, out);
    if !ctx.lights.has_emitters() {
        return;
    }
    let n = ctx.light_samples;
    for u in (layout.emitter..layout.bsdf).map(|k| v.numbers.get(k)) {
        let Some(ls) = ctx.lights.sample_emitter(ctx.scene, v.p, u) else {
            continue;
        };
        let bsdf_pdf = bsdf::pdf(v.material, v.wo, v.frame.to_local(ls.wi));
        let w = power_heuristic(n as f32, ls.pdf, 1.0, bsdf_pdf);
        queue_shadow_ray(ctx, v, &ls, w / n as f32, path, out);
    }
}

/// Queues the occlusion test for one light sample, if it can contribute at all.
fn queue_shadow_ray(
    ctx: &RenderContext,
    v: &Vertex,
    ls: &LightSample,
    scale: f32,
    path: u32,
    out: &mut ShadeOutputs,
) {
    let wi = v.frame.to_local(ls.wi);
    let cos = wi.z;
    if cos <= 0.0 || ls.wi.dot(v.ng) <= 0.0 {
        return;
    }
    let f = bsdf::eval(v.material, v.wo, wi);
    let contribution = v.throughput * f * ls.li * (cos * scale / ls.pdf);
    if contribution.max_element() <= 0.0 || !contribution.is_finite() {
        return;
    }
    let origin = ctx.offset_origin(v.p, v.ng, ls.wi);
    let (dir, t_max) = if ls.dist.is_finite() {
        // Aim from the offset origin, and stop eps short of the light's plane measured along its
        // normal, so that an emissive quad lying in that plane (as in the course's Cornell
        // boxes) never shadows its own light: the write-up's EPS_F puzzle. Measuring the
        // length from the un-offset point instead lets the two offsets cancel for rays along
        // the normal, and then rounding decides, which shows up as noise and bias.
        let q = v.p + ls.dist * ls.wi;
        let d = q - origin;
        let len = d.length();
        (d / len, len - ctx.ray_epsilon(q) / ls.cos_light.max(1e-2))
    } else {
        (ls.wi, f32::INFINITY)
    };
    if t_max > 0.0 {
        out.shadow.push(Ray::segment(origin, dir, 0.0, t_max), contribution, path);
    }
}

/// Uniform hemisphere sampling of direct light, as the course does it: lights x `-l` rays per
/// vertex, each adding what emissive geometry it sees.
fn queue_hemisphere_probes(
    ctx: &RenderContext,
    v: &Vertex,
    layout: &DrawLayout,
    path: u32,
    out: &mut ShadeOutputs,
) {
    let n = hemisphere_draws(ctx);
    for [u1, u2] in (layout.light..layout.emitter).map(|k| v.numbers.get(k)) {
        let wi = bsdf::uniform_hemisphere(u1, u2);
        let f = bsdf::eval(v.material, v.wo, wi);
        let weight = v.throughput * f * (wi.z / (UNIFORM_HEMISPHERE_PDF * n as f32));
        let dir = v.frame.to_world(wi);
        if weight.max_element() <= 0.0 || dir.dot(v.ng) <= 0.0 {
            continue;
        }
        let origin = ctx.offset_origin(v.p, v.ng, dir);
        out.probes.push(Ray::new(origin, dir), weight, path);
    }
}

/// The vertex's BSDF sample, and the roulette's number.
fn sample_bsdf(v: &Vertex, layout: &DrawLayout) -> (Option<BsdfSample>, f32) {
    let [u1, u2] = v.numbers.get(layout.bsdf);
    // The lobe choice and the roulette share one draw, planned only at depths and in scenes
    // where either can apply.
    let [lobe, roulette] = layout.lobe.map_or([0.0, 0.0], |k| v.numbers.get(k));
    (bsdf::sample(v.material, v.wo, [u1, u2, lobe]), roulette)
}

/// Continues the path along the BSDF sample `s`: updates the throughput, plays the roulette
/// (with the number `roulette`), and queues the bounce ray.
fn continue_path(
    ctx: &RenderContext,
    v: &Vertex,
    s: BsdfSample,
    roulette: f32,
    path: u32,
    paths: &mut PathState,
    out: &mut ShadeOutputs,
) {
    let pi = path as usize;
    let roulette_applies = v.depth + 1 >= RR_START_DEPTH;
    let mut throughput = v.throughput * s.weight;
    if roulette_applies {
        let q = throughput.max_element().min(1.0);
        if q <= 0.0 || roulette >= q {
            return;
        }
        throughput /= q;
    }
    if throughput.max_element() <= 0.0 || !throughput.is_finite() {
        return;
    }
    let dir = v.frame.to_world(s.wi).normalize();
    let origin = ctx.offset_origin(v.p, v.ng, dir);
    paths.throughput[pi] = throughput;
    paths.bsdf_pdf[pi] = s.pdf;
    out.next.push(Ray::new(origin, dir), path);
}
