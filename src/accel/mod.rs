//! Acceleration structure: the public surface every stage uses.
//!
//! Triangles live in SoA blocks of eight in leaf order under one flat 8-wide BVH (224-byte
//! nodes, one SIMD test for eight boxes), collapsed from a binned-SAH binary BVH that is
//! dropped once collapsed. Single rays and packets traverse the same wide tree, so the
//! structure is the wide nodes plus the triangle blocks. Analytic spheres are tested after the
//! triangles (`spheres`): a short list, or a tree of their own when a scene has many.

mod binary_node;
pub mod build;
mod child_order;
mod hugepage;
mod leaf;
pub mod node;
pub(crate) mod packet;
mod packet_interval;
mod spheres;
pub(crate) mod traverse_packet;
pub mod traverse_single;
pub(crate) mod wide_node;

use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::geometry::TriangleSoa;
use crate::math::{fill_no_hits, Aabb, Hit, Ray, Vec3};
use crate::scene::Scene;
use crate::simd::{LaneWidth, Lanes, VFloat};
use crate::{Error, Result};
use spheres::Spheres;

pub use binary_node::{binary_node, BinaryNode};
pub use build::BuildParams;
pub use node::BvhNode;
pub use packet::RayPacket;
use packet::{CullBox, RayLanes};
pub use traverse_packet::PacketStack;
pub use wide_node::{WideNode, MAX_LEAF, MAX_TRIANGLES};

/// Largest binary subtree the collapse merges into one wide leaf (`build::collapse`; 0 keeps
/// the binary leaves). The binary SAH makes leaves of 1.7 triangles on average; the
/// single-ray leaf test takes 8 at once. Measured (PERF.md, "Wide BVH").
pub(crate) const WIDE_LEAF: usize = 8;

/// Bytes of structure per triangle, a lower bound for the estimate of `large` before the
/// build (measured 59.6 to 63.0 on the course scenes and the 1M tori, `bench`'s
/// bytes_per_triangle).
const EST_BYTES_PER_TRIANGLE: usize = 48;

/// Which structure to build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AccelKind {
    /// The 8-wide BVH collapsed from a binned-SAH binary BVH (the default).
    #[default]
    Bvh,
    /// Every triangle tested for every ray that enters the scene box (`--no-bvh`): leaves of
    /// eight under a tree whose boxes are all the scene box (`build::flat_tree`). The oracle
    /// for tests and the write-up's timing comparison.
    BruteForce,
}

/// Exact work counters, deterministic for a given traversal and ray order.
///
/// - `rays`: queries (a packet counts its active lanes).
/// - `node_tests`: ray-box tests, one per ray per box. Single-ray traversal (`intersect`,
///   `occluded`) counts, at every wide node it visits, one test per child box that the node holds
///   (2 to 8, `wide_node::ARITY`; the root of a one-leaf tree holds 1), whether or not the lanes of
///   unused slots are computed; the scene box is not tested separately. A packet counts, at every
///   node it visits, one test per child box per lane active at that node (lanes that entered its
///   box and whose best hit is not yet nearer), not W: inactive and finished lanes cost nothing in
///   the count. A closest-hit packet of 16 rays whose lanes share direction signs first tests the
///   node's boxes against the whole packet at once (`packet_interval`): that counts one test per
///   child box, and then only the boxes it passes count per lane. A closest-hit packet whose
///   first ray starts outside the scene box first tests all its lanes against that box at once
///   (`packet::CullBox`): one test per packet. A lane handed to single-ray
///   fallback counts as single-ray traversal from then on.
/// - `triangle_tests`: ray-triangle tests. One ray against a leaf of k triangles counts k (the
///   8-wide SIMD test of k < 8 triangles still counts k; an any-hit ray that stops at a
///   blocking group of 8 counts the groups tested). A packet leaf counts, per triangle, the
///   lanes active at that leaf (any-hit: the lanes not yet blocked).
/// - `sphere_tests`: ray-sphere tests (spheres are not in the triangles' BVH; the node tests
///   of their own tree, `spheres`, count as node tests).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TraceStats {
    /// Queries traced (a packet counts its active lanes).
    pub rays: u64,
    /// Ray-box tests, one per ray per child box.
    pub node_tests: u64,
    /// Ray-triangle tests.
    pub triangle_tests: u64,
    /// Ray-sphere tests.
    pub sphere_tests: u64,
}

impl TraceStats {
    /// Adds `o`'s counts to these, field by field (merging the counts of threads or tiles).
    pub fn add(&mut self, o: &TraceStats) {
        self.rays += o.rays;
        self.node_tests += o.node_tests;
        self.triangle_tests += o.triangle_tests;
        self.sphere_tests += o.sphere_tests;
    }
}

/// The acceleration structure over one scene: the 8-wide BVH over its triangles in SoA
/// blocks, and its spheres, tested after the triangles. Built once ([`Accel::new`],
/// [`Accel::try_build`]), then shared read-only by every thread that traces rays.
pub struct Accel {
    wide_nodes: Vec<WideNode>,
    tris: TriangleSoa,
    spheres: Spheres,
    bounds: Aabb,
    /// `bounds` prepared for rejecting closest-hit packets that miss the scene (`CullBox`).
    cull: Option<CullBox>,
    build_time: Duration,
    /// Whether the structure outgrows the caches (`traverse_single::STREAM_LARGE_BYTES`):
    /// then traversal keeps more rays in flight and prefetches leaves too.
    large: bool,
    /// Whether the structure fits one core's L2 cache (`l2_cache_bytes`): then single rays
    /// are traced one at a time, with no other ray in flight to hide node loads behind.
    in_l2: bool,
}

/// One core's L2 cache in bytes, as Linux reports it for CPU 0
/// (`/sys/devices/system/cpu/cpu0/cache/index*/`, the level-2 data or unified cache), or 1 MiB
/// where it reports none (a common size, and the smaller one keeps rays in flight).
pub fn l2_cache_bytes() -> usize {
    static L2: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *L2.get_or_init(|| l2_from_sysfs().unwrap_or(1 << 20))
}

/// The level-2 data or unified cache of CPU 0 from sysfs, if Linux lists one.
fn l2_from_sysfs() -> Option<usize> {
    let dir = std::path::Path::new("/sys/devices/system/cpu/cpu0/cache");
    (0..8).find_map(|i| {
        let index = dir.join(format!("index{i}"));
        let read = |name: &str| std::fs::read_to_string(index.join(name)).ok();
        let level = read("level")?;
        let kind = read("type")?;
        if level.trim() != "2" || kind.trim() == "Instruction" {
            return None;
        }
        parse_cache_size(read("size")?.trim())
    })
}

/// A sysfs cache size ("2048K", "1M", "512") in bytes; `None` if it does not parse or is 0.
fn parse_cache_size(s: &str) -> Option<usize> {
    let (digits, unit) = match s.char_indices().find(|(_, c)| !c.is_ascii_digit()) {
        Some((i, _)) => s.split_at(i),
        None => (s, ""),
    };
    let n: usize = digits.parse().ok()?;
    let scale = match unit {
        "" => 1,
        "K" => 1 << 10,
        "M" => 1 << 20,
        _ => return None,
    };
    n.checked_mul(scale).filter(|&b| b > 0)
}

impl Accel {
    /// Whether `scene` fits the structure: at most `MAX_TRIANGLES` triangles and as many
    /// spheres (their tree is built the same way). The error is one line, an [`Error::Scene`]
    /// without a path (`Error::in_scene` names the file).
    pub fn check_limits(scene: &Scene) -> Result<()> {
        let max = MAX_TRIANGLES;
        for (n, what) in [(scene.triangles.len(), "triangles"), (scene.spheres.len(), "spheres")] {
            if n > max {
                let message = format!("{n} {what}: at most {max} are supported");
                return Err(Error::Scene { path: None, message });
            }
        }
        Ok(())
    }

    /// [`build`](Accel::build) after [`check_limits`](Accel::check_limits): a scene too large
    /// is an error before any work.
    pub fn try_build(scene: &Scene, kind: AccelKind) -> Result<Accel> {
        Accel::check_limits(scene)?;
        Ok(Accel::build(scene, kind))
    }

    /// Panics if the scene is too large (`check_limits`; `try_build` returns the error).
    pub fn build(scene: &Scene, kind: AccelKind) -> Accel {
        Accel::build_with(scene, kind, BuildParams::default())
    }

    /// Panics if the scene is too large (`check_limits`).
    pub fn build_with(scene: &Scene, kind: AccelKind, params: BuildParams) -> Accel {
        if let Err(e) = Accel::check_limits(scene) {
            panic!("{e}");
        }
        let t0 = Instant::now();
        let (nodes, order, tri_bounds) = match kind {
            // Triangle boxes straight from the indexed mesh, in the builder's parallel pass
            // (in the caller's rayon pool); the corners are read again, in leaf order, for the
            // SoA store.
            AccelKind::Bvh => {
                let merge = WIDE_LEAF.min(params.max_leaf);
                let n = scene.triangles.len();
                let built = build::build_merged(
                    n,
                    |i| Aabb::from_points(&scene.triangle(i)),
                    params,
                    merge,
                );
                (built.nodes, built.order, built.bounds)
            }
            AccelKind::BruteForce => {
                let b = (0..scene.triangles.len())
                    .into_par_iter()
                    .map(|i| Aabb::from_points(&scene.triangle(i)))
                    .collect::<Vec<_>>()
                    .into_iter()
                    .fold(Aabb::EMPTY, |b, t| b.union(t));
                let (min, max) =
                    if b.is_empty() { ([0.0; 3], [0.0; 3]) } else { (b.min.into(), b.max.into()) };
                let n = scene.triangles.len() as u32;
                (build::flat_tree(n, MAX_LEAF as u32, min, max), (0..n).collect(), b)
            }
        };
        let nodes = if order.is_empty() { Vec::new() } else { nodes };
        // A structure that will outgrow the caches (`large`, estimated from the triangle
        // count) gets huge pages for its two big arrays before anything touches them: pages
        // faulted in after the advice are huge from the start, where collapsing touched pages
        // afterwards copies them (25 to 130 ms on the 1M tori in a fresh process).
        let huge = order.len() * EST_BYTES_PER_TRIANGLE > traverse_single::STREAM_LARGE_BYTES;
        let mut wide_nodes = Vec::new();
        if huge {
            wide_nodes.reserve_exact(build::wide_capacity(&nodes));
            hugepage::prefer(wide_nodes.spare_capacity_mut());
        }
        let mut wide_nodes = build::collapse_into(wide_nodes, &nodes, WIDE_LEAF);
        drop(nodes);
        wide_nodes.shrink_to_fit();
        let slots = build::pack_leaves(&mut wide_nodes, &order);
        let mut blocks = Vec::new();
        if huge {
            blocks.reserve_exact(slots.len().div_ceil(crate::geometry::triangles::LANES));
            hugepage::prefer(blocks.spare_capacity_mut());
        }
        let tris = TriangleSoa::from_slots_in(blocks, |i| scene.triangle(i), &slots);
        // `Scene::bounds` without its pass over every corner: the triangles' boxes are
        // already united, the spheres are added the same way.
        let bounds = scene.spheres.iter().fold(tri_bounds, |b, s| {
            b.grow(s.center - Vec3::splat(s.radius)).grow(s.center + Vec3::splat(s.radius))
        });
        let mut accel = Accel {
            wide_nodes,
            tris,
            spheres: Spheres::new(&scene.spheres, bounds.diagonal()),
            bounds,
            cull: CullBox::new(&bounds),
            build_time: Duration::ZERO,
            large: false,
            in_l2: false,
        };
        accel.large = accel.memory_bytes() > traverse_single::STREAM_LARGE_BYTES;
        // Huge pages only for a structure that outgrows the caches, where the TLB misses
        // they save were measured (PERF.md, "Large scenes"). Collapsing the pages of a few
        // megabytes copies them and took 1 to 14 ms per build on maxplanck (3.2 MB), more
        // than the rest of its build, for traversal within noise (PERF.md, "Build speed").
        // After the advice above this only collapses what was not huge already.
        if accel.large {
            hugepage::advise(&accel.wide_nodes);
            hugepage::advise(accel.tris.blocks());
        }
        accel.build_time = t0.elapsed();
        // After the clock: the first build of a process reads the cache size from the OS.
        accel.in_l2 = accel.memory_bytes() <= l2_cache_bytes();
        accel
    }

    /// The BVH over `scene`'s triangles (and its spheres, tested after them). Panics if the
    /// scene is too large (`check_limits`).
    pub fn new(scene: &Scene) -> Accel {
        Accel::build(scene, AccelKind::Bvh)
    }

    /// The closest hit along `ray` within [t_min, t_max]: [`intersect`](Accel::intersect)
    /// without counting the work.
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.intersect(ray, &mut TraceStats::default())
    }

    /// Whether anything blocks `ray` within [t_min, t_max]: [`occluded`](Accel::occluded)
    /// without counting the work.
    pub fn any_hit(&self, ray: &Ray) -> bool {
        self.occluded(ray, &mut TraceStats::default())
    }

    /// Closest hits of up to `W` rays traced as one packet (`hits[i]` answers `rays[i]`):
    /// [`intersect_packet`](Accel::intersect_packet) without counting the work.
    pub fn closest_hit_packet<const W: usize>(&self, rays: &[Ray], hits: &mut [Option<Hit>])
    where
        Lanes<W>: LaneWidth,
    {
        self.intersect_packet::<W>(rays, hits, &mut TraceStats::default());
    }

    /// Occlusion of up to `W` rays traced as one packet (`blocked[i]` answers `rays[i]`):
    /// [`occluded_packet`](Accel::occluded_packet) without counting the work.
    pub fn any_hit_packet<const W: usize>(&self, rays: &[Ray], blocked: &mut [bool])
    where
        Lanes<W>: LaneWidth,
    {
        self.occluded_packet::<W>(rays, blocked, &mut TraceStats::default());
    }

    /// Wall time the build took (boxes, binary tree, collapse, triangle store).
    pub fn build_time(&self) -> Duration {
        self.build_time
    }

    /// The scene's bounding box (triangles and spheres), as [`Scene::bounds`] gave it.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The triangles in SoA blocks, in leaf order.
    pub fn triangles(&self) -> &TriangleSoa {
        &self.tris
    }

    /// The wide tree.
    pub fn wide_nodes(&self) -> &[WideNode] {
        &self.wide_nodes
    }

    /// Whether the structure outgrows the caches (over `STREAM_LARGE_BYTES`).
    pub(crate) fn is_large(&self) -> bool {
        self.large
    }

    /// Bytes held by the structure: the wide nodes plus the triangle blocks.
    pub fn memory_bytes(&self) -> usize {
        self.wide_nodes.capacity() * std::mem::size_of::<WideNode>() + self.tris.memory_bytes()
    }

    /// The closest hit along the ray within [t_min, t_max].
    pub fn intersect(&self, ray: &Ray, stats: &mut TraceStats) -> Option<Hit> {
        stats.rays += 1;
        let mut r = *ray;
        let best = traverse_single::intersect(&self.wide_nodes, &self.tris, &mut r, stats);
        self.spheres.closest(r, best, stats)
    }

    /// Closest hits of any number of rays (`hits[i]` answers `rays[i]`), the same as
    /// `intersect` ray by ray, with a few rays interleaved on the thread
    /// (`traverse_single::intersect_stream`) unless the structure fits the L2 cache, where
    /// interleaving cost more than the node loads it hides (PERF.md, "Single rays in L2").
    pub fn intersect_stream(&self, rays: &[Ray], hits: &mut [Option<Hit>], stats: &mut TraceStats) {
        use traverse_single::{intersect_stream, STREAM_LARGE, STREAM_SMALL};
        stats.rays += rays.len() as u64;
        let (nodes, tris) = (&self.wide_nodes, &self.tris);
        if self.in_l2 {
            // One ray at a time: the plain walk, whose box-test terms stay in registers.
            for (r, h) in rays.iter().zip(hits.iter_mut()) {
                *h = traverse_single::intersect(nodes, tris, &mut { *r }, stats);
            }
        } else if !self.large {
            intersect_stream::<STREAM_SMALL, false>(nodes, tris, rays, hits, stats);
        } else {
            intersect_stream::<STREAM_LARGE, true>(nodes, tris, rays, hits, stats);
        }
        if !self.spheres.is_empty() {
            for (r, h) in rays.iter().zip(hits.iter_mut()) {
                let mut r = *r;
                if let Some(hit) = h {
                    r.t_max = hit.t;
                }
                *h = self.spheres.closest(r, *h, stats);
            }
        }
    }

    /// Whether anything blocks the ray within [t_min, t_max].
    pub fn occluded(&self, ray: &Ray, stats: &mut TraceStats) -> bool {
        stats.rays += 1;
        traverse_single::occluded(&self.wide_nodes, &self.tris, ray, stats)
            || self.spheres.blocks(ray, stats)
    }

    /// Occlusion of any number of rays (`blocked[i]` answers `rays[i]`), the same as
    /// `occluded` ray by ray. A structure over `STREAM_LARGE_BYTES` keeps several rays in
    /// flight (`traverse_single::occluded_stream`); a cache-resident one traces them one at a
    /// time, which measured faster there (PERF.md, "Rays in flight").
    pub fn occluded_stream(&self, rays: &[Ray], blocked: &mut [bool], stats: &mut TraceStats) {
        use traverse_single::{occluded_stream, STREAM_LARGE};
        if !self.large {
            for (b, r) in blocked.iter_mut().zip(rays) {
                *b = self.occluded(r, stats);
            }
            return;
        }
        stats.rays += rays.len() as u64;
        occluded_stream::<STREAM_LARGE>(&self.wide_nodes, &self.tris, rays, blocked, stats);
        for (r, b) in rays.iter().zip(blocked.iter_mut()) {
            *b = *b || self.spheres.blocks(r, stats);
        }
    }

    /// Closest hits of up to `W` rays traced as one packet: `hits[i]` answers `rays[i]`
    /// (`rays.len() <= W`, `hits.len() >= rays.len()`), bit-identical to `intersect`.
    pub fn intersect_packet<const W: usize>(
        &self,
        rays: &[Ray],
        hits: &mut [Option<Hit>],
        stats: &mut TraceStats,
    ) where
        Lanes<W>: LaneWidth,
    {
        let fallback = traverse_packet::default_fallback(W);
        self.intersect_rays::<W>(rays, fallback, &mut PacketStack::new(), hits, stats);
    }

    /// Closest hits of up to `W` rays traced as one packet, as `intersect_ray_packet`; a packet
    /// whose every lane's line misses the scene box (`CullBox`) is answered by that one test,
    /// before the packet's per-ray terms are computed. The test runs only when the first ray
    /// starts outside the box: a line through a point inside meets it, so bounce rays, and
    /// camera rays from inside the scene, skip a test that could not succeed.
    #[inline(always)]
    fn intersect_rays<const W: usize>(
        &self,
        rays: &[Ray],
        fallback: u32,
        stack: &mut PacketStack<VFloat<W>>,
        hits: &mut [Option<Hit>],
        stats: &mut TraceStats,
    ) where
        Lanes<W>: LaneWidth,
    {
        let lanes = RayLanes::<VFloat<W>>::gather(rays, !0);
        let outside = |b: &&CullBox| rays.first().is_some_and(|r| !b.holds(r.origin));
        if let Some(b) = self.cull.as_ref().filter(outside) {
            stats.node_tests += 1;
            let active = lanes.active_bits();
            if b.missed_by(lanes) == active {
                stats.rays += active.count_ones() as u64;
                let n = hits.len().min(W);
                fill_no_hits(&mut hits[..n]);
                return;
            }
        }
        let packet = RayPacket::from_lanes(lanes);
        self.intersect_ray_packet::<W>(packet, fallback, stack, hits, stats);
    }

    /// Closest hits of a prepared packet; `hits[i]` answers lane `i` (`None` for inactive
    /// lanes). `fallback`: interior subtrees entered by at most this many lanes finish ray by
    /// ray. The packet is taken by value (traversal shrinks its `t_max`), so no copy is made of it.
    pub fn intersect_ray_packet<const W: usize>(
        &self,
        mut packet: RayPacket<VFloat<W>>,
        fallback: u32,
        stack: &mut PacketStack<VFloat<W>>,
        hits: &mut [Option<Hit>],
        stats: &mut TraceStats,
    ) where
        Lanes<W>: LaneWidth,
    {
        let p = &mut packet;
        let active = p.active_bits();
        stats.rays += active.count_ones() as u64;
        let found = traverse_packet::intersect(
            &self.wide_nodes,
            &self.tris,
            p,
            fallback,
            self.large,
            stack,
            stats,
        );
        // Inactive lanes never hit: `found` has no hit bit for them.
        let n = hits.len().min(W);
        let hits = &mut hits[..n];
        found.write_to(hits);
        if self.spheres.is_empty() {
            return;
        }
        // The spheres after the triangles, in the order `intersect` tests them.
        self.spheres.closest_packet(p, active, hits, stats);
    }

    /// Occlusion of up to `W` rays traced as one packet: `blocked[i]` answers `rays[i]`,
    /// identical to `occluded`.
    pub fn occluded_packet<const W: usize>(
        &self,
        rays: &[Ray],
        blocked: &mut [bool],
        stats: &mut TraceStats,
    ) where
        Lanes<W>: LaneWidth,
    {
        let packet = RayPacket::<VFloat<W>>::from_rays(rays);
        let fallback = traverse_packet::default_fallback(W);
        self.occluded_ray_packet::<W>(&packet, fallback, &mut PacketStack::new(), blocked, stats);
    }

    /// Occlusion of a prepared packet; `blocked[i]` answers lane `i` (false when inactive).
    pub fn occluded_ray_packet<const W: usize>(
        &self,
        packet: &RayPacket<VFloat<W>>,
        fallback: u32,
        stack: &mut PacketStack<VFloat<W>>,
        blocked: &mut [bool],
        stats: &mut TraceStats,
    ) where
        Lanes<W>: LaneWidth,
    {
        let active = packet.active_bits();
        stats.rays += active.count_ones() as u64;
        let bits = traverse_packet::occluded(
            &self.wide_nodes,
            &self.tris,
            packet,
            fallback,
            self.large,
            stack,
            stats,
        );
        // Lanes a triangle blocks need no sphere test.
        let bits = if self.spheres.is_empty() {
            bits
        } else {
            bits | self.spheres.blocks_packet(packet, active & !bits, stats)
        };
        for (i, out) in blocked.iter_mut().enumerate().take(W) {
            *out = bits & (1 << i) != 0;
        }
    }

    /// Closest hits of any number of rays, `W` at a time in slice order (the last packet
    /// partly filled).
    pub fn intersect_packets<const W: usize>(
        &self,
        rays: &[Ray],
        hits: &mut [Option<Hit>],
        stats: &mut TraceStats,
    ) where
        Lanes<W>: LaneWidth,
    {
        self.intersect_packets_with::<W>(rays, traverse_packet::default_fallback(W), hits, stats);
    }

    /// `intersect_packets` with an explicit single-ray fallback threshold (for measuring it).
    pub(crate) fn intersect_packets_with<const W: usize>(
        &self,
        rays: &[Ray],
        fallback: u32,
        hits: &mut [Option<Hit>],
        stats: &mut TraceStats,
    ) where
        Lanes<W>: LaneWidth,
    {
        let mut stack = PacketStack::new();
        for (k, (r, h)) in rays.chunks(W).zip(hits.chunks_mut(W)).enumerate() {
            // The packet after next starts loading while this one is traced (measured:
            // PERF.md, "Measurements moved from doc comments").
            traverse_single::prefetch_slice(rays.get((k + 2) * W..(k + 3) * W).unwrap_or(&[]));
            self.intersect_rays::<W>(r, fallback, &mut stack, h, stats);
        }
    }

    /// Occlusion of any number of rays, `W` at a time in slice order.
    pub fn occluded_packets<const W: usize>(
        &self,
        rays: &[Ray],
        blocked: &mut [bool],
        stats: &mut TraceStats,
    ) where
        Lanes<W>: LaneWidth,
    {
        self.occluded_packets_with::<W>(rays, traverse_packet::default_fallback(W), blocked, stats);
    }

    /// `occluded_packets` with an explicit single-ray fallback threshold.
    pub(crate) fn occluded_packets_with<const W: usize>(
        &self,
        rays: &[Ray],
        fallback: u32,
        blocked: &mut [bool],
        stats: &mut TraceStats,
    ) where
        Lanes<W>: LaneWidth,
    {
        let mut stack = PacketStack::new();
        for (k, (r, b)) in rays.chunks(W).zip(blocked.chunks_mut(W)).enumerate() {
            traverse_single::prefetch_slice(rays.get((k + 2) * W..(k + 3) * W).unwrap_or(&[]));
            let packet = RayPacket::<VFloat<W>>::from_rays(r);
            self.occluded_ray_packet::<W>(&packet, fallback, &mut stack, b, stats);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::parse_cache_size;

    #[test]
    fn sysfs_cache_sizes_parse() {
        assert_eq!(parse_cache_size("2048K"), Some(2 << 20));
        assert_eq!(parse_cache_size("1M"), Some(1 << 20));
        assert_eq!(parse_cache_size("512"), Some(512));
        assert_eq!(parse_cache_size("0K"), None);
        assert_eq!(parse_cache_size("12G"), None);
        assert_eq!(parse_cache_size(""), None);
        assert_eq!(parse_cache_size("K"), None);
    }
}
