//! Stage 1: camera rays for a batch of samples of every pixel of a tile.

use super::super::{PathState, RayQueue, RenderContext, Tile};
use crate::sampler::{Decision, PathSampler};

/// Starts one path per (active pixel, sample) and queues its camera ray. With one sample per pixel the
/// ray goes through the pixel centre (as the course does); otherwise it is jittered within the
/// pixel by the sampler's camera-jitter decision (stratified over the pixel's samples with
/// `--sampler sobol`, uniform with `independent`).
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
            let pixel_in_image = y as u64 * width as u64 + x as u64;
            for s in first_sample..first_sample + batch {
                let mut sampler = PathSampler::new(ctx.seed, pixel_in_image, s, ctx.spp);
                let [jx, jy] = if ctx.spp == 1 {
                    [0.5, 0.5]
                } else {
                    sampler.get_2d(ctx.sampler, 0, Decision::CameraJitter, 0, 1)
                };
                let ray = ctx.camera.ray_through_pixel(x as f32 + jx, y as f32 + jy);
                let id = paths.push(local, sampler);
                rays.push(ray, id);
            }
        }
    }
}
