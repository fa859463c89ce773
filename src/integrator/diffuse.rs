//! Vertices on diffuse, microfacet and specular surfaces, `LANES` paths at a time.
//!
//! Most course scenes are diffuse surfaces under area, point, directional or sky lights. Shaded one
//! vertex after another (`path::shade_hit`), such a vertex is a chain of dependent square roots,
//! divisions and compares, and shading was half of a render's time (PERF.md "Whole renders"). Here
//! the same arithmetic runs over `LANES` vertices in SIMD lanes: each lane computes, operation for
//! operation and in the same order, what `path::shade_hit` computes for
//! `DirectLighting::LightSampling`, uniform hemisphere sampling (`-H`: emission probes) or MIS
//! with triangle emitters at a vertex on any surface but an emitter, lit by any scene lights, so
//! the images are bit-identical to the scalar path's (tests/lighting.rs), which stays for the
//! other cases (MIS with emissive spheres, emitters). The lights are sampled in lanes by
//! `light_lanes`, the microfacet BSDF evaluated and sampled by `microfacet_lanes`, the mirror,
//! glass and refraction BSDFs sampled by `delta_lanes`; a chunk runs code only for the kinds of
//! surface it holds (`shade_diffuse`).

use std::f32::consts::FRAC_1_PI;

use super::bsdf::UNIFORM_HEMISPHERE_PDF;
use super::diffuse_out::ray_records;
pub use super::diffuse_out::{
    queue_all_lanes, queue_lane, BounceLanes, DiffuseOutputs, ShadowLanes,
};
use super::glossy_lanes::{area_light_hits, light_sample_scale};
use super::path::{self, hemisphere_draws, DirectLighting, DrawLayout, RR_START_DEPTH};
use super::RenderContext;
use crate::geometry::prim;
use crate::math::{flat_coordinates, Hit, Ray, Vec3};
use crate::sampler::{DrawBatch, DRAW_BLOCK};
use crate::scene::{Material, Scene, NORMALS_PER_TRIANGLE};
use crate::simd::{gather16, SimdF32};

use super::delta_lanes::{self, DeltaParams};
use super::lane_math::{
    cosine_hemisphere, gt, max, min, neg, normalize_or, offset_origin, ray_epsilon,
    uniform_hemisphere, Frame, Lanes, V, V3,
};
use super::light_lanes::{sample_scene_light, sample_triangle_emitter, LightLanes};
use super::microfacet_lanes::{self, MicrofacetLanes, MicrofacetParams, MicrofacetSample};

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
    /// Each lane's hit distance `t`, barycentrics `u`, `v`, throughput (x, y, z), albedo x, y.
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
    /// The lanes whose surface is microfacet, and their parameters (their albedo is zero).
    micro: MicrofacetParams,
    /// The lanes whose surface is specular (mirror, glass, refraction), and their parameters.
    delta: DeltaParams,
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

    /// Empties the lanes.
    pub fn clear(&mut self) {
        self.len = 0;
        self.micro.mask = 0;
        self.delta.clear();
    }

    /// Loads a microfacet or specular vertex (`material`) into the next free lane, as `push`
    /// does a diffuse one (its albedo zero, its parameters in `micro` or `delta`). Emitters
    /// are not shaded in lanes: false, and nothing is loaded.
    pub fn push_other(
        &mut self,
        path: u32,
        queue: usize,
        ray: &Ray,
        hit: &Hit,
        throughput: Vec3,
        material: &Material,
    ) -> bool {
        let loaded = match *material {
            Material::Microfacet { alpha, eta, k } => {
                self.micro.set(self.len, alpha, eta, k);
                true
            }
            _ => self.delta.set(self.len, material),
        };
        if loaded {
            self.push(path, queue, ray, hit, throughput, Vec3::ZERO);
        }
        loaded
    }

    /// Loads a vertex into the next free lane: path, queue index, ray, hit, throughput, albedo.
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
            let loaded = if self.prim.iter().all(|&p| p == self.prim[0]) {
                self.splat_triangle(normals)
            } else if cfg!(target_feature = "avx512f") {
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

    /// `load_surfaces` for lanes that all hit the same triangle: its normals record read once
    /// and copied to every lane. A pixel's samples are neighbours in the queue, and where they
    /// land on one large triangle (a wall) the gathers loaded one record sixteen times over.
    /// `false` if the index is out of range (`gather_triangles`).
    fn splat_triangle(&mut self, normals: &[Vec3]) -> bool {
        let first = prim::triangle_index(self.prim[0]) as usize * NORMALS_PER_TRIANGLE;
        let Some(record) = normals.get(first..first + NORMALS_PER_TRIANGLE) else {
            return false;
        };
        self.face_normal = record[0].to_array().map(|c| [c; LANES]);
        for (k, vertex) in record[1..].iter().enumerate() {
            self.normals[k] = vertex.to_array().map(|c| [c; LANES]);
        }
        true
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

/// Whether `shade_diffuse` can shade this integrator's surface vertices: light sampling with
/// any scene lights, hemisphere sampling, or MIS with triangle emitters (and any scene lights).
pub fn applies(ctx: &RenderContext, direct: DirectLighting) -> bool {
    match direct {
        // Every kind of scene light has a lane sampler (`sample_scene_light`).
        DirectLighting::LightSampling => true,
        DirectLighting::Mis => ctx.lights.emitters_are_triangles(),
        DirectLighting::Hemisphere => true,
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
    /// The lanes that hold vertices with a smooth lobe (not specular): they sample lights.
    smooth: V,
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
    // A chunk runs code for the materials it has: testing for microfacet lanes at each use
    // cost the diffuse chunks 1% of a CBbunny render's instructions.
    let (d, m) = (lanes.delta.bits() != 0, lanes.micro.mask != 0);
    let shade = match (m, d) {
        (false, false) => shade_lanes::<false, false>,
        (true, false) => shade_lanes::<true, false>,
        (false, true) => shade_lanes::<false, true>,
        (true, true) => shade_lanes::<true, true>,
    };
    shade(ctx, direct, depth, layout, draws, lanes, out);
}

/// `shade_diffuse`, with microfacet lanes when `MICRO` and specular ones when `DELTA`.
#[inline(always)]
fn shade_lanes<const MICRO: bool, const DELTA: bool>(
    ctx: &RenderContext,
    direct: DirectLighting,
    depth: u32,
    layout: &DrawLayout,
    draws: &DrawBatch,
    lanes: &mut DiffuseLanes,
    out: &mut DiffuseOutputs,
) {
    lanes.load_surfaces(ctx.scene, ctx.triangle_normals);
    let v = vertex(lanes, if DELTA { lanes.delta.bits() } else { 0 });
    let micro = if MICRO { lanes.micro.lanes() } else { None };
    let micro = micro.as_ref();
    // Glossy vertices weigh area lights against their BSDF sample (`path::weighs_area_lights`).
    let weigh = micro.filter(|_| path::weighs_area_lights(direct, ctx));
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
        let start = (2 * slot + c) * DRAW_BLOCK;
        let row: &[f32; DRAW_BLOCK] = block[start..start + DRAW_BLOCK].try_into().unwrap();
        if in_order {
            V::load(row)
        } else {
            // The remainder tells the compiler what `block_lane` holds: no bounds checks.
            V::load(&std::array::from_fn::<f32, LANES, _>(|l| row[block_lane[l] % DRAW_BLOCK]))
        }
    };
    out.shadows.clear();
    out.probes = direct == DirectLighting::Hemisphere;
    // Specular lanes sample no lights, and chunks of them only (`stages::group_specular`) skip it.
    let lit = !DELTA || lanes.used() & !lanes.delta.bits() != 0;
    if out.probes && lit {
        let n = hemisphere_draws(ctx);
        for k in layout.light..layout.emitter {
            out.shadows.push(hemisphere_probe(ctx, &v, micro, number(k, 0), number(k, 1), n));
        }
    } else if lit {
        let mut slot = layout.light;
        for light in &ctx.lights.scene_lights {
            let n = if light.is_delta() { 1 } else { ctx.light_samples };
            let scale = V::splat(1.0 / n as f32);
            let rectangle = weigh.and(path::area_rectangle(light));
            for _ in 0..n {
                let (u1, u2) = (number(slot, 0), number(slot, 1));
                let ls = sample_scene_light(light, v.p, &v.frame, u1, u2);
                let scale = match (weigh, &rectangle) {
                    (Some(m), Some((r, _))) => light_sample_scale(r, m, &v.frame, v.wo, &ls, n),
                    _ => scale,
                };
                out.shadows.push(shadow_ray(ctx, &v, micro, &ls, scale));
                slot += 1;
            }
        }
    }
    if lit && direct == DirectLighting::Mis && ctx.lights.has_emitters() {
        let n = ctx.light_samples;
        for k in layout.emitter..layout.bsdf {
            let ls = sample_triangle_emitter(ctx, v.p, number(k, 0), number(k, 1));
            // `path::sample_emissive_geometry`: the power heuristic against BSDF sampling.
            let zero = V::splat(0.0);
            let wl = ls.wi.to_local(&v.frame);
            let facing = gt(v.wo.z, zero) & gt(wl.z, zero);
            let mut bsdf_pdf = V::select(facing, wl.z * V::splat(FRAC_1_PI), zero);
            if let Some(m) = micro {
                bsdf_pdf = V::select(m.mask, microfacet_lanes::pdf(m, v.wo, wl, facing), bsdf_pdf);
            }
            let a = V::splat(n as f32) * ls.pdf;
            let w = V::select(
                a.simd_eq(zero) & bsdf_pdf.simd_eq(zero),
                zero,
                a * a / (a * a + bsdf_pdf * bsdf_pdf),
            );
            out.shadows.push(shadow_ray(ctx, &v, micro, &ls, w / V::splat(n as f32)));
        }
    }
    // As in `path::shade_hit`: MIS (the BSDF half) and specular vertices go on at the last depth.
    let smooth_continues = depth + 1 < ctx.max_depth || direct == DirectLighting::Mis;
    let continues = smooth_continues || DELTA;
    // The microfacet lanes' BSDF sample, once for the weighing and the continuation.
    let bsdf = micro
        .filter(|_| weigh.is_some() || continues)
        .map(|m| microfacet_lanes::sample(m, v.wo, number(layout.bsdf, 0), number(layout.bsdf, 1)));
    if let (Some(m), Some(s)) = (weigh, &bsdf) {
        let lights = &ctx.lights.scene_lights;
        for (ls, w) in area_light_hits(lights, ctx.light_samples, m, (v.p, &v.frame), s) {
            out.shadows.push(shadow_ray(ctx, &v, micro, &ls, w));
        }
    }
    out.bounce.valid = 0;
    if continues {
        let delta = if DELTA { Some(&lanes.delta) } else { None };
        let kinds = (micro.zip(bsdf.as_ref()), delta, smooth_continues);
        continue_diffuse(ctx, depth, layout, &v, kinds, &number, &mut out.bounce);
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
fn vertex(lanes: &DiffuseLanes, delta: u32) -> Vertex {
    let zero = V::splat(0.0);
    let (origin, dir) = lanes.ray_lanes();
    let pushed = lanes.value_lanes();
    let neg_dir = V3 { x: neg(dir.x), y: neg(dir.y), z: neg(dir.z) };
    let (p, ng_s, ns_s) = surface(lanes, origin, dir, &pushed);
    let cos_out = neg(ng_s.dot(dir));
    let mut sign = V::select(cos_out.simd_lt(zero), V::splat(-1.0), V::splat(1.0));
    let mut facing_away = ns_s.scale(sign).dot(neg_dir).simd_le(zero);
    // Glass and refraction keep the outward normals, so that the BSDF knows the side, and the
    // interpolated one even where it faces away.
    let transmissive = lanes.delta.transmissive() & delta;
    if transmissive != 0 {
        let t = V::from_bitmask(transmissive);
        sign = V::select(t, V::splat(1.0), sign);
        facing_away = V::select(t, zero, facing_away);
    }
    let ng = ng_s.scale(sign);
    let ns = ns_s.scale(sign);
    let ns = V3::select(facing_away, ng, ns);
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
        smooth: V::from_bitmask(lanes.used() & !delta),
    }
}

/// `path::queue_shadow_ray`: the occlusion test for one light sample per lane.
#[inline(always)]
fn shadow_ray(
    ctx: &RenderContext,
    v: &Vertex,
    micro: Option<&MicrofacetLanes>,
    ls: &LightLanes,
    scale: V,
) -> ShadowLanes {
    let zero = V::splat(0.0);
    let wl = ls.wi.to_local(&v.frame);
    let lit = gt(wl.z, zero) & gt(ls.wi.dot(v.ng), zero);
    let facing = gt(v.wo.z, zero) & gt(wl.z, zero);
    let mut f = V3::select(facing, v.f, V3::splat(Vec3::ZERO));
    if let Some(m) = micro {
        f = V3::select(m.mask, microfacet_lanes::eval(m, v.wo, wl, facing), f);
    }
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
    let valid = v.smooth & ls.sampled & lit & useful & gt(t_max, zero);
    let mut s = ShadowLanes {
        valid: valid.bitmask(),
        rays: ray_records(origin, dir, V::splat(0.0), t_max),
        ..Default::default()
    };
    contribution.store(&mut s.contribution);
    s
}

/// `path::queue_hemisphere_probes` for one of the `n` hemisphere draws per lane: a uniform
/// direction, and the emission probe that adds what emissive geometry it sees.
#[inline(always)]
fn hemisphere_probe(
    ctx: &RenderContext,
    v: &Vertex,
    micro: Option<&MicrofacetLanes>,
    u1: V,
    u2: V,
    n: u32,
) -> ShadowLanes {
    let zero = V::splat(0.0);
    let wi = uniform_hemisphere(u1, u2);
    let facing = gt(v.wo.z, zero) & gt(wi.z, zero);
    let mut f = V3::select(facing, v.f, V3::splat(Vec3::ZERO));
    if let Some(m) = micro {
        f = V3::select(m.mask, microfacet_lanes::eval(m, v.wo, wi, facing), f);
    }
    let weight = v.throughput.mul(f).scale(wi.z / V::splat(UNIFORM_HEMISPHERE_PDF * n as f32));
    let frame = &v.frame;
    let dir = frame.t.scale(wi.x).add(frame.b.scale(wi.y)).add(frame.n.scale(wi.z));
    // Skipped where the scalar path's `<= 0` tests are true (a NaN passes them there too).
    let skip = weight.max_element().simd_le(zero) | dir.dot(v.ng).simd_le(zero);
    let origin = offset_origin(v.p, v.ng, dir, ctx.scene_epsilon);
    let mut s = ShadowLanes {
        valid: v.smooth.bitmask() & !skip.bitmask(),
        rays: ray_records(origin, dir, zero, V::splat(f32::INFINITY)),
        ..Default::default()
    };
    weight.store(&mut s.contribution);
    s
}

/// `path::continue_path` for a diffuse vertex (a cosine-weighted bounce), a microfacet one (a
/// Beckmann-sampled bounce, `kinds.0`: the lanes and their sample) or a specular one
/// (`kinds.1`), with roulette; the smooth lanes continue only if `kinds.2`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn continue_diffuse(
    ctx: &RenderContext,
    depth: u32,
    layout: &DrawLayout,
    v: &Vertex,
    kinds: (Option<(&MicrofacetLanes, &MicrofacetSample)>, Option<&DeltaParams>, bool),
    number: &impl Fn(usize, usize) -> V,
    out: &mut BounceLanes,
) {
    let (micro, delta, smooth_continues) = kinds;
    let (p, ng, frame, wo, throughput, used) = (v.p, v.ng, &v.frame, v.wo, v.throughput, v.used);
    let zero = V::splat(0.0);
    let (u1, u2) = (number(layout.bsdf, 0), number(layout.bsdf, 1));
    let mut wi = cosine_hemisphere(u1, u2);
    let mut pdf = wi.z * V::splat(FRAC_1_PI);
    let mut valid = used & gt(wo.z, zero) & gt(wi.z, zero);
    let mut weight = v.albedo;
    if let Some((m, s)) = micro {
        wi = V3::select(m.mask, s.wi, wi);
        pdf = V::select(m.mask, s.pdf, pdf);
        valid = used & V::select(m.mask, s.valid, valid);
        weight = V3::select(m.mask, s.weight, weight);
    }
    if !smooth_continues {
        valid = zero;
    }
    if let Some(d) = delta {
        let lobe = match layout.lobe {
            Some(k) => number(k, 0),
            None => zero,
        };
        let s = delta_lanes::sample(d, wo, lobe);
        let specular = V::from_bitmask(d.bits());
        wi = V3::select(specular, s.wi, wi);
        pdf = V::select(specular, zero, pdf);
        valid = V::select(specular, used & s.valid, valid);
        weight = V3::select(specular, s.weight, weight);
    }
    let mut t = throughput.mul(weight);
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
    pdf.store(&mut out.pdf);
}
