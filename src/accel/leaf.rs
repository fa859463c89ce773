//! One ray against the triangles of a leaf, 8 at a time (the 8-wide watertight test over a
//! triangle block's rows, taken in the ray's axis order).
//!
//! Hits in front of the leaf box. A hit's distance carries the rounding of the test
//! (`watertight`), so a hit can lie a few ulps in front of its own leaf box.
//! Such a hit would be found or not depending on the visiting order: a leaf is culled when its
//! entry distance is beyond the best hit so far (`near > t_max * BOX_INFLATE`), and packets
//! and single rays reach leaves in different orders. So a hit at `t` in a leaf entered at
//! `near` counts only if `t * BOX_INFLATE >= near`, here and in the packet leaf test: a culled
//! leaf can then only hold hits farther than the best one, and the answer is the same in any
//! order. The check never drops a hit inside the box, whose distance is at least the entry
//! distance up to the rounding `BOX_INFLATE` already absorbs.

use wide::f32x8;

use super::packet::{TriangleFrame, BOX_INFLATE};
use super::TraceStats;
use crate::geometry::triangles::{TriangleBlock, TriangleSoa, LANES};
use crate::geometry::watertight::{axes, intersect_simd, permute, Shear, V3};
use crate::math::{Hit, Ray};
use crate::simd::SimdF32;

/// Every lane on: the lanes outside the leaf are masked off after the test instead.
const ALL: f32x8 = f32x8::new([f32::from_bits(!0); LANES]);

/// What the triangle test needs of one ray, computed once per ray (the traversal keeps it
/// beside its box-test terms): the axis order, and the origin and shear in that order. Scalars,
/// broadcast where a leaf uses them.
#[derive(Clone, Copy, Debug)]
pub(super) struct LeafRay {
    axes: [usize; 3],
    origin: [f32; 3],
    shear: [f32; 3],
}

impl LeafRay {
    #[inline(always)]
    pub(super) fn new(ray: &Ray) -> LeafRay {
        let axes = axes(ray.dir);
        let s = Shear::of(permute(ray.dir, axes), 1.0);
        let o = permute(ray.origin, axes);
        LeafRay { axes, origin: [o.x, o.y, o.z], shear: [s.sx, s.sy, s.sz] }
    }

    /// `LeafRay::new` of lane `i` of the packet whose terms `f` holds: the frame computes the
    /// same axis order, permuted origin and shear lane by lane, so the bits are the same, and a
    /// lane handed to single-ray code skips its own division.
    #[inline(always)]
    pub(super) fn of_lane<V: SimdF32>(f: &TriangleFrame<V>, i: usize) -> LeafRay {
        let (o, s) = (&f.origin_in_axes, &f.shear);
        LeafRay {
            axes: f.axes.lane(i),
            origin: [o.x.lane(i), o.y.lane(i), o.z.lane(i)],
            shear: [s.sx.lane(i), s.sy.lane(i), s.sz.lane(i)],
        }
    }

    /// Rows x, y, z of a block's vertex in the ray's axis order.
    #[inline(always)]
    fn rows(&self, r: &[[f32; LANES]; 3]) -> V3<f32x8> {
        let [kx, ky, kz] = self.axes;
        V3 { x: f32x8::new(r[kx]), y: f32x8::new(r[ky]), z: f32x8::new(r[kz]) }
    }
}

/// The ray against all eight slots of `block` within [t_min, t_max]: hit mask, t, u, v.
/// Lanes outside the leaf are masked off by the caller.
#[inline(always)]
fn test_block(
    ray: &LeafRay,
    block: &TriangleBlock,
    t_min: f32,
    t_max: f32,
) -> (f32x8, f32x8, f32x8, f32x8) {
    let tri = [ray.rows(&block.v0), ray.rows(&block.v1), ray.rows(&block.v2)];
    let [ox, oy, oz] = ray.origin.map(f32x8::splat);
    let [sx, sy, sz] = ray.shear.map(f32x8::splat);
    let (origin, shear) = (V3 { x: ox, y: oy, z: oz }, Shear { sx, sy, sz });
    intersect_simd(origin, &shear, tri, f32x8::splat(t_min), f32x8::splat(t_max), ALL)
}

/// Calls `test(block, lanes)` for each block the slots `first .. first + count` occupy, with
/// the bit mask of their lanes in it, until it returns true; returns whether one did. A leaf
/// of at most `LANES` triangles lies in one block (`build::pack_leaves`).
#[inline(always)]
fn leaf_blocks(
    tris: &TriangleSoa,
    first: usize,
    count: usize,
    mut test: impl FnMut(&TriangleBlock, u32) -> bool,
) -> bool {
    let end = first + count;
    let mut at = first;
    while at < end {
        let b = at / LANES;
        let (lo, hi) = (at % LANES, (end - b * LANES).min(LANES));
        let lanes = ((1u32 << hi) - 1) & !((1u32 << lo) - 1);
        if test(&tris.blocks()[b], lanes) {
            return true;
        }
        at = (b + 1) * LANES;
    }
    false
}

/// Tests the leaf's triangles `first .. first + count`, which the ray entered at distance
/// `near`; shrinks `ray.t_max` and records the closest hit. Among hits at equal distance the
/// smallest prim wins, here and against the best so far, so the result does not depend on
/// the order in which leaves are visited.
#[inline]
#[allow(clippy::too_many_arguments)] // the leaf (range, entry distance), the ray twice (as the test takes it, and its interval), its best hit and the counters
pub(super) fn intersect_leaf(
    tris: &TriangleSoa,
    first: usize,
    count: usize,
    near: f32,
    leaf_ray: &LeafRay,
    ray: &mut Ray,
    best: &mut Option<Hit>,
    stats: &mut TraceStats,
) {
    let near_v = f32x8::splat(near);
    stats.triangle_tests += count as u64;
    leaf_blocks(tris, first, count, |block, lanes| {
        let (mask, t, u, v) = test_block(leaf_ray, block, ray.t_min, ray.t_max);
        let mut bits = mask.to_bitmask() & lanes;
        if bits == 0 {
            return false;
        }
        // Hits in front of the leaf box do not count (module comment).
        bits &= (t * f32x8::splat(BOX_INFLATE)).simd_ge(near_v).to_bitmask();
        if bits == 0 {
            return false;
        }
        let ts = t.to_array();
        let prims = &block.prim;
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
                return false;
            }
        }
        ray.t_max = ts[k];
        *best = Some(Hit { t: ts[k], u: u.to_array()[k], v: v.to_array()[k], prim: prims[k] });
        false
    });
}

/// Whether any of the leaf's triangles `first .. first + count` blocks the ray. (Occlusion
/// needs no check of hits in front of the leaf box: its t_max never shrinks, so which leaves
/// it enters does not depend on the order.)
#[inline]
pub(super) fn occluded_leaf(
    tris: &TriangleSoa,
    first: usize,
    count: usize,
    leaf_ray: &LeafRay,
    ray: &Ray,
    stats: &mut TraceStats,
) -> bool {
    leaf_blocks(tris, first, count, |block, lanes| {
        stats.triangle_tests += lanes.count_ones() as u64;
        let (mask, ..) = test_block(leaf_ray, block, ray.t_min, ray.t_max);
        mask.to_bitmask() & lanes != 0
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::packet::RayPacket;
    use crate::accel::traverse_single::WideRay;
    use crate::accel::wide_node::WideNode;
    use crate::math::Vec3;
    use crate::sampler::Pcg32;
    use wide::{f32x4, f32x8};

    /// A lane's terms read out of its packet (`LeafRay::of_lane`, `WideRay::of_lane`) are the
    /// terms its ray computes alone, bit for bit: the same triangle-test terms, and the same
    /// entry distances and masks from every box test, zero and tiny direction components too.
    fn lane_terms_equal<V: SimdF32>() {
        let mut rng = Pcg32::new(5, 9);
        let mut r = || rng.next_f32() * 2.0 - 1.0;
        let mut n = WideNode::EMPTY_NODE;
        for i in 0..8 {
            let (c, h) = (Vec3::new(r(), r(), r()), Vec3::new(r(), r(), r()).abs() * 0.5);
            n.set_child(i, (c - h).into(), (c + h).into(), i as u32 + 1);
        }
        let mut entered = 0;
        for case in 0..500 {
            let rays: Vec<Ray> = (0..V::W)
                .map(|k| {
                    let mut d = Vec3::new(r(), r(), r());
                    match (case + k) % 5 {
                        0 => d.x = 0.0,
                        1 => d.y = -0.0,
                        2 => d.z = 1e-20,
                        _ => {}
                    }
                    let o = Vec3::new(r(), r(), r()) * 3.0;
                    Ray::segment(o, d, 0.01 * r().abs(), 2.0 + r())
                })
                .collect();
            let p = RayPacket::<V>::from_rays(&rays);
            let f = TriangleFrame::of(&p);
            for (i, ray) in rays.iter().enumerate() {
                let leaf = LeafRay::of_lane(&f, i);
                assert_eq!(format!("{leaf:?}"), format!("{:?}", LeafRay::new(ray)), "case {case}");
                let (lane, alone) = (WideRay::of_lane(&p, i, leaf), WideRay::new(ray));
                let ((t_lane, m_lane), (t_alone, m_alone)) =
                    (lane.slab(&n, ray.t_max), alone.slab(&n, ray.t_max));
                assert_eq!(m_lane, m_alone, "case {case} lane {i}");
                let bits = |t: [f32; 8]| t.map(f32::to_bits);
                assert_eq!(bits(t_lane.to_array()), bits(t_alone.to_array()), "case {case}");
                entered += m_alone.count_ones();
            }
        }
        assert!(entered > 100 * V::W as u32, "{entered}");
    }

    #[test]
    fn packet_lane_terms_equal_the_single_ray_terms() {
        lane_terms_equal::<f32x4>();
        lane_terms_equal::<f32x8>();
        lane_terms_equal::<crate::simd::F32x16>();
    }
}
