//! Stage 4: any-hit queries for the shadow-ray queue; unblocked rays deliver their radiance.

use super::super::{PathState, RenderContext, ShadowQueue, Surface};
use super::extend::{Coherence, PACKET};
use crate::accel::TraceStats;
use crate::math::Vec3;

/// Shadow rays take the coherence of the queue whose hits made them (`Coherence::of_queue`):
/// from a coherent queue they start at neighbouring points and head for the same lights, so
/// they go in packets; otherwise one at a time. Both give the same answers, so the image does
/// not depend on the choice.
pub fn trace_shadow_rays(
    ctx: &RenderContext,
    shadow: &ShadowQueue,
    coherence: Coherence,
    blocked: &mut Vec<bool>,
    paths: &mut PathState,
    stats: &mut TraceStats,
) {
    blocked.clear();
    blocked.resize(shadow.len(), false);
    match coherence {
        Coherence::Coherent => ctx.accel.occluded_packets::<PACKET>(&shadow.rays, blocked, stats),
        Coherence::Incoherent => ctx.accel.occluded_stream(&shadow.rays, blocked, stats),
    }
    for (i, _) in blocked.iter().enumerate().filter(|(_, &b)| !b) {
        paths.radiance[shadow.path[i] as usize] += shadow.radiance[i];
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
