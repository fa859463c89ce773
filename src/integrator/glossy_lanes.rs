//! The glossy vertices' weighing (`path::weighs_area_lights`) in `diffuse`'s lanes: each
//! function repeats its scalar twin (`path`, `rectangle`) operation for operation, so that lanes
//! and scalar code agree bit for bit.

use super::lane_math::{gt, neg, Frame, V, V3};
use super::light_lanes::{corner_weights, pdf_at, LightLanes};
use super::microfacet_lanes::{self, MicrofacetLanes, MicrofacetSample};
use super::rectangle::Rectangle;
use crate::math::Vec3;
use crate::scene::Light;
use crate::simd::{Arith, SimdF32};

/// `path::power_heuristic` lane by lane.
#[inline(always)]
pub(super) fn power_heuristic(nf: V, f: V, ng: V, g: V) -> V {
    let (a, b) = (nf * f, ng * g);
    // Through the trait: the 512-bit build's vector has its own `splat` too.
    let zero = <V as SimdF32>::splat(0.0);
    V::select(a.simd_eq(zero) & b.simd_eq(zero), zero, a * a / (a * a + b * b))
}

/// The scale of one of an area light's `n` samples at the microfacet lanes `m` (the others:
/// 1 / n), as `path::sample_scene_lights` weighs it.
#[inline(always)]
pub(super) fn light_sample_scale(
    r: &Rectangle,
    m: &MicrofacetLanes,
    frame: &Frame,
    wo: V3,
    ls: &LightLanes,
    n: u32,
) -> V {
    let zero = V::splat(0.0);
    let wl = ls.wi.to_local(frame);
    let facing = gt(wo.z, zero) & gt(wl.z, zero);
    let bsdf_pdf = microfacet_lanes::pdf(m, wo, wl, facing);
    let light_pdf = ls.pdf * ls.cos_light / plane_cos(r, ls.wi);
    let nf = V::splat(n as f32);
    let w = power_heuristic(nf, light_pdf, V::splat(1.0), bsdf_pdf) / nf;
    V::select(m.mask, w, V::splat(1.0 / n as f32))
}

/// `path::queue_area_lights_hit` for the microfacet lanes `m`, given their BSDF sample `s`
/// (`microfacet_lanes::sample`, the one the path continues with): per area light, the light
/// sample its direction finds with its weight.
#[inline(always)]
pub(super) fn area_light_hits<'a>(
    lights: &'a [Light],
    light_samples: u32,
    m: &MicrofacetLanes,
    (p, frame): (V3, &Frame),
    s: &MicrofacetSample,
) -> impl Iterator<Item = (LightLanes, V)> + 'a {
    let usable = m.mask & s.valid & s.pdf.simd_lt(V::splat(f32::INFINITY));
    let world = frame.t.scale(s.wi.x).add(frame.b.scale(s.wi.y)).add(frame.n.scale(s.wi.z));
    let dir = world.scale(V::splat(1.0) / world.dot(world).sqrt());
    let (frame_n, pdf) = (frame.n, s.pdf);
    lights.iter().filter_map(move |light| match *light {
        Light::Area { position, direction, dim_x, dim_y, radiance } => {
            let r = Rectangle::new(position, direction, dim_x, dim_y);
            let hit = hit_by(&r, radiance, p, frame_n, dir);
            let ns = V::splat(light_samples as f32);
            let w = power_heuristic(V::splat(1.0), pdf, ns, hit.pdf);
            let sampled = hit.sampled & usable;
            Some((LightLanes { pdf, sampled, ..hit }, w))
        }
        _ => None,
    })
}

/// `Rectangle::plane_cos` lane by lane.
#[inline(always)]
fn plane_cos(r: &Rectangle, wi: V3) -> V {
    let normal = r.dim_x.cross(r.dim_y).normalize_or_zero();
    Arith::abs(V3::splat(normal).dot(wi))
}

/// `Rectangle::hit_by` lane by lane; `sampled` masks the lanes whose ray meets the light.
#[inline(always)]
fn hit_by(r: &Rectangle, radiance: Vec3, p: V3, n: V3, dir: V3) -> LightLanes {
    let (zero, one) = (V::splat(0.0), V::splat(1.0));
    let normal = r.dim_x.cross(r.dim_y);
    let nv = V3::splat(normal);
    let dist = nv.dot(V3::splat(r.corner).sub(p)) / nv.dot(dir);
    let cos_l = neg(V3::splat(r.direction).dot(dir));
    let front = gt(dist, zero) & dist.simd_lt(V::splat(f32::INFINITY)) & gt(cos_l, zero);
    let rel = p.add(dir.scale(dist)).sub(V3::splat(r.corner));
    let nn = V::splat(normal.dot(normal));
    let s = rel.cross(V3::splat(r.dim_y)).dot(nv) / nn;
    let t = V3::splat(r.dim_x).cross(rel).dot(nv) / nn;
    let inside = s.simd_ge(zero) & s.simd_lt(one) & t.simd_ge(zero) & t.simd_lt(one);
    let cos_plane = plane_cos(r, dir);
    let pdf = pdf_at(r, corner_weights(r, p, n), s, t, dist, cos_l);
    LightLanes {
        finite: true,
        wi: dir,
        dist,
        li: V3::splat(radiance).scale(cos_l / cos_plane),
        pdf: pdf * cos_l / cos_plane,
        cos_light: cos_plane,
        sampled: if r.area > 0.0 { front & inside } else { zero },
    }
}
