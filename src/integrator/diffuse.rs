//! Light-sampling vertices on diffuse surfaces, `LANES` paths at a time.
//!
//! Most course scenes are diffuse surfaces under area, point, directional or sky lights. Shaded one
//! vertex after another (`path::shade_hit`), such a vertex is a chain of dependent square roots,
//! divisions and compares, and shading was half of a render's time (PERF.md "Whole renders"). Here
//! the same arithmetic runs over `LANES` vertices in SIMD lanes: each lane computes, operation for
//! operation and in the same order, what `path::shade_hit` computes for
//! `DirectLighting::LightSampling` at a `Material::Diffuse` vertex lit by any scene lights, so the
//! images are bit-identical to the scalar path's (tests/lighting.rs), which stays for every other
//! case.

use std::f32::consts::FRAC_1_PI;

use super::diffuse_out::ray_records;
pub use super::diffuse_out::{
    queue_all_lanes, queue_lane, BounceLanes, DiffuseOutputs, ShadowLanes,
};
use super::lights::{Rectangle, TriangleEmitter, CORNER_WEIGHT_FLOOR};
use super::path::{DirectLighting, DrawLayout, RR_START_DEPTH};
use super::RenderContext;
use crate::geometry::prim;
use crate::math::{flat_coordinates, Hit, Ray, Vec3};
use crate::sampler::{DrawBatch, DRAW_BLOCK};
use crate::scene::{Light, Scene, NORMALS_PER_TRIANGLE};
use crate::simd::{gather16, SimdF32};

use super::lane_math::{
    gt, max, min, neg, normalize_or, offset_origin, ray_epsilon, sincos_turns, Frame, Lanes, V, V3,
};

/// Vertices shaded together. Sixteen, not eight: a vertex's arithmetic is one long chain of
/// dependent divisions and square roots, so its time goes by latency, and 16 lanes (one
/// AVX-512 register, or two independent 8-lane halves below it) cost little more than 8
/// (PERF.md "Whole renders", "What changed, each measured", ninth round).
pub const LANES: usize = 16;
// A chunk of the queue (`stages::shade`) is one block of the draw batch, so its numbers are
// side by side.
const _: () = assert!(LANES == DRAW_BLOCK);

/// Up to `LANES` diffuse vertices, loaded lane by lane: each lane's ray and hit, and what
/// reconstructing its surface reads (`load_surfaces`), so that `Surface::at` runs in lanes.
/// A lane's ray and its other per-vertex values are pushed as records of 8 floats and turned
/// into lanes by 8 x 8 transposes (`vertex`): a vertex's values stored one float per lane
/// array cost 27 scalar stores per vertex, and the vector loads after them waited on failed
/// store-to-load forwards. The surfaces' face and vertex normals are gathered in AVX-512 builds
/// (`gather_triangles`), transposed from rows below it (`transpose_triangles`), and loaded
/// lane by lane where a lane hit a sphere.
#[derive(Default)]
pub struct DiffuseLanes {
    /// Lanes in use: vertices pushed so far (at most `LANES`).
    pub len: usize,
    /// Path index of each lane's vertex (into `PathState`).
    pub path: [u32; LANES],
    /// Queue index of each vertex's ray (its random numbers in the `DrawBatch`).
    queue: [usize; LANES],
    prim: [u32; LANES],
    /// Each lane's ray: origin, direction, t_min, t_max.
    rays: [[f32; 8]; LANES],
    /// Each lane's hit distance `t`, barycentrics `u`, `v`, path throughput (x, y, z) and the
    /// x and y of its albedo.
    values: [[f32; 8]; LANES],
    albedo_z: Lanes,
    /// A sphere's radius, lane by lane.
    radius: Lanes,
    /// Lanes whose hit is a sphere, as a bit mask.
    spheres: u32,
    /// A triangle's geometric normal (`RenderContext::triangle_normals`), or a sphere's centre.
    face_normal: [Lanes; 3],
    /// A triangle's vertex normals.
    normals: [[Lanes; 3]; 3],
}

fn put(a: &mut [Lanes; 3], l: usize, v: Vec3) {
    (a[0][l], a[1][l], a[2][l]) = (v.x, v.y, v.z);
}

/// A lane's vertex values from `DiffuseLanes::values`, as lanes.
struct PushedValues {
    t: V,
    u: V,
    v: V,
    throughput: V3,
    albedo: V3,
}

impl DiffuseLanes {
    /// Whether all `LANES` lanes hold a vertex.
    pub fn is_full(&self) -> bool {
        self.len == LANES
    }

    /// Loads a vertex into the next free lane: its path, its ray's queue index, the ray and hit,
    /// the path's throughput and the diffuse albedo.
    pub fn push(
        &mut self,
        path: u32,
        queue: usize,
        ray: &Ray,
        hit: &Hit,
        throughput: Vec3,
        albedo: Vec3,
    ) {
        let l = self.len;
        self.path[l] = path;
        self.queue[l] = queue;
        self.prim[l] = hit.prim;
        self.rays[l] = ray.record();
        let (t, a) = (throughput, albedo);
        self.values[l] = [hit.t, hit.u, hit.v, t.x, t.y, t.z, a.x, a.y];
        self.albedo_z[l] = a.z;
        self.len += 1;
    }

    /// Fills unused lanes with copies of lane 0, so they compute ordinary numbers.
    fn pad(&mut self) {
        for l in self.len..LANES {
            self.path[l] = self.path[0];
            self.queue[l] = self.queue[0];
            self.prim[l] = self.prim[0];
            self.rays[l] = self.rays[0];
            self.values[l] = self.values[0];
            self.albedo_z[l] = self.albedo_z[0];
        }
    }

    /// The pushed rays' origins and directions, as lanes.
    #[inline(always)]
    fn ray_lanes(&self) -> (V3, V3) {
        let [ox, oy, oz, dx, dy, dz, _, _] = V::columns8(LANES, |l| self.rays[l]);
        (V3 { x: ox, y: oy, z: oz }, V3 { x: dx, y: dy, z: dz })
    }

    /// The pushed hits, throughputs and albedos, as lanes.
    #[inline(always)]
    fn value_lanes(&self) -> PushedValues {
        let [t, u, v, tx, ty, tz, ax, ay] = V::columns8(LANES, |l| self.values[l]);
        PushedValues {
            t,
            u,
            v,
            throughput: V3 { x: tx, y: ty, z: tz },
            albedo: V3 { x: ax, y: ay, z: V::load(&self.albedo_z) },
        }
    }

    /// Reads what reconstructing every lane's surface needs (a triangle's face normal and
    /// vertex normals from `RenderContext::triangle_normals`, a sphere's centre and radius).
    fn load_surfaces(&mut self, scene: &Scene, normals: &[Vec3]) {
        // Gathers pay where one instruction makes a lane vector (AVX-512: -m 5 renders
        // 0.98-0.99x); below it a checked gather loop was slower than the lane-by-lane loads
        // at the end (1.04x), and rows transposed take fewer instructions than either.
        self.spheres = 0;
        if self.prim.iter().all(|&p| !prim::is_sphere(p)) {
            let loaded = if cfg!(target_feature = "avx512f") {
                self.gather_triangles(normals)
            } else {
                self.transpose_triangles(normals)
            };
            if loaded {
                return;
            }
        }
        for l in 0..LANES {
            if prim::is_sphere(self.prim[l]) {
                self.spheres |= 1 << l;
                let s = &scene.spheres[prim::sphere_index(self.prim[l]) as usize];
                put(&mut self.face_normal, l, s.center);
                self.radius[l] = s.radius;
            } else {
                let first = prim::triangle_index(self.prim[l]) as usize * NORMALS_PER_TRIANGLE;
                put(&mut self.face_normal, l, normals[first]);
                for (k, &vertex) in
                    normals[first + 1..first + NORMALS_PER_TRIANGLE].iter().enumerate()
                {
                    put(&mut self.normals[k], l, vertex);
                }
            }
        }
    }

    /// `load_surfaces` for lanes that all hit triangles, one coordinate of all 16 lanes at a
    /// time (`simd::gather16`: one AVX-512 gather each). `false` if an index is out of range,
    /// which leaves the checked loads of `load_surfaces` to report it.
    fn gather_triangles(&mut self, normals: &[Vec3]) -> bool {
        const F: u32 = 3 * NORMALS_PER_TRIANGLE as u32;
        let flat = flat_coordinates(normals);
        if flat.len() > u32::MAX as usize {
            return false;
        }
        let triangle = self.prim.map(prim::triangle_index);
        if triangle.iter().any(|&t| t as usize >= normals.len() / NORMALS_PER_TRIANGLE) {
            return false;
        }
        let record = triangle.map(|t| F * t);
        for axis in 0..3 {
            if !gather16(flat, &record.map(|r| r + axis as u32), &mut self.face_normal[axis]) {
                return false;
            }
        }
        for k in 0..3 {
            for axis in 0..3 {
                let at = record.map(|r| r + (3 + 3 * k + axis) as u32);
                if !gather16(flat, &at, &mut self.normals[k][axis]) {
                    return false;
                }
            }
        }
        true
    }

    /// `load_surfaces` for lanes that all hit triangles, below AVX-512: each lane's normals
    /// record (face normal and three vertex normals, 12 floats) read as two overlapping rows of
    /// 8 and turned into lanes by two 8 x 8 transposes (`columns8`), then stored as lane
    /// vectors. The lane-by-lane loads stored 12 scalars per lane, and the vector loads of
    /// `surface` then waited on failed store-to-load forwards (as `DiffuseLanes` says of the
    /// vertex values). `false` if an index is out of range, which leaves the checked loads of
    /// `load_surfaces` to report it.
    fn transpose_triangles(&mut self, normals: &[Vec3]) -> bool {
        const F: usize = 3 * NORMALS_PER_TRIANGLE;
        let flat = flat_coordinates(normals);
        let first = self.prim.map(|p| prim::triangle_index(p) as usize * F);
        if first.iter().any(|&f| f + F > flat.len()) {
            return false;
        }
        let row =
            |l: usize, at: usize| -> [f32; 8] { std::array::from_fn(|k| flat[first[l] + at + k]) };
        // Row one: face (x, y, z), vertex 0 (x, y, z), vertex 1 (x, y); row two starts at
        // float 4 so that its last four are vertex 1's z and vertex 2 (x, y, z).
        let [fx, fy, fz, ax, ay, az, bx, by] = V::columns8(LANES, |l| row(l, 0));
        let [_, _, _, _, bz, cx, cy, cz] = V::columns8(LANES, |l| row(l, 4));
        V3 { x: fx, y: fy, z: fz }.store(&mut self.face_normal);
        V3 { x: ax, y: ay, z: az }.store(&mut self.normals[0]);
        V3 { x: bx, y: by, z: bz }.store(&mut self.normals[1]);
        V3 { x: cx, y: cy, z: cz }.store(&mut self.normals[2]);
        true
    }

    /// Lanes `0..len` as a bit mask.
    fn used(&self) -> u32 {
        (1u32 << self.len) - 1
    }
}

/// Whether `shade_diffuse` can shade this integrator's vertices on diffuse surfaces: light
/// sampling with any scene lights, or MIS with triangle emitters (and any scene lights).
pub fn applies(ctx: &RenderContext, direct: DirectLighting) -> bool {
    match direct {
        // Every kind of scene light has a lane sampler (`sample_scene_light`).
        DirectLighting::LightSampling => true,
        DirectLighting::Mis => ctx.lights.emitters_are_triangles(),
        DirectLighting::Hemisphere => false,
    }
}

/// A lane vertex as `path::shade_hit` sets it up.
struct Vertex {
    p: V3,
    /// Geometric normal on the viewer's side.
    ng: V3,
    frame: Frame,
    wo: V3,
    throughput: V3,
    albedo: V3,
    /// The diffuse BSDF value, albedo / pi.
    f: V3,
    /// The lanes that hold vertices.
    used: V,
}

/// Light samples of `lights::LightSample`, lane by lane; `sampled` masks the lanes that have one.
/// `finite`: whether the sampled points are at a finite distance (area and point lights), the
/// same for every lane of one light.
struct LightLanes {
    finite: bool,
    wi: V3,
    dist: V,
    li: V3,
    pdf: V,
    cos_light: V,
    sampled: V,
}

/// Shades the vertices of `lanes` (reached by rays of depth `depth < max_depth`): their shadow
/// rays and bounces into `out`, in the order the scalar path would queue them.
pub fn shade_diffuse(
    ctx: &RenderContext,
    direct: DirectLighting,
    depth: u32,
    layout: &DrawLayout,
    draws: &DrawBatch,
    lanes: &mut DiffuseLanes,
    out: &mut DiffuseOutputs,
) {
    lanes.pad();
    lanes.load_surfaces(ctx.scene, ctx.triangle_normals);
    let v = vertex(lanes);
    // The chunk's numbers sit in one block of the batch (`[slot][coordinate][lane]`, the
    // chunk's queue entries in its lanes); lane l reads the block lane of its vertex, and in
    // queue order (nearly always) a coordinate's lanes are one vector load.
    let (block, _) = draws.block_of(lanes.queue[0]);
    let block_lane: [usize; LANES] = std::array::from_fn(|l| lanes.queue[l] % DRAW_BLOCK);
    // Compared lane by lane: comparing the arrays whole loaded them with one vector load
    // across the compiler's narrower stores of `block_lane`, a failed store-to-load forward
    // that held 8% of this function's samples at `-m 1`.
    let in_order = block_lane.iter().enumerate().all(|(l, &b)| b == l);
    let number = |slot: usize, c: usize| -> V {
        let row = &block[(2 * slot + c) * DRAW_BLOCK..(2 * slot + c + 1) * DRAW_BLOCK];
        if in_order {
            V::load(row)
        } else {
            V::load(&std::array::from_fn::<f32, LANES, _>(|l| row[block_lane[l]]))
        }
    };
    out.shadows.clear();
    let mut slot = layout.light;
    for light in &ctx.lights.scene_lights {
        let n = if light.is_delta() { 1 } else { ctx.light_samples };
        let scale = V::splat(1.0 / n as f32);
        for _ in 0..n {
            let ls = sample_scene_light(light, &v, number(slot, 0), number(slot, 1));
            out.shadows.push(shadow_ray(ctx, &v, &ls, scale));
            slot += 1;
        }
    }
    if direct == DirectLighting::Mis && ctx.lights.has_emitters() {
        let n = ctx.light_samples;
        for k in layout.emitter..layout.bsdf {
            let ls = sample_triangle_emitter(ctx, v.p, number(k, 0), number(k, 1));
            // `path::sample_emissive_geometry`: the power heuristic against BSDF sampling.
            let zero = V::splat(0.0);
            let wl = ls.wi.to_local(&v.frame);
            let bsdf_pdf =
                V::select(gt(v.wo.z, zero) & gt(wl.z, zero), wl.z * V::splat(FRAC_1_PI), zero);
            let a = V::splat(n as f32) * ls.pdf;
            let w = V::select(
                a.simd_eq(zero) & bsdf_pdf.simd_eq(zero),
                zero,
                a * a / (a * a + bsdf_pdf * bsdf_pdf),
            );
            out.shadows.push(shadow_ray(ctx, &v, &ls, w / V::splat(n as f32)));
        }
    }
    out.bounce.valid = 0;
    // As in `path::shade_hit`, MIS continues from the last vertex too (the BSDF half).
    if depth + 1 < ctx.max_depth || direct == DirectLighting::Mis {
        continue_diffuse(ctx, depth, layout, &v, &number, &mut out.bounce);
    }
}

/// `Surface::at` in lanes: the hit point, the geometric normal and the shading normal.
#[inline(always)]
fn surface(lanes: &DiffuseLanes, origin: V3, dir: V3, hit: &PushedValues) -> (V3, V3, V3) {
    let p = origin.add(dir.scale(hit.t));
    let face = V3::load(&lanes.face_normal);
    let [na, nb, nc] = lanes.normals.each_ref().map(V3::load);
    let (u, v) = (hit.u, hit.v);
    let ng = normalize_or(face, V3::splat(Vec3::Y));
    let w = V::splat(1.0) - u - v;
    let ns = normalize_or(na.scale(w).add(nb.scale(u)).add(nc.scale(v)), ng);
    if lanes.spheres == 0 {
        return (p, ng, ns);
    }
    // A sphere's normal.
    let n = normalize_or(p.sub(face).div(V::load(&lanes.radius)), V3::splat(Vec3::Y));
    let sphere = V::from_bitmask(lanes.spheres);
    (p, V3::select(sphere, n, ng), V3::select(sphere, n, ns))
}

/// The vertex of `path::shade_hit`: normals turned towards the viewer, the shading frame.
#[inline(always)]
fn vertex(lanes: &DiffuseLanes) -> Vertex {
    let zero = V::splat(0.0);
    let (origin, dir) = lanes.ray_lanes();
    let pushed = lanes.value_lanes();
    let neg_dir = V3 { x: neg(dir.x), y: neg(dir.y), z: neg(dir.z) };
    let (p, ng_s, ns_s) = surface(lanes, origin, dir, &pushed);
    let cos_out = neg(ng_s.dot(dir));
    let sign = V::select(cos_out.simd_lt(zero), V::splat(-1.0), V::splat(1.0));
    let ng = ng_s.scale(sign);
    let ns = ns_s.scale(sign);
    let ns = V3::select(ns.dot(neg_dir).simd_le(zero), ng, ns);
    let frame = Frame::new(ns);
    let wo = neg_dir.to_local(&frame);
    Vertex {
        p,
        ng,
        frame,
        wo,
        throughput: pushed.throughput,
        albedo: pushed.albedo,
        f: pushed.albedo.scale(V::splat(FRAC_1_PI)),
        used: V::from_bitmask(lanes.used()),
    }
}

/// `lights::sample_scene_light` at the lanes' vertices, for any kind of scene light.
#[inline(always)]
fn sample_scene_light(light: &Light, v: &Vertex, u0: V, u1: V) -> LightLanes {
    let (zero, one, inf) = (V::splat(0.0), V::splat(1.0), V::splat(f32::INFINITY));
    let p = v.p;
    match *light {
        Light::Area { position, direction, dim_x, dim_y, radiance } => sample_rectangle(
            &Rectangle::new(position, direction, dim_x, dim_y),
            radiance,
            v,
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
            let f = &v.frame;
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
fn sample_rectangle(r: &Rectangle, radiance: Vec3, v: &Vertex, u0: V, u1: V) -> LightLanes {
    let (zero, one, half) = (V::splat(0.0), V::splat(1.0), V::splat(0.5));
    let [w00, w10, w01, w11] = corner_weights(r, v.p, v.frame.n);
    let (a, b, c, d) = (w00 + w01, w10 + w11, w00 + w10, w01 + w11);
    let (s, t) = (sample_linear(u0, a, b), sample_linear(u1, c, d));
    let weight = ((one - s) * a + s * b) * ((one - t) * c + t * d);
    let norm = (half * (a + b)) * (half * (c + d));
    let q = V3::splat(r.corner).add(V3::splat(r.dim_x).scale(s)).add(V3::splat(r.dim_y).scale(t));
    let dv = q.sub(v.p);
    let dist = dv.dot(dv).sqrt();
    let wi = dv.div(dist);
    let cos_l = neg(V3::splat(r.direction).dot(wi));
    let area = V::splat(r.area);
    LightLanes {
        finite: true,
        wi,
        dist,
        li: V3::splat(radiance),
        pdf: weight * (dist * dist) / (norm * (area * cos_l)),
        cos_light: cos_l,
        sampled: gt(cos_l, zero) & gt(dist, zero) & gt(area, zero),
    }
}

/// `Rectangle::corner_weights` lane by lane.
#[inline(always)]
fn corner_weights(r: &Rectangle, p: V3, n: V3) -> [V; 4] {
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

/// `lights::sample_linear` lane by lane.
#[inline(always)]
fn sample_linear(xi: V, a: V, b: V) -> V {
    let x = xi * (a + b) / (a + ((V::splat(1.0) - xi) * a * a + xi * b * b).sqrt());
    min(x, V::splat(1.0 - f32::EPSILON / 2.0))
}

/// `bsdf::cosine_hemisphere`, lane by lane.
#[inline(always)]
fn cosine_hemisphere(u1: V, u2: V) -> V3 {
    let r = u1.sqrt();
    let (sin_phi, cos_phi) = sincos_turns(u2);
    V3 { x: r * cos_phi, y: r * sin_phi, z: max(V::splat(1.0) - u1, V::splat(0.0)).sqrt() }
}

/// `LightSet::sample_emitter` for triangle emitters: the pick lane by lane (an alias-table
/// look-up), the point and its pdf in lanes.
#[inline(always)]
fn sample_triangle_emitter(ctx: &RenderContext, p: V3, u0: V, u1: V) -> LightLanes {
    // Each lane's emitter as two 8-float records (zeros where none is picked), then lanes by
    // two transposes: the 14 fields stored lane by lane made 224 scalar stores per batch.
    let mut u0_rescaled: Lanes = [0.0; LANES];
    let mut u0_lanes: Lanes = [0.0; LANES];
    u0.store(&mut u0_lanes);
    let mut picked = 0u32;
    // Each record written once (a zeroed array first cost a 1 KiB memset per chunk).
    let records: [[[f32; 8]; 2]; LANES] =
        std::array::from_fn(|l| match ctx.lights.pick_triangle_emitter(u0_lanes[l]) {
            Some((t, u)) => {
                (u0_rescaled[l], picked) = (u, picked | 1 << l);
                emitter_records(&t)
            }
            None => [[0.0; 8]; 2],
        });
    let [ax, ay, az, bx, by, bz, cx, cy] = V::columns8(LANES, |l| records[l][0]);
    let [cz, rx, ry, rz, pick_pdf, area, _, _] = V::columns8(LANES, |l| records[l][1]);
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
        sampled: V::from_bitmask(picked) & gt(cos_l, zero) & gt(dist, zero),
    }
}

/// A triangle emitter's fields as two records of 8 floats (corners, then the third corner's
/// z, radiance, pick pdf and area), so that lanes of emitters are made by two transposes.
#[inline(always)]
fn emitter_records(t: &TriangleEmitter) -> [[f32; 8]; 2] {
    let (a, b, c, r) = (t.a, t.b, t.c, t.radiance);
    [[a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y], [c.z, r.x, r.y, r.z, t.pick_pdf, t.area, 0.0, 0.0]]
}

/// `path::queue_shadow_ray`: the occlusion test for one light sample per lane.
#[inline(always)]
fn shadow_ray(ctx: &RenderContext, v: &Vertex, ls: &LightLanes, scale: V) -> ShadowLanes {
    let zero = V::splat(0.0);
    let wl = ls.wi.to_local(&v.frame);
    let lit = gt(wl.z, zero) & gt(ls.wi.dot(v.ng), zero);
    let facing = gt(v.wo.z, zero) & gt(wl.z, zero);
    let f = V3::select(facing, v.f, V3::splat(Vec3::ZERO));
    let contribution = v.throughput.mul(f).mul(ls.li).scale(wl.z * scale / ls.pdf);
    let useful = gt(contribution.max_element(), zero) & contribution.is_finite();
    let origin = offset_origin(v.p, v.ng, ls.wi, ctx.scene_epsilon);
    let (dir, t_max) = if ls.finite {
        let q = v.p.add(ls.wi.scale(ls.dist));
        let d = q.sub(origin);
        let len = d.dot(d).sqrt();
        (d.div(len), len - ray_epsilon(q, ctx.scene_epsilon) / max(ls.cos_light, V::splat(1e-2)))
    } else {
        (ls.wi, V::splat(f32::INFINITY))
    };
    let valid = v.used & ls.sampled & lit & useful & gt(t_max, zero);
    let mut s = ShadowLanes {
        valid: valid.bitmask(),
        rays: ray_records(origin, dir, V::splat(0.0), t_max),
        ..Default::default()
    };
    contribution.store(&mut s.contribution);
    s
}

/// `path::continue_path` for a diffuse vertex: a cosine-weighted bounce, with roulette.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn continue_diffuse(
    ctx: &RenderContext,
    depth: u32,
    layout: &DrawLayout,
    v: &Vertex,
    number: &impl Fn(usize, usize) -> V,
    out: &mut BounceLanes,
) {
    let (p, ng, frame, wo, throughput, used) = (v.p, v.ng, &v.frame, v.wo, v.throughput, v.used);
    let zero = V::splat(0.0);
    let (u1, u2) = (number(layout.bsdf, 0), number(layout.bsdf, 1));
    let wi = cosine_hemisphere(u1, u2);
    let mut valid = used & gt(wo.z, zero) & gt(wi.z, zero);
    let mut t = throughput.mul(v.albedo);
    if depth + 1 >= RR_START_DEPTH {
        let roulette = match layout.lobe {
            Some(k) => number(k, 1),
            None => zero,
        };
        let q = min(t.max_element(), V::splat(1.0));
        valid = valid & gt(q, zero) & roulette.simd_lt(q);
        t = t.div(q);
    }
    valid = valid & gt(t.max_element(), zero) & t.is_finite();
    let world = frame.t.scale(wi.x).add(frame.b.scale(wi.y)).add(frame.n.scale(wi.z));
    let dir = world.scale(V::splat(1.0) / world.dot(world).sqrt());
    let origin = offset_origin(p, ng, dir, ctx.scene_epsilon);
    out.valid = valid.bitmask();
    out.rays = ray_records(origin, dir, zero, V::splat(f32::INFINITY));
    t.store(&mut out.throughput);
    (wi.z * V::splat(FRAC_1_PI)).store(&mut out.pdf);
}
