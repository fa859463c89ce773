//! `RayPacket<V>`: W rays in structure-of-arrays form (one lane per ray) for packet traversal,
//! generic over the lane type `V` (`wide::f32x4`, `wide::f32x8` or `simd::F32x16`, see
//! `crate::simd`).
//!
//! A packet is gathered from a slice of `Ray` records (the queues' layout); lanes past the end
//! of the slice, or switched off by the caller, are inactive and never produce a hit or count
//! in `TraceStats`.

use crate::geometry::watertight::{PacketAxes, Shear, V3};
use crate::math::{Hit, Ray, Vec3};
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
    /// Each lane's axis order for the triangle test (`watertight`).
    pub(crate) axes: PacketAxes<V>,
    /// The origins in each lane's axis order.
    pub(crate) origin_in_axes: V3<V>,
    /// Each lane's shear for the triangle test.
    pub(crate) shear: Shear<V>,
}

impl<V: SimdF32> RayPacket<V> {
    /// The first `V::W` rays of `rays` (fewer fill the first lanes; the rest are inactive).
    pub fn from_rays(rays: &[Ray]) -> RayPacket<V> {
        RayPacket::from_rays_masked(rays, !0)
    }

    /// As `from_rays`, with only the lanes whose bit is set in `active_bits` active.
    #[inline]
    pub fn from_rays_masked(rays: &[Ray], active_bits: u32) -> RayPacket<V> {
        let n = rays.len().min(V::W);
        // Inactive lanes keep zeros.
        let [ox, oy, oz, dx, dy, dz, t_min, t_max] = V::columns8(n, |i| rays[i].record());
        let dir = V3 { x: dx, y: dy, z: dz };
        let filled = if n >= 32 { !0 } else { (1u32 << n) - 1 };
        let origin = V3 { x: ox, y: oy, z: oz };
        let inv_dir = V3 { x: safe_recip_v(dir.x), y: safe_recip_v(dir.y), z: safe_recip_v(dir.z) };
        let (neg_o_inv, slack) = slab_terms(&origin, &inv_dir);
        let axes = PacketAxes::of(&dir, filled & active_bits);
        RayPacket {
            origin,
            dir,
            inv_dir,
            neg_o_inv,
            slack,
            t_min,
            t_max,
            active: V::from_bitmask(filled & active_bits),
            origin_in_axes: axes.permute(origin),
            shear: Shear::of(axes.permute(dir), V::splat(1.0)),
            axes,
        }
    }

    /// Bit `i` set iff lane `i` is active.
    #[inline(always)]
    pub fn active_bits(&self) -> u32 {
        self.active.bitmask()
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
