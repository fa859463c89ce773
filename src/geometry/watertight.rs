//! The watertight ray-triangle test of Woop, Benthin and Wald (2013), with the
//! [t_min, t_max] convention: a hit has t_min <= t <= t_max and lies inside the triangle or on
//! its boundary, with barycentrics u, v (of v1 and v2).
//!
//! The test. Each ray takes its dominant axis as kz and the next two, cyclically, as kx and ky
//! ([`axes`]), and the shear that maps its direction onto the kz axis ([`Shear`]). A triangle's
//! vertices, taken relative to the origin, permuted and sheared, project onto the plane across
//! the ray, where the ray is the point (0, 0). There the three edge functions (twice the signed
//! areas of the sub-triangles the ray cuts) give the barycentrics: the ray hits iff none is
//! negative or none is positive, and their sum is not zero.
//!
//! Why it is watertight. Each edge function is computed from its edge's two projected vertices
//! alone, as `a.x * b.y - a.y * b.x`, and each projected vertex from the stored vertex alone;
//! swapping the two vertices negates the result exactly (products commute, and `p - q` is
//! exactly `-(q - p)`), so two triangles sharing an edge see one value with opposite signs: a
//! ray exactly on the edge hits both, a ray beside it exactly one. No slack is needed, so no
//! hit lies outside its triangle by more than the rounding of the ray's own projection.
//!
//! Möller-Trumbore (the write-up's test, ours until PERF.md "Watertight triangles") computes
//! each triangle's barycentrics from its own first vertex and edges, so the two triangles at an
//! edge round independently; rays leaked through meshes unless each side was widened by its
//! rounding bound, eps (|s|.|p|) / |det|, which grows with the distance of the origin over the
//! triangle's size. On the 1M tori, seen from 50 units, that slack reached 0.9 % of a triangle:
//! false hits, and one more hit than Embree's.
//!
//! One arithmetic core, generic over the lane type, serves the scalar test, one ray against 8
//! triangles, and W rays (W = 4, 8 or 16) against one triangle. The same operations in the same
//! order (no fused multiply-add, same permutation) give bit-identical t, u, v in every lane,
//! which the tests check lane by lane.

use std::ops::{Add, Mul, Sub};

use glam::Vec3;

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

/// The ray's dominant axis: the largest |d| component, the earlier axis only when strictly
/// larger (the rule `PacketAxes` applies lane by lane). Without branches: incoherent rays
/// would mispredict them.
#[inline(always)]
pub fn dominant_axis(d: Vec3) -> usize {
    let a = d.abs();
    let x_beats_y = a.x > a.y;
    let is_x = x_beats_y & (a.x > a.z);
    let is_y = !x_beats_y & (a.y > a.z);
    axis_of(is_x, is_y)
}

/// The dominant axis from the two comparisons' outcomes: x, else y, else z.
#[inline(always)]
fn axis_of(is_x: bool, is_y: bool) -> usize {
    2 - 2 * is_x as usize - is_y as usize
}

/// [kx, ky, kz] for the dominant axis `kz`: it last, the other two after it cyclically.
#[inline(always)]
fn order_ending_in(kz: usize) -> [usize; 3] {
    [(kz + 1) % 3, (kz + 2) % 3, kz]
}

/// [kx, ky, kz]: the dominant axis last, the other two after it cyclically.
#[inline(always)]
pub fn axes(d: Vec3) -> [usize; 3] {
    order_ending_in(dominant_axis(d))
}

/// `v` with its components in the order `k` ([kx, ky, kz]).
#[inline(always)]
pub fn permute(v: Vec3, k: [usize; 3]) -> V3<f32> {
    let c = v.to_array();
    V3 { x: c[k[0]], y: c[k[1]], z: c[k[2]] }
}

/// A ray's shear, from its direction permuted by [`axes`]: x -= sx z and y -= sy z make the
/// direction (0, 0, d_kz); sz = 1 / d_kz scales the projected heights to distances.
#[derive(Clone, Copy, Debug)]
pub struct Shear<T> {
    /// `d[kx] / d[kz]`.
    pub sx: T,
    /// `d[ky] / d[kz]`.
    pub sy: T,
    /// `1 / d[kz]`.
    pub sz: T,
}

impl<T: Arith + std::ops::Div<Output = T>> Shear<T> {
    /// The shear of a permuted direction (one reciprocal, then products, in every lane type).
    #[inline(always)]
    pub fn of(d: V3<T>, one: T) -> Shear<T> {
        let sz = one / d.z;
        Shear { sx: d.x * sz, sy: d.y * sz, sz }
    }
}

/// The edge functions (U of v0, V of v1, W of v2), their sum det, and det * t, from the
/// permuted vertices relative to the origin.
#[inline(always)]
fn core<T: Arith>(a: V3<T>, b: V3<T>, c: V3<T>, s: &Shear<T>) -> [T; 5] {
    let (ax, ay) = (a.x - s.sx * a.z, a.y - s.sy * a.z);
    let (bx, by) = (b.x - s.sx * b.z, b.y - s.sy * b.z);
    let (cx, cy) = (c.x - s.sx * c.z, c.y - s.sy * c.z);
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let det = u + v + w;
    let t_det = (u * a.z + v * b.z + w * c.z) * s.sz;
    [u, v, w, det, t_det]
}

/// Scalar test of the ray (o, d) against the triangle `tri`. Returns (t, u, v) of a hit within
/// [t_min, t_max].
#[inline]
pub fn intersect1(
    o: Vec3,
    d: Vec3,
    tri: [Vec3; 3],
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32, f32)> {
    let k = axes(d);
    let shear = Shear::of(permute(d, k), 1.0);
    let op = permute(o, k);
    let [a, b, c] = tri.map(|v| permute(v, k).minus(op));
    let [u, v, w, det, t_det] = core(a, b, c, &shear);
    let inside = (u >= 0.0 && v >= 0.0 && w >= 0.0) || (u <= 0.0 && v <= 0.0 && w <= 0.0);
    if !inside || det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let (t, u, v) = (t_det * inv, v * inv, w * inv);
    (t >= t_min && t <= t_max).then_some((t, u, v))
}

/// W lanes at once (8 triangles and one ray broadcast, or W rays and one triangle broadcast):
/// `o` the permuted origins, `tri` the permuted vertices (in each lane's own order).
/// Returns the hit mask and t, u, v per lane; `valid` masks out lanes to ignore.
#[inline(always)]
pub(crate) fn intersect_simd<V: SimdF32>(
    o: V3<V>,
    shear: &Shear<V>,
    tri: [V3<V>; 3],
    t_min: V,
    t_max: V,
    valid: V,
) -> (V, V, V, V) {
    edge_test(o, shear, tri, valid).hit(t_min, t_max)
}

/// The first half of [`intersect_simd`]: which lanes the triangle's edges enclose, before the
/// one division that t, u and v need. A caller that tests many lanes against one triangle
/// skips that division when no lane is left (`EdgeTest::candidates`).
#[inline(always)]
pub(crate) fn edge_test<V: SimdF32>(
    o: V3<V>,
    shear: &Shear<V>,
    tri: [V3<V>; 3],
    valid: V,
) -> EdgeTest<V> {
    let [a, b, c] = tri.map(|v| v.minus(o));
    let [u, v, w, det, t_det] = core(a, b, c, shear);
    let zero = V::splat(0.0);
    // No edge function negative, or none positive. (A NaN in any of them makes t NaN, which
    // the interval test rejects, so how min and max treat NaN does not matter.)
    let inside = u.fast_min(v).fast_min(w).simd_ge(zero) | u.fast_max(v).fast_max(w).simd_le(zero);
    EdgeTest { candidates: valid & inside & det.simd_ne(zero), v, w, det, t_det }
}

/// What [`edge_test`] found, per lane.
#[derive(Clone, Copy)]
pub(crate) struct EdgeTest<V> {
    /// Lanes inside all three edges, with a nonzero determinant: the only ones that can hit.
    pub candidates: V,
    v: V,
    w: V,
    det: V,
    t_det: V,
}

impl<V: SimdF32> EdgeTest<V> {
    /// The hit mask (the candidates whose t lies in [t_min, t_max]) and t, u, v per lane.
    #[inline(always)]
    pub fn hit(&self, t_min: V, t_max: V) -> (V, V, V, V) {
        let inv = V::splat(1.0) / self.det;
        let (t, u, v) = (self.t_det * inv, self.v * inv, self.w * inv);
        (self.candidates & t.simd_ge(t_min) & t.simd_le(t_max), t, u, v)
    }
}

/// Each lane's [`axes`] as masks, to permute lane vectors: `is_x` where kz = x, `is_y` where
/// kz = y; `uniform` is the axis order when every lane shares it (then a broadcast point is
/// permuted by picking its components, for free).
#[derive(Clone, Copy, Debug)]
pub struct PacketAxes<V> {
    is_x: V,
    is_y: V,
    /// [kx, ky, kz] shared by every lane, if they share it.
    pub uniform: Option<[usize; 3]>,
}

impl<V: SimdF32> PacketAxes<V> {
    /// The axes of the directions `d` in the lanes `filled` (other lanes follow but do not
    /// count for `uniform`).
    #[inline]
    pub fn of(d: &V3<V>, filled: u32) -> PacketAxes<V> {
        let (ax, ay, az) = (d.x.abs(), d.y.abs(), d.z.abs());
        let x_beats_y = ay.simd_lt(ax);
        let is_x = x_beats_y & az.simd_lt(ax);
        let is_y = V::select(x_beats_y, V::splat(0.0), az.simd_lt(ay));
        let (bx, by) = (is_x.bitmask() & filled, is_y.bitmask() & filled);
        let uniform = match (bx, by) {
            (0, 0) => Some([0, 1, 2]),
            (x, 0) if x == filled => Some([1, 2, 0]),
            (0, y) if y == filled => Some([2, 0, 1]),
            _ => None,
        };
        PacketAxes { is_x, is_y, uniform }
    }

    /// `v` in each lane's order [kx, ky, kz].
    #[inline(always)]
    pub fn permute(&self, v: V3<V>) -> V3<V> {
        let pick = |for_x: V, for_y: V, for_z: V| {
            V::select(self.is_x, for_x, V::select(self.is_y, for_y, for_z))
        };
        // kz = x: (y, z, x); kz = y: (z, x, y); kz = z: (x, y, z).
        V3 { x: pick(v.y, v.z, v.x), y: pick(v.z, v.x, v.y), z: pick(v.x, v.y, v.z) }
    }

    /// Lane `i`'s [kx, ky, kz]: what [`axes`] gives for that lane's direction (the same
    /// comparisons, so the same choice).
    #[inline(always)]
    pub fn lane(&self, i: usize) -> [usize; 3] {
        let bit = |v: V| (v.bitmask() >> i) & 1 != 0;
        order_ending_in(axis_of(bit(self.is_x), bit(self.is_y)))
    }

    /// A point broadcast to every lane, in each lane's order.
    #[inline(always)]
    pub fn permute_splat(&self, p: Vec3) -> V3<V> {
        match self.uniform {
            Some(k) => broadcast(permute(p, k)),
            None => self.permute(splat3(p)),
        }
    }
}

/// Broadcast a scalar vector to all lanes.
#[inline(always)]
pub(crate) fn splat3<V: SimdF32>(v: Vec3) -> V3<V> {
    broadcast(scalar3(v))
}

/// Broadcast a one-lane `V3` to all lanes.
#[inline(always)]
pub(crate) fn broadcast<V: SimdF32>(v: V3<f32>) -> V3<V> {
    V3 { x: V::splat(v.x), y: V::splat(v.y), z: V::splat(v.z) }
}

/// A scalar vector as a one-lane `V3`.
#[inline(always)]
pub fn scalar3(v: Vec3) -> V3<f32> {
    V3 { x: v.x, y: v.y, z: v.z }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::Pcg32;
    use wide::f32x8;

    fn lane(v: f32x8, i: usize) -> f32 {
        v.to_array()[i]
    }

    /// The leaf test's inputs: one ray broadcast, eight triangles in rows, both permuted by
    /// the ray's axes.
    fn one_ray_eight_triangles(o: Vec3, d: Vec3, tris: &[[Vec3; 3]]) -> (u32, f32x8, f32x8, f32x8) {
        let k = axes(d);
        let col =
            |c: usize, f: &dyn Fn(Vec3) -> f32| f32x8::new(std::array::from_fn(|j| f(tris[j][c])));
        let vertex = |c: usize| V3 {
            x: col(c, &|v| v[k[0]]),
            y: col(c, &|v| v[k[1]]),
            z: col(c, &|v| v[k[2]]),
        };
        let shear = Shear::of(broadcast(permute(d, k)), f32x8::splat(1.0));
        let (mask, t, u, v) = intersect_simd(
            broadcast(permute(o, k)),
            &shear,
            [vertex(0), vertex(1), vertex(2)],
            f32x8::splat(0.5),
            f32x8::splat(3.5),
            f32x8::splat(f32::from_bits(!0)),
        );
        (mask.to_bitmask(), t, u, v)
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
            if case % 3 == 0 {
                d = Vec3::new(d.z, d.x, d.y); // other dominant axes
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
            let (mask, t, u, v) = one_ray_eight_triangles(o, d, &tris);
            for (k, tri) in tris.iter().enumerate() {
                let s = intersect1(o, d, *tri, 0.5, 3.5);
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

    /// W rays against one broadcast triangle (the packet leaf test), at every width, with the
    /// lanes' dominant axes mixed or shared: every lane equals the scalar test exactly.
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
                    if case % 2 == 0 && k % 3 != 0 {
                        d = Vec3::new(d.z, d.x, d.y); // mixed axes in half the packets
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
            let lanes = PacketAxes::of(&d, (1u32 << V::W) - 1);
            assert_eq!(lanes.uniform.is_some(), case % 2 == 1, "case {case}");
            let shear = Shear::of(lanes.permute(d), V::splat(1.0));
            let (mask, t, u, v) = intersect_simd(
                lanes.permute(o),
                &shear,
                tri.map(|p| lanes.permute_splat(p)),
                V::splat(0.5),
                V::splat(3.5),
                V::first_lanes(V::W),
            );
            for (k, ray) in rays.iter().enumerate() {
                let s = intersect1(ray.0, ray.1, tri, 0.5, 3.5);
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
        let (o, d) = (Vec3::ZERO, Vec3::Z);
        assert_eq!(intersect1(o, d, tri, 2.0, 2.0).map(|h| h.0), Some(2.0));
        assert!(intersect1(o, d, tri, 0.0, 1.999).is_none());
        assert!(intersect1(o, d, tri, 2.001, 9.0).is_none());
        // A ray in the triangle's plane never hits (det = 0).
        assert!(intersect1(Vec3::new(0.0, 0.0, 2.0), Vec3::X, tri, 0.0, 9.0).is_none());
        // Both windings hit, with the same t.
        let back = [tri[0], tri[2], tri[1]];
        assert_eq!(intersect1(o, d, back, 0.0, 9.0).map(|h| h.0), Some(2.0));
    }

    /// The test in f64 (the f32 inputs are exact in f64): whether the ray meets the triangle.
    fn hits_in_f64(o: Vec3, d: Vec3, tri: [Vec3; 3]) -> bool {
        let f = |v: Vec3| v.as_dvec3();
        let (o, d) = (f(o), f(d));
        let [a, b, c] = tri.map(|v| f(v) - o);
        let (u, v, w) = (d.dot(b.cross(c)), d.dot(c.cross(a)), d.dot(a.cross(b)));
        (u >= 0.0 && v >= 0.0 && w >= 0.0) || (u <= 0.0 && v <= 0.0 && w <= 0.0)
    }

    /// Two small triangles sharing an edge, seen from far away (the origin 5000 triangle sizes
    /// off): no ray that meets one of them in exact arithmetic misses both (no leak), and rays
    /// aimed 0.3 % of the triangle's size beyond a corner miss. Möller-Trumbore with its
    /// rounding-bound slack accepted points up to 0.9 % outside on the 1M tori.
    #[test]
    fn far_small_triangles_are_watertight_without_slack() {
        let mut rng = Pcg32::new(3, 7);
        let mut r = || rng.next_f32();
        let size = 0.01;
        let o = Vec3::new(0.0, 33.0, 42.5);
        let (mut near_edge, mut leaks, mut false_hits) = (0, 0, 0);
        for _ in 0..20_000 {
            let base = Vec3::new(r() * 4.0 - 2.0, r() * 0.5, r() * 4.0 - 2.0);
            let (p, q) = (base, base + size * Vec3::new(1.0, 0.2 * r(), 0.3 * r()));
            let (x, y) = (
                base + size * Vec3::new(0.4, 0.9 + 0.1 * r(), -0.2),
                base + size * Vec3::new(0.6, -0.9 - 0.1 * r(), 0.3),
            );
            let (left, right) = ([p, q, x], [q, p, y]);
            let hit = |d: Vec3, tri| intersect1(o, d, tri, 0.0, f32::INFINITY).is_some();
            // Aimed at the shared edge (up to the rounding of the aim point and direction),
            // away from its ends, where the two triangles' outer edges meet it.
            let d = p + (q - p) * (0.01 + 0.98 * r()) - o;
            if hits_in_f64(o, d, left) || hits_in_f64(o, d, right) {
                near_edge += 1;
                leaks += usize::from(!hit(d, left) && !hit(d, right));
            }
            // 0.3 % of the triangle's size beyond its corner x, away from its centroid.
            let centroid = (p + q + x) / 3.0;
            let outside = x + (x - centroid).normalize() * (0.003 * size);
            false_hits += usize::from(hit(outside - o, left));
        }
        assert!(near_edge > 19_000, "{near_edge}");
        assert_eq!((leaks, false_hits), (0, 0));
    }
}
