//! Stage 4: any-hit queries for the shadow-ray queue; unblocked rays deliver their radiance.

use super::super::{PathState, RenderContext, ShadowQueue};
use super::extend::{Coherence, CAMERA_PACKET, PACKET};
use crate::accel::TraceStats;
use crate::integrator::emission_seen;
use crate::math::{reset_hits, Hit, Vec3};

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
        Coherence::Camera => {
            ctx.accel.occluded_packets::<CAMERA_PACKET>(&shadow.rays, blocked, stats)
        }
        Coherence::Coherent => ctx.accel.occluded_packets::<PACKET>(&shadow.rays, blocked, stats),
        Coherence::Incoherent => ctx.accel.occluded_stream(&shadow.rays, blocked, stats),
    }
    for (i, _) in blocked.iter().enumerate().filter(|(_, &b)| !b) {
        paths.radiance[shadow.path[i] as usize] += shadow.radiance[i];
    }
}

/// Closest-hit queries for emission probes (uniform hemisphere sampling's directions, the
/// extra camera rays on emitter outlines): each probe adds its weight times the emission of
/// the front face it hits (scene lights are not geometry and are never hit). `hits` is scratch
/// space; the probes of a coherent queue go in packets.
pub fn trace_emission_probes(
    ctx: &RenderContext,
    probes: &ShadowQueue,
    coherence: Coherence,
    hits: &mut Vec<Option<Hit>>,
    paths: &mut PathState,
    stats: &mut TraceStats,
) {
    if probes.is_empty() {
        return;
    }
    reset_hits(hits, probes.len());
    match coherence {
        Coherence::Camera => {
            ctx.accel.intersect_packets::<CAMERA_PACKET>(&probes.rays, hits, stats)
        }
        Coherence::Coherent => ctx.accel.intersect_packets::<PACKET>(&probes.rays, hits, stats),
        Coherence::Incoherent => ctx.accel.intersect_stream(&probes.rays, hits, stats),
    }
    for (i, hit) in hits.iter().enumerate() {
        let seen = hit.map_or(Vec3::ZERO, |h| emission_seen(ctx.scene, &probes.rays[i], &h));
        if seen != Vec3::ZERO {
            paths.radiance[probes.path[i] as usize] += probes.radiance[i] * seen;
        }
    }
}
