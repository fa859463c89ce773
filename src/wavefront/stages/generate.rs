//! Stage 1: camera rays for a batch of samples of every pixel of a tile.

use super::super::{PathState, RayQueue, RenderContext, Tile};
use crate::math::{Ray, Vec3};
use crate::sampler::{self, Decision, PathSampler, SamplerKind};

/// Paths whose camera rays are made together in SIMD lanes.
const LANES: usize = 8;

/// Starts one path per (active pixel, sample) and queues its camera ray. With one sample per pixel the
/// ray goes through the pixel centre (as the course does); otherwise it is jittered within the
/// pixel by the sampler's camera-jitter decision (stratified over the pixel's samples with
/// `--sampler sobol`, uniform with `independent`).
///
/// Two passes: the paths first (a pixel's key hashed once for all its samples), then their
/// rays 8 at a time, the Sobol jitter and the directions in lanes. Done one path at a time this
/// stage was a sixth of a `-m 1` render (PERF.md, "Whole renders"); the rays are the same bits.
pub fn generate_camera_rays(
    ctx: &RenderContext,
    tile: Tile,
    first_sample: u32,
    batch: u32,
    active: &[bool],
    paths: &mut PathState,
    rays: &mut RayQueue,
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
            for s in first_sample..first_sample + batch {
                let path = PathSampler::for_pixel(ctx.sampler, ctx.seed, pixel, key, s, ctx.spp);
                paths.push(local, path);
            }
        }
    }
    for first in (0..paths.len()).step_by(LANES) {
        let ids = first..(first + LANES).min(paths.len());
        let (mut px, mut py) = ([0.0f32; LANES], [0.0f32; LANES]);
        for (l, p) in ids.clone().enumerate() {
            let local = paths.pixel[p];
            px[l] = (tile.x0 + local % tile.width) as f32;
            py[l] = (tile.y0 + local / tile.width) as f32;
        }
        let (jx, jy) = jitter(ctx, &mut paths.sampler[ids.clone()]);
        for l in 0..LANES {
            px[l] += jx[l];
            py[l] += jy[l];
        }
        // Each ray straight from the lane arrays: staging whole `Vec3`s first made every
        // ray's copy wait on a failed store-to-load forward (a sixth of this stage's samples).
        let [x, y, z] = ctx.camera.dirs_through_pixels(px, py);
        for (l, p) in ids.enumerate() {
            rays.push(Ray::new(ctx.camera.eye, Vec3::new(x[l], y[l], z[l])), p as u32);
        }
    }
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
