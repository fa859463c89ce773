//! What a batch of diffuse lanes (`diffuse::shade_diffuse`) produces, and queueing it: the
//! shadow rays of each light draw and the bounces, as ray records per lane, moved into the
//! wavefront's queues in the order the scalar path would have queued them.

use super::diffuse::LANES;
use super::lane_math::{Lanes, V, V3};
use super::{PathState, RayQueue, ShadeOutputs, ShadowQueue};
use crate::math::{Ray, Vec3};
use crate::simd::SimdF32;

fn get(a: &[Lanes; 3], l: usize) -> Vec3 {
    Vec3::new(a[0][l], a[1][l], a[2][l])
}

/// The rays of `LANES` lanes as records of 8 floats (`Ray::record`), by 8 x 8 transposes
/// (`SimdF32::rows8`): queueing a lane's ray is then one copy, not eight lane extractions.
#[inline(always)]
pub(super) fn ray_records(origin: V3, dir: V3, t_min: V, t_max: V) -> [[f32; 8]; LANES] {
    let mut out = [[0.0; 8]; LANES];
    V::rows8([origin.x, origin.y, origin.z, dir.x, dir.y, dir.z, t_min, t_max], &mut out);
    out
}

/// Shadow rays of one light draw, lane by lane; lane `l` is queued iff bit `l` of `valid`.
#[derive(Default, Clone)]
pub struct ShadowLanes {
    /// Lanes with a shadow ray to queue, as a bit mask.
    pub valid: u32,
    pub(super) rays: [[f32; 8]; LANES],
    pub(super) contribution: [Lanes; 3],
}

impl ShadowLanes {
    /// The shadow ray of lane `l`.
    pub fn ray(&self, l: usize) -> Ray {
        Ray::from_record(&self.rays[l])
    }
    /// What lane `l`'s shadow ray adds to its path's radiance if unblocked.
    pub fn contribution(&self, l: usize) -> Vec3 {
        get(&self.contribution, l)
    }
}

/// Continuation rays, lane by lane; lane `l` continues iff bit `l` of `valid`.
#[derive(Default)]
pub struct BounceLanes {
    /// Lanes that continue with a bounce, as a bit mask.
    pub valid: u32,
    pub(super) rays: [[f32; 8]; LANES],
    pub(super) throughput: [Lanes; 3],
    pub(super) pdf: Lanes,
}

impl BounceLanes {
    /// The continuation ray of lane `l`.
    pub fn ray(&self, l: usize) -> Ray {
        Ray::from_record(&self.rays[l])
    }
    /// The path throughput of lane `l` after the bounce: times the albedo, divided by the
    /// Russian-roulette survival probability where roulette applies.
    pub fn throughput(&self, l: usize) -> Vec3 {
        get(&self.throughput, l)
    }
    /// The solid-angle pdf of lane `l`'s bounce direction, cos / pi.
    pub fn pdf(&self, l: usize) -> f32 {
        self.pdf[l]
    }
}

/// What one batch queues: a shadow ray per light draw and lane, and a bounce per lane.
#[derive(Default)]
pub struct DiffuseOutputs {
    /// One `ShadowLanes` per light draw, in light-draw order.
    pub shadows: Vec<ShadowLanes>,
    /// Whether `shadows` are emission probes (uniform hemisphere sampling), queued as
    /// `ShadeOutputs::probes`, not shadow rays.
    pub probes: bool,
    /// The continuation of every lane.
    pub bounce: BounceLanes,
}

impl DiffuseOutputs {
    /// The queue the light draws' rays go to (the probe queue for emission probes, else the
    /// shadow queue), and the bounce queue.
    fn light_queues<'a>(&self, q: &'a mut ShadeOutputs) -> (&'a mut ShadowQueue, &'a mut RayQueue) {
        let light = if self.probes { &mut *q.probes } else { &mut *q.shadow };
        (light, &mut *q.next)
    }
}

/// Queues what every lane of a batch produced, as `queue_lane` for each lane in turn (the
/// queues come out the same), for a chunk whose vertices all went through the lanes: the
/// queue columns grow once per chunk, and only lanes with a ray are visited.
pub fn queue_all_lanes(
    out: &DiffuseOutputs,
    lanes: &super::diffuse::DiffuseLanes,
    paths: &mut PathState,
    queues: &mut ShadeOutputs,
) {
    let (shadow, next) = out.light_queues(queues);
    let count: u32 = out.shadows.iter().map(|s| s.valid.count_ones()).sum();
    shadow.reserve(count as usize);
    let (n, all) = (lanes.len, low_bits(lanes.len));
    if let [s] = out.shadows.as_slice() {
        // One light draw (the common case): its lanes straight, without the per-lane draw loop
        // of `queue_shadows` (that loop here cost -m 5 renders 1-2%); every lane's in one go
        // when each has a ray.
        if s.valid == all {
            let c = &s.contribution;
            shadow.push_records(
                &s.rays[..n],
                [&c[0][..n], &c[1][..n], &c[2][..n]],
                &lanes.path[..n],
            );
        } else {
            for l in set_bits(s.valid) {
                shadow.push(s.ray(l), s.contribution(l), lanes.path[l]);
            }
        }
    } else {
        for l in set_bits(out.shadows.iter().fold(0, |m, s| m | s.valid)) {
            queue_shadows(out, l, lanes.path[l], shadow);
        }
    }
    let b = &out.bounce;
    if b.valid == all {
        next.push_records(&b.rays[..n], &lanes.path[..n]);
        for (l, &path) in lanes.path[..n].iter().enumerate() {
            continue_path(b, l, path, paths);
        }
        return;
    }
    next.reserve(b.valid.count_ones() as usize);
    for l in set_bits(b.valid) {
        queue_bounce(b, l, lanes.path[l], paths, next);
    }
}

/// The mask of lanes `0..n`.
#[inline(always)]
fn low_bits(n: usize) -> u32 {
    ((1u64 << n) - 1) as u32
}

/// The positions of the set bits of `mask`, lowest first.
#[inline(always)]
fn set_bits(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        let l = mask.trailing_zeros() as usize;
        mask &= mask.wrapping_sub(1);
        (l < 32).then_some(l)
    })
}

/// Queues what lane `l` of a batch produced for path `path`, as the scalar path would have:
/// its shadow rays in light-draw order, then its bounce.
#[inline]
pub fn queue_lane(
    out: &DiffuseOutputs,
    l: usize,
    path: u32,
    paths: &mut PathState,
    queues: &mut ShadeOutputs,
) {
    queue_shadows(out, l, path, out.light_queues(queues).0);
    if out.bounce.valid & (1 << l) != 0 {
        queue_bounce(&out.bounce, l, path, paths, queues.next);
    }
}

/// Lane `l`'s shadow rays, in light-draw order.
#[inline(always)]
fn queue_shadows(out: &DiffuseOutputs, l: usize, path: u32, shadow: &mut ShadowQueue) {
    for s in out.shadows.iter().filter(|s| s.valid & (1 << l) != 0) {
        shadow.push(s.ray(l), s.contribution(l), path);
    }
}

/// Lane `l`'s bounce (which it has): the path's new throughput and pdf, and its ray.
#[inline(always)]
fn queue_bounce(b: &BounceLanes, l: usize, path: u32, paths: &mut PathState, next: &mut RayQueue) {
    continue_path(b, l, path, paths);
    next.push(b.ray(l), path);
}

/// Path `path`'s throughput and pdf after lane `l`'s bounce.
#[inline(always)]
fn continue_path(b: &BounceLanes, l: usize, path: u32, paths: &mut PathState) {
    paths.throughput[path as usize] = b.throughput(l);
    paths.bsdf_pdf[path as usize] = b.pdf(l);
}
