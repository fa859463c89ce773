//! Möller-Trumbore ray-triangle intersection with the [t_min, t_max] convention: a hit has
//! t_min <= t <= t_max and barycentrics (u, v of v1 and v2) inside the triangle up to a
//! rounding-error margin: u >= -mu, v >= -mv, u + v <= 1 + mu + mv.
//!
//! Watertightness. Computed in f32, the barycentrics of a point on an edge come out a few
//! ulps either side of 0 (or of u + v = 1), independently for the two triangles sharing the
//! edge: when both land outside, the ray slips through the mesh. `tests/watertight.rs` aims
//! rays exactly at the shared edges and vertices of closed meshes; with the exact test 2-3 %
//! of them leaked. The error of u = (s.p) / det is bounded by a small multiple of
//! eps (|s|.|p|) / |det| (each product and sum rounds once; pbrt-v4 6.8), and likewise
//! eps (|d|.|q|) / |det| for v; it grows with the distance of the ray origin from the
//! triangle (|s|), which a fixed slack cannot follow (a fixed 32 ulps still leaked rays from
//! far origins). So each side is widened by its own bound: mu = BARY_EPS (|s|.|p|) / |det|,
//! mv = BARY_EPS (|d|.|q|) / |det|, with BARY_EPS = 8 ulps (1 ulp still leaked 2 of 66,564
//! rays). Adjacent triangles overlap by that sliver, so a ray at an edge hits one or both
//! (the nearer, then smaller prim, wins). A truly watertight test (Woop et al. 2013) would
//! need the three vertices instead of v0 and two edges, and a per-ray shear.
//!
//! One arithmetic core, generic over the lane type, serves the scalar test, one ray against 8
//! triangles, and W rays (W = 4, 8 or 16) against one triangle. The same operations in the same order give
//! bit-identical t, u, v in every lane (no fused multiply-add in any of them), which the
//! tests check lane by lane.

use std::ops::{Add, Mul, Sub};

use crate::simd::{Arith, SimdF32};

/// Three lanes-wide coordinates.
#[derive(Clone, Copy, Debug)]
pub struct V3<T> {
    /// The x coordinates, one per lane.
    pub x: T,
    /// The y coordinates, one per lane.
    pub y: T,
    /// The z coordinates, one per lane.
    pub z: T,
}

impl<T: Copy + Add<Output = T> + Sub<Output = T> + Mul<Output = T>> V3<T> {
    /// The cross product `self x b`, lane by lane.
    #[inline(always)]
    pub fn cross(self, b: V3<T>) -> V3<T> {
        V3 {
            x: self.y * b.z - self.z * b.y,
            y: self.z * b.x - self.x * b.z,
            z: self.x * b.y - self.y * b.x,
        }
    }
    /// The dot product, lane by lane (no fused multiply-add).
    #[inline(always)]
    pub fn dot(self, b: V3<T>) -> T {
        self.x * b.x + self.y * b.y + self.z * b.z
    }
    /// The difference `self - b`, lane by lane.
    #[inline(always)]
    pub fn minus(self, b: V3<T>) -> V3<T> {
        V3 { x: self.x - b.x, y: self.y - b.y, z: self.z - b.z }
    }
}

/// Slack on the barycentric test, relative to the rounding-error scale of each numerator
/// (see the module comment).
pub(crate) const BARY_EPS: f32 = 8.0 * f32::EPSILON;

impl<T: Arith> V3<T> {
    #[inline(always)]
    fn abs(self) -> V3<T> {
        V3 { x: self.x.abs(), y: self.y.abs(), z: self.z.abs() }
    }
}

/// det, the unnormalised u, v, t numerators (hit iff det != 0 and the ratios qualify), and
/// the scales of the rounding errors of the u and v numerators: |s|.|p| and |d|.|q|.
#[inline(always)]
fn core<T: Arith>(o: V3<T>, d: V3<T>, v0: V3<T>, e1: V3<T>, e2: V3<T>) -> [T; 6] {
    let p = d.cross(e2);
    let det = e1.dot(p);
    let s = o.minus(v0);
    let q = s.cross(e1);
    [det, s.dot(p), d.dot(q), e2.dot(q), s.abs().dot(p.abs()), d.abs().dot(q.abs())]
}

/// Scalar test. Returns (t, u, v) of a hit within [t_min, t_max].
#[inline]
pub fn intersect1(
    o: V3<f32>,
    d: V3<f32>,
    v0: V3<f32>,
    e1: V3<f32>,
    e2: V3<f32>,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    let [det, un, vn, tn, eu, ev] = core(o, d, v0, e1, e2);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let (u, v, t) = (un * inv, vn * inv, tn * inv);
    let k = inv.abs() * BARY_EPS;
    let (mu, mv) = (eu * k, ev * k);
    (u >= -mu && v >= -mv && u + v <= 1.0 + (mu + mv) && t >= t_min && t <= t_max)
        .then_some((t, u, v))
}

/// W lanes at once (8 triangles and one ray broadcast, or W rays and one triangle broadcast).
/// Returns the hit mask and t, u, v per lane; `valid` masks out lanes to ignore.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // one SIMD kernel: the five vectors of the test, the interval and the lane mask
pub(crate) fn intersect_simd<V: SimdF32>(
    o: V3<V>,
    d: V3<V>,
    v0: V3<V>,
    e1: V3<V>,
    e2: V3<V>,
    t_min: V,
    t_max: V,
    valid: V,
) -> (V, V, V, V) {
    let [det, un, vn, tn, eu, ev] = core(o, d, v0, e1, e2);
    let one = V::splat(1.0);
    let inv = one / det;
    let (u, v, t) = (un * inv, vn * inv, tn * inv);
    let k = inv.abs() * V::splat(BARY_EPS);
    let (mu, mv) = (eu * k, ev * k);
    let zero = V::splat(0.0);
    let hit = valid
        & det.simd_ne(zero)
        & u.simd_ge(zero - mu)
        & v.simd_ge(zero - mv)
        & (u + v).simd_le(one + (mu + mv))
        & t.simd_ge(t_min)
        & t.simd_le(t_max);
    (hit, t, u, v)
}

/// Broadcast a scalar vector to all lanes.
#[inline(always)]
pub(crate) fn splat3<V: SimdF32>(v: glam::Vec3) -> V3<V> {
    V3 { x: V::splat(v.x), y: V::splat(v.y), z: V::splat(v.z) }
}

/// A scalar vector as a one-lane `V3` (for [`intersect1`]).
#[inline(always)]
pub fn scalar3(v: glam::Vec3) -> V3<f32> {
    V3 { x: v.x, y: v.y, z: v.z }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::Pcg32;
    use glam::Vec3;
    use wide::f32x8;

    fn lane(v: f32x8, i: usize) -> f32 {
        v.to_array()[i]
    }

    /// Random rays against random, degenerate and parallel triangles: every lane of the 8-wide
    /// test equals the scalar test exactly.
    #[test]
    fn simd_lanes_equal_the_scalar_test() {
        let mut rng = Pcg32::new(9, 9);
        let mut r = || rng.next_f32() * 2.0 - 1.0;
        let mut hits = 0;
        for case in 0..20_000 {
            let o = Vec3::new(r(), r(), r() - 3.0);
            let mut d = Vec3::new(r() * 0.3, r() * 0.3, 1.0);
            if case % 7 == 0 {
                d.x = 0.0; // zero direction components
            }
            let tris: Vec<[Vec3; 3]> = (0..8)
                .map(|k| {
                    let a = Vec3::new(r(), r(), r());
                    match (case + k) % 5 {
                        0 => [a, a, a],                                          // zero area
                        1 => [a, a + Vec3::X, a + 2.0 * Vec3::X],                // collinear
                        2 => [a, a + Vec3::X, a + Vec3::new(0.0, 0.0, 1.0) + d], // parallel-ish
                        _ => [a, Vec3::new(r(), r(), r()), Vec3::new(r(), r(), r())],
                    }
                })
                .collect();
            let (t_min, t_max) = (0.5, 3.5);
            let col =
                |f: &dyn Fn(&[Vec3; 3]) -> f32| f32x8::new(std::array::from_fn(|k| f(&tris[k])));
            let v0 = V3 { x: col(&|t| t[0].x), y: col(&|t| t[0].y), z: col(&|t| t[0].z) };
            let e1 = V3 {
                x: col(&|t| t[1].x - t[0].x),
                y: col(&|t| t[1].y - t[0].y),
                z: col(&|t| t[1].z - t[0].z),
            };
            let e2 = V3 {
                x: col(&|t| t[2].x - t[0].x),
                y: col(&|t| t[2].y - t[0].y),
                z: col(&|t| t[2].z - t[0].z),
            };
            let (mask, t, u, v) = intersect_simd(
                splat3(o),
                splat3(d),
                v0,
                e1,
                e2,
                f32x8::splat(t_min),
                f32x8::splat(t_max),
                f32x8::splat(f32::from_bits(!0)),
            );
            let mask = mask.to_bitmask();
            for (k, tri) in tris.iter().enumerate() {
                let s = intersect1(
                    scalar3(o),
                    scalar3(d),
                    scalar3(tri[0]),
                    scalar3(tri[1] - tri[0]),
                    scalar3(tri[2] - tri[0]),
                    t_min,
                    t_max,
                );
                assert_eq!(s.is_some(), mask & (1 << k) != 0, "case {case} lane {k}");
                if let Some((ts, us, vs)) = s {
                    hits += 1;
                    assert_eq!(
                        (ts.to_bits(), us.to_bits(), vs.to_bits()),
                        (lane(t, k).to_bits(), lane(u, k).to_bits(), lane(v, k).to_bits())
                    );
                }
            }
        }
        assert!(hits > 1000, "the test must exercise hits: {hits}");
    }

    /// W rays against one broadcast triangle (the packet leaf test), at every width: every
    /// lane equals the scalar test exactly.
    fn rays_vs_one_triangle<V: SimdF32>() -> usize {
        let mut rng = Pcg32::new(5, V::W as u64);
        let mut r = || rng.next_f32() * 2.0 - 1.0;
        let mut hits = 0;
        for case in 0..5_000 {
            let tri =
                [Vec3::new(r(), r(), r()), Vec3::new(r(), r(), r()), Vec3::new(r(), r(), r())];
            let rays: Vec<(Vec3, Vec3)> = (0..V::W)
                .map(|k| {
                    let o = Vec3::new(r(), r(), r() - 3.0);
                    let mut d = Vec3::new(r() * 0.3, r() * 0.3, 1.0);
                    if (case + k) % 5 == 0 {
                        d.y = 0.0;
                    }
                    (o, d)
                })
                .collect();
            let col = |f: &dyn Fn(&(Vec3, Vec3)) -> f32| {
                let a: Vec<f32> = rays.iter().map(f).collect();
                V::load(&a)
            };
            let o = V3 { x: col(&|r| r.0.x), y: col(&|r| r.0.y), z: col(&|r| r.0.z) };
            let d = V3 { x: col(&|r| r.1.x), y: col(&|r| r.1.y), z: col(&|r| r.1.z) };
            let (mask, t, u, v) = intersect_simd(
                o,
                d,
                splat3(tri[0]),
                splat3(tri[1] - tri[0]),
                splat3(tri[2] - tri[0]),
                V::splat(0.5),
                V::splat(3.5),
                V::first_lanes(V::W),
            );
            for (k, ray) in rays.iter().enumerate() {
                let s = intersect1(
                    scalar3(ray.0),
                    scalar3(ray.1),
                    scalar3(tri[0]),
                    scalar3(tri[1] - tri[0]),
                    scalar3(tri[2] - tri[0]),
                    0.5,
                    3.5,
                );
                assert_eq!(s.is_some(), mask.bitmask() & (1 << k) != 0, "case {case} lane {k}");
                if let Some((ts, us, vs)) = s {
                    hits += 1;
                    assert_eq!(
                        (ts.to_bits(), us.to_bits(), vs.to_bits()),
                        (t.lane(k).to_bits(), u.lane(k).to_bits(), v.lane(k).to_bits())
                    );
                }
            }
        }
        hits
    }

    #[test]
    fn packet_lanes_equal_the_scalar_test() {
        assert!(rays_vs_one_triangle::<wide::f32x4>() > 500);
        assert!(rays_vs_one_triangle::<f32x8>() > 1000);
        assert!(rays_vs_one_triangle::<crate::simd::F32x16>() > 2000);
    }

    #[test]
    fn interval_ends_are_inclusive_and_parallel_rays_miss() {
        let tri = [Vec3::new(-1.0, -1.0, 2.0), Vec3::new(1.0, -1.0, 2.0), Vec3::new(0.0, 1.0, 2.0)];
        let (v0, e1, e2) = (scalar3(tri[0]), scalar3(tri[1] - tri[0]), scalar3(tri[2] - tri[0]));
        let o = scalar3(Vec3::ZERO);
        let d = scalar3(Vec3::Z);
        assert_eq!(intersect1(o, d, v0, e1, e2, 2.0, 2.0).map(|h| h.0), Some(2.0));
        assert!(intersect1(o, d, v0, e1, e2, 0.0, 1.999).is_none());
        assert!(intersect1(o, d, v0, e1, e2, 2.001, 9.0).is_none());
        // A ray in the triangle's plane direction never hits (det = 0).
        assert!(intersect1(
            scalar3(Vec3::new(0.0, 0.0, 2.0)),
            scalar3(Vec3::X),
            v0,
            e1,
            e2,
            0.0,
            9.0
        )
        .is_none());
    }
}
