//! Stage 4: any-hit queries for the shadow-ray queue; unblocked rays deliver their radiance.

use super::super::{PathState, RenderContext, ShadowQueue};
use super::extend::{closest_hits, extend_to_emitters, occlusion, Coherence, EmitterScratch};
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
    occlusion(ctx.accel, &shadow.rays, coherence, blocked, stats);
    // Zipped, not indexed: one bounds check per ray instead of three.
    let delivered = blocked.iter().zip(&shadow.path).zip(&shadow.radiance);
    for ((_, &path), &radiance) in delivered.filter(|((&b, _), _)| !b) {
        paths.radiance[path as usize] += radiance;
    }
}

/// Closest-hit queries for emission probes (uniform hemisphere sampling's directions, the
/// extra camera rays on emitter outlines): each probe adds its weight times the emission of
/// the front face it hits (scene lights are not geometry and are never hit). `hits` and
/// `scratch` are scratch space; the probes of a coherent queue go in packets, and where the
/// scene's emitters have a structure of their own, they are found there first
/// (`extend_to_emitters`).
pub fn trace_emission_probes(
    ctx: &RenderContext,
    probes: &ShadowQueue,
    coherence: Coherence,
    hits: &mut Vec<Option<Hit>>,
    scratch: &mut EmitterScratch,
    paths: &mut PathState,
    stats: &mut TraceStats,
) {
    if probes.is_empty() {
        return;
    }
    match ctx.emitters {
        Some(emitters) => {
            extend_to_emitters(ctx, emitters, &probes.rays, coherence, hits, scratch, stats)
        }
        None => {
            reset_hits(hits, probes.len());
            closest_hits(ctx.accel, &probes.rays, coherence, hits, stats);
        }
    }
    for (i, hit) in hits.iter().enumerate() {
        let seen = hit.map_or(Vec3::ZERO, |h| emission_seen(ctx.scene, &probes.rays[i], &h));
        if seen != Vec3::ZERO {
            paths.radiance[probes.path[i] as usize] += probes.radiance[i] * seen;
        }
    }
}
