//! A 4-wide BVH for single rays, collapsed from the binary one: one SIMD slab test checks a
//! ray against four child boxes, and the tree is about half as deep. Packets keep the binary
//! tree (their lanes already fill the SIMD width). `Accel::intersect` and `occluded` use it
//! (measured against the binary tree in PERF.md). Closest hit visits entered children
//! nearest first; one or two entered children (the common cases) skip the general sort,
//! which alone made the 4-wide closest hit slower than the binary one.
//!
//! Leaves are the binary tree's leaves (the same triangle ranges of the SoA store), so leaf
//! tests, hit ordering and the conservative box test are exactly those of the binary
//! traversal and every ray gets the same hit.

use std::mem::MaybeUninit;

use wide::f32x4;

use super::node::BvhNode;
use super::packet::{safe_recip, BOX_INFLATE};
use super::traverse_single::{intersect_leaf_range, occluded_leaf_range};
use super::TraceStats;
use crate::math::{Hit, Ray};
use crate::simd::SimdF32;

/// Four child boxes in SoA form and what each child is.
#[repr(C, align(64))]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bvh4Node {
    /// min x, y, z of the four children, lane per child.
    pub min: [[f32; 4]; 3],
    pub max: [[f32; 4]; 3],
    /// Interior child: its node index. Leaf child: its first triangle.
    pub index: [u32; 4],
    /// 0: interior child; k > 0: a leaf of k triangles; `UNUSED`: no child in this slot
    /// (slots fill from the first; a node has 2 to 4 children, 1 only when the whole tree
    /// is one leaf).
    pub count: [u32; 4],
}

pub const UNUSED: u32 = u32::MAX;

const _: () = assert!(std::mem::size_of::<Bvh4Node>() == 128);

impl Bvh4Node {
    /// Number of children.
    #[inline(always)]
    pub fn children(&self) -> u32 {
        1 + (self.count[1] != UNUSED) as u32
            + (self.count[2] != UNUSED) as u32
            + (self.count[3] != UNUSED) as u32
    }
}

/// Collapses the binary tree: each 4-wide node takes a binary node's children and keeps
/// opening its largest-area interior child until it holds four.
pub fn collapse(bin: &[BvhNode]) -> Vec<Bvh4Node> {
    let mut out = Vec::with_capacity(bin.len() / 2 + 1);
    if !bin.is_empty() {
        collapse_node(bin, 0, &mut out);
    }
    out.shrink_to_fit();
    out
}

fn area(n: &BvhNode) -> f32 {
    let d = [n.max[0] - n.min[0], n.max[1] - n.min[1], n.max[2] - n.min[2]];
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

fn collapse_node(bin: &[BvhNode], root: usize, out: &mut Vec<Bvh4Node>) -> u32 {
    let at = out.len();
    out.push(Bvh4Node {
        min: [[0.0; 4]; 3],
        max: [[0.0; 4]; 3],
        index: [0; 4],
        count: [UNUSED; 4],
    });
    let mut kids: Vec<usize> =
        if bin[root].is_leaf() { vec![root] } else { vec![root + 1, bin[root].index as usize] };
    while kids.len() < 4 {
        let open = (0..kids.len())
            .filter(|&i| !bin[kids[i]].is_leaf())
            .max_by(|&a, &b| area(&bin[kids[a]]).total_cmp(&area(&bin[kids[b]])));
        let Some(i) = open else { break };
        let k = kids.remove(i);
        kids.insert(i, bin[k].index as usize);
        kids.insert(i, k + 1);
    }
    let mut node = out[at];
    for (j, &k) in kids.iter().enumerate() {
        let n = &bin[k];
        for axis in 0..3 {
            node.min[axis][j] = n.min[axis];
            node.max[axis][j] = n.max[axis];
        }
        if n.is_leaf() {
            node.index[j] = n.index;
            node.count[j] = n.count;
        } else {
            node.index[j] = collapse_node(bin, k, out);
            node.count[j] = 0;
        }
    }
    out[at] = node;
    at as u32
}

/// A ray prepared for 4-wide box tests.
struct Ray4 {
    o: [f32x4; 3],
    inv: [f32x4; 3],
    t_min: f32x4,
}

impl Ray4 {
    fn new(ray: &Ray) -> Ray4 {
        let o = ray.origin;
        Ray4 {
            o: [f32x4::splat(o.x), f32x4::splat(o.y), f32x4::splat(o.z)],
            inv: [
                f32x4::splat(safe_recip(ray.dir.x)),
                f32x4::splat(safe_recip(ray.dir.y)),
                f32x4::splat(safe_recip(ray.dir.z)),
            ],
            t_min: f32x4::splat(ray.t_min),
        }
    }

    /// Entry distances into the four boxes and the mask of boxes entered: lane by lane the
    /// operations of `traverse_single::RayBox::slab`.
    #[inline(always)]
    fn slab(&self, n: &Bvh4Node, t_max: f32) -> (u32, [f32; 4]) {
        let t = |b: &[f32; 4], k: usize| (f32x4::new(*b) - self.o[k]) * self.inv[k];
        let (x0, x1) = (t(&n.min[0], 0), t(&n.max[0], 0));
        let (y0, y1) = (t(&n.min[1], 1), t(&n.max[1], 1));
        let (z0, z1) = (t(&n.min[2], 2), t(&n.max[2], 2));
        let near = x0
            .fast_min(x1)
            .fast_max(y0.fast_min(y1))
            .fast_max(z0.fast_min(z1))
            .fast_max(self.t_min);
        let far = x0
            .fast_max(x1)
            .fast_min(y0.fast_max(y1))
            .fast_min(z0.fast_max(z1))
            .fast_min(f32x4::splat(t_max))
            * f32x4::splat(BOX_INFLATE);
        let valid = (1u32 << n.children()) - 1;
        (SimdF32::bitmask(near.simd_le(far)) & valid, near.to_array())
    }
}

/// Stack bound: up to three entries pushed per level of a tree at most `MAX_DEPTH` deep.
const STACK: usize = 3 * super::build::MAX_DEPTH;

/// A stack entry: node index or first triangle, triangle count (0: node), entry distance.
type Entry = (u32, u32, f32);

/// The hit children of a node, nearest first (at most four: insertion sort).
#[inline(always)]
fn sorted_hits(n: &Bvh4Node, bits: u32, near: &[f32; 4]) -> ([Entry; 4], usize) {
    let mut out = [(0u32, 0u32, 0f32); 4];
    let mut len = 0;
    let mut b = bits;
    while b != 0 {
        let j = b.trailing_zeros() as usize;
        b &= b - 1;
        let e = (n.index[j], n.count[j], near[j]);
        let mut i = len;
        while i > 0 && out[i - 1].2 > e.2 {
            out[i] = out[i - 1];
            i -= 1;
        }
        out[i] = e;
        len += 1;
    }
    (out, len)
}

/// Closest hit among the triangles; `ray.t_max` shrinks to the hit distance.
pub fn intersect(
    nodes: &[Bvh4Node],
    tris: &crate::geometry::TriangleSoa,
    ray: &mut Ray,
    stats: &mut TraceStats,
) -> Option<Hit> {
    let mut best = None;
    if nodes.is_empty() {
        stats.node_tests += 1;
        return None;
    }
    let r4 = Ray4::new(ray);
    // Uninitialised: zeroing 192 entries per ray cost more than the whole traversal of a
    // typical camera ray (measured, PERF.md).
    let mut stack = [const { MaybeUninit::<Entry>::uninit() }; STACK];
    let mut sp = 0;
    let mut cur: Entry = (0, 0, 0.0);
    loop {
        if cur.1 > 0 {
            intersect_leaf_range(tris, cur.0 as usize, cur.1 as usize, ray, &mut best, stats);
        } else {
            let n = &nodes[cur.0 as usize];
            let (bits, near) = r4.slab(n, ray.t_max);
            stats.node_tests += n.children() as u64;
            let entry = |j: usize| (n.index[j], n.count[j], near[j]);
            if bits != 0 && bits & (bits - 1) == 0 {
                // One child entered (the common case): no sorting.
                cur = entry(bits.trailing_zeros() as usize);
                continue;
            }
            if bits.count_ones() == 2 {
                let (a, b) = (
                    entry(bits.trailing_zeros() as usize),
                    entry(31 - bits.leading_zeros() as usize),
                );
                let (first, second) = if a.2 <= b.2 { (a, b) } else { (b, a) };
                stack[sp].write(second);
                sp += 1;
                cur = first;
                continue;
            }
            if bits != 0 {
                let (kids, len) = sorted_hits(n, bits, &near);
                for k in (1..len).rev() {
                    stack[sp].write(kids[k]);
                    sp += 1;
                }
                cur = kids[0];
                continue;
            }
        }
        loop {
            if sp == 0 {
                return best;
            }
            sp -= 1;
            // SAFETY: entries 0..sp (before the decrement) were all written by the pushes
            // above; sp only grows by writing stack[sp].
            let e = unsafe { stack[sp].assume_init() };
            if e.2 <= ray.t_max * BOX_INFLATE {
                cur = e;
                break;
            }
        }
    }
}

/// Whether any triangle blocks the ray within [t_min, t_max].
pub fn occluded(
    nodes: &[Bvh4Node],
    tris: &crate::geometry::TriangleSoa,
    ray: &Ray,
    stats: &mut TraceStats,
) -> bool {
    if nodes.is_empty() {
        stats.node_tests += 1;
        return false;
    }
    let r4 = Ray4::new(ray);
    let mut stack = [const { MaybeUninit::<(u32, u32)>::uninit() }; STACK];
    let mut sp = 0;
    let mut cur = (0u32, 0u32);
    loop {
        if cur.1 > 0 {
            if occluded_leaf_range(tris, cur.0 as usize, cur.1 as usize, ray, stats) {
                return true;
            }
        } else {
            let n = &nodes[cur.0 as usize];
            let (bits, _) = r4.slab(n, ray.t_max);
            stats.node_tests += n.children() as u64;
            if bits != 0 {
                let mut b = bits;
                let j = b.trailing_zeros() as usize;
                b &= b - 1;
                while b != 0 {
                    let k = b.trailing_zeros() as usize;
                    b &= b - 1;
                    stack[sp].write((n.index[k], n.count[k]));
                    sp += 1;
                }
                cur = (n.index[j], n.count[j]);
                continue;
            }
        }
        if sp == 0 {
            return false;
        }
        sp -= 1;
        // SAFETY: as in `intersect`: every entry below the old sp was written.
        cur = unsafe { stack[sp].assume_init() };
    }
}

#[cfg(test)]
mod tests {
    use crate::accel::{traverse_single, Accel, AccelKind, TraceStats};
    use crate::math::{Ray, Vec3};
    use crate::sampler::Pcg32;
    use crate::scene::Scene;

    /// The 4-wide tree answers every ray exactly as the binary tree does (closest hit and
    /// occlusion), on a random triangle soup and on a tree that is a single leaf.
    #[test]
    fn four_wide_equals_binary() {
        let mut rng = Pcg32::new(11, 4);
        let mut r = || rng.next_f32() * 2.0 - 1.0;
        for count in [1usize, 7, 3000] {
            let mut scene = Scene::default();
            for i in 0..count {
                let c = Vec3::new(r(), r(), r()) * 4.0;
                for _ in 0..3 {
                    scene.positions.push(c + Vec3::new(r(), r(), r()) * 0.3);
                }
                let b = 3 * i as u32;
                scene.triangles.push([b, b + 1, b + 2]);
                scene.triangle_materials.push(0);
            }
            scene.normals = vec![Vec3::Y; scene.positions.len()];
            let accel = Accel::build(&scene, AccelKind::Bvh);
            let mut stats = TraceStats::default();
            let mut hits = 0;
            for _ in 0..4000 {
                let o = Vec3::new(r(), r(), r()) * 6.0;
                // Towards a random triangle's first corner, give or take.
                let k = ((r().abs() * count as f32) as usize).min(count - 1);
                let d = scene.positions[3 * k] + Vec3::new(r(), r(), r()) * 0.2 - o;
                let ray = Ray::segment(o, d, 0.0, 0.5 + r().abs());
                let (mut a, mut b) = (ray, ray);
                let ha = traverse_single::intersect(&accel.nodes, &accel.tris, &mut a, &mut stats);
                let hb = super::intersect(&accel.nodes4, &accel.tris, &mut b, &mut stats);
                let key = |h: Option<crate::math::Hit>| h.map(|h| (h.t.to_bits(), h.prim));
                assert_eq!(key(ha), key(hb), "{count} triangles, {ray:?}");
                hits += ha.is_some() as usize;
                assert_eq!(
                    traverse_single::occluded(&accel.nodes, &accel.tris, &ray, &mut stats),
                    super::occluded(&accel.nodes4, &accel.tris, &ray, &mut stats)
                );
            }
            assert!(hits > 20, "{count} triangles: {hits} hits");
        }
    }
}
