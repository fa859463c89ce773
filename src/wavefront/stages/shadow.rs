//! Stage 4: any-hit queries for the shadow-ray queue; unblocked rays deliver their radiance.

use super::super::{PathState, RenderContext, ShadowQueue};
use super::Surface;
use crate::accel::TraceStats;
use crate::math::Vec3;

pub fn trace_shadow_rays(
    ctx: &RenderContext,
    shadow: &ShadowQueue,
    paths: &mut PathState,
    stats: &mut TraceStats,
) {
    for ((ray, radiance), &path) in shadow.rays.iter().zip(&shadow.radiance).zip(&shadow.path) {
        if !ctx.accel.occluded(ray, stats) {
            paths.radiance[path as usize] += *radiance;
        }
    }
}

/// Closest-hit queries for uniform hemisphere sampling: each probe adds its weight times the
/// emission of the front face it hits (scene lights are not geometry and are never hit).
pub fn trace_emission_probes(
    ctx: &RenderContext,
    probes: &ShadowQueue,
    paths: &mut PathState,
    stats: &mut TraceStats,
) {
    for ((ray, weight), &path) in probes.rays.iter().zip(&probes.radiance).zip(&probes.path) {
        let Some(hit) = ctx.accel.intersect(ray, stats) else {
            continue;
        };
        let surface = Surface::at(ctx.scene, ray, &hit);
        let emitted = ctx.scene.materials[surface.material as usize].emission();
        if emitted != Vec3::ZERO && surface.ng.dot(ray.dir) < 0.0 {
            paths.radiance[path as usize] += *weight * emitted;
        }
    }
}
