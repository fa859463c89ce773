//! W rays at once through the flat BVH: closest hit and any hit.
//!
//! Every node is tested against all active lanes at once (one SIMD slab test per child);
//! children are visited front to back (the child nearer for more lanes first) with one stack
//! shared by the packet, each entry remembering which lanes entered the subtree and at what
//! distance. Leaves test one triangle against all W rays with the same Möller-Trumbore core as
//! the single-ray path, so t, u, v are bit-identical. When no more than `fallback` lanes enter
//! a subtree, those lanes finish it with single-ray traversal (`traverse_single::*_subtree`):
//! a mostly-empty packet pays W lanes of work per node for a few rays' worth of benefit.
//!
//! Hits are the nearest (t, then smallest prim), which does not depend on the visiting
//! order, and box tests are conservative (`BOX_INFLATE`), so packet and single-ray traversal
//! return the same hit for every ray.

use super::build::MAX_DEPTH;
use super::node::BvhNode;
use super::packet::{PacketHits, RayPacket, BOX_INFLATE};
use super::traverse_single;
use super::TraceStats;
use crate::geometry::moller_trumbore::{intersect_simd, V3};
use crate::geometry::triangles::TriangleSoa;
use crate::simd::SimdF32;

/// Default single-ray fallback thresholds: a subtree entered by at most this many lanes is
/// finished one ray at a time. Measured (PERF.md, "Traversal kernels"): with our scalar-box
/// single-ray traversal every threshold above 0 was slower at both widths (a packet lane
/// walks a node as cheaply as a lone ray does), so the fallback is off by default; it stays
/// for a wider single-ray BVH, which would change that balance.
pub const FALLBACK_4: u32 = 0;
pub const FALLBACK_8: u32 = 0;

/// The default fallback threshold for width `W`.
pub fn default_fallback(w: usize) -> u32 {
    if w <= 4 {
        FALLBACK_4
    } else {
        FALLBACK_8
    }
}

/// Entry distances of all lanes into the box, and the mask of lanes that enter it within
/// [t_min, t_max]. Lane by lane the same operations as `traverse_single::RayBox::slab`.
#[inline(always)]
fn slab<V: SimdF32>(p: &RayPacket<V>, n: &BvhNode, t_max: V) -> (V, V) {
    let (o, inv) = (&p.origin, &p.inv_dir);
    let x0 = (V::splat(n.min[0]) - o.x) * inv.x;
    let x1 = (V::splat(n.max[0]) - o.x) * inv.x;
    let y0 = (V::splat(n.min[1]) - o.y) * inv.y;
    let y1 = (V::splat(n.max[1]) - o.y) * inv.y;
    let z0 = (V::splat(n.min[2]) - o.z) * inv.z;
    let z1 = (V::splat(n.max[2]) - o.z) * inv.z;
    let near =
        x0.fast_min(x1).fast_max(y0.fast_min(y1)).fast_max(z0.fast_min(z1)).fast_max(p.t_min);
    let far = x0.fast_max(x1).fast_min(y0.fast_max(y1)).fast_min(z0.fast_max(z1)).fast_min(t_max)
        * V::splat(BOX_INFLATE);
    (near.simd_le(far), near)
}

#[inline(always)]
fn splat_tri<V: SimdF32>(cols: &[Vec<f32>; 3], i: usize) -> V3<V> {
    V3 { x: V::splat(cols[0][i]), y: V::splat(cols[1][i]), z: V::splat(cols[2][i]) }
}

/// One stack entry: a subtree, the lanes that entered its box and their entry distances.
#[derive(Clone, Copy)]
struct Entry<V> {
    node: u32,
    lanes: u32,
    near: V,
}

/// Traversal stacks, reused from packet to packet: a fixed array of `MAX_DEPTH` entries would
/// be zeroed for every packet (4 KiB at W = 8), which cost about a tenth of a primary ray.
pub struct PacketStack<V> {
    closest: Vec<Entry<V>>,
    any: Vec<(u32, u32)>,
}

impl<V> PacketStack<V> {
    pub fn new() -> PacketStack<V> {
        PacketStack { closest: Vec::with_capacity(MAX_DEPTH), any: Vec::with_capacity(MAX_DEPTH) }
    }
}

impl<V> Default for PacketStack<V> {
    fn default() -> Self {
        Self::new()
    }
}

/// Closest hits of the packet's active lanes; `p.t_max` shrinks lane by lane as hits are found.
pub fn intersect<V: SimdF32>(
    nodes: &[BvhNode],
    tris: &TriangleSoa,
    p: &mut RayPacket<V>,
    fallback: u32,
    stack: &mut PacketStack<V>,
    stats: &mut TraceStats,
) -> PacketHits<V> {
    let mut hits = PacketHits::none();
    let active = p.active_bits();
    stats.node_tests += active.count_ones() as u64;
    if nodes.is_empty() || active == 0 {
        return hits;
    }
    let (m, near) = slab(p, &nodes[0], p.t_max);
    let lanes = m.bitmask() & active;
    let stack = &mut stack.closest;
    stack.clear();
    let mut cur = Entry { node: 0, lanes, near };
    loop {
        // Lanes whose best hit is already nearer than the subtree drop out of it.
        let lanes = cur.lanes & cur.near.simd_le(p.t_max * V::splat(BOX_INFLATE)).bitmask();
        if lanes != 0 {
            let node = cur.node as usize;
            if lanes.count_ones() <= fallback {
                finish_single(nodes, tris, node, lanes, p, &mut hits, stats);
            } else {
                let n = &nodes[node];
                if n.is_leaf() {
                    intersect_leaf(tris, n, lanes, p, &mut hits, stats);
                } else {
                    let (a, b) = (node + 1, n.index as usize);
                    let (ma, ta) = slab(p, &nodes[a], p.t_max);
                    let (mb, tb) = slab(p, &nodes[b], p.t_max);
                    stats.node_tests += 2 * lanes.count_ones() as u64;
                    let (la, lb) = (ma.bitmask() & lanes, mb.bitmask() & lanes);
                    if la != 0 && lb != 0 {
                        // Front to back for the majority of the lanes that enter both.
                        let both = la & lb;
                        let a_first = ta.simd_le(tb).bitmask() & both;
                        let (first, second) = if 2 * a_first.count_ones() >= both.count_ones() {
                            (
                                Entry { node: a as u32, lanes: la, near: ta },
                                Entry { node: b as u32, lanes: lb, near: tb },
                            )
                        } else {
                            (
                                Entry { node: b as u32, lanes: lb, near: tb },
                                Entry { node: a as u32, lanes: la, near: ta },
                            )
                        };
                        stack.push(second);
                        cur = first;
                        continue;
                    } else if la != 0 {
                        cur = Entry { node: a as u32, lanes: la, near: ta };
                        continue;
                    } else if lb != 0 {
                        cur = Entry { node: b as u32, lanes: lb, near: tb };
                        continue;
                    }
                }
            }
        }
        match stack.pop() {
            Some(e) => cur = e,
            None => return hits,
        }
    }
}

/// Lanes `lanes` finish the subtree at `node` one ray at a time.
#[inline(never)]
fn finish_single<V: SimdF32>(
    nodes: &[BvhNode],
    tris: &TriangleSoa,
    node: usize,
    lanes: u32,
    p: &mut RayPacket<V>,
    hits: &mut PacketHits<V>,
    stats: &mut TraceStats,
) {
    let mut bits = lanes;
    let mut t_max = [0.0f32; super::packet::MAX_W];
    p.t_max.store(&mut t_max);
    let mut u = t_max;
    let mut v = t_max;
    hits.u.store(&mut u);
    hits.v.store(&mut v);
    while bits != 0 {
        let i = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let mut ray = p.ray(i);
        let mut best = hits.get(i);
        traverse_single::intersect_subtree(nodes, tris, node, &mut ray, &mut best, stats);
        if let Some(h) = best {
            t_max[i] = h.t;
            u[i] = h.u;
            v[i] = h.v;
            hits.prim[i] = h.prim;
            hits.hit_bits |= 1 << i;
        }
    }
    p.t_max = V::load(&t_max);
    hits.t = p.t_max;
    hits.u = V::load(&u);
    hits.v = V::load(&v);
}

/// Every triangle of the leaf against the lanes `lanes`.
#[inline(always)]
fn intersect_leaf<V: SimdF32>(
    tris: &TriangleSoa,
    n: &BvhNode,
    lanes: u32,
    p: &mut RayPacket<V>,
    hits: &mut PacketHits<V>,
    stats: &mut TraceStats,
) {
    let (first, count) = (n.index as usize, n.count as usize);
    stats.triangle_tests += (count as u64) * lanes.count_ones() as u64;
    let valid = V::from_bitmask(lanes);
    for i in first..first + count {
        let (mask, t, u, v) = intersect_simd(
            p.origin,
            p.dir,
            splat_tri(&tris.v0, i),
            splat_tri(&tris.e1, i),
            splat_tri(&tris.e2, i),
            p.t_min,
            p.t_max,
            valid,
        );
        let take = mask.bitmask();
        if take == 0 {
            continue;
        }
        let prim = tris.prim[i];
        // Equal distance: the smaller prim wins (as in the single-ray leaf test). Rare, so
        // handled lane by lane off the fast path.
        let ties = take & t.simd_eq(p.t_max).bitmask() & hits.hit_bits;
        let (take, m) = if ties == 0 { (take, mask) } else { drop_ties(take, ties, prim, hits) };
        p.t_max = V::select(m, t, p.t_max);
        hits.u = V::select(m, u, hits.u);
        hits.v = V::select(m, v, hits.v);
        hits.hit_bits |= take;
        let mut bits = take;
        while bits != 0 {
            let k = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            hits.prim[k] = prim;
        }
    }
    hits.t = p.t_max;
}

/// Removes from `take` the tied lanes whose current hit has a smaller prim.
#[cold]
fn drop_ties<V: SimdF32>(mut take: u32, ties: u32, prim: u32, hits: &PacketHits<V>) -> (u32, V) {
    let mut bits = ties;
    while bits != 0 {
        let k = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        if prim > hits.prim[k] {
            take &= !(1 << k);
        }
    }
    (take, V::from_bitmask(take))
}

/// Which active lanes are blocked within [t_min, t_max] (bit `i` for lane `i`); stops as soon
/// as every active lane is.
pub fn occluded<V: SimdF32>(
    nodes: &[BvhNode],
    tris: &TriangleSoa,
    p: &RayPacket<V>,
    fallback: u32,
    stack: &mut PacketStack<V>,
    stats: &mut TraceStats,
) -> u32 {
    let active = p.active_bits();
    stats.node_tests += active.count_ones() as u64;
    if nodes.is_empty() || active == 0 {
        return 0;
    }
    let mut blocked = 0u32;
    let (m, _) = slab(p, &nodes[0], p.t_max);
    let stack = &mut stack.any;
    stack.clear();
    let mut cur = (0u32, m.bitmask() & active);
    loop {
        let lanes = cur.1 & !blocked;
        if lanes != 0 {
            let node = cur.0 as usize;
            if lanes.count_ones() <= fallback {
                let mut bits = lanes;
                while bits != 0 {
                    let i = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    if traverse_single::occluded_subtree(nodes, tris, node, &p.ray(i), stats) {
                        blocked |= 1 << i;
                    }
                }
            } else {
                let n = &nodes[node];
                if n.is_leaf() {
                    blocked |= occluded_leaf(tris, n, lanes, p, stats);
                } else {
                    let (a, b) = (node + 1, n.index as usize);
                    let (ma, _) = slab(p, &nodes[a], p.t_max);
                    let (mb, _) = slab(p, &nodes[b], p.t_max);
                    stats.node_tests += 2 * lanes.count_ones() as u64;
                    let (la, lb) = (ma.bitmask() & lanes, mb.bitmask() & lanes);
                    if la != 0 && lb != 0 {
                        stack.push((b as u32, lb));
                    }
                    if la != 0 {
                        cur = (a as u32, la);
                        continue;
                    } else if lb != 0 {
                        cur = (b as u32, lb);
                        continue;
                    }
                }
            }
            if blocked == active {
                return blocked;
            }
        }
        match stack.pop() {
            Some(e) => cur = e,
            None => return blocked,
        }
    }
}

/// The lanes of `lanes` that a triangle of the leaf blocks; a lane stops testing once blocked.
#[inline(always)]
fn occluded_leaf<V: SimdF32>(
    tris: &TriangleSoa,
    n: &BvhNode,
    lanes: u32,
    p: &RayPacket<V>,
    stats: &mut TraceStats,
) -> u32 {
    let mut open = lanes;
    for i in n.index as usize..(n.index + n.count) as usize {
        stats.triangle_tests += open.count_ones() as u64;
        let (mask, ..) = intersect_simd(
            p.origin,
            p.dir,
            splat_tri(&tris.v0, i),
            splat_tri(&tris.e1, i),
            splat_tri(&tris.e2, i),
            p.t_min,
            p.t_max,
            V::from_bitmask(open),
        );
        open &= !mask.bitmask();
        if open == 0 {
            break;
        }
    }
    lanes & !open
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::traverse_single::RayBox;
    use crate::math::{Ray, Vec3};
    use crate::sampler::Pcg32;
    use wide::{f32x4, f32x8};

    /// The packet slab test, lane by lane, equals the single-ray one (entry distance and
    /// hit/miss), including zero direction components and origins on box faces.
    fn slab_lanes<V: SimdF32>() {
        let mut rng = Pcg32::new(3, 3);
        let mut r = || rng.next_f32() * 2.0 - 1.0;
        let mut hit = 0;
        for case in 0..4000 {
            let (a, b) = (Vec3::new(r(), r(), r()), Vec3::new(r(), r(), r()));
            let n = BvhNode { min: a.min(b).into(), index: 0, max: a.max(b).into(), count: 0 };
            let rays: Vec<Ray> = (0..V::W)
                .map(|k| {
                    let mut o = Vec3::new(r(), r(), r()) * 2.0;
                    // Aim at a point of the box (most lanes hit, grazing ones too).
                    let f = Vec3::new(r(), r(), r()) * 0.5 + 0.5;
                    let mut d = a.min(b) + f * (a - b).abs() - o;
                    match (case + k) % 4 {
                        0 => d.x = 0.0,
                        1 => {
                            d.z = -0.0;
                            o.z = n.min[2];
                        }
                        _ => {}
                    }
                    Ray::segment(o, d, 0.1 * r().abs(), 1.0 + 3.0 * r().abs())
                })
                .collect();
            let p = RayPacket::<V>::from_rays(&rays);
            let (mask, near) = slab(&p, &n, p.t_max);
            for (k, ray) in rays.iter().enumerate() {
                let s = RayBox::new(ray).slab(&n, ray.t_max);
                let lane_hit = mask.bitmask() & (1 << k) != 0;
                assert_eq!(s != f32::INFINITY, lane_hit, "case {case} lane {k}");
                if lane_hit {
                    hit += 1;
                    assert_eq!(s.to_bits(), near.lane(k).to_bits());
                }
            }
        }
        assert!(hit > 1000, "{hit}");
    }

    #[test]
    fn packet_slab_lanes_equal_the_single_ray_test() {
        slab_lanes::<f32x4>();
        slab_lanes::<f32x8>();
    }
}
