//! One ray against the triangles of a leaf, 8 at a time (the 8-wide Möller-Trumbore test over
//! the SoA columns).
//!
//! Hits in front of the leaf box. Möller-Trumbore's rounding margin (`moller_trumbore`)
//! accepts hits a few ulps outside a triangle, so a hit can lie in front of its own leaf box.
//! Such a hit would be found or not depending on the visiting order: a leaf is culled when its
//! entry distance is beyond the best hit so far (`near > t_max * BOX_INFLATE`), and packets
//! and single rays reach leaves in different orders. So a hit at `t` in a leaf entered at
//! `near` counts only if `t * BOX_INFLATE >= near`, here and in the packet leaf test: a culled
//! leaf can then only hold hits farther than the best one, and the answer is the same in any
//! order. The check never drops a hit inside the box, whose distance is at least the entry
//! distance up to the rounding `BOX_INFLATE` already absorbs.

use wide::f32x8;

use super::packet::BOX_INFLATE;
use super::TraceStats;
use crate::geometry::moller_trumbore::{intersect_simd, splat3, V3};
use crate::geometry::triangles::{TriangleSoa, LANES};
use crate::math::{Hit, Ray};

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

/// Tests the leaf's triangles `first .. first + count`, which the ray entered at distance
/// `near`; shrinks `ray.t_max` and records the closest hit. Among hits at equal distance the
/// smallest prim wins, here and against the best so far, so the result does not depend on
/// the order in which leaves are visited.
#[inline]
pub(super) fn intersect_leaf(
    tris: &TriangleSoa,
    first: usize,
    count: usize,
    near: f32,
    ray: &mut Ray,
    best: &mut Option<Hit>,
    stats: &mut TraceStats,
) {
    let (o, d) = (splat3(ray.origin), splat3(ray.dir));
    let near_v = f32x8::splat(near);
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
        // Hits in front of the leaf box do not count (module comment).
        bits &= (t * f32x8::splat(BOX_INFLATE)).simd_ge(near_v).to_bitmask();
        if bits == 0 {
            continue;
        }
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

/// Whether any of the leaf's triangles `first .. first + count` blocks the ray. (Occlusion
/// needs no check of hits in front of the leaf box: its t_max never shrinks, so which leaves it enters does
/// not depend on the order.)
#[inline]
pub(super) fn occluded_leaf(
    tris: &TriangleSoa,
    first: usize,
    count: usize,
    ray: &Ray,
    stats: &mut TraceStats,
) -> bool {
    let (o, d) = (splat3(ray.origin), splat3(ray.dir));
    let (t_min, t_max) = (f32x8::splat(ray.t_min), f32x8::splat(ray.t_max));
    for at in (first..first + count).step_by(LANES) {
        stats.triangle_tests += (first + count - at).min(LANES) as u64;
        let valid = first_lanes(first + count - at);
        let (mask, ..) = intersect_simd(
            o,
            d,
            load3(&tris.v0, at),
            load3(&tris.e1, at),
            load3(&tris.e2, at),
            t_min,
            t_max,
            valid,
        );
        if mask.to_bitmask() != 0 {
            return true;
        }
    }
    false
}
