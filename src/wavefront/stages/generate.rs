//! Stage 1: camera rays for a batch of samples of every pixel of a tile.
//!
//! On the outline of a visible emitter a pixel's value jumps by the emitter's radiance between
//! camera samples that land on it and beside it, and at moderate spp that step is most of the
//! image's noise (PERF.md, "Whole renders"). So each sample of such a pixel also traces K extra
//! camera rays (`--edge-samples K`, stratified by their own Sobol sequence) that only look for
//! emission, and the K + 1 rays share the zero-bounce estimate, each weighted 1 / (K + 1). The
//! rest of the path still starts at the sample's own camera ray. Which pixels count as outline
//! is decided before any sample, from rays through the tile's pixel corners (a pixel whose four
//! corners see different emission), so the choice does not depend on the samples it changes and
//! the estimator stays unbiased; a pixel the corners miss keeps the plain estimate.

use super::super::{PathState, RayQueue, RenderContext, ShadowQueue, Tile};
use super::extend::{extend, Coherence};
use crate::accel::TraceStats;
use crate::integrator::emission_seen;
use crate::math::{Hit, Ray, Vec3};
use crate::sampler::{self, Decision, PathSampler, SamplerKind};
use crate::scene::{Camera, Scene};

/// A tile's pixels on an emitter's outline and the extra camera rays each of their samples
/// takes (`mark_emitter_edges`).
#[derive(Default)]
pub struct EdgePixels {
    /// Per pixel of the tile (row-major): on an outline.
    pub marked: Vec<bool>,
    /// Extra camera rays per sample of a marked pixel: `--edge-samples`, fewer where so many
    /// pixels are marked that the tile would trace more than `EDGE_BUDGET` extra rays per
    /// camera ray.
    pub extra: u32,
}

/// At most this many extra camera rays per camera ray of a tile: a tile full of outlines (an
/// emitter made of many small pieces) then costs at most twice its camera rays, while the thin
/// outline of an ordinary light keeps all `--edge-samples` (CBbunny at 400 x 300: up to 32
/// marked pixels of a tile's 256; a budget of 0.5 cut some of its tiles to fewer rays and left
/// 0.4% more noise).
const EDGE_BUDGET: f32 = 1.0;

/// Paths whose camera rays are made together in SIMD lanes: 16, two chains of 8-lane
/// arithmetic that overlap (`Camera::dirs_through_pixels`; 8 took 0.032 s of a `-m 1`
/// render's camera rays where 16 take 0.029 s: PERF.md, "Whole renders").
const LANES: usize = 16;

/// Starts one path per (active pixel, sample) and queues its camera ray. With one sample per pixel the
/// ray goes through the pixel centre (as the course does); otherwise it is jittered within the
/// pixel by the sampler's camera-jitter decision (stratified over the pixel's samples with
/// `--sampler sobol`, uniform with `independent`).
///
/// Two passes: the paths first (a pixel's key hashed once for all its samples), then their
/// rays 16 at a time, the Sobol jitter and the directions in lanes. Done one path at a time this
/// stage was a sixth of a `-m 1` render (PERF.md, "Whole renders"); the rays are the same bits.
///
/// Paths of pixels marked in `edges` (`mark_emitter_edges`) also queue their K = `edges.extra`
/// extra camera rays in `edge_rays`, as emission probes weighted 1 / (K + 1)
/// (`trace_emission_probes`).
#[allow(clippy::too_many_arguments)]
pub fn generate_camera_rays(
    ctx: &RenderContext,
    tile: Tile,
    first_sample: u32,
    batch: u32,
    active: &[bool],
    edges: &EdgePixels,
    paths: &mut PathState,
    rays: &mut RayQueue,
    edge_rays: &mut ShadowQueue,
) {
    paths.clear();
    rays.clear();
    let width = ctx.camera.width;
    for local_y in 0..tile.height {
        for local_x in 0..tile.width {
            let local = local_y * tile.width + local_x;
            if !active[local as usize] {
                continue;
            }
            let (x, y) = (tile.x0 + local_x, tile.y0 + local_y);
            let pixel = y as u64 * width as u64 + x as u64;
            let key = sampler::pixel_key(ctx.seed, pixel);
            let samples = first_sample..first_sample + batch;
            paths.push_pixel_samples(
                local,
                samples
                    .map(|s| PathSampler::for_pixel(ctx.sampler, ctx.seed, pixel, key, s, ctx.spp)),
            );
        }
    }
    for first in (0..paths.len()).step_by(LANES) {
        let ids = first..(first + LANES).min(paths.len());
        let (mut px, mut py) = ([0.0f32; LANES], [0.0f32; LANES]);
        // A pixel's samples are consecutive paths: its coordinates are divided out once.
        let mut pixel = (u32::MAX, 0.0, 0.0);
        for (l, p) in ids.clone().enumerate() {
            let local = paths.pixel[p];
            if local != pixel.0 {
                let (x, y) = (tile.x0 + local % tile.width, tile.y0 + local / tile.width);
                pixel = (local, x as f32, y as f32);
            }
            (px[l], py[l]) = (pixel.1, pixel.2);
        }
        let (jx, jy) = jitter(ctx, &mut paths.sampler[ids.clone()]);
        for l in 0..LANES {
            px[l] += jx[l];
            py[l] += jy[l];
        }
        // Each ray straight from the lane arrays: staging whole `Vec3`s first made every
        // ray's copy wait on a failed store-to-load forward (a sixth of this stage's samples).
        let [x, y, z] = ctx.camera.dirs_through_pixels(px, py);
        let eye = ctx.camera.eye;
        let lane_rays = (0..ids.len()).map(|l| Ray::new(eye, Vec3::new(x[l], y[l], z[l])));
        rays.push_run(lane_rays, first as u32);
    }
    edge_rays.clear();
    if edges.extra > 0 {
        queue_edge_rays(tile, edges, ctx, paths, edge_rays);
    }
}

/// The extra camera rays of the paths whose pixel is marked in `edges`.
fn queue_edge_rays(
    tile: Tile,
    edges: &EdgePixels,
    ctx: &RenderContext,
    paths: &mut PathState,
    edge_rays: &mut ShadowQueue,
) {
    let k = edges.extra;
    let weight = 1.0 / (k + 1) as f32;
    for p in 0..paths.len() {
        let local = paths.pixel[p];
        if !edges.marked[local as usize] {
            continue;
        }
        paths.zero_bounce_weight[p] = weight;
        let px = (tile.x0 + local % tile.width) as f32;
        let py = (tile.y0 + local / tile.width) as f32;
        for sub in 0..k {
            let [jx, jy] = paths.sampler[p].get_2d(ctx.sampler, 0, Decision::EdgeJitter, sub, k);
            let ray = ctx.camera.ray_through_pixel(px + jx, py + jy);
            edge_rays.push(ray, Vec3::splat(weight), p as u32);
        }
    }
}

/// Marks in `edges` the tile's pixels whose four corners see different emission (an emitter's
/// outline, or an occluder's in front of one), in a tile that the emitters' projection reaches
/// (`RenderContext::emitter_window`, `None` when the render takes no extra rays); and sets how
/// many extra rays their samples take (`EdgePixels::extra`, within `EDGE_BUDGET`). Everything
/// here depends on the tile alone, never on the samples. `rays`, `hits` and `seen` are scratch
/// space; returns the number of corner rays traced.
pub fn mark_emitter_edges(
    ctx: &RenderContext,
    tile: Tile,
    rays: &mut RayQueue,
    hits: &mut Vec<Option<Hit>>,
    seen: &mut Vec<Vec3>,
    edges: &mut EdgePixels,
    stats: &mut TraceStats,
) -> u64 {
    edges.marked.clear();
    edges.marked.resize(tile.pixel_count(), false);
    edges.extra = 0;
    let applies = ctx.emitter_window.is_some_and(|[x0, y0, x1, y1]| {
        // The tile's pixels, with a pixel's margin for the window's rounding.
        let (tx0, ty0) = (tile.x0 as f32 - 1.0, tile.y0 as f32 - 1.0);
        let (tx1, ty1) =
            ((tile.x0 + tile.width) as f32 + 1.0, (tile.y0 + tile.height) as f32 + 1.0);
        tx0 <= x1 && x0 <= tx1 && ty0 <= y1 && y0 <= ty1
    });
    if !applies {
        return 0;
    }
    rays.clear();
    let (w, h) = (tile.width + 1, tile.height + 1);
    for cy in 0..h {
        for cx in 0..w {
            let ray = ctx.camera.ray_through_pixel((tile.x0 + cx) as f32, (tile.y0 + cy) as f32);
            rays.push(ray, 0);
        }
    }
    extend(ctx, rays, Coherence::of_queue(0, 0, 0, ctx.packets, false), hits, stats);
    seen.clear();
    seen.extend(
        rays.rays
            .iter()
            .zip(hits.iter())
            .map(|(r, h)| h.as_ref().map_or(Vec3::ZERO, |h| emission_seen(ctx.scene, r, h))),
    );
    for y in 0..tile.height {
        for x in 0..tile.width {
            let c = (y * w + x) as usize;
            let corners = [seen[c], seen[c + 1], seen[c + w as usize], seen[c + w as usize + 1]];
            edges.marked[(y * tile.width + x) as usize] = corners.iter().any(|&e| e != corners[0]);
        }
    }
    let marked = edges.marked.iter().filter(|&&m| m).count();
    let budget = (EDGE_BUDGET * tile.pixel_count() as f32) as usize;
    if let Some(per_pixel) = budget.checked_div(marked) {
        edges.extra = ctx.edge_samples.min(per_pixel as u32);
    }
    rays.len() as u64
}

/// The image rectangle [x0, y0, x1, y1] (pixels, row 0 at the top) that holds the projection
/// of every primitive with an emissive material: no camera ray outside it can hit an emitter,
/// so tiles outside it look for no outline. `None` without emissive primitives; the whole
/// image plane when an emitter reaches behind the camera (its projection is then unbounded).
pub fn emitter_window(scene: &Scene, camera: &Camera) -> Option<[f32; 4]> {
    let emits = |m: u32| scene.materials[m as usize].emission() != Vec3::ZERO;
    let triangles = (0..scene.triangles.len())
        .filter(|&i| emits(scene.triangle_materials[i]))
        .flat_map(|i| scene.triangle(i));
    // A sphere's bounding box corners: their projection holds the sphere's.
    let spheres = scene.spheres.iter().filter(|s| emits(s.material)).flat_map(|s| {
        (0..8).map(move |k: u32| {
            let sign = |bit: u32| if k >> bit & 1 == 1 { 1.0 } else { -1.0 };
            s.center + s.radius * Vec3::new(sign(0), sign(1), sign(2))
        })
    });
    let mut window: Option<[f32; 4]> = None;
    for p in triangles.chain(spheres) {
        let Some([x, y]) = camera.pixel_of(p) else {
            return Some([f32::NEG_INFINITY, f32::NEG_INFINITY, f32::INFINITY, f32::INFINITY]);
        };
        let [x0, y0, x1, y1] = window.unwrap_or([x, y, x, y]);
        window = Some([x0.min(x), y0.min(y), x1.max(x), y1.max(y)]);
    }
    window
}

/// The position within the pixel of each of up to `LANES` paths' camera rays; lanes past
/// `samplers.len()` are unused.
fn jitter(ctx: &RenderContext, samplers: &mut [PathSampler]) -> ([f32; LANES], [f32; LANES]) {
    if ctx.spp == 1 {
        return ([0.5; LANES], [0.5; LANES]);
    }
    match ctx.sampler {
        SamplerKind::Sobol => {
            let (mut keys, mut samples) = ([0u32; LANES], [0u32; LANES]);
            for (l, s) in samplers.iter().enumerate() {
                (keys[l], samples[l]) = (s.pixel_key(), s.sample());
            }
            sampler::sobol_camera_jitter(&keys, &samples)
        }
        SamplerKind::Independent => {
            let (mut jx, mut jy) = ([0.0f32; LANES], [0.0f32; LANES]);
            for (l, s) in samplers.iter_mut().enumerate() {
                [jx[l], jy[l]] =
                    s.get_2d(SamplerKind::Independent, 0, Decision::CameraJitter, 0, 1);
            }
            (jx, jy)
        }
    }
}
