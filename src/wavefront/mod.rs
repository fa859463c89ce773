//! The wavefront renderer: every integrator is a configuration of the same stages.
//!
//! The image is cut into tiles (`TILE` x `TILE` pixels); rayon hands whole tiles to threads, and
//! each thread runs the stage loop below over its tile with its own queues. A path's random
//! numbers depend only on (seed, pixel, sample), and each pixel sums its samples in a fixed
//! order, so the image is bit-identical for any thread count.
//!
//! ```text
//!  generate ──> RayQueue ──> extend ──> hits ──> shade ──┬──> next RayQueue (bounces) ─┐
//!  (camera)         ^        (closest hit)               └──> ShadowQueue ──> shadow   │
//!                   └──────────────────────────────────────── (any hit) ──> PathState  │
//!                   └──────────────────────────────────────────────────────────────────┘
//!  accumulate: PathState radiance ──> tile pixels (film)
//! ```
//!
//! Before its first batch a tile finds the pixels on an emitter's outline (rays through its
//! pixel corners); their samples also queue extra camera rays that only add emission
//! (`stages::generate`, `--edge-samples`).
//!
//! The rays that left the scene are dropped from the queue before it is shaded
//! (`stages::drop_misses`): their paths end with nothing added. Rays that can only add emission
//! (the last depth's rays, whose surface hits count nothing, and the emission probes) look for
//! the emitters first and test occlusion only up to the front face they find
//! (`stages::extend_to_emitters`, `integrator::EmitterAccel`).
//!
//! Where the scene mixes specular surfaces (mirror, glass, refraction) with light-sampling
//! ones, the queue's specular vertices then move behind the others (`stages::group_specular`),
//! so that chunks of either kind run only their own code (specular lanes sample no lights),
//! and the rays they queue stay together at the next depth; the image does not change.
//!
//! Shading a queue (`stages::shade`) starts with one pass that draws every random number its
//! vertices may use (`sampler::DrawBatch`, vectorised). Then the queue goes by in chunks of 16:
//! surface vertices (under MIS, where the emitters are triangles) are shaded together in SIMD
//! lanes (`integrator::diffuse`), the others (emitters) one by one (`Integrator::shade_hit`),
//! and each vertex's rays are queued in queue order, so the images are bit-identical either way.
//! Where the mesh's normals outgrow the L2 cache, each chunk first prefetches the next chunk's
//! hit materials and normals, which are indexed by the hit triangle.
//!
//! Queue sizes: a tile of 16 x 16 pixels with `spp` samples holds at most 256 x `spp` paths;
//! samples are processed in batches of at most `SAMPLE_BATCH` per pixel, so a ray queue never
//! holds more than 256 x 16 = 4096 rays (4096 x 36 bytes = 144 KiB: it stays in L2). Each path
//! vertex may queue one shadow ray per light sample (`-l` per area light, and at glossy vertices
//! one more per area light, `path::weighs_area_lights`), so the batch shrinks
//! until a shadow queue holds at most `SHADOW_QUEUE_CAP` rays (8192 x 48 bytes = 384 KiB; at
//! `-l 32` the queue used to reach 6 MiB per tile). The extra camera rays of a tile's outline
//! pixels are at most one per camera ray (`stages::generate`), so at most 4096 per pass.
//!
//! With `RenderContext::stage_times` each stage call is timed (`StageTimes`: two clock reads
//! per call, not per ray); the workspace keeps the times until the caller takes them
//! (`Workspace::take_times`), and `--stage-times` prints them.
//!
//! The queues' SoA columns, the `RenderContext` and the `Surface` at a hit belong to the
//! integrator, which writes them (`integrator::queues`, `integrator::context`); they are
//! re-exported here. This module holds the stage loop, its tiles and its scratch space.

mod stages;

pub use crate::integrator::{
    PathState, RayQueue, RenderContext, ShadeOutputs, ShadowQueue, Surface,
};
pub use stages::emitter_window;

use std::time::{Duration, Instant};

use crate::accel::TraceStats;
use crate::integrator::{is_glossy, weighs_area_lights};
use crate::math::{ExactRgb, Hit, Vec3};
use crate::sampler::DrawBatch;
use crate::scene::Light;

/// Tile side in pixels.
pub const TILE: u32 = 16;
/// Samples per pixel traced together in one wavefront pass.
pub const SAMPLE_BATCH: u32 = 16;
// A full pass starts each pixel's paths with fixed-size copies of this many
// (`PathState::push_pixel_samples`).
const _: () = assert!(SAMPLE_BATCH as usize == crate::integrator::PATH_FILL);
/// Most shadow rays one wavefront pass may queue per depth.
pub const SHADOW_QUEUE_CAP: u32 = 8192;

/// Samples per pixel per pass: `SAMPLE_BATCH`, fewer when each path vertex queues so many
/// shadow rays that a full batch would overflow `SHADOW_QUEUE_CAP`.
fn sample_batch(ctx: &RenderContext) -> u32 {
    // Light sampling and MIS: one ray per delta light, `-l` per other light and for the
    // emitters; hemisphere sampling: `-l` per scene light (at least one). The larger bounds both.
    let l = ctx.light_samples;
    let sampled: u32 = ctx
        .lights
        .scene_lights
        .iter()
        .map(|light| if light.is_delta() { 1 } else { l })
        .fold(if ctx.lights.has_emitters() { l } else { 0 }, u32::saturating_add);
    let hemisphere = (ctx.scene.lights.len().max(1) as u32).saturating_mul(l);
    // Glossy vertices that weigh the area lights add one ray per area light their BSDF
    // sample meets (`path::weighs_area_lights`).
    let weighed = match ctx.integrator.direct_lighting() {
        Some(d) if weighs_area_lights(d, ctx) && ctx.scene.materials.iter().any(is_glossy) => {
            ctx.lights.scene_lights.iter().filter(|l| matches!(l, Light::Area { .. })).count()
        }
        _ => 0,
    };
    let per_vertex = sampled.saturating_add(weighed as u32).max(hemisphere).max(1);
    let pixels = TILE * TILE;
    (SHADOW_QUEUE_CAP / pixels.saturating_mul(per_vertex)).clamp(1, SAMPLE_BATCH)
}

/// Rays traced, by kind, and the traversal work they caused.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RenderStats {
    /// Primary rays, one per path.
    pub camera_rays: u64,
    /// Continuation rays queued by shading.
    pub bounce_rays: u64,
    /// Shadow (any-hit) rays of direct lighting.
    pub shadow_rays: u64,
    /// Closest-hit rays that add the emission they see: uniform hemisphere sampling's
    /// direct-light rays, and the extra camera rays on emitter outlines with the corner rays
    /// that find those outlines (`stages::generate`).
    pub probe_rays: u64,
    /// Path vertices shaded in SIMD lanes (`integrator::diffuse`) rather than one by one.
    pub lane_vertices: u64,
    /// The traversal work of all these rays.
    pub trace: TraceStats,
}

impl RenderStats {
    /// Adds `o`'s counts to these.
    pub fn add(&mut self, o: &RenderStats) {
        self.camera_rays += o.camera_rays;
        self.bounce_rays += o.bounce_rays;
        self.shadow_rays += o.shadow_rays;
        self.probe_rays += o.probe_rays;
        self.lane_vertices += o.lane_vertices;
        self.trace.add(&o.trace);
    }

    /// Rays of all kinds.
    pub fn total_rays(&self) -> u64 {
        self.camera_rays + self.bounce_rays + self.shadow_rays + self.probe_rays
    }
}

/// Time spent in each stage of the loop, summed over tiles and threads (thread time, not wall
/// time): where a render's time goes, and how fast its rays go through traversal inside it
/// (`--stage-times`). Never part of the image or of `RenderStats`' counts.
#[derive(Debug, Clone, Copy, Default)]
pub struct StageTimes {
    /// Camera rays and the paths they start (`stages::generate_camera_rays`).
    pub generate: Duration,
    /// Closest hits of camera rays (depth 0).
    pub camera_hits: Duration,
    /// Closest hits of bounce rays (depth 1 on), and the emitters' walk of the last depth's
    /// rays (`stages::extend_to_emitters`).
    pub bounce_hits: Duration,
    /// Shading: dropping misses, the draw pass, surfaces, BSDFs, light samples and queueing.
    pub shade: Duration,
    /// Occlusion of the shadow rays.
    pub shadow_rays: Duration,
    /// Emission probes: hemisphere sampling's rays, and the tile's emitter outlines (corner
    /// rays and the extra camera rays of `--edge-samples`).
    pub probes: Duration,
    /// Adding each path's radiance to its pixel (`stages::accumulate`).
    pub accumulate: Duration,
}

impl StageTimes {
    /// Adds `o`'s times to these, stage by stage.
    pub fn add(&mut self, o: &StageTimes) {
        self.generate += o.generate;
        self.camera_hits += o.camera_hits;
        self.bounce_hits += o.bounce_hits;
        self.shade += o.shade;
        self.shadow_rays += o.shadow_rays;
        self.probes += o.probes;
        self.accumulate += o.accumulate;
    }

    /// Time in traversal: closest hits, shadow rays and probes.
    pub fn traversal(&self) -> Duration {
        self.camera_hits + self.bounce_hits + self.shadow_rays + self.probes
    }

    /// Time in all stages.
    pub fn total(&self) -> Duration {
        self.traversal() + self.generate + self.shade + self.accumulate
    }
}

/// Runs `f` and, when `on` (`RenderContext::stage_times`), adds the time it took to `slot`.
/// Two clock reads of about 25 ns per stage call (PERF.md, "Stage times").
#[inline(always)]
fn timed<R>(on: bool, slot: &mut Duration, f: impl FnOnce() -> R) -> R {
    if !on {
        return f();
    }
    let start = Instant::now();
    let r = f();
    *slot += start.elapsed();
    r
}

/// A rectangle of pixels, row 0 at the top of the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tile {
    /// Column of the tile's left edge, in pixels.
    pub x0: u32,
    /// Row of the tile's top edge, in pixels.
    pub y0: u32,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Tile {
    /// Pixels in the tile.
    pub fn pixel_count(&self) -> usize {
        (self.width * self.height) as usize
    }
}

/// Cuts a `width` x `height` image into tiles of at most `TILE` x `TILE`, row-major.
pub fn tiles(width: u32, height: u32) -> Vec<Tile> {
    let mut out = Vec::new();
    for y0 in (0..height).step_by(TILE as usize) {
        for x0 in (0..width).step_by(TILE as usize) {
            out.push(Tile { x0, y0, width: TILE.min(width - x0), height: TILE.min(height - y0) });
        }
    }
    out
}

/// Per-thread scratch space, reused across tiles so the stage loop never allocates.
#[derive(Default)]
pub struct Workspace {
    paths: PathState,
    rays: RayQueue,
    next_rays: RayQueue,
    shadow: ShadowQueue,
    probes: ShadowQueue,
    hits: Vec<Option<Hit>>,
    /// Occlusion answers of the shadow queue.
    blocked: Vec<bool>,
    /// The occlusion queries of rays that can only add emission (`stages::extend_to_emitters`).
    emitter_rays: stages::EmitterScratch,
    /// The random numbers of the current depth's vertices.
    draws: DrawBatch,
    shade: stages::ShadeScratch,
    pixels: PixelStats,
    /// The tile's pixels on an emitter's outline (`stages::mark_emitter_edges`), the emission
    /// seen through its pixel corners, and the extra camera rays of those pixels.
    edges: stages::EdgePixels,
    corner_emission: Vec<Vec3>,
    edge_rays: ShadowQueue,
    /// The stages' times since the caller last took them (`take_times`).
    times: StageTimes,
}

impl Workspace {
    /// The stages' times of the tiles rendered since the last call; starts again from zero.
    pub fn take_times(&mut self) -> StageTimes {
        std::mem::take(&mut self.times)
    }
}

/// Per-pixel running sums of one tile: radiance, and the illuminance moments that adaptive
/// sampling tests.
#[derive(Default)]
pub struct PixelStats {
    /// Exact radiance sums: any split of the samples adds up to the same bytes.
    pub sum: Vec<ExactRgb>,
    /// Sums of each sample's luminance (adaptive sampling only; zero without it).
    pub lum_sum: Vec<f64>,
    /// Sums of each sample's squared luminance.
    pub lum_sq_sum: Vec<f64>,
    /// Samples taken per pixel.
    pub count: Vec<u32>,
    /// Pixels that still take samples.
    pub active: Vec<bool>,
}

impl PixelStats {
    fn reset(&mut self, n: usize) {
        for v in [&mut self.lum_sum, &mut self.lum_sq_sum] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.sum.clear();
        self.sum.resize(n, ExactRgb::default());
        self.count.clear();
        self.count.resize(n, 0);
        self.active.clear();
        self.active.resize(n, true);
    }

    /// The course's test: with mean mu and standard deviation sigma of the illuminance over a
    /// pixel's n samples, the pixel has converged when 1.96 sigma / sqrt(n) <= tolerance * mu.
    pub fn converged(&self, i: usize, tolerance: f32) -> bool {
        let n = self.count[i] as f64;
        if n < 2.0 {
            return false;
        }
        let mu = self.lum_sum[i] / n;
        let var = ((self.lum_sq_sum[i] - n * mu * mu) / (n - 1.0)).max(0.0);
        1.96 * var.sqrt() / n.sqrt() <= tolerance as f64 * mu
    }
}

/// Renders samples `ctx.samples` of one tile: the exact radiance sum of each of its pixels,
/// row-major, into `out`, and the number of samples each pixel took into `samples`.
pub fn render_tile(
    ctx: &RenderContext,
    tile: Tile,
    ws: &mut Workspace,
    out: &mut [ExactRgb],
    samples: &mut [u32],
    stats: &mut RenderStats,
) {
    ws.pixels.reset(tile.pixel_count());
    stats.probe_rays += timed(ctx.stage_times, &mut ws.times.probes, || {
        stages::mark_emitter_edges(
            ctx,
            tile,
            &mut ws.rays,
            &mut ws.hits,
            &mut ws.corner_emission,
            &mut ws.edges,
            &mut stats.trace,
        )
    });
    let max_batch = sample_batch(ctx);
    let mut first = ctx.samples.start;
    while first < ctx.samples.end {
        // Batches end on multiples of the adaptive batch size, where convergence is tested.
        let mut batch = max_batch.min(ctx.samples.end - first);
        if let Some((every, _)) = ctx.adaptive {
            batch = batch.min(every - first % every);
        }
        trace_sample_batch(ctx, tile, first, batch, ws, stats);
        first += batch;
        if let Some((every, tolerance)) = ctx.adaptive {
            if first.is_multiple_of(every) {
                retire_converged_pixels(&mut ws.pixels, tolerance);
                if !ws.pixels.active.contains(&true) {
                    break;
                }
            }
        }
    }
    for (i, (o, n)) in out.iter_mut().zip(samples.iter_mut()).enumerate() {
        *n = ws.pixels.count[i];
        *o = ws.pixels.sum[i];
    }
}

fn retire_converged_pixels(pixels: &mut PixelStats, tolerance: f32) {
    for i in 0..pixels.active.len() {
        if pixels.active[i] && pixels.converged(i, tolerance) {
            pixels.active[i] = false;
        }
    }
}

/// Samples `first .. first + batch` of every pixel of the tile, through all stages.
fn trace_sample_batch(
    ctx: &RenderContext,
    tile: Tile,
    first: u32,
    batch: u32,
    ws: &mut Workspace,
    stats: &mut RenderStats,
) {
    let times = &mut ws.times;
    timed(ctx.stage_times, &mut times.generate, || {
        stages::generate_camera_rays(
            ctx,
            tile,
            first,
            batch,
            &ws.pixels.active,
            &ws.edges,
            &mut ws.paths,
            &mut ws.rays,
            &mut ws.edge_rays,
        )
    });
    let camera_len = ws.rays.len();
    stats.camera_rays += camera_len as u64;
    stats.probe_rays += ws.edge_rays.len() as u64;
    timed(ctx.stage_times, &mut times.probes, || {
        stages::trace_emission_probes(
            ctx,
            &ws.edge_rays,
            stages::Coherence::of_queue(0, 0, 0, ctx.packets, false),
            &mut ws.hits,
            &mut ws.emitter_rays,
            &mut ws.paths,
            &mut stats.trace,
        )
    });
    let mut depth = 0;
    while !ws.rays.is_empty() {
        let coherence = stages::Coherence::of_queue(
            depth,
            ws.rays.len(),
            camera_len,
            ctx.packets,
            ctx.accel.is_large(),
        );
        let hits_time = if depth == 0 { &mut times.camera_hits } else { &mut times.bounce_hits };
        // Where no hit but an emitter's adds anything (a path's last segment), the emitters
        // are found first (`integrator::EmitterAccel`).
        timed(ctx.stage_times, hits_time, || {
            match ctx.emitters.filter(|_| ctx.integrator.ignores_surface_hit(depth, ctx.max_depth))
            {
                Some(emitters) => stages::extend_to_emitters(
                    ctx,
                    emitters,
                    &ws.rays.rays,
                    coherence,
                    &mut ws.hits,
                    &mut ws.emitter_rays,
                    &mut stats.trace,
                ),
                None => stages::extend(ctx, &ws.rays, coherence, &mut ws.hits, &mut stats.trace),
            }
        });
        let queued = ws.rays.len();
        timed(ctx.stage_times, &mut times.shade, || {
            // Misses out, and specular vertices behind the others where that pays: one pass.
            if !stages::group_specular(ctx, depth, &mut ws.rays, &mut ws.hits, &mut ws.shade) {
                stages::drop_misses(&mut ws.rays, &mut ws.hits);
            }
            ws.next_rays.clear();
            ws.shadow.clear();
            ws.probes.clear();
            let queues = ShadeOutputs {
                next: &mut ws.next_rays,
                shadow: &mut ws.shadow,
                probes: &mut ws.probes,
            };
            let (rays, hits) = (&ws.rays, &ws.hits);
            stats.lane_vertices += stages::shade(
                ctx,
                depth,
                rays,
                hits,
                &mut ws.paths,
                &mut ws.draws,
                &mut ws.shade,
                queues,
            );
        });
        stats.shadow_rays += ws.shadow.len() as u64;
        stats.probe_rays += ws.probes.len() as u64;
        timed(ctx.stage_times, &mut times.shadow_rays, || {
            stages::trace_shadow_rays(
                ctx,
                &ws.shadow,
                coherence,
                &mut ws.blocked,
                &mut ws.paths,
                &mut stats.trace,
            )
        });
        // Hemisphere probes leave the surfaces this queue hit, as the next depth's bounces do;
        // the queue's density counts the rays traced at this depth, misses included.
        let probe_coherence = stages::Coherence::of_queue(
            depth + 1,
            queued,
            camera_len,
            ctx.packets,
            ctx.accel.is_large(),
        );
        timed(ctx.stage_times, &mut times.probes, || {
            stages::trace_emission_probes(
                ctx,
                &ws.probes,
                probe_coherence,
                &mut ws.hits,
                &mut ws.emitter_rays,
                &mut ws.paths,
                &mut stats.trace,
            )
        });
        std::mem::swap(&mut ws.rays, &mut ws.next_rays);
        stats.bounce_rays += ws.rays.len() as u64;
        depth += 1;
    }
    timed(ctx.stage_times, &mut times.accumulate, || {
        stages::accumulate(&ws.paths, &mut ws.pixels, ctx.adaptive.is_some())
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every stage counts once in `total`, and the traversal stages (hits, shadow rays and
    /// probes) in `traversal`; `add` adds stage by stage.
    #[test]
    fn stage_times_add_up_and_split_into_traversal_and_the_rest() {
        let ms = Duration::from_millis;
        let t = StageTimes {
            generate: ms(1),
            camera_hits: ms(2),
            bounce_hits: ms(4),
            shade: ms(8),
            shadow_rays: ms(16),
            probes: ms(32),
            accumulate: ms(64),
        };
        assert_eq!(t.traversal(), ms(2 + 4 + 16 + 32));
        assert_eq!(t.total(), ms(127));
        let mut sum = t;
        sum.add(&t);
        assert_eq!(sum.total(), ms(254));
        assert_eq!(sum.traversal(), ms(108));
        assert_eq!((sum.generate, sum.shade, sum.accumulate), (ms(2), ms(16), ms(128)));
        let mut slot = ms(5);
        assert_eq!(timed(false, &mut slot, || 7), 7);
        assert_eq!(slot, ms(5), "not asked: the clock is not read");
        timed(true, &mut slot, || std::thread::sleep(ms(2)));
        assert!(slot >= ms(7));
    }
}
