//! One ray through the 4-wide BVH (`wide_node`): closest hit and any hit, with one `f32x4`
//! slab test for the four children of a node, hit children visited nearest first, a fixed
//! stack, and leaves tested 8 triangles at a time by the same code as the binary traversal.
//!
//! Hits are bit-identical to `traverse_single`'s: the leaves run the same triangle test and
//! order hits by (t, prim), and each lane of the box test computes exactly what the binary
//! test computes for that box (the same subtractions and products, no fused multiply-add, the
//! same `BOX_INFLATE` tolerance), so a box both trees hold is culled here iff it is culled
//! there. Hits in leaves merged from several binary leaves are checked against their binary
//! leaf box (`binary_culling`), with the current t_max where the binary walk used the t_max it
//! had on reaching that leaf: they could differ only for a hit in front of its own leaf box
//! found after a nearer box was entered, which no test ray has met.

use std::mem::MaybeUninit;

use wide::{f32x4, f32x8};

use super::build::{MAX_DEPTH, NO_LEAF};
use super::node::BvhNode;
use super::packet::{safe_recip, BOX_INFLATE};
use super::traverse_single::{intersect_leaf, occluded_leaf, HitFilter, RayBox};
use super::wide_node::{Bvh4Node, LEAF_BIT};
use super::TraceStats;
use crate::geometry::triangles::TriangleSoa;
use crate::math::{Hit, Ray};
use crate::simd::SimdF32;

/// A wide tree is no deeper than the binary tree it came from, and each level pushes at most
/// three siblings.
const STACK: usize = 3 * MAX_DEPTH + 1;

/// A ray prepared for 4-wide box tests: origin and reciprocal direction broadcast, and per
/// axis whether the direction is negative (then the box maximum is the near plane).
struct WideRay {
    origin: [f32x4; 3],
    inv_dir: [f32x4; 3],
    neg: [bool; 3],
    t_min: f32x4,
    /// The same ray for the binary tree's scalar box test (merged leaves' hit check).
    scalar: RayBox,
}

impl WideRay {
    #[inline(always)]
    fn new(ray: &Ray) -> WideRay {
        let inv = [safe_recip(ray.dir.x), safe_recip(ray.dir.y), safe_recip(ray.dir.z)];
        WideRay {
            origin: [ray.origin.x, ray.origin.y, ray.origin.z].map(f32x4::splat),
            inv_dir: inv.map(f32x4::splat),
            neg: inv.map(f32::is_sign_negative),
            t_min: f32x4::splat(ray.t_min),
            scalar: RayBox::from_recips(ray, inv),
        }
    }

    /// Entry distances into the four child boxes and the bit mask of the boxes the ray enters
    /// within [t_min, t_max] (exit enlarged by `BOX_INFLATE`). Taking the near plane by the
    /// direction's sign gives, for finite rays, the same values as the binary test's
    /// min/max of the two plane distances (the product with a fixed-sign factor is monotonic).
    #[inline(always)]
    fn slab(&self, n: &Bvh4Node, t_max: f32) -> (f32x4, u32) {
        let plane = |axis: usize, max: bool| {
            // `max as usize` is 0 or 1, so the row index is provably in bounds.
            let row = f32x4::new(n.bounds[2 * axis + max as usize]);
            (row - self.origin[axis]) * self.inv_dir[axis]
        };
        let near = |axis: usize| plane(axis, self.neg[axis]);
        let far = |axis: usize| plane(axis, !self.neg[axis]);
        let t_near = near(0).fast_max(near(1)).fast_max(near(2)).fast_max(self.t_min);
        let t_far = far(0).fast_min(far(1)).fast_min(far(2)).fast_min(f32x4::splat(t_max))
            * f32x4::splat(BOX_INFLATE);
        (t_near, t_near.simd_le(t_far).bitmask())
    }
}

/// A fixed traversal stack left uninitialised: a zeroed 2.3 KiB array cost a `memset` per
/// ray (measured below in PERF.md, "Wide BVH").
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

/// A stacked subtree: a child reference (`Bvh4Node::child`), its leaf count, its entry
/// distance.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    count: u32,
    t: f32,
}

/// The wide tree and what its merged leaves need: the binary leaf of every triangle in a
/// merged leaf (`leaf_of`, `NO_LEAF` elsewhere, empty when nothing was merged) and the binary
/// nodes.
#[derive(Clone, Copy)]
pub struct WideBvh<'a> {
    pub nodes: &'a [Bvh4Node],
    pub bvh2: &'a [BvhNode],
    pub leaf_of: &'a [u32],
}

/// Keeps the hits the binary tree would find. A merged wide leaf has one box where the binary
/// tree had several smaller ones, and the binary tree's box test does cull some real hits:
/// Möller-Trumbore's margin accepts hits a few ulps outside a triangle, hence possibly outside
/// its leaf box, and a ray lying in a flat box's plane (a zero direction component, made
/// 1e-18 by `safe_recip`) leaves that box at once. So every hit in a merged leaf is checked
/// against its binary leaf box with the same scalar test the binary traversal runs (the binary
/// ancestors inside the merged subtree contain that box, so they would pass too).
#[inline(always)]
fn binary_culling<'a>(w: WideBvh<'a>, rb: &'a RayBox) -> impl HitFilter + 'a {
    move |mut bits: u32, at: usize, _: f32x8, _: f32x8, ray: &Ray| {
        if w.leaf_of.is_empty() {
            return bits;
        }
        let mut check = bits;
        while check != 0 {
            let lane = check.trailing_zeros() as usize;
            check &= check - 1;
            let leaf = w.leaf_of[at + lane];
            if leaf == NO_LEAF {
                continue;
            }
            if rb.slab(&w.bvh2[leaf as usize], ray.t_max) == f32::INFINITY {
                bits &= !(1 << lane);
            }
        }
        bits
    }
}

/// Orders two entries so the farther comes first.
#[inline(always)]
fn far_first(x: &mut Entry, y: &mut Entry) {
    if x.t < y.t {
        std::mem::swap(x, y);
    }
}

/// Closest hit among the triangles; `ray.t_max` shrinks to the hit distance. Among hits at
/// equal distance the smallest prim wins.
pub fn intersect(
    w: WideBvh<'_>,
    tris: &TriangleSoa,
    ray: &mut Ray,
    stats: &mut TraceStats,
) -> Option<Hit> {
    let nodes = w.nodes;
    let mut best = None;
    if nodes.is_empty() {
        return None;
    }
    let wr = WideRay::new(ray);
    let mut stack = Stack::<Entry>::new();
    // Counted in a register and stored once: `stats` is behind a reference the leaf test also
    // writes, so a per-node `+=` would be a load and store per node.
    let mut node_tests = 0u64;
    // The root node.
    let (mut child, mut count) = (0u32, 0u32);
    'visit: loop {
        while child & LEAF_BIT == 0 {
            let n = &nodes[child as usize];
            node_tests += n.children() as u64;
            let (t_near, mut bits) = wr.slab(n, ray.t_max);
            if bits == 0 {
                break;
            }
            let t = t_near.to_array();
            let a = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if bits == 0 {
                (child, count) = (n.child[a], n.count[a]);
                continue;
            }
            let b = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if bits == 0 {
                let (near, far) = if t[a] <= t[b] { (a, b) } else { (b, a) };
                stack.push(Entry { child: n.child[far], count: n.count[far], t: t[far] });
                (child, count) = (n.child[near], n.count[near]);
                continue;
            }
            // Three or four: sort far to near with a compare-exchange network (in registers),
            // push all but the nearest, visit the nearest.
            let entry = |i: usize| Entry { child: n.child[i], count: n.count[i], t: t[i] };
            let c = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let (mut e0, mut e1, mut e2) = (entry(a), entry(b), entry(c));
            let nearest = if bits == 0 {
                far_first(&mut e0, &mut e1);
                far_first(&mut e1, &mut e2);
                far_first(&mut e0, &mut e1);
                stack.push(e0);
                stack.push(e1);
                e2
            } else {
                let mut e3 = entry(bits.trailing_zeros() as usize);
                far_first(&mut e0, &mut e1);
                far_first(&mut e2, &mut e3);
                far_first(&mut e0, &mut e2);
                far_first(&mut e1, &mut e3);
                far_first(&mut e1, &mut e2);
                stack.push(e0);
                stack.push(e1);
                stack.push(e2);
                e3
            };
            (child, count) = (nearest.child, nearest.count);
        }
        if child & LEAF_BIT != 0 {
            intersect_leaf(
                tris,
                (child & !LEAF_BIT) as usize,
                count as usize,
                ray,
                &mut best,
                stats,
                binary_culling(w, &wr.scalar),
            );
        }
        // Pop the next subtree that can still hold a nearer hit (the box test's tolerance, so
        // nothing is dropped that the box test would keep).
        loop {
            let Some(e) = stack.pop() else {
                stats.node_tests += node_tests;
                return best;
            };
            if e.t <= ray.t_max * BOX_INFLATE {
                (child, count) = (e.child, e.count);
                continue 'visit;
            }
        }
    }
}

/// Whether any triangle blocks the ray within [t_min, t_max]; stops at the first one found.
///
/// The farthest entered child is visited first. Occlusion rays start on a surface, and the
/// boxes around their origin (entered at t_min, so nearest) hold the surface they leave, which
/// rarely blocks them; what blocks them lies farther along. Measured (PERF.md, "Wide BVH"):
/// maxplanck shadow 66.8 -> 41.6 node tests per ray and about 1.7x the rays per second
/// against slot order; nearest-first was worse than slot order (83.5 tests per ray).
pub fn occluded(w: WideBvh<'_>, tris: &TriangleSoa, ray: &Ray, stats: &mut TraceStats) -> bool {
    let nodes = w.nodes;
    if nodes.is_empty() {
        return false;
    }
    let wr = WideRay::new(ray);
    let mut stack = Stack::<(u32, u32)>::new();
    let mut node_tests = 0u64;
    let (mut child, mut count) = (0u32, 0u32);
    loop {
        while child & LEAF_BIT == 0 {
            let n = &nodes[child as usize];
            node_tests += n.children() as u64;
            let (t_near, mut bits) = wr.slab(n, ray.t_max);
            if bits == 0 {
                break;
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
                stack.push((n.child[i], n.count[i]));
            }
            (child, count) = (n.child[a], n.count[a]);
        }
        if child & LEAF_BIT != 0
            && occluded_leaf(
                tris,
                (child & !LEAF_BIT) as usize,
                count as usize,
                ray,
                stats,
                binary_culling(w, &wr.scalar),
            )
        {
            stats.node_tests += node_tests;
            return true;
        }
        let Some(next) = stack.pop() else {
            stats.node_tests += node_tests;
            return false;
        };
        (child, count) = next;
    }
}
