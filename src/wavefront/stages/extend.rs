//! Stage 2: closest-hit queries for every queued ray; for rays that can only add emission, the
//! emitters' closest hit and one occlusion query up to it (`extend_to_emitters`).

use super::super::{RayQueue, RenderContext};
use crate::accel::{Accel, TraceStats};
use crate::integrator::{emission_seen, EmitterAccel};
use crate::math::{reset_hits, Hit, Ray, Vec3};

/// How a queue's rays are traced. Camera rays of a tile (and their shadow rays) are coherent:
/// neighbouring queue entries are samples of the same or adjacent pixels, so packets
/// (`CAMERA_PACKET` rays) share most nodes. Bounces keep the queue order of their pixels, so
/// while most paths of the tile are alive, neighbouring entries still start from nearby points
/// and packets (`PACKET` rays) win on a cache-resident structure; once most have left the
/// scene, neighbours come from pixels far apart and single rays (in streams) win. Packet and single-ray traversal return
/// bit-identical hits, so the choice never changes the image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coherence {
    /// Camera rays and the rays their hits make: packets of `CAMERA_PACKET` rays.
    Camera,
    /// Packets of `PACKET` rays.
    Coherent,
    /// Single rays, in streams.
    Incoherent,
}

impl Coherence {
    /// Camera rays (depth 0) are coherent, and first bounces (depth 1) unless the structure
    /// outgrows the caches; later bounces too while the queue holds at least half as many rays
    /// as the tile's camera queue (measured: PERF.md, "Whole renders").
    /// `packets: false` treats every queue as incoherent (single rays throughout).
    pub fn of_queue(
        depth: u32,
        queue_len: usize,
        camera_len: usize,
        packets: bool,
        large_structure: bool,
    ) -> Coherence {
        let dense = queue_len * 2 >= camera_len;
        let coherent = match depth {
            0 => true,
            1 => !large_structure,
            _ => !large_structure && dense,
        };
        match (packets && coherent, depth) {
            (false, _) => Coherence::Incoherent,
            (true, 0) => Coherence::Camera,
            (true, _) => Coherence::Coherent,
        }
    }
}

/// Packet width for coherent bounce queues: 16 rays where one register holds them (the avx512
/// build), 8 below it, where 16-ray packets are two halves and did not pay for bounces
/// (PERF.md, "One binary for every x86-64 CPU", "Camera packets of 16 and whole-chunk
/// queueing").
pub const PACKET: usize = if cfg!(target_feature = "avx512f") { 16 } else { 8 };

/// Single-ray fallback threshold of bounce packets: an interior subtree entered by at most this
/// many lanes is finished one ray at a time (leaves never are: `traverse_packet`). Bounce rays
/// diverge, so a 16-ray packet reaches most subtrees with few lanes left, and handing over up
/// to 3 of them took 1-2% off CBbunny's `-m 5` renders on Zen 4; 8-ray packets (and camera
/// packets) keep the traversal's default, which 3 made slower (PERF.md, "Whole renders",
/// "Misses out of the queue, one wall's normals read once"; 2 and 5 re-measured in "Rooms split
/// into walls").
pub const BOUNCE_FALLBACK: u32 = if PACKET >= 16 { 3 } else { 1 };

/// Packet width for camera rays and the shadow rays and probes of their hits: 16 rays in every
/// build. A tile's queue holds a pixel's samples one after the other, so 16 neighbouring camera
/// rays share nearly every node and one walk of the tree serves all of them, even as two 8-wide
/// halves below AVX-512 (PERF.md, "Camera packets of 16 and whole-chunk queueing").
pub const CAMERA_PACKET: usize = 16;

/// Finds the closest hit of each queued ray; `hits[i]` answers `rays.rays[i]`.
pub fn extend(
    ctx: &RenderContext,
    rays: &RayQueue,
    coherence: Coherence,
    hits: &mut Vec<Option<Hit>>,
    stats: &mut TraceStats,
) {
    reset_hits(hits, rays.len());
    closest_hits(ctx.accel, &rays.rays, coherence, hits, stats);
}

/// The closest hit in `accel` of each ray, traced as `coherence` says.
pub(super) fn closest_hits(
    accel: &Accel,
    rays: &[Ray],
    coherence: Coherence,
    hits: &mut [Option<Hit>],
    stats: &mut TraceStats,
) {
    match coherence {
        Coherence::Camera => accel.intersect_packets::<CAMERA_PACKET>(rays, hits, stats),
        Coherence::Coherent => {
            accel.intersect_packets_with::<PACKET>(rays, BOUNCE_FALLBACK, hits, stats)
        }
        Coherence::Incoherent => accel.intersect_stream(rays, hits, stats),
    }
}

/// Whether anything in `accel` blocks each ray, traced as `coherence` says.
pub(super) fn occlusion(
    accel: &Accel,
    rays: &[Ray],
    coherence: Coherence,
    blocked: &mut [bool],
    stats: &mut TraceStats,
) {
    match coherence {
        Coherence::Camera => accel.occluded_packets::<CAMERA_PACKET>(rays, blocked, stats),
        Coherence::Coherent => accel.occluded_packets::<PACKET>(rays, blocked, stats),
        Coherence::Incoherent => accel.occluded_stream(rays, blocked, stats),
    }
}

/// Scratch space of `extend_to_emitters`.
#[derive(Default)]
pub struct EmitterScratch {
    /// The rays that reach an emitter's front face, ending just before it.
    rays: Vec<Ray>,
    /// Where each of `rays` is in the traced slice.
    index: Vec<u32>,
    blocked: Vec<bool>,
}

/// For rays that can only add emission (`integrator::EmitterAccel`): the closest hit of each
/// ray where it is the front face of an emitter, `None` elsewhere (where `extend` and
/// `emission_seen` find no emission). The emitters' closest hit first, then for the rays that
/// found a front face, whether anything in the scene lies before it.
#[allow(clippy::too_many_arguments)]
pub fn extend_to_emitters(
    ctx: &RenderContext,
    emitters: &EmitterAccel,
    rays: &[Ray],
    coherence: Coherence,
    hits: &mut Vec<Option<Hit>>,
    scratch: &mut EmitterScratch,
    stats: &mut TraceStats,
) {
    reset_hits(hits, rays.len());
    let Some(accel) = emitters.accel() else {
        return;
    };
    closest_hits(accel, rays, coherence, hits, stats);
    scratch.rays.clear();
    scratch.index.clear();
    for (i, (ray, hit)) in rays.iter().zip(hits.iter_mut()).enumerate() {
        let Some(h) = *hit else { continue };
        let h = emitters.scene_hit(h);
        if emission_seen(ctx.scene, ray, &h) == Vec3::ZERO {
            *hit = None;
            continue;
        }
        *hit = Some(h);
        // Up to, not including, the emitter's distance: the emitter itself does not block.
        let before = Ray::segment(ray.origin, ray.dir, ray.t_min, h.t.next_down());
        scratch.rays.push(before);
        scratch.index.push(i as u32);
    }
    scratch.blocked.clear();
    scratch.blocked.resize(scratch.rays.len(), false);
    occlusion(ctx.accel, &scratch.rays, coherence, &mut scratch.blocked, stats);
    for (&i, _) in scratch.index.iter().zip(&scratch.blocked).filter(|(_, &b)| b) {
        hits[i as usize] = None;
    }
}

/// Removes the rays that left the scene (`hits[i]` is `None`) from the queue and `hits`,
/// keeping the others in order. Such a ray's path ends with nothing added (scene lights are
/// reached only by light sampling), so shading it did nothing but take a lane of its chunk:
/// at depths 1 and later a sixth of CBbunny's bounces leave through the open side of the box,
/// and their chunks ran 82-85% full. The paths left draw the same numbers (a path's numbers
/// depend on the path, not on its place in the queue), so the image does not change.
pub fn drop_misses(rays: &mut RayQueue, hits: &mut Vec<Option<Hit>>) {
    let Some(first) = hits.iter().position(Option::is_none) else {
        return;
    };
    retain_from(rays, hits, first, |_, _, _, hit| hit.is_some());
}

/// Keeps the queue entries before `first` as they are and, of the others, those for which
/// `keep(index, ray, path, hit)` holds, moved up in queue order; `keep` sees every entry from
/// `first` on once, in order (`drop_misses`, `shade::group_specular`).
#[inline(always)]
pub(super) fn retain_from(
    rays: &mut RayQueue,
    hits: &mut Vec<Option<Hit>>,
    first: usize,
    mut keep: impl FnMut(usize, &Ray, u32, &Option<Hit>) -> bool,
) {
    let n = hits.len();
    let (queued, paths) = (&mut rays.rays[..n], &mut rays.path[..n]);
    let mut kept = first;
    for i in first..n {
        if keep(i, &queued[i], paths[i], &hits[i]) {
            // `kept <= i < n`: said, so that the writes need no bounds checks of their own.
            let k = kept.min(i);
            (queued[k], paths[k], hits[k]) = (queued[i], paths[i], hits[i]);
            kept += 1;
        }
    }
    rays.rays.truncate(kept);
    rays.path.truncate(kept);
    hits.truncate(kept);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Ray, Vec3};

    fn hit(prim: u32) -> Option<Hit> {
        Some(Hit { t: 1.0, u: 0.0, v: 0.0, prim })
    }

    #[test]
    fn drop_misses_keeps_the_hits_in_queue_order() {
        let mut rays = RayQueue::default();
        for path in 0..6 {
            rays.push(Ray::new(Vec3::new(path as f32, 0.0, 0.0), Vec3::Z), path);
        }
        let mut hits = vec![None, hit(1), None, None, hit(4), hit(5)];
        drop_misses(&mut rays, &mut hits);
        assert_eq!(rays.path, [1, 4, 5]);
        assert_eq!(rays.rays.iter().map(|r| r.origin.x).collect::<Vec<_>>(), [1.0, 4.0, 5.0]);
        assert_eq!(hits, [hit(1), hit(4), hit(5)]);
        // No misses: nothing moves.
        drop_misses(&mut rays, &mut hits);
        assert_eq!(rays.path, [1, 4, 5]);
    }
}
