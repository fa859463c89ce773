//! `RayPacket<V>`: W rays in structure-of-arrays form (one lane per ray) for packet traversal,
//! generic over the lane type `V` (`wide::f32x4`, `wide::f32x8` or `simd::F32x16`, see
//! `crate::simd`).
//!
//! A packet is gathered from a slice of `Ray` records (the queues' layout) into `RayLanes`;
//! lanes past the end of the slice, or switched off by the caller, are inactive and never
//! produce a hit or count in `TraceStats`. Closest-hit traversal first asks `CullBox` whether
//! every lane's line misses the scene box, and only otherwise derives the packet's slab terms
//! (`RayPacket`) and, at its first leaf, its triangle-test terms (`TriangleFrame`).

use crate::geometry::watertight::{PacketAxes, Shear, V3};
use crate::math::{Aabb, Hit, Ray, Vec3};
use crate::simd::SimdF32;

/// Widest packet: bounds the per-lane scratch arrays.
pub const MAX_W: usize = 16;

/// Direction components smaller than this in magnitude are replaced by it (keeping the sign)
/// before taking reciprocals, as Embree's `rcp_safe` does: the slab test then never computes
/// 0 * inf = NaN, so it needs no NaN-aware min/max, and a parallel ray still gets slab
/// distances of about 1e18 x (box - origin), infinite for any practical purpose.
pub const MIN_DIR: f32 = 1e-18;

/// The box test's tolerance: the exit distance is enlarged by this factor (about 16 ulps) so
/// that rounding in the slab distances never culls a box whose triangles the triangle test hits
/// (Ize, "Robust BVH Ray Traversal", uses 1 + 2 gamma_3 for the slab rounding alone; the
/// triangle test's own t carries a few ulps more). Conservative culling is what lets packet
/// and single-ray traversal, which visit nodes in different orders, agree exactly.
pub const BOX_INFLATE: f32 = 1.0 + 16.0 * f32::EPSILON;

/// The reciprocal used by every slab test, single-ray and packet alike.
#[inline(always)]
pub fn safe_recip(d: f32) -> f32 {
    let d = if d.abs() < MIN_DIR { MIN_DIR.copysign(d) } else { d };
    1.0 / d
}

/// `safe_recip` lane by lane (IEEE division rounds the same in every lane width, so each
/// lane equals the scalar result bit for bit).
#[inline(always)]
pub fn safe_recip_v<V: SimdF32>(d: V) -> V {
    let tiny = d.abs().simd_lt(V::splat(MIN_DIR));
    let signed_min = (d & V::splat(-0.0)) | V::splat(MIN_DIR);
    V::splat(1.0) / V::select(tiny, signed_min, d)
}

/// Slab distances are `fma(plane, inv, -origin * inv)`: one fused multiply-add per plane
/// instead of a subtraction and a product. Its error is not relative to the distance alone:
/// the rounding of `origin * inv` adds up to half an ulp of `|origin * inv|`, which for a ray
/// far from the origin of coordinates can exceed the distance itself (without a margin for it,
/// `tests/watertight.rs` leaked a ray on a flat leaf box: PERF.md, "Tried, did not help"). So
/// every box test widens the slab interval by `slack` on both sides, `SLACK` times the largest
/// `|origin * inv|` over the axes (`slab_terms`), and the entry distance it reports (which
/// the leaf test's front-of-box rule compares hits against) is the widened one. The exit
/// distance keeps its relative tolerance `BOX_INFLATE` for the rest of the rounding.
/// Measured (PERF.md, "Fused slab test"): packet8 primary rays 1.07-1.08x.
pub const SLACK: f32 = 2.0 * f32::EPSILON;

/// The per-ray terms of the fused slab test, lane by lane the same at every width (so single
/// rays, which compute them on broadcast lanes, agree with packets bit for bit): `-origin *
/// inv` per axis, and the slack.
#[inline(always)]
pub fn slab_terms<V: SimdF32>(origin: &V3<V>, inv: &V3<V>) -> (V3<V>, V) {
    let (x, y, z) = (origin.x * inv.x, origin.y * inv.y, origin.z * inv.z);
    let slack = x.abs().fast_max(y.abs()).fast_max(z.abs()) * V::splat(SLACK);
    let m = V::splat(-1.0);
    (V3 { x: x * m, y: y * m, z: z * m }, slack)
}

/// Up to `V::W` rays in structure-of-arrays form, one lane per ray, with the per-ray terms of
/// the slab test precomputed; gathered by [`from_rays`](RayPacket::from_rays) and traced by
/// [`Accel::intersect_ray_packet`](crate::Accel::intersect_ray_packet) and
/// [`Accel::occluded_ray_packet`](crate::Accel::occluded_ray_packet).
#[derive(Clone, Copy, Debug)]
pub struct RayPacket<V: SimdF32> {
    /// Ray origins, one lane per ray.
    pub origin: V3<V>,
    /// Ray directions (not necessarily normalised), one lane per ray.
    pub dir: V3<V>,
    /// `safe_recip` of each direction component.
    pub inv_dir: V3<V>,
    /// `-origin * inv_dir` per axis and the slab slack (`slab_terms`).
    pub neg_o_inv: V3<V>,
    /// How far each lane's box tests widen the slab interval on both sides (`SLACK` times the
    /// largest `|origin * inv_dir|`, `slab_terms`).
    pub slack: V,
    /// Start of each ray's interval.
    pub t_min: V,
    /// End of each ray's interval; closest-hit traversal shrinks it to the nearest hit so far.
    pub t_max: V,
    /// Lane mask: all-ones for rays to trace.
    pub active: V,
}

/// The per-lane terms of the watertight triangle test (`watertight`): each lane's axis order,
/// its origin in that order and its shear. Kept out of `RayPacket` and made only when a packet
/// first reaches a leaf: most coherent packets never do (on the standard primary rays most
/// packets leave at the root), and these terms cost a division and a dozen selects per packet.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriangleFrame<V: SimdF32> {
    /// Each lane's axis order.
    pub axes: PacketAxes<V>,
    /// The origins in each lane's axis order.
    pub origin_in_axes: V3<V>,
    /// Each lane's shear.
    pub shear: Shear<V>,
}

impl<V: SimdF32> TriangleFrame<V> {
    /// The terms for the active lanes of `p`.
    #[inline(never)]
    pub fn of(p: &RayPacket<V>) -> TriangleFrame<V> {
        let axes = PacketAxes::of(&p.dir, p.active_bits());
        TriangleFrame {
            origin_in_axes: axes.permute(p.origin),
            shear: Shear::of(axes.permute(p.dir), V::splat(1.0)),
            axes,
        }
    }
}

/// A packet's rays as gathered, before anything is derived from them: what `RayPacket`
/// computes its terms from, and what `CullBox` reads first.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RayLanes<V: SimdF32> {
    origin: V3<V>,
    dir: V3<V>,
    t_min: V,
    t_max: V,
    /// Bit `i` set iff lane `i` holds a ray to trace.
    active: u32,
}

impl<V: SimdF32> RayLanes<V> {
    /// The first `V::W` rays of `rays` (fewer fill the first lanes; the rest are inactive,
    /// with zeros), with only the lanes whose bit is set in `active_bits` active.
    #[inline(always)]
    pub fn gather(rays: &[Ray], active_bits: u32) -> RayLanes<V> {
        let n = rays.len().min(V::W);
        let [ox, oy, oz, dx, dy, dz, t_min, t_max] = V::columns8(n, |i| rays[i].record());
        let filled = if n >= 32 { !0 } else { (1u32 << n) - 1 };
        RayLanes {
            origin: V3 { x: ox, y: oy, z: oz },
            dir: V3 { x: dx, y: dy, z: dz },
            t_min,
            t_max,
            active: filled & active_bits,
        }
    }

    /// Bit `i` set iff lane `i` is active.
    #[inline(always)]
    pub fn active_bits(&self) -> u32 {
        self.active
    }
}

/// Relative tolerance of `CullBox::missed_by`: 64 ulps of the terms of each comparison, where
/// their rounding is a few ulps.
const CULL_TOL: f32 = 64.0 * f32::EPSILON;

/// Margin by which `CullBox` grows the scene box, relative to the scene's scale (the largest
/// centre coordinate plus the largest half-extent): it covers the rounding of the box's own
/// centre and half-extents, and hits that the triangle test reports a rounding error outside
/// a triangle.
const CULL_MARGIN: f32 = 1.0 / 4096.0;

/// The scene's box, grown by `CULL_MARGIN`, for a test that rejects a whole packet whose
/// rays all miss the scene before any of its per-ray terms are computed: on the standard
/// primary rays most packets of 16 miss the scene (CBbunny two thirds, maxplanck half), and
/// for them the reciprocals, slab terms and interval bounds were most of their cost.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CullBox {
    center: [f32; 3],
    half: [f32; 3],
}

impl CullBox {
    /// `None` for an empty or non-finite box (nothing to cull against).
    pub fn new(b: &Aabb) -> Option<CullBox> {
        let (lo, hi): ([f32; 3], [f32; 3]) = (b.min.into(), b.max.into());
        let finite = lo.iter().chain(&hi).all(|v| v.is_finite());
        if b.is_empty() || !finite {
            return None;
        }
        let center: [f32; 3] = std::array::from_fn(|k| 0.5 * lo[k] + 0.5 * hi[k]);
        let half: [f32; 3] = std::array::from_fn(|k| 0.5 * hi[k] - 0.5 * lo[k]);
        let scale = center.iter().fold(0.0f32, |m, c| m.max(c.abs()))
            + half.iter().fold(0.0f32, |m, e| m.max(*e));
        let margin = scale * CULL_MARGIN;
        Some(CullBox { center, half: half.map(|e| e + margin) })
    }

    /// Whether the point lies in the grown box (then every line through it meets the box).
    #[inline(always)]
    pub fn holds(&self, p: Vec3) -> bool {
        let p: [f32; 3] = p.into();
        (0..3).all(|k| (p[k] - self.center[k]).abs() <= self.half[k])
    }

    /// The active lanes of `r` whose line (the ray extended both ways) surely misses the box:
    /// for an axis k, the box's projection onto k x d, `e_i |d_j| + e_j |d_i|`, is smaller
    /// than the projection of the line, `|((o - c) x d)_k|` (the separating axes of a line and
    /// a box), by more than `CULL_TOL` of the terms. Lanes with a NaN or infinite origin or
    /// direction are never missed: their traversal decides.
    #[inline(always)]
    pub fn missed_by<V: SimdF32>(&self, r: RayLanes<V>) -> u32 {
        let (c, e) = (self.center, self.half);
        let o = [r.origin.x, r.origin.y, r.origin.z];
        let w = [0, 1, 2].map(|k| o[k] - V::splat(c[k]));
        let d = [r.dir.x, r.dir.y, r.dir.z];
        let a = d.map(V::abs);
        // Axis k with the other two axes i, j: (w x d)_k = w_i d_j - w_j d_i.
        let separated = |k: usize| {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            let (p, q) = (w[i] * d[j], w[j] * d[i]);
            let reach = V::splat(e[i]) * a[j] + V::splat(e[j]) * a[i];
            let tol = (p.abs() + q.abs() + reach) * V::splat(CULL_TOL);
            (reach + tol).simd_lt((p - q).abs())
        };
        // NaN compares false, and any infinity makes the sum infinite or NaN.
        let sum = w[0].abs() + w[1].abs() + w[2].abs() + a[0] + a[1] + a[2];
        let finite = sum.simd_lt(V::splat(f32::INFINITY));
        ((separated(0) | separated(1) | separated(2)) & finite).bitmask() & r.active
    }
}

impl<V: SimdF32> RayPacket<V> {
    /// The first `V::W` rays of `rays` (fewer fill the first lanes; the rest are inactive).
    pub fn from_rays(rays: &[Ray]) -> RayPacket<V> {
        RayPacket::from_rays_masked(rays, !0)
    }

    /// As `from_rays`, with only the lanes whose bit is set in `active_bits` active.
    #[inline]
    pub fn from_rays_masked(rays: &[Ray], active_bits: u32) -> RayPacket<V> {
        RayPacket::from_lanes(RayLanes::gather(rays, active_bits))
    }

    /// The packet of the gathered rays `r`, its per-ray terms computed.
    #[inline]
    pub(crate) fn from_lanes(r: RayLanes<V>) -> RayPacket<V> {
        let (origin, dir) = (r.origin, r.dir);
        let inv_dir = V3 { x: safe_recip_v(dir.x), y: safe_recip_v(dir.y), z: safe_recip_v(dir.z) };
        let (neg_o_inv, slack) = slab_terms(&origin, &inv_dir);
        RayPacket {
            origin,
            dir,
            inv_dir,
            neg_o_inv,
            slack,
            t_min: r.t_min,
            t_max: r.t_max,
            active: V::from_bitmask(r.active),
        }
    }

    /// Bit `i` set iff lane `i` is active.
    #[inline(always)]
    pub fn active_bits(&self) -> u32 {
        self.active.bitmask()
    }

    /// Whether the lanes `lanes` head into different octants (a sign of the reciprocal
    /// direction, which `safe_recip` keeps from the direction, differs between them on some
    /// axis): rays that scattered, rather than left one point or one pixel block.
    #[inline(always)]
    pub fn mixed_octants(&self, lanes: u32) -> bool {
        [self.inv_dir.x, self.inv_dir.y, self.inv_dir.z].iter().any(|d| {
            let neg = d.bitmask() & lanes; // sign bits
            neg != 0 && neg != lanes
        })
    }

    /// Lane `i` as a single ray (with the packet's current `t_max`).
    #[inline]
    pub fn ray(&self, i: usize) -> Ray {
        let l = |v: &V3<V>| Vec3::new(v.x.lane(i), v.y.lane(i), v.z.lane(i));
        Ray::segment(l(&self.origin), l(&self.dir), self.t_min.lane(i), self.t_max.lane(i))
    }
}

/// The closest hits of a packet, per lane.
#[derive(Clone, Copy, Debug)]
pub struct PacketHits<V: SimdF32> {
    /// Hit distance per lane, meaningful where `hit_bits` is set.
    pub t: V,
    /// Barycentric `u` of the hit per lane.
    pub u: V,
    /// Barycentric `v` of the hit per lane.
    pub v: V,
    /// Primitive id per lane (`geometry::prim`), meaningful where `hit_bits` is set.
    pub prim: [u32; MAX_W],
    /// Bit `i` set iff lane `i` hit something.
    pub hit_bits: u32,
}

impl<V: SimdF32> PacketHits<V> {
    /// No lane has hit anything yet: `t` infinite, `hit_bits` 0.
    pub fn none() -> PacketHits<V> {
        PacketHits {
            t: V::splat(f32::INFINITY),
            u: V::splat(0.0),
            v: V::splat(0.0),
            prim: [u32::MAX; MAX_W],
            hit_bits: 0,
        }
    }

    /// Writes lane `i`'s hit (`None` where nothing was hit) to `out[i]` for the first
    /// `out.len()` (at most `W`) lanes, with one store per vector rather than one per lane and
    /// field, and no `MAX_W`-long temporary.
    #[inline(always)]
    pub fn write_to(&self, out: &mut [Option<Hit>]) {
        let (mut t, mut u, mut v) = ([0.0; MAX_W], [0.0; MAX_W], [0.0; MAX_W]);
        self.t.store(&mut t);
        self.u.store(&mut u);
        self.v.store(&mut v);
        for (i, o) in out.iter_mut().enumerate().take(V::W) {
            *o = (self.hit_bits & (1 << i) != 0).then(|| Hit {
                t: t[i],
                u: u[i],
                v: v[i],
                prim: self.prim[i],
            });
        }
    }

    /// Lane `i`'s hit, `None` where nothing was hit.
    pub fn get(&self, i: usize) -> Option<Hit> {
        (self.hit_bits & (1 << i) != 0).then(|| Hit {
            t: self.t.lane(i),
            u: self.u.lane(i),
            v: self.v.lane(i),
            prim: self.prim[i],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wide::{f32x4, f32x8};

    fn gathers<V: SimdF32>() {
        let rays: Vec<Ray> = (0..3)
            .map(|i| {
                Ray::segment(
                    Vec3::new(i as f32, 1.0, 2.0),
                    Vec3::new(0.0, -1.0, 2.0),
                    0.5,
                    9.0 + i as f32,
                )
            })
            .collect();
        let p = RayPacket::<V>::from_rays(&rays);
        assert_eq!(p.active_bits(), 0b111);
        for (i, r) in rays.iter().enumerate() {
            assert_eq!(p.ray(i), *r);
        }
        assert_eq!(p.inv_dir.x.lane(0), 1e18);
        assert_eq!(p.inv_dir.y.lane(1), -1.0);
        let q = RayPacket::<V>::from_rays_masked(&rays, 0b101);
        assert_eq!(q.active_bits(), 0b101);
    }

    #[test]
    fn packets_gather_lanes_and_mask_the_tail() {
        gathers::<f32x4>();
        gathers::<f32x8>();
    }
}

#[cfg(test)]
mod cull_tests {
    use super::*;
    use crate::sampler::Pcg32;
    use wide::f32x8;

    /// Whether the line o + t d (any t) meets the closed box [lo, hi], in f64.
    fn line_meets_box(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> bool {
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        for k in 0..3 {
            let (o, d, lo, hi) = (o[k] as f64, d[k] as f64, lo[k] as f64, hi[k] as f64);
            if d == 0.0 {
                if o < lo || o > hi {
                    return false;
                }
                continue;
            }
            let (a, b) = ((lo - o) / d, (hi - o) / d);
            (t0, t1) = (t0.max(a.min(b)), t1.min(a.max(b)));
        }
        t0 <= t1
    }

    /// The line's distance from the box, in f64, relative to the box's diagonal: how far
    /// the box would have to grow for the line to meet it (0 if it meets), by bisection.
    fn growth_to_meet(o: Vec3, d: Vec3, lo: Vec3, hi: Vec3) -> f64 {
        let diag = (hi - lo).length() as f64;
        let (mut a, mut b) = (0.0f64, 1e3);
        for _ in 0..60 {
            let m = 0.5 * (a + b);
            let g = Vec3::splat((m * diag) as f32);
            if line_meets_box(o, d, lo - g, hi + g) {
                b = m;
            } else {
                a = m;
            }
        }
        b
    }

    /// The cull never rejects a line that meets the box, including lines through its
    /// corners and edges, from near and far, axis-parallel ones, and lines in its face planes;
    /// and it rejects nearly every line that passes clearly beside it.
    #[test]
    fn the_scene_box_cull_never_rejects_a_line_that_meets_the_box() {
        let mut rng = Pcg32::new(11, 5);
        let mut r = move || rng.next_f32();
        let (mut clear_misses, mut culled_clear_misses, mut meets) = (0, 0, 0);
        for case in 0..3000 {
            let scale = [1e-3f32, 1.0, 1e3][case % 3];
            let offset = Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * scale * 10.0;
            let a = Vec3::new(r(), r(), r()) * scale + offset;
            let b = Vec3::new(r(), r(), r()) * scale + offset;
            let (lo, hi) = (a.min(b), a.max(b));
            let bx = CullBox::new(&Aabb { min: lo, max: hi }).unwrap();
            let rays: Vec<Ray> = (0..8)
                .map(|k| {
                    let far = [1.0, 30.0, 1e4][(case + k) % 3];
                    let o = offset + Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * scale * far;
                    // Aim at a corner, an edge point, a face point or anywhere near the box.
                    let f = Vec3::new(r(), r(), r());
                    let f = match (case + k) % 5 {
                        0 => f.round(),
                        1 => Vec3::new(f.x.round(), f.y.round(), f.z),
                        2 => Vec3::new(f.x.round(), f.y, f.z),
                        3 => f * 3.0 - Vec3::splat(1.0),
                        _ => f,
                    };
                    let target = lo + f * (hi - lo);
                    let mut d = target - o;
                    if (case + k) % 7 == 0 {
                        d = Vec3::new(0.0, 0.0, d.z);
                    }
                    Ray::new(o, d)
                })
                .collect();
            let missed = bx.missed_by(RayLanes::<f32x8>::gather(&rays, !0));
            for (k, ray) in rays.iter().enumerate() {
                let culled = missed & (1 << k) != 0;
                if line_meets_box(ray.origin, ray.dir, lo, hi) {
                    meets += 1;
                    assert!(!culled, "case {case} lane {k}: culled a line that meets the box");
                } else if growth_to_meet(ray.origin, ray.dir, lo, hi) > 0.01 {
                    clear_misses += 1;
                    culled_clear_misses += culled as u32;
                }
            }
        }
        assert!(meets > 5000 && clear_misses > 3000, "{meets} {clear_misses}");
        // Lines from 1e4 box sizes away get a tolerance of about a tenth of the box.
        let culled = culled_clear_misses as f64 / clear_misses as f64;
        assert!(culled > 0.95, "{culled_clear_misses} of {clear_misses}");
    }

    /// A line through a point the grown box holds is never rejected (so skipping the test for
    /// such a packet changes nothing), and points clearly outside are not held.
    #[test]
    fn lines_through_held_points_are_never_culled() {
        let mut rng = Pcg32::new(2, 9);
        let mut r = move || rng.next_f32();
        let (lo, hi) = (Vec3::new(-1.0, 2.0, -3.0), Vec3::new(4.0, 2.5, 1.0));
        let bx = CullBox::new(&Aabb { min: lo, max: hi }).unwrap();
        for _ in 0..2000 {
            // Points over a box 1.2 times as large: most held, some not.
            let f = Vec3::new(r(), r(), r()) * 1.2 - Vec3::splat(0.1);
            let o = lo + f * (hi - lo);
            let rays: Vec<Ray> =
                (0..8).map(|_| Ray::new(o, Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5))).collect();
            let inside = f.cmpge(Vec3::ZERO).all() && f.cmple(Vec3::ONE).all();
            if inside {
                assert!(bx.holds(o));
            }
            if bx.holds(o) {
                assert_eq!(bx.missed_by(RayLanes::<f32x8>::gather(&rays, !0)), 0);
            }
            let far = f.cmplt(Vec3::splat(-0.01)).any() || f.cmpgt(Vec3::splat(1.01)).any();
            assert!(!(far && bx.holds(o)));
        }
    }

    /// Empty and non-finite boxes give no cull, and NaN or infinite lanes are never rejected.
    #[test]
    fn the_scene_box_cull_skips_empty_boxes_and_nan_lanes() {
        assert!(CullBox::new(&Aabb::EMPTY).is_none());
        let inf = Aabb { min: Vec3::splat(0.0), max: Vec3::new(1.0, f32::INFINITY, 1.0) };
        assert!(CullBox::new(&inf).is_none());
        let bx = CullBox::new(&Aabb { min: Vec3::splat(0.0), max: Vec3::splat(1.0) }).unwrap();
        let away = Ray::new(Vec3::new(5.0, 5.0, 5.0), Vec3::new(1.0, 0.0, 0.0));
        let nan = Ray::new(Vec3::new(5.0, f32::NAN, 5.0), Vec3::new(1.0, 0.0, 0.0));
        let inf = Ray::new(Vec3::new(5.0, 5.0, 5.0), Vec3::new(f32::INFINITY, 0.0, 0.0));
        let lanes = RayLanes::<f32x8>::gather(&[away, nan, inf, away], 0b0111);
        assert_eq!(bx.missed_by(lanes), 0b0001);
    }
}
