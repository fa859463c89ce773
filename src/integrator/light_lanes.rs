//! Scene lights and triangle emitters sampled at `LANES` vertices at once, for `diffuse`'s
//! lanes: each function repeats the scalar sampler it names (`lights`) operation for
//! operation, so that lanes and scalar code agree bit for bit.

use super::diffuse::LANES;
use super::lane_math::{cosine_hemisphere, gt, max, min, neg, normalize_or, Frame, Lanes, V, V3};
use super::lights::{EmitterRows, TRIANGLE_FLAG};
use super::rectangle::{Rectangle, CORNER_WEIGHT_FLOOR};
use super::RenderContext;
use crate::math::Vec3;
use crate::scene::Light;
use crate::simd::SimdF32;

/// Light samples of `lights::LightSample`, lane by lane; `sampled` masks the lanes that have one.
/// `finite`: whether the sampled points are at a finite distance (area and point lights), the
/// same for every lane of one light.
pub(super) struct LightLanes {
    pub(super) finite: bool,
    pub(super) wi: V3,
    pub(super) dist: V,
    pub(super) li: V3,
    pub(super) pdf: V,
    pub(super) cos_light: V,
    pub(super) sampled: V,
}

/// `lights::sample_scene_light` at the lanes' vertices, for any kind of scene light.
#[inline(always)]
pub(super) fn sample_scene_light(light: &Light, p: V3, frame: &Frame, u0: V, u1: V) -> LightLanes {
    let (zero, one, inf) = (V::splat(0.0), V::splat(1.0), V::splat(f32::INFINITY));
    match *light {
        Light::Area { position, direction, dim_x, dim_y, radiance } => sample_rectangle(
            &Rectangle::new(position, direction, dim_x, dim_y),
            radiance,
            p,
            frame.n,
            u0,
            u1,
        ),
        Light::Point { position, radiance } => {
            let d = V3::splat(position).sub(p);
            let dist = d.dot(d).sqrt();
            LightLanes {
                finite: true,
                wi: d.div(dist),
                dist,
                li: V3::splat(radiance),
                pdf: one,
                cos_light: one,
                sampled: gt(dist, zero),
            }
        }
        Light::Directional { direction, radiance } => LightLanes {
            finite: false,
            wi: V3::splat(direction),
            dist: inf,
            li: V3::splat(radiance),
            pdf: one,
            cos_light: one,
            sampled: V::from_bitmask(!0),
        },
        Light::Ambient { radiance } => {
            // `bsdf::cosine_hemisphere` in the shading frame, as `math::orthonormal_basis`
            // builds it around the shading normal.
            let l = cosine_hemisphere(u0, u1);
            let f = frame;
            let wi = f.t.scale(l.x).add(f.b.scale(l.y)).add(f.n.scale(l.z));
            LightLanes {
                finite: false,
                wi,
                dist: inf,
                li: V3::splat(radiance),
                pdf: l.z / V::splat(std::f32::consts::PI),
                cos_light: one,
                sampled: gt(wi.y, zero) & gt(l.z, zero),
            }
        }
    }
}

/// `Rectangle::sample` lane by lane.
#[inline(always)]
fn sample_rectangle(r: &Rectangle, radiance: Vec3, p: V3, n: V3, u0: V, u1: V) -> LightLanes {
    let zero = V::splat(0.0);
    let w = corner_weights(r, p, n);
    let [a, b, c, d] = edge_weights(w);
    let (s, t) = (sample_linear(u0, a, b), sample_linear(u1, c, d));
    let q = V3::splat(r.corner).add(V3::splat(r.dim_x).scale(s)).add(V3::splat(r.dim_y).scale(t));
    let dv = q.sub(p);
    let dist = dv.dot(dv).sqrt();
    let wi = dv.div(dist);
    let cos_l = neg(V3::splat(r.direction).dot(wi));
    let area = V::splat(r.area);
    LightLanes {
        finite: true,
        wi,
        dist,
        li: V3::splat(radiance),
        pdf: pdf_at(r, w, s, t, dist, cos_l),
        cos_light: cos_l,
        sampled: gt(cos_l, zero) & gt(dist, zero) & gt(area, zero),
    }
}

/// `rectangle::edge_weights` lane by lane.
#[inline(always)]
fn edge_weights([w00, w10, w01, w11]: [V; 4]) -> [V; 4] {
    [w00 + w01, w10 + w11, w00 + w10, w01 + w11]
}

/// `Rectangle::pdf_at` lane by lane.
#[inline(always)]
pub(super) fn pdf_at(r: &Rectangle, w: [V; 4], s: V, t: V, dist: V, cos_l: V) -> V {
    let (one, half) = (V::splat(1.0), V::splat(0.5));
    let [a, b, c, d] = edge_weights(w);
    let weight = ((one - s) * a + s * b) * ((one - t) * c + t * d);
    let norm = (half * (a + b)) * (half * (c + d));
    weight * (dist * dist) / (norm * (V::splat(r.area) * cos_l))
}

/// `Rectangle::corner_weights` lane by lane.
#[inline(always)]
pub(super) fn corner_weights(r: &Rectangle, p: V3, n: V3) -> [V; 4] {
    let zero = V::splat(0.0);
    let c10 = r.corner + r.dim_x;
    let v = [r.corner, c10, r.corner + r.dim_y, c10 + r.dim_y].map(|q| V3::splat(q).sub(p));
    let r2 = v.map(|v| v.dot(v));
    let one = V::splat(1.0);
    let (i01, i23) = (one / (r2[0] * r2[1]), one / (r2[2] * r2[3]));
    let inv = [r2[1] * i01, r2[0] * i01, r2[3] * i23, r2[2] * i23];
    let w: [V; 4] = std::array::from_fn(|k| max(v[k].dot(n), zero) * inv[k] * inv[k]);
    let largest = max(max(w[0], w[1]), max(w[2], w[3]));
    let usable = gt(largest, zero) & largest.simd_lt(V::splat(f32::INFINITY));
    let scale = one / largest;
    let floor = V::splat(CORNER_WEIGHT_FLOOR);
    w.map(|x| V::select(usable, max(x * scale, floor), one))
}

/// `rectangle::sample_linear` lane by lane.
#[inline(always)]
fn sample_linear(xi: V, a: V, b: V) -> V {
    let x = xi * (a + b) / (a + ((V::splat(1.0) - xi) * a * a + xi * b * b).sqrt());
    min(x, V::splat(1.0 - f32::EPSILON / 2.0))
}

/// `LightSet::sample_emitter` for triangle emitters: the pick lane by lane (an alias-table
/// look-up), the point and its pdf in lanes.
#[inline(always)]
pub(super) fn sample_triangle_emitter(ctx: &RenderContext, p: V3, u0: V, u1: V) -> LightLanes {
    // Each lane's emitter as two 8-float rows, then lanes by two transposes: the 14 fields
    // stored lane by lane made 224 scalar stores per batch. The rows are read in place (copied
    // into an array of records first, they cost a call and a 512-byte copy per chunk), and
    // the pick has no branch on which emitter it took: the rows' flag marks the triangles.
    const NONE: EmitterRows = [[0.0; 8]; 2];
    let mut u0_rescaled: Lanes = [0.0; LANES];
    let mut u0_lanes: Lanes = [0.0; LANES];
    u0.store(&mut u0_lanes);
    let mut rows: [&EmitterRows; LANES] = [&NONE; LANES];
    for l in 0..LANES {
        if let Some((r, u)) = ctx.lights.pick_emitter_rows(u0_lanes[l]) {
            (rows[l], u0_rescaled[l]) = (r, u);
        }
    }
    let [ax, ay, az, bx, by, bz, cx, cy] = V::columns8(LANES, |l| rows[l][0]);
    let [cz, rx, ry, rz, pick_pdf, area, triangle, _] = V::columns8(LANES, |l| rows[l][1]);
    const _: () = assert!(TRIANGLE_FLAG == 6);
    let (a, b) = (V3 { x: ax, y: ay, z: az }, V3 { x: bx, y: by, z: bz });
    let c = V3 { x: cx, y: cy, z: cz };
    // `lights::sample_emitter_point` for a triangle.
    let zero = V::splat(0.0);
    let s = V::load(&u0_rescaled).sqrt();
    let (b1, b2) = (V::splat(1.0) - s, u1 * s);
    let (ab, ac) = (b.sub(a), c.sub(a));
    let q = a.add(ab.scale(b1)).add(ac.scale(b2));
    let nq = normalize_or(ab.cross(ac), V3::splat(Vec3::Y));
    let d = q.sub(p);
    let dist = d.dot(d).sqrt();
    let wi = d.div(dist);
    let cos_l = neg(nq.dot(wi));
    LightLanes {
        finite: true,
        wi,
        dist,
        li: V3 { x: rx, y: ry, z: rz },
        pdf: pick_pdf * dist * dist / (area * cos_l),
        cos_light: cos_l,
        sampled: gt(triangle, zero) & gt(cos_l, zero) & gt(dist, zero),
    }
}
