//! The scene's analytic spheres, tested after the triangles. The course scenes hold one or two,
//! and a list tested one by one costs nothing there; a scene with many would pay every sphere
//! on every ray, so above `LIST_MAX` the spheres get a binned-SAH tree of their own (the
//! triangle builder over their boxes) and a ray tests only the spheres whose boxes it enters.
//!
//! Both forms give the same answer: the nearest root (`intersect_sphere`) over all spheres,
//! and among spheres at exactly the same distance the one of highest index, which is what the
//! list finds by testing in index order with `t <= t_max`.

use super::build::{self, BuildParams, MAX_DEPTH};
use super::node::BvhNode;
use super::packet::RayPacket;
use super::TraceStats;
use crate::geometry::prim;
use crate::geometry::sphere::intersect_sphere;
use crate::geometry::watertight::V3;
use crate::math::{Aabb, Hit, Ray, Vec3};
use crate::scene::Sphere;
use crate::simd::SimdF32;

/// Most spheres tested as a plain list; more get a tree.
pub const LIST_MAX: usize = 8;

/// The spheres, and their tree when there are more than `LIST_MAX`.
#[derive(Default)]
pub(crate) struct Spheres {
    list: Vec<Sphere>,
    /// Depth-first binary nodes over `list` (empty for a short list); a leaf's range indexes
    /// `order`.
    nodes: Vec<BvhNode>,
    /// Sphere indices in leaf order.
    order: Vec<u32>,
}

impl Spheres {
    /// `scale`: the size of the scene (its bounding box's diagonal), which bounds how far rays
    /// travel and so the rounding error of where they meet a sphere.
    pub(crate) fn new(spheres: &[Sphere], scale: f32) -> Spheres {
        let list = spheres.to_vec();
        if list.len() <= LIST_MAX {
            return Spheres { list, ..Default::default() };
        }
        let boxes: Vec<Aabb> = list.iter().map(|s| padded_box(s, scale)).collect();
        let built = build::build(&boxes, BuildParams { max_leaf: 4, ..BuildParams::default() });
        Spheres { list, nodes: built.nodes, order: built.order }
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// The nearest sphere hit within `r`'s interval, if it beats `best` (whose distance is
    /// `r.t_max` when it is a hit); otherwise `best`.
    #[inline]
    pub(crate) fn closest(
        &self,
        mut r: Ray,
        mut best: Option<Hit>,
        stats: &mut TraceStats,
    ) -> Option<Hit> {
        let mut tests = 0;
        let mut test = |k: u32, r: &mut Ray, best: &mut Option<Hit>| {
            tests += 1;
            let Some(t) = intersect_sphere(r, &self.list[k as usize]) else {
                return;
            };
            // At equal distance the higher index wins (the list's order of replacement).
            let beats = t < r.t_max
                || best.is_none_or(|h| !prim::is_sphere(h.prim) || prim::sphere_index(h.prim) < k);
            if beats {
                r.t_max = t;
                *best = Some(Hit { t, u: 0.0, v: 0.0, prim: prim::sphere(k) });
            }
        };
        if self.nodes.is_empty() {
            for k in 0..self.list.len() as u32 {
                test(k, &mut r, &mut best);
            }
        } else {
            let start = r;
            self.walk(&start, stats, |k| {
                test(k, &mut r, &mut best);
                (r.t_max, false)
            });
        }
        stats.sphere_tests += tests;
        best
    }

    /// Whether a sphere blocks `r` within its interval.
    #[inline]
    pub(crate) fn blocks(&self, r: &Ray, stats: &mut TraceStats) -> bool {
        if self.nodes.is_empty() {
            return self.list.iter().any(|s| {
                stats.sphere_tests += 1;
                intersect_sphere(r, s).is_some()
            });
        }
        let mut blocked = false;
        let mut tests = 0;
        self.walk(r, stats, |k| {
            tests += 1;
            blocked = intersect_sphere(r, &self.list[k as usize]).is_some();
            (r.t_max, blocked)
        });
        stats.sphere_tests += tests;
        blocked
    }

    /// `closest` for the active lanes (`active`) of a packet after its triangles: `hits[i]`
    /// (lane `i`'s triangle hit, whose distance is the lane's `t_max`) improves to a sphere
    /// hit where there is a nearer one. A short list is tested in the packet's lanes, sphere
    /// by sphere, with the scalar test's operations (`intersect_sphere_lanes`), so every lane
    /// finds what `closest` finds.
    #[inline]
    pub(crate) fn closest_packet<V: SimdF32>(
        &self,
        p: &RayPacket<V>,
        active: u32,
        hits: &mut [Option<Hit>],
        stats: &mut TraceStats,
    ) {
        let lanes = || (0..hits.len()).filter(move |i| active & (1 << i) != 0);
        if !self.nodes.is_empty() {
            for i in lanes() {
                hits[i] = self.closest(p.ray(i), hits[i], stats);
            }
            return;
        }
        stats.sphere_tests += lanes().count() as u64 * self.list.len() as u64;
        let (mut t_max, on) = (p.t_max, V::from_bitmask(active));
        for (k, s) in self.list.iter().enumerate() {
            let (t, found) = intersect_sphere_lanes(&p.origin, &p.dir, p.t_min, t_max, s);
            // In index order, a later sphere at the same distance replaces an earlier hit.
            let found = found & on;
            t_max = V::select(found, t, t_max);
            let mut bits = found.bitmask();
            while bits != 0 {
                let i = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                if let Some(h) = hits.get_mut(i) {
                    *h = Some(Hit { t: t.lane(i), u: 0.0, v: 0.0, prim: prim::sphere(k as u32) });
                }
            }
        }
    }

    /// The lanes (a bit mask) among `active` whose ray a sphere blocks, as `blocks` per lane.
    #[inline]
    pub(crate) fn blocks_packet<V: SimdF32>(
        &self,
        p: &RayPacket<V>,
        active: u32,
        stats: &mut TraceStats,
    ) -> u32 {
        if !self.nodes.is_empty() {
            let lanes = (0..V::W).filter(|i| active & (1 << i) != 0);
            return lanes.filter(|&i| self.blocks(&p.ray(i), stats)).fold(0, |b, i| b | 1 << i);
        }
        let mut blocked = 0;
        for s in &self.list {
            // Counted as `blocks` counts: a lane stops at its first blocking sphere.
            let open = active & !blocked;
            if open == 0 {
                break;
            }
            stats.sphere_tests += open.count_ones() as u64;
            blocked |= intersect_sphere_lanes(&p.origin, &p.dir, p.t_min, p.t_max, s).1.bitmask();
        }
        blocked & active
    }

    /// Visits the leaves' spheres whose boxes the ray enters within [t_min, t_max], where
    /// `visit` returns the current t_max (a closest-hit search shrinks it) and whether to stop.
    #[inline(never)]
    fn walk(&self, r: &Ray, stats: &mut TraceStats, mut visit: impl FnMut(u32) -> (f32, bool)) {
        let inv = Vec3::new(1.0 / r.dir.x, 1.0 / r.dir.y, 1.0 / r.dir.z);
        let mut t_max = r.t_max;
        // The builder keeps a tree over at most `MAX_TRIANGLES` primitives (`check_limits`
        // holds spheres to that too) within `MAX_DEPTH` levels; the stack has room for twice
        // that, so no sphere count can overrun it.
        let mut stack = [0u32; 2 * MAX_DEPTH + 2];
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let i = stack[len];
            let node = &self.nodes[i as usize];
            stats.node_tests += 1;
            if !enters(node, r.origin, inv, r.t_min, t_max) {
                continue;
            }
            if node.is_leaf() {
                for &k in &self.order[node.index as usize..(node.index + node.count) as usize] {
                    let (t, stop) = visit(k);
                    if stop {
                        return;
                    }
                    t_max = t;
                }
            } else {
                // The second child waits; the first (the next node) goes next. A path down
                // the tree leaves at most one waiting sibling per level.
                stack[len] = node.index;
                stack[len + 1] = i + 1;
                len += 2;
            }
        }
    }
}

/// Whether the ray enters the node's box within [t_min, t_max]. A NaN slab (a zero direction
/// component on the box's plane) decides nothing, which keeps the test conservative.
#[inline]
fn enters(n: &BvhNode, o: Vec3, inv: Vec3, t_min: f32, t_max: f32) -> bool {
    let (mut lo, mut hi) = (t_min, t_max);
    for a in 0..3 {
        let t0 = (n.min[a] - o[a]) * inv[a];
        let t1 = (n.max[a] - o[a]) * inv[a];
        let (near, far) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
        if near > lo {
            lo = near;
        }
        if far < hi {
            hi = far;
        }
    }
    lo <= hi
}

/// `intersect_sphere` in lanes: each lane's root and the mask of lanes that have one, from the
/// same operations in the same order (no fused multiply-add), so every lane equals the scalar
/// test bit for bit.
#[inline(always)]
fn intersect_sphere_lanes<V: SimdF32>(
    o: &V3<V>,
    d: &V3<V>,
    t_min: V,
    t_max: V,
    s: &Sphere,
) -> (V, V) {
    let splat3 = |v: Vec3| V3 { x: V::splat(v.x), y: V::splat(v.y), z: V::splat(v.z) };
    let (zero, sign_bit) = (V::splat(0.0), V::splat(-0.0));
    let oc = o.minus(splat3(s.center));
    let a = d.dot(*d);
    let half_b = oc.dot(*d);
    let r2 = V::splat(s.radius * s.radius);
    let c = oc.dot(oc) - r2;
    let disc = a * r2 - {
        let x = oc.cross(*d);
        x.dot(x)
    };
    let valid = disc.simd_ge(zero) & a.simd_ne(zero);
    let sq = disc.sqrt();
    // `sq.copysign(half_b)` and the negation, by the sign bit.
    let signed = sq.abs() | (half_b & sign_bit);
    let q = V::splat(-1.0) * (half_b + signed);
    // The two roots in either order (q / a is the far one for a ray heading at the sphere).
    let (ra, rb) = (q / a, V::select(q.simd_ne(zero), c / q, q / a));
    let swap = rb.simd_lt(ra);
    let (t0, t1) = (V::select(swap, rb, ra), V::select(swap, ra, rb));
    let inside = |t: V| t.simd_ge(t_min) & t.simd_le(t_max);
    let (in0, in1) = (inside(t0), inside(t1));
    (V::select(in0, t0, t1), valid & (in0 | in1))
}

/// A sphere's box, widened so that rounding in the slab test and in `intersect_sphere` cannot
/// drop a hit: both err by a few ulps of the distance travelled, which stays within a few
/// scene diagonals for rays that start in the scene or at the course camera (1.5 diagonals
/// out); the pad is 10^-5 of the radius plus the scene's diagonal.
fn padded_box(s: &Sphere, scale: f32) -> Aabb {
    let r = s.radius.abs();
    let scale = if scale.is_finite() { scale.abs() } else { 0.0 };
    let pad = 1e-5 * (r + scale) + f32::MIN_POSITIVE;
    let e = Vec3::splat(r + pad);
    Aabb { min: s.center - e, max: s.center + e }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::Pcg32;

    fn random_spheres(n: usize, rng: &mut Pcg32) -> Vec<Sphere> {
        (0..n)
            .map(|i| Sphere {
                center: Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 20.0 - 10.0,
                radius: 0.05 + rng.next_f32() * if i % 7 == 0 { 3.0 } else { 0.5 },
                material: 0,
            })
            .collect()
    }

    /// The tree answers every closest-hit and any-hit query as the list does, on rays from
    /// inside and outside the spheres, with far fewer sphere tests.
    #[test]
    fn tree_answers_as_the_list() {
        let mut rng = Pcg32::new(5, 6);
        for n in [9, 100, 2000] {
            let spheres = random_spheres(n, &mut rng);
            let tree = Spheres::new(&spheres, 30.0);
            assert!(!tree.nodes.is_empty());
            let list = Spheres { list: spheres.clone(), ..Default::default() };
            let (mut st_tree, mut st_list) = (TraceStats::default(), TraceStats::default());
            let mut hits = 0;
            for i in 0..4000 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 30.0 - 15.0;
                let jitter = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
                // Half the rays aim near a sphere (grazing ones included), the rest anywhere.
                let aim = &spheres[i % n];
                let mut d =
                    if i % 2 == 0 { aim.center + 2.4 * aim.radius * jitter - o } else { jitter };
                if i % 5 == 0 {
                    d.x = 0.0; // axis-parallel rays: zero direction components
                }
                let mut r = Ray::new(o, d.normalize_or(Vec3::X));
                if i % 3 == 0 {
                    r.t_max = 8.0;
                }
                let a = tree.closest(r, None, &mut st_tree);
                let b = list.closest(r, None, &mut st_list);
                assert_eq!(a.map(|h| (h.t.to_bits(), h.prim)), b.map(|h| (h.t.to_bits(), h.prim)));
                assert_eq!(tree.blocks(&r, &mut st_tree), list.blocks(&r, &mut st_list));
                hits += a.is_some() as u32;
            }
            assert!(hits > 500, "{n} spheres: only {hits} hits");
            if n >= 100 {
                assert!(
                    st_tree.sphere_tests * 5 < st_list.sphere_tests,
                    "{n} spheres: tree {} against list {} sphere tests",
                    st_tree.sphere_tests,
                    st_list.sphere_tests
                );
            }
        }
    }

    /// Packets of 4, 8 and 16 rays find, lane by lane, the bits and the counts the scalar
    /// tests find: closest hits and occlusion, with a short list and with a tree.
    #[test]
    fn packet_lanes_answer_as_single_rays() {
        use crate::simd::VFloat;
        fn check<const W: usize>(set: &Spheres, rays: &[Ray], hit_count: &mut usize)
        where
            crate::simd::Lanes<W>: crate::simd::LaneWidth,
        {
            for chunk in rays.chunks(W) {
                let p = RayPacket::<VFloat<W>>::from_rays(chunk);
                let active = ((1u32 << chunk.len()) - 1) & !0b10; // lane 1 inactive
                let (mut st_p, mut st_s) = (TraceStats::default(), TraceStats::default());
                let mut got = vec![None; chunk.len()];
                set.closest_packet(&p, active, &mut got, &mut st_p);
                let blocked = set.blocks_packet(&p, active, &mut st_p);
                for (i, r) in chunk.iter().enumerate() {
                    let on = active & (1 << i) != 0;
                    let want = if on { set.closest(*r, None, &mut st_s) } else { None };
                    let key = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.prim));
                    assert_eq!(key(got[i]), key(want), "lane {i} of {W}: {r:?}");
                    let b = on && set.blocks(r, &mut st_s);
                    assert_eq!(blocked & (1 << i) != 0, b, "lane {i} of {W}: {r:?}");
                }
                assert_eq!(st_p.sphere_tests, st_s.sphere_tests);
                *hit_count += got.iter().flatten().count();
            }
        }
        let mut rng = Pcg32::new(7, 8);
        for n in [2, 8, 40] {
            let spheres = random_spheres(n, &mut rng);
            let set = Spheres::new(&spheres, 30.0);
            let rays: Vec<Ray> = (0..3000)
                .map(|i| {
                    let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 30.0 - 15.0;
                    let aim = &spheres[i % n];
                    let j = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
                    // Directions of any length: the test divides by |d|^2.
                    let len = 0.3 + 3.0 * rng.next_f32();
                    let d = (aim.center + 2.2 * aim.radius * j - o).normalize() * len;
                    let mut r = Ray::new(o, d);
                    r.t_max = if i % 3 == 0 { 12.0 } else { f32::INFINITY };
                    r
                })
                .collect();
            let mut hits = 0;
            check::<4>(&set, &rays, &mut hits);
            check::<8>(&set, &rays, &mut hits);
            check::<16>(&set, &rays, &mut hits);
            assert!(hits > 3000, "{n} spheres: {hits} hits in 3 x 3000 rays");
        }
    }

    /// Spheres at exactly the same place: the highest index wins, in both forms.
    #[test]
    fn equal_distances_go_to_the_highest_index() {
        let s = Sphere { center: Vec3::new(0.0, 0.0, 5.0), radius: 1.0, material: 0 };
        let spheres = vec![s; 20];
        let r = Ray::new(Vec3::ZERO, Vec3::Z);
        let mut st = TraceStats::default();
        let tree = Spheres::new(&spheres, 30.0);
        let list = Spheres { list: spheres, ..Default::default() };
        assert_eq!(tree.closest(r, None, &mut st).unwrap().prim, prim::sphere(19));
        assert_eq!(list.closest(r, None, &mut st).unwrap().prim, prim::sphere(19));
    }
}
