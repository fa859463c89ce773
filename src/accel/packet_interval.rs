//! The whole packet as one interval ray: a conservative test of all children of a node at once.
//!
//! On coherent packets most child boxes are entered by no lane at all (counted on the standard
//! primary rays: 84 % of the child tests of maxplanck, 90 % of CBbunny's), yet the exact
//! per-lane slab test (`traverse_packet::slab`) costs one W-wide test per child. So before it,
//! the packet's origins and reciprocal directions are bounded per axis by intervals, and one
//! 8-wide test over the node's children (one lane per child, like the single-ray test) finds
//! the children that some lane may enter; only those get the exact test. The pre-test never
//! drops a child that a lane's exact test enters (margins below), so which lanes enter which
//! subtree, and therefore every hit and t, is unchanged.
//!
//! Bounds. For an axis on which every active lane's direction has the same sign (positive, say),
//! a lane's entry distance to a plane P is (P - o) inv with o <= o_hi and inv in [inv_lo, inv_hi],
//! so it is at least min((P - o_hi) inv_lo, (P - o_hi) inv_hi) (linear in inv); its exit
//! distance to the far plane is at most max((P - o_lo) inv_lo, (P - o_lo) inv_hi). A negative
//! direction swaps the planes and the origin bounds. Some lane enters only if the largest
//! lower entry bound over the axes (and t_min) is at most the smallest upper exit bound (and
//! t_max). Packets whose directions change sign on an axis, or hold a non-finite origin,
//! direction or t_min, skip the pre-test (`PacketInterval::new` returns `None`).
//!
//! Margins. The exact lane test widens its interval by `slack` = 2 eps max|o inv| on both sides
//! and its exit distance by `BOX_INFLATE` (16 eps), and both tests round: the pre-test widens by
//! 8 eps K (K bounds every |o inv|) plus 8 eps of the entry distance and 24 eps of the exit
//! distance, more than all of it together. `tests` checks the pre-test against the exact one
//! on random and adversarial packets.

use super::packet::{RayPacket, BOX_INFLATE};
use super::wide_node::{ChildLanes, WideNode};
use crate::simd::SimdF32;

/// One axis of the interval ray, its terms broadcast to a lane per child.
#[derive(Clone, Copy, Debug)]
struct Axis {
    /// Bounds rows (`WideNode::bounds`) of the entered and the exited planes.
    near_row: usize,
    far_row: usize,
    /// The reciprocal direction's bounds (lo, hi), and `-o inv` for each with the origin
    /// bound that gives the least entry (`near_c`) and the largest exit (`far_c`) distance.
    inv: [ChildLanes; 2],
    near_c: [ChildLanes; 2],
    far_c: [ChildLanes; 2],
}

/// Interval bounds of a packet's active lanes, for `may_enter`.
#[derive(Clone, Copy, Debug)]
pub struct PacketInterval {
    axes: [Axis; 3],
    t_min: ChildLanes,
    t_max: ChildLanes,
    margin: ChildLanes,
}

const EPS: f32 = f32::EPSILON;

#[inline(always)]
fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

impl PacketInterval {
    /// The bounds of the lanes `lanes` of `p`, or `None` where the pre-test would not be
    /// sound or could not cull: a direction sign that differs between lanes on some axis, a
    /// non-finite origin, reciprocal or t_min, or a NaN t_max.
    #[inline(always)]
    pub fn new<V: SimdF32>(p: &RayPacket<V>, lanes: u32) -> Option<PacketInterval> {
        if p.mixed_octants(lanes) {
            return None;
        }
        let (o, inv) = (&p.origin, &p.inv_dir);
        let sum = o.x + o.y + o.z + inv.x + inv.y + inv.z + p.t_min;
        // NaN compares false; any infinity makes the sum infinite or NaN.
        let finite = sum.abs().simd_lt(V::splat(f32::INFINITY)).bitmask()
            & p.t_max.simd_ge(V::splat(f32::NEG_INFINITY)).bitmask();
        if finite & lanes != lanes {
            return None;
        }
        let rows = [o.x, o.y, o.z, inv.x, inv.y, inv.z, p.t_min, p.t_max];
        let (lo, hi) = if lanes == (1u32 << V::W) - 1 {
            (V::min_of_rows(rows), V::max_of_rows(rows))
        } else {
            // Inactive lanes take values neutral for the minima and maxima.
            let on = V::from_bitmask(lanes);
            let (inf, ninf) = (V::splat(f32::INFINITY), V::splat(f32::NEG_INFINITY));
            (
                V::min_of_rows(rows.map(|v| V::select(on, v, inf))),
                V::max_of_rows(rows.map(|v| V::select(on, v, ninf))),
            )
        };
        let s = ChildLanes::splat;
        let mut k = 0.0f32;
        let axes = std::array::from_fn(|a| {
            let (o_lo, o_hi, i_lo, i_hi) = (lo[a], hi[a], lo[3 + a], hi[3 + a]);
            k = fmax(k, fmax(o_lo.abs(), o_hi.abs()) * fmax(i_lo.abs(), i_hi.abs()));
            // Positive direction: the min plane is entered, seen from the largest origin.
            let positive = i_lo > 0.0;
            let (o_near, o_far) = if positive { (o_hi, o_lo) } else { (o_lo, o_hi) };
            Axis {
                near_row: 2 * a + !positive as usize,
                far_row: 2 * a + positive as usize,
                inv: [s(i_lo), s(i_hi)],
                near_c: [s(-(o_near * i_lo)), s(-(o_near * i_hi))],
                far_c: [s(-(o_far * i_lo)), s(-(o_far * i_hi))],
            }
        });
        Some(PacketInterval { axes, t_min: s(lo[6]), t_max: s(hi[7]), margin: s(8.0 * EPS * k) })
    }

    /// Bit `i` set if some lane of the packet may enter child slot `i` of `n` (a superset of
    /// the slots the exact test enters; unused slots may be set too).
    #[inline(always)]
    pub fn may_enter(&self, n: &WideNode) -> u32 {
        let (mut near, mut far) = (self.t_min, self.t_max);
        for ax in &self.axes {
            let pn = ChildLanes::new(n.bounds[ax.near_row]);
            let pf = ChildLanes::new(n.bounds[ax.far_row]);
            let [i0, i1] = ax.inv;
            let n_a = pn.mul_add(i0, ax.near_c[0]).fast_min(pn.mul_add(i1, ax.near_c[1]));
            let f_a = pf.mul_add(i0, ax.far_c[0]).fast_max(pf.mul_add(i1, ax.far_c[1]));
            near = near.fast_max(n_a);
            far = far.fast_min(f_a);
        }
        let s = ChildLanes::splat;
        let near = near - near.abs().mul_add(s(8.0 * EPS), self.margin);
        let far = far + far.abs().mul_add(s(24.0 * EPS), self.margin);
        near.simd_le(far).to_bitmask()
    }
}

const _: () = assert!(BOX_INFLATE <= 1.0 + 16.0 * EPS);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::traverse_single::WideRay;
    use crate::math::{Ray, Vec3};
    use crate::sampler::Pcg32;
    use wide::{f32x4, f32x8};

    fn child_box_corners(n: &WideNode, i: usize) -> (Vec3, Vec3) {
        let b = &n.bounds;
        (Vec3::new(b[0][i], b[2][i], b[4][i]), Vec3::new(b[1][i], b[3][i], b[5][i]))
    }

    /// Every child that a lane's exact (single-ray) slab test enters passes the pre-test.
    /// (Without its absolute margin the pre-test fails here: near-parallel lanes, whose
    /// `-o inv` terms round by far more than the slab distances themselves.)
    fn conservative<V: SimdF32>() {
        let mut rng = Pcg32::new(7, 11);
        let mut r = || rng.next_f32() * 2.0 - 1.0;
        let (mut entered, mut culled, mut tested) = (0, 0, 0);
        for case in 0..6000 {
            // Scales from 1e-3 to 1e6 and offsets up to 1e6: the margins are relative to both.
            let scale = [1e-3, 1.0, 1e3, 1e6][case % 4];
            let offset = Vec3::new(r(), r(), r()) * [0.0, 1.0, 1e4, 1e6][(case / 4) % 4];
            let mut n = WideNode::EMPTY_NODE;
            for i in 0..8 {
                let c = offset + Vec3::new(r(), r(), r()) * scale;
                let h = Vec3::new(r().abs(), r().abs(), r().abs()) * scale * 0.3;
                let (min, max) = (c - h, c + h);
                // Some boxes flat on an axis.
                let max = if (case + i) % 5 == 0 { Vec3::new(min.x, max.y, max.z) } else { max };
                n.set_child(i, min.into(), max.into(), i as u32 + 1);
            }
            // A coherent bundle: one origin region, directions within a cone towards a box,
            // or (every third case) exactly at a corner or an edge point of a child box, so
            // that a lane grazes it; with a single active lane the interval is that lane's
            // own slab interval and only the margins keep the pre-test conservative.
            let eye = offset + Vec3::new(r(), r(), r()) * scale * 3.0;
            let spread = [0.0, 1e-3, 0.05, 0.5][(case / 16) % 4];
            let target = offset + Vec3::new(r(), r(), r()) * scale;
            let graze = case % 3 == 1;
            let rays: Vec<Ray> = (0..V::W)
                .map(|k| {
                    let o = if case % 3 == 0 {
                        eye
                    } else {
                        eye + Vec3::new(r(), r(), r()) * scale * spread
                    };
                    let mut d = if graze {
                        let c = (case + k) % 8;
                        let (lo, hi) = child_box_corners(&n, c);
                        let f = if k % 2 == 0 {
                            Vec3::new(0.0, 1.0, 0.0)
                        } else {
                            Vec3::splat(r().abs())
                        };
                        let pick = |a: f32, b: f32, t: f32| {
                            if t == 0.0 {
                                a
                            } else if t == 1.0 {
                                b
                            } else {
                                a + (b - a) * t
                            }
                        };
                        Vec3::new(pick(lo.x, hi.x, f.x), pick(lo.y, hi.y, f.y), hi.z) - o
                    } else {
                        target - o + Vec3::new(r(), r(), r()) * scale * spread
                    };
                    if !graze && (case + k) % 7 == 0 {
                        d.y = 0.0;
                    }
                    Ray::segment(
                        o,
                        d,
                        0.0,
                        if k % 2 == 0 { f32::INFINITY } else { 1.0 + r().abs() },
                    )
                })
                .collect();
            let lanes = match case % 9 {
                0 => 0b1011,
                1 | 4 => 0b1,
                _ => (1u32 << V::W) - 1,
            };
            let p = RayPacket::<V>::from_rays_masked(&rays, lanes);
            let Some(iv) = PacketInterval::new(&p, lanes) else { continue };
            tested += 1;
            let may = iv.may_enter(&n);
            let mut exact = 0u32;
            for (k, ray) in rays.iter().enumerate().filter(|(k, _)| lanes & (1 << k) != 0) {
                exact |= WideRay::new(ray).slab(&n, ray.t_max).1 & 0xff;
                let _ = k;
            }
            assert_eq!(exact & !may, 0, "case {case}: exact {exact:08b} pre-test {may:08b}");
            entered += exact.count_ones();
            culled += (!may & 0xff).count_ones();
        }
        // The pre-test must also cull (or it is useless) and the cases must exercise it.
        assert!(tested > 2000 && entered > 2000 && culled > 1000, "{tested} {entered} {culled}");
    }

    #[test]
    fn the_pre_test_keeps_every_child_a_lane_enters() {
        conservative::<f32x4>();
        conservative::<f32x8>();
    }

    #[test]
    fn mixed_signs_and_nan_skip_the_pre_test() {
        let o = Vec3::ZERO;
        let mk = |d: Vec3| Ray::segment(o, d, 0.0, f32::INFINITY);
        let mixed = [mk(Vec3::new(1.0, 1.0, 1.0)), mk(Vec3::new(-1.0, 1.0, 1.0))];
        assert!(PacketInterval::new(&RayPacket::<f32x4>::from_rays(&mixed), 0b11).is_none());
        // Lane 1 inactive: its sign does not matter.
        assert!(PacketInterval::new(&RayPacket::<f32x4>::from_rays(&mixed), 0b01).is_some());
        let nan = [mk(Vec3::new(1.0, 1.0, 1.0)), mk(Vec3::new(f32::NAN, 1.0, 1.0))];
        assert!(PacketInterval::new(&RayPacket::<f32x4>::from_rays(&nan), 0b11).is_none());
    }
}
