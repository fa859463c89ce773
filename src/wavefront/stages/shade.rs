//! Stage 3: turn each hit (or miss) into radiance, continuation rays and shadow rays, by asking
//! the integrator.

use super::super::{PathState, RayQueue, RenderContext, ShadeOutputs, Surface};
use crate::accel;
use crate::geometry::prim;
use crate::integrator::diffuse::{self, DiffuseLanes, DiffuseOutputs, LANES};
use crate::integrator::surface_material;
use crate::math::{Hit, Vec3};
use crate::sampler::DrawBatch;
use crate::scene::{Material, NORMALS_PER_TRIANGLE};
use crate::simd;

/// How one queue entry of a chunk is shaded. Small on purpose: a chunk's surfaces for the
/// scalar path wait in `ShadeScratch::surfaces`, so that the common lane entries do not move
/// a whole `Surface` each.
#[derive(Clone, Copy, Default)]
enum Entry {
    /// Nothing more to do: the ray left the scene (the stage loop drops those before shading,
    /// `drop_misses`, but a queue that keeps them is shaded the same), its hit counts nothing,
    /// or it hit an emitter, which the walk has already shaded.
    #[default]
    Miss,
    /// In the chunk's lanes, which reconstruct the surface themselves.
    Lane,
    /// One by one, at the chunk's next surface.
    Scalar,
}

/// Scratch space of the shade stage, reused across depths and tiles.
#[derive(Default)]
pub struct ShadeScratch {
    /// How each entry of the chunk is shaded: `entries[i]` for queue entry `start + i`.
    entries: [Entry; LANES],
    surfaces: Vec<Surface>,
    lanes: DiffuseLanes,
    lane_out: DiffuseOutputs,
}

/// Shades every queued ray's hit. The random numbers of all vertices are drawn first, in one
/// pass (`DrawBatch`). Then the queue goes by in chunks of `LANES`: where the integrator allows
/// it, the chunk's surface vertices (diffuse, microfacet, specular) are shaded together in SIMD
/// lanes (`integrator::diffuse`), the others one by one, and every vertex's rays are queued in
/// queue order, so the queues (and the image) are the same as if all were shaded one by one.
/// Each chunk starts by prefetching the next chunk's surfaces (`prefetch_surfaces`).
/// Returns the number of vertices shaded in lanes.
#[allow(clippy::too_many_arguments)]
pub fn shade(
    ctx: &RenderContext,
    depth: u32,
    rays: &RayQueue,
    hits: &[Option<Hit>],
    paths: &mut PathState,
    draws: &mut DrawBatch,
    scratch: &mut ShadeScratch,
    mut out: ShadeOutputs,
) -> u64 {
    let layout = ctx.integrator.plan_draws(ctx, depth, draws);
    draws.draw(ctx.sampler, &mut paths.sampler, &rays.path);
    let lanes_apply =
        ctx.shading_lanes && depth < ctx.max_depth && ctx.integrator.shades_diffuse_in_lanes(ctx);
    // Only where the normals outgrow the L2 cache: small scenes keep them there, and the
    // prefetch pass cost CBspheres_lambertian 1.7% more instructions.
    let prefetch = std::mem::size_of_val(ctx.triangle_normals) > accel::l2_cache_bytes();
    let mut in_lanes = 0;
    for start in (0..rays.len()).step_by(LANES) {
        let chunk = start..(start + LANES).min(rays.len());
        if prefetch {
            prefetch_surfaces(ctx, &hits[chunk.end..(chunk.end + LANES).min(hits.len())]);
        }
        scratch.surfaces.clear();
        scratch.lanes.clear();
        let queued = rays.rays[chunk.clone()].iter().zip(&rays.path[chunk.clone()]);
        for (i, ((ray, &path), hit)) in queued.zip(&hits[chunk.clone()]).enumerate() {
            let q = start + i;
            let entry = match hit {
                None => Entry::Miss,
                Some(hit) => {
                    let material =
                        &ctx.scene.materials[surface_material(ctx.scene, hit.prim) as usize];
                    match lane_albedo(lanes_apply, material) {
                        Some(albedo) => {
                            let throughput = paths.throughput[path as usize];
                            scratch.lanes.push(path, q, ray, hit, throughput, albedo);
                            Entry::Lane
                        }
                        // An emitter ends the path. One that counts here adds its emission;
                        // it queues no rays, so it is shaded now and the chunk's rays still
                        // come from its lanes alone (`queue_all_lanes`).
                        None if matches!(material, Material::Emission { .. }) => {
                            let pdf = paths.bsdf_pdf[path as usize];
                            if !ctx.integrator.ignores_emitter_hit(depth, pdf) {
                                let s = Surface::at(ctx.scene, ray, hit);
                                let numbers = (&layout, draws.of(q));
                                let out = &mut out;
                                ctx.integrator
                                    .shade_hit(ctx, depth, ray, &s, path, paths, numbers, out);
                            }
                            Entry::Miss
                        }
                        // Microfacet and specular surfaces join the same lanes (the diffuse ones
                        // above take the first arm, whose code stays as short as before).
                        None if lanes_apply
                            && scratch.lanes.push_other(
                                path,
                                q,
                                ray,
                                hit,
                                paths.throughput[path as usize],
                                material,
                            ) =>
                        {
                            Entry::Lane
                        }
                        None if ctx.integrator.ignores_surface_hit(depth, ctx.max_depth) => {
                            Entry::Miss
                        }
                        None => {
                            scratch.surfaces.push(Surface::at(ctx.scene, ray, hit));
                            Entry::Scalar
                        }
                    }
                }
            };
            scratch.entries[i] = entry;
        }
        in_lanes += scratch.lanes.len as u64;
        if let (true, Some(direct)) = (scratch.lanes.len > 0, ctx.integrator.direct_lighting()) {
            diffuse::shade_diffuse(
                ctx,
                direct,
                depth,
                &layout,
                draws,
                &mut scratch.lanes,
                &mut scratch.lane_out,
            );
        }
        if scratch.surfaces.is_empty() {
            // Lanes and misses only: every ray the chunk queues comes from the lanes.
            if scratch.lanes.len > 0 {
                diffuse::queue_all_lanes(&scratch.lane_out, &scratch.lanes, paths, &mut out);
            }
            continue;
        }
        let (mut lane, mut surfaces) = (0, scratch.surfaces.iter());
        for (q, entry) in chunk.zip(&scratch.entries) {
            let (ray, path) = (&rays.rays[q], rays.path[q]);
            match entry {
                Entry::Lane => {
                    diffuse::queue_lane(&scratch.lane_out, lane, path, paths, &mut out);
                    lane += 1;
                }
                Entry::Scalar => {
                    let s = surfaces.next().expect("one surface per scalar entry");
                    let numbers = (&layout, draws.of(q));
                    ctx.integrator.shade_hit(ctx, depth, ray, s, path, paths, numbers, &mut out);
                }
                // Rays that leave the scene see black: scene lights (the sky included) are not
                // geometry and are reached only by light sampling (SCENE_FORMAT.md). Emitters
                // that count nothing at this vertex end the path the same way; the others
                // were shaded in the walk above.
                Entry::Miss => {}
            }
        }
    }
    in_lanes
}

/// Starts loading what the walk and the lanes will read of the next chunk's hit triangles:
/// each one's material index and its normals record (`RenderContext::triangle_normals`). Both
/// are indexed by the hit, so on a mesh larger than the L2 cache they missed it, and the
/// material's load was the largest stall of the stage (PERF.md, "Whole renders", "The next
/// chunk's surfaces prefetched"). A chunk's shading is long enough to hide the wait.
#[inline(always)]
fn prefetch_surfaces(ctx: &RenderContext, hits: &[Option<Hit>]) {
    for hit in hits.iter().flatten() {
        if !prim::is_sphere(hit.prim) {
            let t = prim::triangle_index(hit.prim) as usize;
            simd::prefetch(ctx.scene.triangle_materials.as_ptr().wrapping_add(t));
            let normals = ctx.triangle_normals.as_ptr().wrapping_add(t * NORMALS_PER_TRIANGLE);
            simd::prefetch(normals as *const [Vec3; NORMALS_PER_TRIANGLE]);
        }
    }
}

/// The albedo of a surface that is shaded in lanes: diffuse, when lanes apply at all.
#[inline]
fn lane_albedo(lanes_apply: bool, material: &Material) -> Option<Vec3> {
    if !lanes_apply {
        return None;
    }
    match *material {
        Material::Diffuse { albedo } => Some(albedo),
        _ => None,
    }
}
