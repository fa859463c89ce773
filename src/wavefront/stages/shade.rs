//! Stage 3: turn each hit (or miss) into radiance, continuation rays and shadow rays, by asking
//! the integrator.

use super::super::{PathState, RayQueue, RenderContext, ShadeOutputs, Surface};
use super::extend::retain_from;
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
    /// `group_specular`: each chunk's specular entries as a bit mask, and those entries while
    /// the others move up.
    specular_masks: Vec<u32>,
    specular_rays: RayQueue,
    specular_hits: Vec<Option<Hit>>,
}

/// Whether the integrator can shade the surface vertices at `depth` in SIMD lanes; they go
/// there unless `RenderContext::shading_lanes` is off (`shade`).
fn lanes_can_apply(ctx: &RenderContext, depth: u32) -> bool {
    depth < ctx.max_depth && ctx.integrator.shades_diffuse_in_lanes(ctx)
}

/// Puts the queue's specular vertices (mirror, glass, refraction) after the others, each
/// group in queue order, where the scene mixes both kinds (`RenderContext::mixes_specular`)
/// and grouping leaves fewer chunks holding a specular vertex. A chunk runs the specular code
/// for all its lanes if one is specular, and samples lights for all if one is not: on CBgems
/// two chunks in three held both. Queue order only decides which vertices share a chunk or a
/// packet; a path's numbers, hits and sums do not depend on it, so the image does not change.
/// The same pass drops the misses, as `drop_misses` does; returns whether it ran (if not, the
/// misses are still in the queue).
pub fn group_specular(
    ctx: &RenderContext,
    depth: u32,
    rays: &mut RayQueue,
    hits: &mut Vec<Option<Hit>>,
    scratch: &mut ShadeScratch,
) -> bool {
    // Not asked of `shading_lanes`: vertices shaded one by one (for tests) see the same queues.
    if !ctx.mixes_specular || !lanes_can_apply(ctx, depth) {
        return false;
    }
    let scene = ctx.scene;
    let specular = |h: &Option<Hit>| {
        h.is_some_and(|h| scene.materials[surface_material(scene, h.prim) as usize].is_specular())
    };
    // Per chunk of the queue, its specular entries as a bit mask.
    let masks = &mut scratch.specular_masks;
    masks.clear();
    masks.extend(hits.chunks(LANES).map(|chunk| {
        chunk.iter().enumerate().fold(0u32, |m, (i, h)| m | (specular(h) as u32) << i)
    }));
    if !grouping_pays(masks) {
        return false;
    }
    move_specular_last(masks, rays, hits, &mut scratch.specular_rays, &mut scratch.specular_hits);
    true
}

/// Whether grouping would leave fewer chunks holding a specular vertex (`masks`: each chunk's
/// specular entries). Grouped, they fill whole chunks but for one, plus at most one chunk
/// shared with the others.
fn grouping_pays(masks: &[u32]) -> bool {
    let count = masks.iter().map(|m| m.count_ones() as usize).sum::<usize>();
    masks.iter().filter(|&&m| m != 0).count() > count.div_ceil(LANES) + 1
}

/// Moves the entries that `masks` marks (bit `i` of `masks[c]`: entry `c * LANES + i`) behind
/// the others, each group in queue order, and drops the misses (`hits[i]` is `None`, never
/// marked); `moved` and `moved_hits` are scratch space. One pass for both: the misses' own
/// pass moved the queue a second time.
fn move_specular_last(
    masks: &[u32],
    rays: &mut RayQueue,
    hits: &mut Vec<Option<Hit>>,
    moved: &mut RayQueue,
    moved_hits: &mut Vec<Option<Hit>>,
) {
    let count = masks.iter().map(|m| m.count_ones() as usize).sum::<usize>();
    moved.clear();
    moved.reserve(count);
    moved_hits.clear();
    moved_hits.reserve(count);
    let n = hits.len();
    let first_chunk = masks.iter().position(|&m| m != 0).unwrap_or(masks.len());
    let first_miss = hits.iter().position(Option::is_none).unwrap_or(n);
    let first = (first_chunk * LANES).min(first_miss);
    retain_from(rays, hits, first, |i, ray, path, hit| {
        if masks[i / LANES] >> (i % LANES) & 1 != 0 {
            moved.push(*ray, path);
            moved_hits.push(*hit);
            return false;
        }
        hit.is_some()
    });
    rays.rays.extend_from_slice(&moved.rays);
    rays.path.extend_from_slice(&moved.path);
    hits.extend_from_slice(moved_hits);
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
    let lanes_apply = ctx.shading_lanes && lanes_can_apply(ctx, depth);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Ray;

    #[test]
    fn specular_entries_move_behind_the_others_in_queue_order_and_misses_go() {
        let (n, specular, misses) = (40usize, [3usize, 17, 18, 39], [1usize, 5, 30]);
        let mut rays = RayQueue::default();
        for path in 0..n as u32 {
            rays.push(Ray::new(Vec3::new(path as f32, 0.0, 0.0), Vec3::Z), path);
        }
        let hit = |p: u32| Some(Hit { t: 1.0, u: 0.0, v: 0.0, prim: p });
        let mut hits: Vec<Option<Hit>> = (0..n as u32)
            .map(|p| if misses.contains(&(p as usize)) { None } else { hit(p) })
            .collect();
        let mut masks = vec![0u32; n.div_ceil(LANES)];
        for &i in &specular {
            masks[i / LANES] |= 1 << (i % LANES);
        }
        // Three chunks hold one, where grouped they would take one: it pays.
        assert!(grouping_pays(&masks));
        let (mut moved, mut moved_hits) = (RayQueue::default(), Vec::new());
        move_specular_last(&masks, &mut rays, &mut hits, &mut moved, &mut moved_hits);
        let kept = |p: &u32| !specular.contains(&(*p as usize)) && !misses.contains(&(*p as usize));
        let others = (0..n as u32).filter(kept);
        let want: Vec<u32> = others.chain(specular.iter().map(|&i| i as u32)).collect();
        assert_eq!(rays.path, want);
        let origins: Vec<u32> = rays.rays.iter().map(|r| r.origin.x as u32).collect();
        assert_eq!(origins, want);
        assert_eq!(hits.iter().map(|h| h.unwrap().prim).collect::<Vec<_>>(), want);
        // Already grouped (a full chunk and one entry after it), or none: nothing to gain.
        assert!(!grouping_pays(&[0, 0xffff, 1]));
        assert!(!grouping_pays(&[0, 0, 0]));
        assert!(!grouping_pays(&[1 << 15, 1]));
    }
}
