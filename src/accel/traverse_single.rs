//! One ray through the flat BVH: closest hit and any hit, with a fixed stack, nearer child
//! first, and leaves tested 8 triangles at a time.

use wide::f32x8;

use super::build::MAX_DEPTH;
use super::node::BvhNode;
use super::packet::{safe_recip, BOX_INFLATE};
use super::TraceStats;
use crate::geometry::moller_trumbore::{intersect_simd, splat3, V3};
use crate::geometry::triangles::{TriangleSoa, LANES};
use crate::math::{Hit, Ray, Vec3};

/// A ray prepared for box tests.
pub struct RayBox {
    origin: Vec3,
    inv_dir: Vec3,
    t_min: f32,
}

/// `minps`/`maxps` semantics, so a lane of the packet box test and this scalar test compute
/// the same thing.
#[inline(always)]
fn min_ps(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn max_ps(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

impl RayBox {
    pub fn new(ray: &Ray) -> RayBox {
        let inv_dir =
            Vec3::new(safe_recip(ray.dir.x), safe_recip(ray.dir.y), safe_recip(ray.dir.z));
        RayBox { origin: ray.origin, inv_dir, t_min: ray.t_min }
    }

    /// From reciprocals the caller already took with `safe_recip` (equal to `new`).
    #[inline(always)]
    pub fn from_recips(ray: &Ray, inv_dir: [f32; 3]) -> RayBox {
        RayBox { origin: ray.origin, inv_dir: Vec3::from(inv_dir), t_min: ray.t_min }
    }

    /// Entry distance into the node's box, or infinity if the ray misses it within
    /// [t_min, t_max] (exit enlarged by `BOX_INFLATE`). The same operations in the same order
    /// as a lane of `traverse_packet::slab`.
    #[inline(always)]
    pub fn slab(&self, n: &BvhNode, t_max: f32) -> f32 {
        let (o, inv) = (self.origin, self.inv_dir);
        let lo = |k: usize| (n.min[k] - o[k]) * inv[k];
        let hi = |k: usize| (n.max[k] - o[k]) * inv[k];
        let (x0, x1, y0, y1, z0, z1) = (lo(0), hi(0), lo(1), hi(1), lo(2), hi(2));
        let near =
            max_ps(max_ps(max_ps(min_ps(x0, x1), min_ps(y0, y1)), min_ps(z0, z1)), self.t_min);
        let far = min_ps(min_ps(min_ps(max_ps(x0, x1), max_ps(y0, y1)), max_ps(z0, z1)), t_max)
            * BOX_INFLATE;
        if near <= far {
            near
        } else {
            f32::INFINITY
        }
    }
}

/// Lane mask for the first `n` lanes.
#[inline(always)]
fn first_lanes(n: usize) -> f32x8 {
    const ON: f32 = f32::from_bits(!0);
    f32x8::new(std::array::from_fn(|i| if i < n { ON } else { 0.0 }))
}

#[inline(always)]
fn load8(col: &[f32], at: usize) -> f32x8 {
    let a: [f32; LANES] = col[at..at + LANES].try_into().expect("columns are padded by LANES");
    f32x8::new(a)
}

#[inline(always)]
fn load3(cols: &[Vec<f32>; 3], at: usize) -> V3<f32x8> {
    V3 { x: load8(&cols[0], at), y: load8(&cols[1], at), z: load8(&cols[2], at) }
}

/// Which hit lanes of a group of 8 triangles to keep: `(hit bits, first triangle of the
/// group, u, v, ray) -> kept bits`. The binary tree keeps them all; the wide tree drops margin
/// hits that the binary tree's leaf boxes would have culled (`traverse_wide`).
pub(super) trait HitFilter: Fn(u32, usize, f32x8, f32x8, &Ray) -> u32 {}
impl<F: Fn(u32, usize, f32x8, f32x8, &Ray) -> u32> HitFilter for F {}

/// Keeps every hit.
#[inline(always)]
pub(super) fn keep_all(bits: u32, _: usize, _: f32x8, _: f32x8, _: &Ray) -> u32 {
    bits
}

/// Tests the leaf's triangles `first .. first + count` 8 at a time; shrinks `ray.t_max` and
/// records the closest hit among those `keep` keeps. Shared with the wide traversal, so both
/// compute the same hits.
#[inline]
pub(super) fn intersect_leaf(
    tris: &TriangleSoa,
    first: usize,
    count: usize,
    ray: &mut Ray,
    best: &mut Option<Hit>,
    stats: &mut TraceStats,
    keep: impl HitFilter,
) {
    let (o, d) = (splat3(ray.origin), splat3(ray.dir));
    stats.triangle_tests += count as u64;
    for at in (first..first + count).step_by(LANES) {
        let valid = first_lanes(first + count - at);
        let (mask, t, u, v) = intersect_simd(
            o,
            d,
            load3(&tris.v0, at),
            load3(&tris.e1, at),
            load3(&tris.e2, at),
            f32x8::splat(ray.t_min),
            f32x8::splat(ray.t_max),
            valid,
        );
        let mut bits = mask.to_bitmask();
        if bits == 0 {
            continue;
        }
        bits = keep(bits, at, u, v, ray);
        if bits == 0 {
            continue;
        }
        // The nearest hit lane; among equal distances the smallest prim wins, here and
        // against the best so far, so the result does not depend on the order in which
        // leaves are visited (packet traversal visits them in another order).
        let ts = t.to_array();
        let prims = &tris.prim[at..];
        let mut k = bits.trailing_zeros() as usize;
        for lane in k + 1..LANES {
            if bits & (1 << lane) != 0
                && (ts[lane] < ts[k] || (ts[lane] == ts[k] && prims[lane] < prims[k]))
            {
                k = lane;
            }
        }
        if let Some(b) = best {
            if ts[k] == b.t && prims[k] > b.prim {
                continue;
            }
        }
        ray.t_max = ts[k];
        *best = Some(Hit { t: ts[k], u: u.to_array()[k], v: v.to_array()[k], prim: prims[k] });
    }
}

/// Whether any of the leaf's triangles `first .. first + count` blocks the ray.
#[inline]
pub(super) fn occluded_leaf(
    tris: &TriangleSoa,
    first: usize,
    count: usize,
    ray: &Ray,
    stats: &mut TraceStats,
    keep: impl HitFilter,
) -> bool {
    let (o, d) = (splat3(ray.origin), splat3(ray.dir));
    let (t_min, t_max) = (f32x8::splat(ray.t_min), f32x8::splat(ray.t_max));
    for at in (first..first + count).step_by(LANES) {
        stats.triangle_tests += (first + count - at).min(LANES) as u64;
        let valid = first_lanes(first + count - at);
        let (mask, _, u, v) = intersect_simd(
            o,
            d,
            load3(&tris.v0, at),
            load3(&tris.e1, at),
            load3(&tris.e2, at),
            t_min,
            t_max,
            valid,
        );
        let bits = mask.to_bitmask();
        if bits != 0 && keep(bits, at, u, v, ray) != 0 {
            return true;
        }
    }
    false
}

/// Closest hit among the triangles; `ray.t_max` shrinks to the hit distance. Among hits at
/// equal distance the smallest prim wins.
pub fn intersect(
    nodes: &[BvhNode],
    tris: &TriangleSoa,
    ray: &mut Ray,
    stats: &mut TraceStats,
) -> Option<Hit> {
    let mut best = None;
    stats.node_tests += 1;
    if nodes.is_empty() || RayBox::new(ray).slab(&nodes[0], ray.t_max) == f32::INFINITY {
        return None;
    }
    intersect_subtree(nodes, tris, 0, ray, &mut best, stats);
    best
}

/// Closest hit within the subtree at `root`, whose box the caller has already tested (packet
/// traversal hands over lanes here); improves on `best`, whose distance is `ray.t_max`.
pub fn intersect_subtree(
    nodes: &[BvhNode],
    tris: &TriangleSoa,
    root: usize,
    ray: &mut Ray,
    best: &mut Option<Hit>,
    stats: &mut TraceStats,
) {
    let rb = RayBox::new(ray);
    let mut stack = [(0u32, 0f32); MAX_DEPTH];
    let mut sp = 0;
    let mut node = root;
    loop {
        let n = &nodes[node];
        if n.is_leaf() {
            intersect_leaf(tris, n.index as usize, n.count as usize, ray, best, stats, keep_all);
        } else {
            let (a, b) = (node + 1, n.index as usize);
            let (ta, tb) = (rb.slab(&nodes[a], ray.t_max), rb.slab(&nodes[b], ray.t_max));
            stats.node_tests += 2;
            let (near, t_near, far, t_far) = if ta <= tb { (a, ta, b, tb) } else { (b, tb, a, ta) };
            if t_near != f32::INFINITY {
                if t_far != f32::INFINITY {
                    stack[sp] = (far as u32, t_far);
                    sp += 1;
                }
                node = near;
                continue;
            }
        }
        // Pop the next subtree that can still hold a nearer hit (the same tolerance as the
        // box test, so a subtree is never dropped that the box test would keep).
        loop {
            if sp == 0 {
                return;
            }
            sp -= 1;
            let (next, t_entry) = stack[sp];
            if t_entry <= ray.t_max * BOX_INFLATE {
                node = next as usize;
                break;
            }
        }
    }
}

/// Whether any triangle blocks the ray within [t_min, t_max]; stops at the first one found.
pub fn occluded(nodes: &[BvhNode], tris: &TriangleSoa, ray: &Ray, stats: &mut TraceStats) -> bool {
    stats.node_tests += 1;
    if nodes.is_empty() || RayBox::new(ray).slab(&nodes[0], ray.t_max) == f32::INFINITY {
        return false;
    }
    occluded_subtree(nodes, tris, 0, ray, stats)
}

/// Whether any triangle of the subtree at `root` (box already tested) blocks the ray.
pub fn occluded_subtree(
    nodes: &[BvhNode],
    tris: &TriangleSoa,
    root: usize,
    ray: &Ray,
    stats: &mut TraceStats,
) -> bool {
    let rb = RayBox::new(ray);
    let mut stack = [0u32; MAX_DEPTH];
    let mut sp = 0;
    let mut node = root;
    loop {
        let n = &nodes[node];
        if n.is_leaf() {
            if occluded_leaf(tris, n.index as usize, n.count as usize, ray, stats, keep_all) {
                return true;
            }
        } else {
            let (a, b) = (node + 1, n.index as usize);
            let (ta, tb) = (rb.slab(&nodes[a], ray.t_max), rb.slab(&nodes[b], ray.t_max));
            stats.node_tests += 2;
            match (ta != f32::INFINITY, tb != f32::INFINITY) {
                (true, true) => {
                    stack[sp] = b as u32;
                    sp += 1;
                    node = a;
                    continue;
                }
                (true, false) => {
                    node = a;
                    continue;
                }
                (false, true) => {
                    node = b;
                    continue;
                }
                (false, false) => {}
            }
        }
        if sp == 0 {
            return false;
        }
        sp -= 1;
        node = stack[sp] as usize;
    }
}
