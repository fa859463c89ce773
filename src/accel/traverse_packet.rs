//! W rays at once through the wide BVH (`wide_node`): closest hit and any hit.
//!
//! Every child box of a node is tested against all active lanes at once (one SIMD slab test
//! per child; in closest-hit packets of 16 rays only the boxes that a conservative test of
//! the whole packet against all children at once passes, `packet_interval`); entered
//! children are visited nearest first (by the entry distance of the first lane that entered,
//! `child_order`) with one stack shared by the packet, each entry remembering which lanes
//! entered the subtree and at what distance. Leaves test one triangle against all W rays with the
//! same watertight test as the single-ray path, so t, u, v are bit-identical, or test the
//! lanes one by one against the whole leaf where that is fewer tests (`leaf_by_lane`). When no
//! more than `fallback` lanes enter an interior subtree, those lanes finish it with single-ray
//! traversal (`traverse_single::*_subtree`): a mostly-empty packet pays W lanes of work per
//! box for a few rays' worth of benefit. A leaf goes to the leaf tests whatever its lanes:
//! handed over, it paid the single ray's box-test terms for no box (PERF.md, "Rooms split into
//! walls").
//!
//! Hits are the nearest (t, then smallest prim) among a set that does not depend on the
//! visiting order (`leaf`: hits in front of the leaf box), and each lane's box test computes what the
//! single-ray test computes, so packet and single-ray traversal return the same hit for every
//! ray.

use super::build::MAX_DEPTH;
use super::child_order;
use super::leaf::{self, LeafRay};
use super::packet::{PacketHits, RayPacket, TriangleFrame, BOX_INFLATE};
use super::packet_interval::PacketInterval;
use super::traverse_single::{self, Entry as SingleEntry, WideRay};
use super::wide_node::{leaf_range, WideNode, ARITY, LEAF_BIT};
use super::TraceStats;
use crate::geometry::triangles::{TriangleSoa, LANES};
use crate::geometry::watertight::{edge_test, intersect_simd, V3};
use crate::math::{Hit, Ray};
use crate::simd::SimdF32;

/// Narrowest packet that takes the interval pre-test (`packet_interval`) in closest-hit
/// traversal; occlusion never takes it.
/// Measured: PERF.md, "Measurements moved from doc comments".
pub const INTERVAL_MIN_W: usize = 16;

/// Default single-ray fallback thresholds: an interior subtree entered by at most this many
/// lanes is finished one ray at a time. Measured (PERF.md, "Packets on the wide tree"):
/// handing over lone lanes saves up to 7 % of the instructions on incoherent rays and costs at
/// most 0.2 % on coherent ones; handing over two or three lanes was worse.
/// The threshold for packets of 4 rays or fewer.
pub const FALLBACK_4: u32 = 1;
/// The threshold for packets of 8 and 16 rays.
pub const FALLBACK_8: u32 = 1;

/// The default fallback threshold for width `W`.
pub fn default_fallback(w: usize) -> u32 {
    if w <= 4 {
        FALLBACK_4
    } else {
        FALLBACK_8
    }
}

/// The box of child slot `i` of a node, as a scalar min/max per axis.
#[inline(always)]
fn child_box(n: &WideNode, i: usize) -> ([f32; 3], [f32; 3]) {
    let b = &n.bounds;
    ([b[0][i], b[2][i], b[4][i]], [b[1][i], b[3][i], b[5][i]])
}

/// Entry distances of all lanes into the box, and the mask of lanes that enter it within
/// [t_min, t_max]. Lane by lane the same values as `traverse_single`'s slab test (which picks
/// the near plane by the direction's sign where this takes the min of the two planes: equal
/// for the finite reciprocals `safe_recip` gives).
#[inline(always)]
fn slab<V: SimdF32>(p: &RayPacket<V>, min: [f32; 3], max: [f32; 3], t_max: V) -> (V, V) {
    let (c, inv) = (&p.neg_o_inv, &p.inv_dir);
    let x0 = V::splat(min[0]).mul_add(inv.x, c.x);
    let x1 = V::splat(max[0]).mul_add(inv.x, c.x);
    let y0 = V::splat(min[1]).mul_add(inv.y, c.y);
    let y1 = V::splat(max[1]).mul_add(inv.y, c.y);
    let z0 = V::splat(min[2]).mul_add(inv.z, c.z);
    let z1 = V::splat(max[2]).mul_add(inv.z, c.z);
    let near = x0.fast_min(x1).fast_max(y0.fast_min(y1)).fast_max(z0.fast_min(z1));
    let near = near.fast_max(p.t_min) - p.slack;
    let far = x0.fast_max(x1).fast_min(y0.fast_max(y1)).fast_min(z0.fast_max(z1)).fast_min(t_max);
    let far = far.mul_add(V::splat(BOX_INFLATE), p.slack);
    (near.simd_le(far), near)
}

/// The vertices of slot `i`, broadcast to every lane in each lane's axis order: read in that
/// order when the lanes share it, else permuted lane by lane.
#[inline(always)]
fn splat_tri<V: SimdF32>(tris: &TriangleSoa, i: usize, f: &TriangleFrame<V>) -> [V3<V>; 3] {
    // Each coordinate broadcast straight from the block: gathered into a vector first, the nine
    // floats went through masked loads, permutes and a stack copy before their broadcasts.
    let (b, l) = tris.slot(i);
    let k = f.axes.uniform.unwrap_or([0, 1, 2]);
    let get = |row: &[[f32; LANES]; 3]| V3 {
        x: V::splat(row[k[0]][l]),
        y: V::splat(row[k[1]][l]),
        z: V::splat(row[k[2]][l]),
    };
    let v = [get(&b.v0), get(&b.v1), get(&b.v2)];
    match f.axes.uniform {
        Some(_) => v,
        None => v.map(|v| f.axes.permute(v)),
    }
}

/// One stack entry: a subtree (a child reference, as in `WideNode`), the lanes that entered
/// its box and their entry distances.
#[derive(Clone, Copy)]
struct Entry<V> {
    child: u32,
    lanes: u32,
    near: V,
}

/// Traversal stacks, reused from packet to packet: a fixed array of entries would be zeroed
/// for every packet (kilobytes at W = 8), which cost about a tenth of a primary ray.
pub struct PacketStack<V> {
    closest: Vec<Entry<V>>,
    any: Vec<(u32, u32)>,
    /// The children a node test entered (`Entered`), for closest-hit and any-hit packets alike:
    /// made once here, as a fresh one per packet was a `memset` of about 600 bytes per packet.
    entered: Entered<V>,
}

impl<V: SimdF32> PacketStack<V> {
    /// Empty stacks with room for the deepest traversal (`(ARITY - 1) * MAX_DEPTH` entries).
    pub fn new() -> PacketStack<V> {
        PacketStack {
            closest: Vec::with_capacity((ARITY - 1) * MAX_DEPTH),
            any: Vec::with_capacity((ARITY - 1) * MAX_DEPTH),
            entered: Entered::new(),
        }
    }
}

impl<V: SimdF32> Default for PacketStack<V> {
    fn default() -> Self {
        Self::new()
    }
}

/// The visiting order's key for a child the lanes `lanes` (not 0) entered: the entry
/// distance of the first of them. (The smallest over the lanes ordered no better on the
/// coherent packets this serves, at four times the instructions.)
#[inline(always)]
fn order_key<V: SimdF32>(near: &V, lanes: u32) -> f32 {
    near.lane(lanes.trailing_zeros() as usize % V::W)
}

/// The children of a node that some lanes enter: per slot the lanes and their entry
/// distances, and the entered slots farthest first (by `order_key`).
struct Entered<V> {
    near: [V; ARITY],
    lanes: [u32; ARITY],
    key: [f32; ARITY],
    /// Slots, farthest first; the first `k` are entered.
    order: [u8; ARITY],
    k: usize,
}

impl<V: SimdF32> Entered<V> {
    /// Scratch made once per `PacketStack` and reused at every node of every packet: only the
    /// slots entered at the current node are read, and `entered_children` writes them first
    /// (a fresh one per node cost a zeroing and a 400-byte copy per node; one per packet, a
    /// `memset` per packet).
    fn new() -> Entered<V> {
        Entered {
            near: [V::splat(0.0); ARITY],
            lanes: [0; ARITY],
            key: [0.0; ARITY],
            order: [0; ARITY],
            k: 0,
        }
    }

    /// The exact per-lane test of child slot `i` of `n`: which of `lanes` enter it, and where.
    /// Returns bit `i` if some lane does (the caller gathers them in a register: or-ing into
    /// `hit` here stored and reloaded it at every child).
    #[inline(always)]
    fn test_child(&mut self, p: &RayPacket<V>, n: &WideNode, i: usize, lanes: u32) -> u32 {
        let (min, max) = child_box(n, i);
        let (m, near) = slab(p, min, max, p.t_max);
        let entered = m.bitmask() & lanes;
        (self.near[i], self.lanes[i]) = (near, entered);
        ((entered != 0) as u32) << i
    }

    /// The `j`-th entered child of `n` in farthest-first order.
    #[inline(always)]
    fn entry(&self, n: &WideNode, j: usize) -> Entry<V> {
        let i = self.order[j] as usize;
        Entry { child: n.child[i], lanes: self.lanes[i], near: self.near[i] }
    }
}

/// The children of node `n` that some of `lanes` enter. Only the children the packet's
/// interval pre-test passes (`packet_interval`; all used slots without one) get the exact
/// per-lane test, all of them before any branch on the outcome; then only the entered ones
/// are ordered (`child_order`): a branch per child on whether any lane entered it was the
/// hottest spot of packet traversal (`perf` on maxplanck primary rays; PERF.md, "8-wide
/// nodes").
#[inline(always)]
fn entered_children<V: SimdF32>(
    p: &RayPacket<V>,
    n: &WideNode,
    lanes: u32,
    interval: Option<&PacketInterval>,
    ranked: bool,
    e: &mut Entered<V>,
    stats: &mut TraceStats,
) {
    let used = n.children();
    let mut hit = 0;
    match interval {
        Some(iv) => {
            let mut candidates = iv.may_enter(n) & ((1u32 << used) - 1);
            stats.node_tests +=
                used as u64 + candidates.count_ones() as u64 * lanes.count_ones() as u64;
            while candidates != 0 {
                hit |= e.test_child(p, n, candidates.trailing_zeros() as usize, lanes);
                candidates &= candidates - 1;
            }
        }
        None => {
            // A counted loop over the used slots: the loop over candidate bits above, with
            // every used slot a candidate, measured 0.92-0.93x on shadow packets.
            stats.node_tests += used as u64 * lanes.count_ones() as u64;
            for i in 0..used {
                hit |= e.test_child(p, n, i, lanes);
            }
        }
    }
    let key_of = |i: usize| order_key(&e.near[i], e.lanes[i]);
    e.k = if ranked {
        let mut bits = hit;
        while bits != 0 {
            let i = bits.trailing_zeros() as usize % ARITY; // below ARITY: no bounds check
            bits &= bits - 1;
            e.key[i] = key_of(i);
        }
        child_order::by_rank(&e.key, hit, &mut e.order)
    } else {
        child_order::by_insertion(&mut e.key, key_of, hit, &mut e.order)
    };
}

/// Starts loading a pushed child: an interior node always, a leaf's triangle block if
/// `leaves`: `Accel` asks for leaves only above `traverse_single::STREAM_LARGE_BYTES`.
/// Measured: PERF.md, "Measurements moved from doc comments".
#[inline(always)]
fn prefetch(nodes: &[WideNode], tris: &TriangleSoa, child: u32, leaves: bool) {
    if leaves {
        traverse_single::prefetch_child(nodes, tris, child);
    } else {
        traverse_single::prefetch_node(nodes, child);
    }
}

/// Closest hits of the packet's active lanes; `p.t_max` shrinks lane by lane as hits are found.
/// `prefetch_leaves`: see `prefetch`.
pub fn intersect<V: SimdF32>(
    nodes: &[WideNode],
    tris: &TriangleSoa,
    p: &mut RayPacket<V>,
    fallback: u32,
    prefetch_leaves: bool,
    stack: &mut PacketStack<V>,
    stats: &mut TraceStats,
) -> PacketHits<V> {
    let mut hits = PacketHits::none();
    let active = p.active_bits();
    if nodes.is_empty() || active == 0 {
        return hits;
    }
    // Scattered lanes take ranks (`child_order`) and never the interval, which needs one octant.
    let ranked = p.mixed_octants(active);
    let interval =
        if V::W >= INTERVAL_MIN_W && !ranked { PacketInterval::new(p, active) } else { None };
    let mut frame = None;
    let PacketStack { closest: stack, entered: e, .. } = stack;
    stack.clear();
    // The current subtree's fields as locals, and the single-ray hand-over given a copy of
    // the entry distances: with `&cur` passed to it, `cur` lived in memory, every new subtree
    // was copied into it as two 256-bit halves (LLVM's 256-bit preference on x86-64-v4), and
    // the 512-bit load at the top of the loop waited on both stores. 16-ray packets: primary
    // rays 1.02-1.05x (PERF.md, "16-ray packets and the interval pre-test").
    let (mut child, mut entered, mut near) = (0u32, active, p.t_min);
    loop {
        // Lanes whose best hit is already nearer than the subtree drop out of it.
        let lanes = entered & near.simd_le(p.t_max * V::splat(BOX_INFLATE)).bitmask();
        if lanes != 0 {
            if child & LEAF_BIT != 0 {
                let (first, count) = leaf_range(child);
                let f = frame.get_or_insert_with(|| TriangleFrame::of(p));
                if leaf_by_lane(lanes, count) {
                    lane_by_lane(lanes, near, p, &mut hits, |i, _, ray, best, near| {
                        let leaf_ray = LeafRay::of_lane(f, i);
                        leaf::intersect_leaf(tris, first, count, near, &leaf_ray, ray, best, stats)
                    });
                } else {
                    intersect_leaf(tris, first, count, near, lanes, f, p, &mut hits, stats);
                }
            } else if lanes.count_ones() <= fallback {
                let f = frame.get_or_insert_with(|| TriangleFrame::of(p));
                finish_single(nodes, tris, child, &{ near }, lanes, f, p, &mut hits, stats);
            } else {
                let n = &nodes[child as usize];
                entered_children(p, n, lanes, interval.as_ref(), ranked, e, stats);
                if e.k > 0 {
                    // Pushed subtrees start loading now, as in single-ray traversal.
                    stack.extend((0..e.k - 1).map(|j| {
                        let entry = e.entry(n, j);
                        prefetch(nodes, tris, entry.child, prefetch_leaves);
                        entry
                    }));
                    let next = e.order[e.k - 1] as usize;
                    (child, entered, near) =
                        (n.child[next], e.lanes[next], V::copied(&e.near[next]));
                    continue;
                }
            }
        }
        // The entry is read in place (a copy of it went through two 256-bit halves, see
        // `SimdF32::copied`).
        match stack.last() {
            Some(top) => {
                (child, entered, near) = (top.child, top.lanes, V::copied(&top.near));
                stack.pop();
            }
            None => return hits,
        }
    }
}

/// Runs `trace(lane, packet, ray, best, entry distance)` for each lane of `lanes` as a single ray
/// (with the lane's current best hit), and takes the hits back into the packet. A lane's hit
/// is blended into the packet's vectors: written into arrays of the vectors and loaded back,
/// the vector loads waited on the scalar stores (a failed store-to-load forward per vector,
/// PERF.md "What changed, each measured", twelfth round).
#[inline(always)]
fn lane_by_lane<V: SimdF32>(
    lanes: u32,
    near: V,
    p: &mut RayPacket<V>,
    hits: &mut PacketHits<V>,
    mut trace: impl FnMut(usize, &RayPacket<V>, &mut Ray, &mut Option<Hit>, f32),
) {
    let mut bits = lanes;
    while bits != 0 {
        let i = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let mut ray = p.ray(i);
        let mut best = hits.get(i);
        trace(i, p, &mut ray, &mut best, near.lane(i));
        if let Some(h) = best {
            let lane = V::from_bitmask(1 << i);
            p.t_max = V::select(lane, V::splat(h.t), p.t_max);
            hits.u = V::select(lane, V::splat(h.u), hits.u);
            hits.v = V::select(lane, V::splat(h.v), hits.v);
            hits.prim[i] = h.prim;
            hits.hit_bits |= 1 << i;
        }
    }
    hits.t = p.t_max;
}

/// Lanes `lanes` finish the subtree `child`, entered at `near`, one ray at a time, each
/// prepared from the packet's terms (`WideRay::of_lane`; `f`: the packet's triangle terms).
#[inline(never)]
#[allow(clippy::too_many_arguments)] // the subtree (child, entry distances), the lanes, the packet's state
fn finish_single<V: SimdF32>(
    nodes: &[WideNode],
    tris: &TriangleSoa,
    child: u32,
    near: &V,
    lanes: u32,
    f: &TriangleFrame<V>,
    p: &mut RayPacket<V>,
    hits: &mut PacketHits<V>,
    stats: &mut TraceStats,
) {
    lane_by_lane(lanes, *near, p, hits, |i, p, ray, best, t| {
        let wr = WideRay::of_lane(p, i, LeafRay::of_lane(f, i));
        let start = SingleEntry { child, t };
        traverse_single::intersect_subtree(nodes, tris, &wr, start, ray, best, stats);
    });
}

/// Whether a leaf of `count` triangles is cheaper to test lane by lane (one 8-wide test of
/// up to 8 triangles per lane) than triangle by triangle (one W-wide test per triangle).
/// Packets reach most leaves with one or two lanes left (CBbunny primary rays: 1.5 on
/// average), where testing a merged 8-triangle leaf triangle by triangle wastes most lanes.
#[inline(always)]
fn leaf_by_lane(lanes: u32, count: usize) -> bool {
    lanes.count_ones() as usize * count.div_ceil(LANES) < count
}

/// Every triangle of the leaf `first .. first + count`, entered at `near`, against the lanes
/// `lanes`.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // the leaf (range and entry distances), the lanes, and the packet's state
fn intersect_leaf<V: SimdF32>(
    tris: &TriangleSoa,
    first: usize,
    count: usize,
    near: V,
    lanes: u32,
    f: &TriangleFrame<V>,
    p: &mut RayPacket<V>,
    hits: &mut PacketHits<V>,
    stats: &mut TraceStats,
) {
    stats.triangle_tests += (count as u64) * lanes.count_ones() as u64;
    let valid = V::from_bitmask(lanes);
    let inflate = V::splat(BOX_INFLATE);
    let coherent = f.axes.uniform.is_some();
    for i in first..first + count {
        let tri = splat_tri(tris, i, f);
        let edges = edge_test(f.origin_in_axes, &f.shear, tri, valid);
        // In a coherent packet (its lanes share the dominant axis) most triangles of a leaf
        // enclose none of the lanes: skip their division. Incoherent packets lose more to the
        // branch than they save (PERF.md "Watertight triangles").
        if coherent && edges.candidates.bitmask() == 0 {
            continue;
        }
        let (mask, t, u, v) = edges.hit(p.t_min, p.t_max);
        // Hits in front of the leaf box do not count (`leaf`).
        let mask = mask & (t * inflate).simd_ge(near);
        let take = mask.bitmask();
        if take == 0 {
            continue;
        }
        let prim = tris.prim(i);
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
/// as every active lane is. `prefetch_leaves`: see `prefetch`. Children are visited farthest first, as single-ray occlusion
/// does (`traverse_single::occluded_subtree`).
pub fn occluded<V: SimdF32>(
    nodes: &[WideNode],
    tris: &TriangleSoa,
    p: &RayPacket<V>,
    fallback: u32,
    prefetch_leaves: bool,
    stack: &mut PacketStack<V>,
    stats: &mut TraceStats,
) -> u32 {
    let active = p.active_bits();
    if nodes.is_empty() || active == 0 {
        return 0;
    }
    // No interval pre-test for occlusion: 0.91x on shadow packets (`INTERVAL_MIN_W`).
    let interval = None;
    // Insertion even for scattered rays: ranks measured 0.93-0.98x on shadow packets.
    let ranked = false;
    let mut frame = None;
    let mut blocked = 0u32;
    let PacketStack { any: stack, entered: e, .. } = stack;
    stack.clear();
    // (child reference, lanes)
    let mut cur = (0u32, active);
    loop {
        let lanes = cur.1 & !blocked;
        if lanes != 0 {
            let child = cur.0;
            if child & LEAF_BIT != 0 {
                let (first, count) = leaf_range(child);
                let f = frame.get_or_insert_with(|| TriangleFrame::of(p));
                if leaf_by_lane(lanes, count) {
                    blocked |= blocked_lane_by_lane(lanes, p, |i, ray| {
                        let leaf_ray = LeafRay::of_lane(f, i);
                        leaf::occluded_leaf(tris, first, count, &leaf_ray, ray, stats)
                    });
                } else {
                    blocked |= occluded_leaf(tris, first, count, lanes, f, p, stats);
                }
            } else if lanes.count_ones() <= fallback {
                let f = frame.get_or_insert_with(|| TriangleFrame::of(p));
                blocked |= blocked_lane_by_lane(lanes, p, |i, ray| {
                    let wr = WideRay::of_lane(p, i, LeafRay::of_lane(f, i));
                    traverse_single::occluded_subtree(nodes, tris, &wr, child, ray, stats)
                });
            } else {
                let n = &nodes[child as usize];
                entered_children(p, n, lanes, interval.as_ref(), ranked, e, stats);
                if e.k > 0 {
                    // Farthest first: push in reverse of the farthest-first order.
                    for j in (1..e.k).rev() {
                        let i = e.order[j] as usize;
                        prefetch(nodes, tris, n.child[i], prefetch_leaves);
                        stack.push((n.child[i], e.lanes[i]));
                    }
                    let i = e.order[0] as usize;
                    cur = (n.child[i], e.lanes[i]);
                    continue;
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

/// The lanes of `lanes` whose ray, traced alone, `blocks(lane, ray)` says is blocked.
#[inline(always)]
fn blocked_lane_by_lane<V: SimdF32>(
    lanes: u32,
    p: &RayPacket<V>,
    mut blocks: impl FnMut(usize, &Ray) -> bool,
) -> u32 {
    let (mut bits, mut blocked) = (lanes, 0);
    while bits != 0 {
        let i = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        if blocks(i, &p.ray(i)) {
            blocked |= 1 << i;
        }
    }
    blocked
}

/// The lanes of `lanes` that a triangle of the leaf blocks; a lane stops testing once blocked.
#[inline(always)]
fn occluded_leaf<V: SimdF32>(
    tris: &TriangleSoa,
    first: usize,
    count: usize,
    lanes: u32,
    f: &TriangleFrame<V>,
    p: &RayPacket<V>,
    stats: &mut TraceStats,
) -> u32 {
    let mut open = lanes;
    for i in first..first + count {
        stats.triangle_tests += open.count_ones() as u64;
        let tri = splat_tri(tris, i, f);
        let (mask, ..) = intersect_simd(
            f.origin_in_axes,
            &f.shear,
            tri,
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
    use crate::accel::traverse_single::WideRay;
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
            let (min, max): ([f32; 3], [f32; 3]) = (a.min(b).into(), a.max(b).into());
            // The box in slot 1 of a node (slot 0 a different box, so slots are not mixed up).
            let mut n = WideNode::EMPTY_NODE;
            n.set_child(0, [9.0; 3], [10.0; 3], 1);
            n.set_child(1, min, max, 2);
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
                            o.z = min[2];
                        }
                        _ => {}
                    }
                    Ray::segment(o, d, 0.1 * r().abs(), 1.0 + 3.0 * r().abs())
                })
                .collect();
            let p = RayPacket::<V>::from_rays(&rays);
            let (bmin, bmax) = child_box(&n, 1);
            let (mask, near) = slab(&p, bmin, bmax, p.t_max);
            for (k, ray) in rays.iter().enumerate() {
                let (t, bits) = WideRay::new(ray).slab(&n, ray.t_max);
                let single_hit = bits & 0b10 != 0;
                let lane_hit = mask.bitmask() & (1 << k) != 0;
                assert_eq!(single_hit, lane_hit, "case {case} lane {k}");
                if lane_hit {
                    hit += 1;
                    assert_eq!(t.to_array()[1].to_bits(), near.lane(k).to_bits());
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
