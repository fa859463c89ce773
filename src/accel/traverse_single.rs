//! One ray through the wide BVH (`wide_node`): closest hit and any hit, with one `ChildLanes`
//! slab test for the eight children of a node, hit children visited nearest first, a fixed
//! stack, and leaves tested 8 triangles at a time (`leaf`). The same traversal also runs as
//! resumable walks, several rays in flight per thread (`intersect_stream`, `occluded_stream`),
//! so that one ray's node loads overlap another's tests.
//!
//! Hits are the same as packet traversal's (`traverse_packet`): each lane of the box test
//! computes exactly what a packet lane computes for that box (the same fused multiply-adds on
//! the same per-ray terms, `packet::slab_terms`, the same tolerances), the leaves run the same
//! triangle test, hits are ordered by (t, prim), and hits in front of their leaf box do not count
//! (`leaf`), which removes the one way the visiting order could change the answer.

use std::mem::MaybeUninit;

use super::build::MAX_DEPTH;
use super::leaf::{intersect_leaf, occluded_leaf, LeafRay};
use super::packet::{safe_recip, slab_terms, RayPacket, BOX_INFLATE};
use super::wide_node::{leaf_range, ChildLanes, Row, WideNode, ARITY, LEAF_BIT};
use super::TraceStats;
use crate::geometry::triangles::{TriangleSoa, LANES};
use crate::geometry::watertight::V3;
use crate::math::{fill_no_hits, Hit, Ray, Vec3};
use crate::simd::prefetch;
use crate::simd::SimdF32;

/// A wide tree is no deeper than the binary tree it came from, and each level pushes at most
/// `ARITY - 1` siblings.
const STACK: usize = (ARITY - 1) * MAX_DEPTH + 1;
const _: () = assert!(STACK == 449 && std::mem::size_of::<Entry>() == 8);

/// A ray prepared for wide box tests: reciprocal direction and the fused slab test's terms
/// (`packet::slab_terms`) broadcast, and per axis whether the direction is negative (then the
/// box maximum is the near plane).
#[derive(Clone, Copy)]
pub(super) struct WideRay {
    inv_dir: [ChildLanes; 3],
    neg_o_inv: [ChildLanes; 3],
    slack: ChildLanes,
    /// Per axis, the node's row holding the near plane (the minimum, or the maximum where
    /// the direction is negative) and the far plane: chosen once per ray instead of at every
    /// node (PERF.md, "Instructions per ray on Zen 3").
    near: [Row; 3],
    far: [Row; 3],
    t_min: ChildLanes,
    /// The ray as the triangle test takes it.
    pub(super) leaf: LeafRay,
}

impl WideRay {
    #[inline(always)]
    pub(super) fn new(ray: &Ray) -> WideRay {
        let inv = [safe_recip(ray.dir.x), safe_recip(ray.dir.y), safe_recip(ray.dir.z)];
        let splat = |v: [f32; 3]| V3 {
            x: ChildLanes::splat(v[0]),
            y: ChildLanes::splat(v[1]),
            z: ChildLanes::splat(v[2]),
        };
        let inv_v = splat(inv);
        let (c, slack) = slab_terms(&splat([ray.origin.x, ray.origin.y, ray.origin.z]), &inv_v);
        let (near, far) = Row::near_far(inv);
        WideRay {
            inv_dir: [inv_v.x, inv_v.y, inv_v.z],
            neg_o_inv: [c.x, c.y, c.z],
            slack,
            near,
            far,
            t_min: ChildLanes::splat(ray.t_min),
            leaf: LeafRay::new(ray),
        }
    }

    /// `WideRay::new` of lane `i` of `p`, from the packet's own terms (`safe_recip` and
    /// `slab_terms` lane by lane, so the same bits) and the lane's `leaf` terms.
    #[inline(always)]
    pub(super) fn of_lane<V: SimdF32>(p: &RayPacket<V>, i: usize, leaf: LeafRay) -> WideRay {
        let lane = |v: &V3<V>| [v.x.lane(i), v.y.lane(i), v.z.lane(i)];
        let inv = lane(&p.inv_dir);
        let (near, far) = Row::near_far(inv);
        WideRay {
            inv_dir: inv.map(ChildLanes::splat),
            neg_o_inv: lane(&p.neg_o_inv).map(ChildLanes::splat),
            slack: ChildLanes::splat(p.slack.lane(i)),
            near,
            far,
            t_min: ChildLanes::splat(p.t_min.lane(i)),
            leaf,
        }
    }

    /// Entry distances into the child boxes and the bit mask of the boxes the ray enters
    /// within [t_min, t_max] (exit enlarged by `BOX_INFLATE`). Taking the near plane by the
    /// direction's sign gives, for finite rays, the same values as the packet test's min/max
    /// of the two plane distances (the product with a fixed-sign factor is monotonic).
    #[inline(always)]
    pub(super) fn slab(&self, n: &WideNode, t_max: f32) -> (ChildLanes, u32) {
        // A `Row` is below 6, so indexing the bounds needs no check.
        let plane = |axis: usize, row: Row| {
            ChildLanes::new(n.bounds[row as usize])
                .mul_add(self.inv_dir[axis], self.neg_o_inv[axis])
        };
        let near = |axis: usize| plane(axis, self.near[axis]);
        let far = |axis: usize| plane(axis, self.far[axis]);
        let t_near = near(0).fast_max(near(1)).fast_max(near(2)).fast_max(self.t_min) - self.slack;
        let t_far = far(0).fast_min(far(1)).fast_min(far(2)).fast_min(ChildLanes::splat(t_max));
        let t_far = t_far.mul_add(ChildLanes::splat(BOX_INFLATE), self.slack);
        (t_near, t_near.simd_le(t_far).bitmask())
    }
}

/// A fixed traversal stack left uninitialised: `STACK` = 7 x 64 + 1 = 449 entries, 3.5 KiB of
/// `Entry` for closest hit and 1.75 KiB of `u32` for any hit; zeroing it cost a `memset` per
/// ray (measured in PERF.md, "Wide BVH").
struct Stack<T: Copy> {
    items: [MaybeUninit<T>; STACK],
    len: usize,
}

impl<T: Copy> Stack<T> {
    #[inline(always)]
    fn new() -> Self {
        Stack { items: [const { MaybeUninit::uninit() }; STACK], len: 0 }
    }

    #[inline(always)]
    fn push(&mut self, x: T) {
        self.items[self.len].write(x);
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: `items[..len]` are initialised: `len` grows only in `push`, after a write.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

/// A subtree: a child reference (`WideNode::child`) and the ray's entry distance into its box.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Entry {
    /// The subtree's child reference (`WideNode::child`).
    pub child: u32,
    /// The ray's entry distance into the subtree's box.
    pub t: f32,
}

impl Entry {
    /// The whole tree (node 0), entered at `t_min`.
    pub(crate) fn root(ray: &Ray) -> Entry {
        Entry { child: 0, t: ray.t_min }
    }
}

/// Starts loading node `child` (all its cache lines) if it is one, while the ray descends into
/// a nearer sibling: on the 1M-triangle tori scene most nodes below the top levels miss the
/// caches, and a pushed child would otherwise be loaded only when popped.
/// Measured: PERF.md, "Measurements moved from doc comments".
#[inline(always)]
pub(super) fn prefetch_node(nodes: &[WideNode], child: u32) {
    if child & LEAF_BIT == 0 {
        prefetch(nodes.as_ptr().wrapping_add(child as usize));
    }
}

/// Starts loading every cache line of `s`.
#[inline(always)]
pub(super) fn prefetch_slice<T>(s: &[T]) {
    if let (Some(first), Some(last)) = (s.first(), s.last()) {
        let (a, b) = (first as *const T as usize & !63, last as *const T as usize);
        for line in (a..b + std::mem::size_of::<T>()).step_by(64) {
            prefetch(line as *const u8);
        }
    }
}

/// Starts loading what visiting `child` reads first: the node, or the leaf's triangle block.
#[inline(always)]
pub(super) fn prefetch_child(nodes: &[WideNode], tris: &TriangleSoa, child: u32) {
    if child & LEAF_BIT == 0 {
        prefetch_node(nodes, child);
    } else {
        let (first, _) = leaf_range(child);
        prefetch(tris.blocks().as_ptr().wrapping_add(first / LANES));
    }
}

/// The children of node `n` that the ray enters within `t_max`: the nearest is returned, to
/// be visited next; the others are pushed farthest first (so that the nearer come off the
/// stack first), and interior ones start loading (`prefetch_node`). None when it enters none.
#[inline(always)]
fn descend(
    nodes: &[WideNode],
    wr: &WideRay,
    n: &WideNode,
    t_max: f32,
    stack: &mut Stack<Entry>,
) -> Option<Entry> {
    let mut push = |e: Entry| {
        prefetch_node(nodes, e.child);
        stack.push(e);
    };
    let (t_near, mut bits) = wr.slab(n, t_max);
    if bits == 0 {
        return None;
    }
    let t = t_near.to_array();
    let entry = |i: usize| Entry { child: n.child[i], t: t[i] };
    let a = bits.trailing_zeros() as usize;
    bits &= bits - 1;
    if bits == 0 {
        return Some(entry(a));
    }
    let b = bits.trailing_zeros() as usize;
    bits &= bits - 1;
    if bits == 0 {
        let (near, far) = if t[a] <= t[b] { (a, b) } else { (b, a) };
        push(entry(far));
        return Some(entry(near));
    }
    // Three or more: sort them far to near by insertion (in registers), push all but the
    // nearest, visit the nearest.
    let mut run = [entry(a); ARITY];
    let mut k = 1;
    for e in std::iter::once(entry(b)).chain(std::iter::from_fn(|| {
        (bits != 0).then(|| {
            let i = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            entry(i)
        })
    })) {
        let mut j = k;
        while j > 0 && run[j - 1].t < e.t {
            run[j] = run[j - 1];
            j -= 1;
        }
        run[j] = e;
        k += 1;
    }
    for &e in &run[..k - 1] {
        push(e);
    }
    Some(run[k - 1])
}

/// Closest hit among the triangles; `ray.t_max` shrinks to the hit distance. Among hits at
/// equal distance the smallest prim wins.
pub fn intersect(
    nodes: &[WideNode],
    tris: &TriangleSoa,
    ray: &mut Ray,
    stats: &mut TraceStats,
) -> Option<Hit> {
    let mut best = None;
    if !nodes.is_empty() {
        let wr = WideRay::new(ray);
        intersect_subtree(nodes, tris, &wr, Entry::root(ray), ray, &mut best, stats);
    }
    best
}

/// Closest hit within the subtree `start` (whose box the caller has tested; packets hand
/// their last few lanes over here), improving on `best`, whose distance is `ray.t_max`;
/// `wr` is `ray` prepared (`WideRay::new`, or `WideRay::of_lane` for a packet's lane).
#[inline(always)]
pub(super) fn intersect_subtree(
    nodes: &[WideNode],
    tris: &TriangleSoa,
    wr: &WideRay,
    start: Entry,
    ray: &mut Ray,
    best: &mut Option<Hit>,
    stats: &mut TraceStats,
) {
    let mut stack = Stack::<Entry>::new();
    // Counted in a register and stored once: `stats` is behind a reference the leaf test also
    // writes, so a per-node `+=` would be a load and store per node.
    let mut node_tests = 0u64;
    let mut cur = start;
    'visit: loop {
        // The box test reads a copy made here: with `wr`'s terms read through the reference,
        // they were reloaded from memory at every node visit (the leaf test below needs the
        // registers). PERF.md, "Embree's single rays under callgrind".
        let terms = *wr;
        while cur.child & LEAF_BIT == 0 {
            let n = &nodes[cur.child as usize];
            node_tests += n.children() as u64;
            match descend(nodes, &terms, n, ray.t_max, &mut stack) {
                Some(next) => cur = next,
                None => break,
            }
        }
        if cur.child & LEAF_BIT != 0 {
            let (first, count) = leaf_range(cur.child);
            intersect_leaf(tris, first, count, cur.t, &wr.leaf, ray, best, stats);
        }
        // Pop the next subtree that can still hold a nearer hit (the box test's tolerance, so
        // nothing is dropped that the box test would keep).
        loop {
            let Some(e) = stack.pop() else {
                stats.node_tests += node_tests;
                return;
            };
            if e.t <= ray.t_max * BOX_INFLATE {
                cur = e;
                continue 'visit;
            }
        }
    }
}

/// The children of node `n` that an any-hit ray enters within `t_max`: the farthest is
/// returned, to be visited next (`occluded_subtree`), the others pushed (interior ones start
/// loading). None when it enters none.
#[inline(always)]
fn descend_any(
    nodes: &[WideNode],
    wr: &WideRay,
    n: &WideNode,
    t_max: f32,
    stack: &mut Stack<u32>,
) -> Option<u32> {
    let (t_near, mut bits) = wr.slab(n, t_max);
    if bits == 0 {
        return None;
    }
    let t = t_near.to_array();
    let mut a = bits.trailing_zeros() as usize;
    bits &= bits - 1;
    while bits != 0 {
        let mut i = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        if t[i] > t[a] {
            std::mem::swap(&mut a, &mut i);
        }
        prefetch_node(nodes, n.child[i]);
        stack.push(n.child[i]);
    }
    Some(n.child[a])
}

/// Whether any triangle blocks the ray within [t_min, t_max]; stops at the first one found.
pub fn occluded(nodes: &[WideNode], tris: &TriangleSoa, ray: &Ray, stats: &mut TraceStats) -> bool {
    !nodes.is_empty() && occluded_subtree(nodes, tris, &WideRay::new(ray), 0, ray, stats)
}

/// Whether any triangle of the subtree `start` (box already tested) blocks the ray, prepared
/// as `wr` (see `intersect_subtree`).
///
/// The farthest entered child is visited first. Occlusion rays start on a surface, and the
/// boxes around their origin (entered at t_min, so nearest) hold the surface they leave, which
/// rarely blocks them; what blocks them lies farther along.
/// Measured: PERF.md, "Measurements moved from doc comments".
#[inline(always)]
pub(super) fn occluded_subtree(
    nodes: &[WideNode],
    tris: &TriangleSoa,
    wr: &WideRay,
    start: u32,
    ray: &Ray,
    stats: &mut TraceStats,
) -> bool {
    let mut stack = Stack::<u32>::new();
    let mut node_tests = 0u64;
    let mut child = start;
    loop {
        while child & LEAF_BIT == 0 {
            let n = &nodes[child as usize];
            node_tests += n.children() as u64;
            match descend_any(nodes, wr, n, ray.t_max, &mut stack) {
                Some(next) => child = next,
                None => break,
            }
        }
        if child & LEAF_BIT != 0 && {
            let (first, count) = leaf_range(child);
            occluded_leaf(tris, first, count, &wr.leaf, ray, stats)
        } {
            stats.node_tests += node_tests;
            return true;
        }
        let Some(next) = stack.pop() else {
            stats.node_tests += node_tests;
            return false;
        };
        child = next;
    }
}

/// How many rays `Accel::intersect_stream` keeps in flight on one thread: one for a
/// structure that fits the core's L2 cache, `STREAM_SMALL` for one of at most
/// `STREAM_LARGE_BYTES` (L3-resident on this machine kind), else `STREAM_LARGE`, each ray's next node or leaf prefetched as soon as it is known. Each
/// ray in flight adds a stack and a prepared ray to the working set and mixes the branch
/// history of the traversal loop, and each prefetch costs instructions; on a cache-resident
/// scene that costs more than the overlapped latency gives back.
/// Measured: PERF.md, "Measurements moved from doc comments".
pub(crate) const STREAM_SMALL: usize = 2;
/// Rays in flight for a structure over `STREAM_LARGE_BYTES` (see `STREAM_SMALL`).
pub(crate) const STREAM_LARGE: usize = 8;
/// Structure size (`Accel::memory_bytes`) above which it counts as large: more rays in flight,
/// and leaves prefetched too (see `STREAM_SMALL`).
pub(crate) const STREAM_LARGE_BYTES: usize = 16 << 20;

/// One ray's closest-hit traversal as a resumable state, advanced one node or leaf at a time,
/// so that several rays' traversals can be interleaved on one thread (`intersect_stream`).
struct ClosestWalk {
    wr: WideRay,
    ray: Ray,
    best: Option<Hit>,
    stack: Stack<Entry>,
    cur: Entry,
    node_tests: u64,
    /// Which ray of the stream this is.
    index: usize,
}

impl ClosestWalk {
    #[inline(always)]
    fn start(&mut self, ray: &Ray, index: usize) {
        self.wr = WideRay::new(ray);
        self.ray = *ray;
        self.best = None;
        self.stack.len = 0;
        self.cur = Entry::root(ray);
        self.index = index;
    }

    /// Visits one node or one leaf, then, if that left nothing to descend into, pops the next
    /// subtree that can still hold a nearer hit. True when the traversal is over. With
    /// `PREFETCH` the next node or leaf block starts loading at once: the other rays in flight
    /// take their steps before this one takes its next.
    #[inline(always)]
    fn step<const PREFETCH: bool>(
        &mut self,
        nodes: &[WideNode],
        tris: &TriangleSoa,
        stats: &mut TraceStats,
    ) -> bool {
        if self.cur.child & LEAF_BIT == 0 {
            let n = &nodes[self.cur.child as usize];
            self.node_tests += n.children() as u64;
            if let Some(next) = descend(nodes, &self.wr, n, self.ray.t_max, &mut self.stack) {
                if PREFETCH {
                    prefetch_child(nodes, tris, next.child);
                }
                self.cur = next;
                return false;
            }
        } else {
            let (first, count) = leaf_range(self.cur.child);
            let leaf_ray = &self.wr.leaf;
            intersect_leaf(
                tris,
                first,
                count,
                self.cur.t,
                leaf_ray,
                &mut self.ray,
                &mut self.best,
                stats,
            );
        }
        loop {
            let Some(e) = self.stack.pop() else {
                return true;
            };
            if e.t <= self.ray.t_max * BOX_INFLATE {
                if PREFETCH {
                    prefetch_child(nodes, tris, e.child);
                }
                self.cur = e;
                return false;
            }
        }
    }
}

/// Closest hits of `rays` (`hits[i]` answers `rays[i]`), the same as `intersect` ray by
/// ray, with `K` rays in flight at once: each step advances every live ray by one node or
/// leaf, so the core works on one ray while another's next node is on its way from memory.
/// A ray that finishes hands its place to the next ray of the slice.
pub fn intersect_stream<const K: usize, const PREFETCH: bool>(
    nodes: &[WideNode],
    tris: &TriangleSoa,
    rays: &[Ray],
    hits: &mut [Option<Hit>],
    stats: &mut TraceStats,
) {
    if nodes.is_empty() {
        fill_no_hits(&mut hits[..rays.len()]);
        return;
    }
    let blank = || ClosestWalk {
        wr: WideRay::new(&Ray::new(Vec3::ZERO, Vec3::X)),
        ray: Ray::new(Vec3::ZERO, Vec3::X),
        best: None,
        stack: Stack::new(),
        cur: Entry { child: 0, t: 0.0 },
        node_tests: 0,
        index: usize::MAX,
    };
    let mut walks: [ClosestWalk; K] = std::array::from_fn(|_| blank());
    let mut live = 0u32;
    let mut next = 0;
    for (k, w) in walks.iter_mut().enumerate() {
        if next < rays.len() {
            w.start(&rays[next], next);
            next += 1;
            live |= 1 << k;
        }
    }
    while live != 0 {
        for (k, w) in walks.iter_mut().enumerate() {
            if live & (1 << k) == 0 || !w.step::<PREFETCH>(nodes, tris, stats) {
                continue;
            }
            hits[w.index] = w.best;
            if next < rays.len() {
                w.start(&rays[next], next);
                next += 1;
            } else {
                live &= !(1 << k);
            }
        }
    }
    stats.node_tests += walks.iter().map(|w| w.node_tests).sum::<u64>();
}

/// One ray's any-hit traversal as a resumable state (`occluded_stream`).
struct AnyWalk {
    wr: WideRay,
    ray: Ray,
    stack: Stack<u32>,
    child: u32,
    node_tests: u64,
    index: usize,
}

impl AnyWalk {
    #[inline(always)]
    fn start(&mut self, ray: &Ray, index: usize) {
        self.wr = WideRay::new(ray);
        self.ray = *ray;
        self.stack.len = 0;
        self.child = 0;
        self.index = index;
    }

    /// Visits one node or one leaf, and starts loading the next (as `ClosestWalk::step` with
    /// `PREFETCH`). `Some(blocked)` when the traversal is over.
    #[inline(always)]
    fn step(
        &mut self,
        nodes: &[WideNode],
        tris: &TriangleSoa,
        stats: &mut TraceStats,
    ) -> Option<bool> {
        if self.child & LEAF_BIT == 0 {
            let n = &nodes[self.child as usize];
            self.node_tests += n.children() as u64;
            if let Some(next) = descend_any(nodes, &self.wr, n, self.ray.t_max, &mut self.stack) {
                prefetch_child(nodes, tris, next);
                self.child = next;
                return None;
            }
        } else {
            let (first, count) = leaf_range(self.child);
            if occluded_leaf(tris, first, count, &self.wr.leaf, &self.ray, stats) {
                return Some(true);
            }
        }
        let Some(next) = self.stack.pop() else {
            return Some(false);
        };
        prefetch_child(nodes, tris, next);
        self.child = next;
        None
    }
}

/// Whether each of `rays` is blocked (`blocked[i]` answers `rays[i]`), the same as `occluded`
/// ray by ray, with `K` rays in flight at once and their next node or leaf prefetched
/// (`intersect_stream`). Its scheduling loop is `intersect_stream`'s, copied: one generic
/// driver over a walk trait was slower (PERF.md, "Measurements moved from doc comments").
pub fn occluded_stream<const K: usize>(
    nodes: &[WideNode],
    tris: &TriangleSoa,
    rays: &[Ray],
    blocked: &mut [bool],
    stats: &mut TraceStats,
) {
    if nodes.is_empty() {
        blocked[..rays.len()].fill(false);
        return;
    }
    let blank = || AnyWalk {
        wr: WideRay::new(&Ray::new(Vec3::ZERO, Vec3::X)),
        ray: Ray::new(Vec3::ZERO, Vec3::X),
        stack: Stack::new(),
        child: 0,
        node_tests: 0,
        index: usize::MAX,
    };
    let mut walks: [AnyWalk; K] = std::array::from_fn(|_| blank());
    let mut live = 0u32;
    let mut next = 0;
    for (k, w) in walks.iter_mut().enumerate() {
        if next < rays.len() {
            w.start(&rays[next], next);
            next += 1;
            live |= 1 << k;
        }
    }
    while live != 0 {
        for (k, w) in walks.iter_mut().enumerate() {
            if live & (1 << k) == 0 {
                continue;
            }
            let Some(b) = w.step(nodes, tris, stats) else {
                continue;
            };
            blocked[w.index] = b;
            if next < rays.len() {
                w.start(&rays[next], next);
                next += 1;
            } else {
                live &= !(1 << k);
            }
        }
    }
    stats.node_tests += walks.iter().map(|w| w.node_tests).sum::<u64>();
}
