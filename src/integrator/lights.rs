//! What next-event estimation samples, and with which pdf.
//!
//! Two sources of light exist in a course scene (SCENE_FORMAT.md): *scene lights* (area, point,
//! directional, ambient), which are not geometry and are reached only by shadow rays, and
//! *emissive geometry*, which camera and BSDF rays see. In the course's semantics light
//! sampling samples the scene lights. In the emissive-geometry mode the emissive triangles and
//! spheres themselves are the area lights (picked by power, sampled by area) and the scene's CGL
//! area lights are left out, since in the course files they duplicate the emissive quads.
//! A rectangular area light is sampled with a density fitted to the direct light's integrand
//! at its corners (`rectangle.rs`), emissive triangles uniformly by area.

use std::f32::consts::PI;

use super::rectangle::Rectangle;
use crate::geometry::prim;
use crate::math::Vec3;
use crate::scene::{Light, Material, Scene};

/// A point on a light as seen from a shading point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3,
    /// Distance to the sampled point (infinite for directional and sky light).
    pub dist: f32,
    /// Incident radiance (or intensity, for the course's falloff-free point lights).
    pub li: Vec3,
    /// Solid-angle pdf; 1 for delta lights, whose contribution is not divided by anything.
    pub pdf: f32,
    /// Cosine between the light's normal and the direction back to the shading point (1 for
    /// lights without a surface): a shadow ray must stop eps / cos short of an area light to
    /// stay eps away from its plane.
    pub cos_light: f32,
}

/// An emissive triangle or sphere, chosen with probability proportional to its power.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Emitter {
    Triangle(u32),
    Sphere(u32),
}

/// An emitter as the shading lanes read it (`light_lanes::sample_triangle_emitter`): two rows
/// of 8 floats (a triangle's corners; the third corner's z, radiance, pick pdf, area and 1),
/// so that lanes of emitters are made by two transposes. Zeros for a sphere.
pub type EmitterRows = [[f32; 8]; 2];

/// The slot of `EmitterRows`' second row that is 1 for a triangle, 0 for a sphere.
pub const TRIANGLE_FLAG: usize = 6;

/// The lights of one render.
#[derive(Debug, Clone, Default)]
pub struct LightSet {
    /// Scene lights sampled one by one (all of them in course mode; all but `Area` in the
    /// emissive-geometry mode).
    pub scene_lights: Vec<Light>,
    emitters: Vec<Emitter>,
    /// Per emitter, what `pick_emitter_rows` hands out (zeros for spheres): computed
    /// once here rather than per pick, where the corners' loads, two areas and the pick pdf
    /// were a tenth of a `-m 5 --shading mis` render (PERF.md, "Whole renders").
    emitter_rows: Vec<EmitterRows>,
    /// Emitters picked by power (area x luminance of the emitted radiance) in O(1).
    emitter_table: AliasTable,
    emitter_power: f32,
}

/// Walker's alias table: picks item i with probability weight_i / sum in O(1), from one
/// uniform number that it hands back rescaled to [0, 1) so it can be used again.
#[derive(Debug, Clone, Default)]
pub struct AliasTable {
    /// Per bucket: the probability of keeping the bucket's own item, and the other item.
    buckets: Vec<(f32, u32)>,
}

impl AliasTable {
    /// A table over `weights` (non-negative, finite, not all zero).
    pub fn new(weights: &[f32]) -> AliasTable {
        let n = weights.len();
        let total: f64 = weights.iter().map(|&w| w as f64).sum();
        if n == 0 || !(total > 0.0) {
            return AliasTable::default();
        }
        // Scaled so the mean is 1; below-mean buckets are topped up from above-mean items.
        let mut scaled: Vec<f64> = weights.iter().map(|&w| w as f64 * n as f64 / total).collect();
        let mut buckets: Vec<(f32, u32)> = (0..n as u32).map(|i| (1.0, i)).collect();
        let (mut small, mut large): (Vec<usize>, Vec<usize>) =
            (0..n).partition(|&i| scaled[i] < 1.0);
        while let (Some(&s), Some(&l)) = (small.last(), large.last()) {
            small.pop();
            buckets[s] = (scaled[s] as f32, l as u32);
            scaled[l] -= 1.0 - scaled[s];
            if scaled[l] < 1.0 {
                large.pop();
                small.push(l);
            }
        }
        // Whatever is left is 1 up to rounding: such buckets keep their own item.
        AliasTable { buckets }
    }

    /// The picked index and `u` rescaled to [0, 1) within the picked share.
    #[inline]
    pub fn sample(&self, u: f32) -> Option<(usize, f32)> {
        let n = self.buckets.len();
        if n == 0 {
            return None;
        }
        let x = u * n as f32;
        let i = (x as usize).min(n - 1);
        let f = (x - i as f32).clamp(0.0, 1.0);
        let (keep, alias) = self.buckets[i];
        // Selects rather than branches: which side of `keep` the number falls is a coin toss,
        // and the shading lanes pick an emitter per lane (a mispredicted branch in each).
        let own = f < keep;
        let (pick, num, den) =
            if own { (i, f, keep) } else { (alias as usize, f - keep, 1.0 - keep) };
        Some((pick, (num / den).min(1.0 - f32::EPSILON)))
    }
}

/// Luminance of a linear RGB colour (Rec. 709 / sRGB weights).
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl LightSet {
    /// The scene lights, as the course samples them.
    pub fn course(scene: &Scene) -> LightSet {
        LightSet { scene_lights: scene.lights.clone(), ..Default::default() }
    }

    /// Emissive geometry as area lights, plus the scene's non-area lights.
    pub fn emissive_geometry(scene: &Scene) -> LightSet {
        let mut set = LightSet {
            scene_lights: scene
                .lights
                .iter()
                .filter(|l| !matches!(l, Light::Area { .. }))
                .copied()
                .collect(),
            ..Default::default()
        };
        let triangles = (0..scene.triangles.len() as u32).map(Emitter::Triangle);
        let spheres = (0..scene.spheres.len() as u32).map(Emitter::Sphere);
        let mut powers = Vec::new();
        for e in triangles.chain(spheres) {
            let power = emitter_area(scene, e) * luminance(emitter_radiance(scene, e));
            if power > 0.0 && power.is_finite() {
                set.emitter_power += power;
                set.emitters.push(e);
                powers.push(power);
            }
        }
        set.emitter_table = AliasTable::new(&powers);
        set.emitter_rows = set.emitters.iter().map(|&e| set.rows_of(scene, e)).collect();
        set
    }

    /// What picking emitter `e` gives `diffuse::shade_diffuse` (zeros for a sphere).
    fn rows_of(&self, scene: &Scene, e: Emitter) -> EmitterRows {
        let Emitter::Triangle(t) = e else { return [[0.0; 8]; 2] };
        let [a, b, c] = scene.triangle(t as usize);
        let r = emitter_radiance(scene, e);
        let (pick_pdf, area) = (self.emitter_pick_pdf(scene, e), emitter_area(scene, e));
        let mut second = [c.z, r.x, r.y, r.z, pick_pdf, area, 0.0, 0.0];
        second[TRIANGLE_FLAG] = 1.0;
        [[a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y], second]
    }

    /// Whether there is emissive geometry to sample (never in the course's light set).
    pub fn has_emitters(&self) -> bool {
        !self.emitters.is_empty()
    }

    /// Samples a point on the emissive geometry as seen from `p`; `None` if it faces away.
    ///
    /// `u[0]` picks the emitter by power (alias table, O(1)) and is then rescaled to [0, 1)
    /// within the picked emitter's share, so that the two numbers still stratify the point.
    pub fn sample_emitter(&self, scene: &Scene, p: Vec3, u: [f32; 2]) -> Option<LightSample> {
        let (i, u0) = self.emitter_table.sample(u[0])?;
        let e = self.emitters[i];
        let (q, nq) = sample_emitter_point(scene, e, u0, u[1]);
        let d = q - p;
        let dist = d.length();
        let wi = d / dist;
        let cos_l = -nq.dot(wi);
        if !(cos_l > 0.0 && dist > 0.0) {
            return None;
        }
        let pdf = self.emitter_pick_pdf(scene, e) * dist * dist / (emitter_area(scene, e) * cos_l);
        Some(LightSample { wi, dist, li: emitter_radiance(scene, e), pdf, cos_light: cos_l })
    }

    /// Whether every emitter is a triangle (`diffuse::shade_diffuse` samples only those).
    pub fn emitters_are_triangles(&self) -> bool {
        self.emitters.iter().all(|e| matches!(e, Emitter::Triangle(_)))
    }

    /// The first half of `sample_emitter`, as the shading lanes read it: the rows of the
    /// emitter `u0` picks (`TRIANGLE_FLAG` 0 for a sphere), and `u0` rescaled within its
    /// share; the same values `sample_emitter` computes. `None` without emitters.
    #[inline]
    pub fn pick_emitter_rows(&self, u0: f32) -> Option<(&EmitterRows, f32)> {
        let (i, u0) = self.emitter_table.sample(u0)?;
        Some((&self.emitter_rows[i], u0))
    }

    /// The solid-angle pdf with which `sample_emitter` would have chosen the point that a ray
    /// from a shading point hit at distance `dist`, with cosine `cos_l` at the emitter.
    pub fn emitter_pdf(&self, scene: &Scene, prim: u32, dist: f32, cos_l: f32) -> f32 {
        let e = if prim::is_sphere(prim) {
            Emitter::Sphere(prim::sphere_index(prim))
        } else {
            Emitter::Triangle(prim::triangle_index(prim))
        };
        self.emitter_pick_pdf(scene, e) * dist * dist / (emitter_area(scene, e) * cos_l.max(1e-12))
    }

    fn emitter_pick_pdf(&self, scene: &Scene, e: Emitter) -> f32 {
        emitter_area(scene, e) * luminance(emitter_radiance(scene, e)) / self.emitter_power
    }
}

/// Samples a scene light from shading point `p` with normal `n` (used for the sky).
pub fn sample_scene_light(light: &Light, p: Vec3, n: Vec3, u: [f32; 2]) -> Option<LightSample> {
    match *light {
        Light::Area { position, direction, dim_x, dim_y, radiance } => {
            let r = Rectangle::new(position, direction, dim_x, dim_y);
            r.sample(radiance, p, n, u)
        }
        Light::Point { position, radiance } => {
            let d = position - p;
            let dist = d.length();
            (dist > 0.0).then(|| LightSample {
                wi: d / dist,
                dist,
                li: radiance,
                pdf: 1.0,
                cos_light: 1.0,
            })
        }
        Light::Directional { direction, radiance } => Some(LightSample {
            wi: direction,
            dist: f32::INFINITY,
            li: radiance,
            pdf: 1.0,
            cos_light: 1.0,
        }),
        Light::Ambient { radiance } => {
            // Cosine-weighted about the surface normal; only the upper (+Y) sky emits.
            let (t, b) = crate::math::orthonormal_basis(n);
            let l = super::bsdf::cosine_hemisphere(u[0], u[1]);
            let wi = l.x * t + l.y * b + l.z * n;
            (wi.y > 0.0 && l.z > 0.0).then(|| LightSample {
                wi,
                dist: f32::INFINITY,
                li: radiance,
                pdf: l.z / PI,
                cos_light: 1.0,
            })
        }
    }
}

fn emitter_radiance(scene: &Scene, e: Emitter) -> Vec3 {
    let m = match e {
        Emitter::Triangle(i) => scene.triangle_materials[i as usize],
        Emitter::Sphere(i) => scene.spheres[i as usize].material,
    };
    match scene.materials[m as usize] {
        Material::Emission { radiance } => radiance,
        _ => Vec3::ZERO,
    }
}

fn emitter_area(scene: &Scene, e: Emitter) -> f32 {
    match e {
        Emitter::Triangle(i) => {
            let [a, b, c] = scene.triangle(i as usize);
            0.5 * (b - a).cross(c - a).length()
        }
        Emitter::Sphere(i) => {
            let r = scene.spheres[i as usize].radius;
            4.0 * PI * r * r
        }
    }
}

/// A uniformly distributed point on the emitter and its front-facing normal.
fn sample_emitter_point(scene: &Scene, e: Emitter, u1: f32, u2: f32) -> (Vec3, Vec3) {
    match e {
        Emitter::Triangle(i) => {
            let [a, b, c] = scene.triangle(i as usize);
            let s = u1.sqrt();
            let (b1, b2) = (1.0 - s, u2 * s);
            let q = a + b1 * (b - a) + b2 * (c - a);
            (q, (b - a).cross(c - a).normalize_or(Vec3::Y))
        }
        Emitter::Sphere(i) => {
            let s = scene.spheres[i as usize];
            let z = 1.0 - 2.0 * u1;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * PI * u2;
            let n = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            (s.center + s.radius * n, n)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::rectangle::sample_linear;
    use super::*;

    #[test]
    fn alias_table_picks_by_weight_and_rescales_uniformly() {
        let weights = [1.0f32, 0.0, 3.0, 0.5, 2.5, 1e-3];
        let table = AliasTable::new(&weights);
        let total: f32 = weights.iter().sum();
        let n = 200_000;
        let mut counts = [0usize; 6];
        let mut rescaled_sum = [0.0f64; 6];
        for k in 0..n {
            let u = (k as f32 + 0.5) / n as f32;
            let (i, v) = table.sample(u).unwrap();
            assert!((0.0..1.0).contains(&v));
            counts[i] += 1;
            rescaled_sum[i] += v as f64;
        }
        for i in 0..6 {
            let p = counts[i] as f32 / n as f32;
            assert!((p - weights[i] / total).abs() < 1e-3, "item {i}: {p}");
            if counts[i] > 1000 {
                let mean = rescaled_sum[i] / counts[i] as f64;
                assert!((mean - 0.5).abs() < 0.01, "item {i}: rescaled mean {mean}");
            }
        }
        assert!(AliasTable::new(&[]).sample(0.3).is_none());
        assert!(AliasTable::new(&[0.0, 0.0]).sample(0.3).is_none());
    }

    /// The course scenes' light (0.6 by 0.8 at y = 1.49, facing down) and receivers (point,
    /// shading normal) below it, close beside its plane, at a slant, far away, with the
    /// horizon through the light, and facing away from it.
    fn light_and_points() -> (Light, Vec<(Vec3, Vec3)>) {
        let light = Light::Area {
            position: Vec3::new(0.1, 1.49, -0.2),
            direction: Vec3::new(0.0, -1.0, 0.0),
            dim_x: Vec3::new(-0.6, 0.0, 0.0),
            dim_y: Vec3::new(0.0, 0.0, 0.8),
            radiance: Vec3::splat(10.0),
        };
        let points = vec![
            (Vec3::new(0.0, 0.0, 0.0), Vec3::Y),
            (Vec3::new(0.1, 1.2, -0.2), Vec3::Y),
            (Vec3::new(0.55, 1.47, 0.3), Vec3::new(-1.0, 0.0, 0.0)),
            (Vec3::new(-0.21, 1.489, 0.25), Vec3::new(0.3, 0.2, -1.0).normalize()),
            (Vec3::new(-1.0, 0.3, 0.9), Vec3::new(1.0, 1.0, -0.5).normalize()),
            (Vec3::new(0.4, -8.0, 0.1), Vec3::Y),
            (Vec3::new(0.1, 1.3, -0.2), Vec3::new(1.0, 0.3, 0.0).normalize()),
            (Vec3::new(0.0, 0.0, 0.0), -Vec3::Y),
        ];
        (light, points)
    }

    /// Irradiance at `p` (normal `n`) from the light, by a 2000 x 2000 midpoint rule over its
    /// area in f64.
    fn irradiance_by_quadrature(light: &Light, p: Vec3, n: Vec3) -> f64 {
        let Light::Area { position, direction, dim_x, dim_y, radiance } = *light else {
            unreachable!()
        };
        let m = 2000;
        let area = dim_x.cross(dim_y).length() as f64;
        let mut sum = 0.0f64;
        for i in 0..m {
            for j in 0..m {
                let (u, v) = ((i as f64 + 0.5) / m as f64 - 0.5, (j as f64 + 0.5) / m as f64 - 0.5);
                let q = [0, 1, 2].map(|c| {
                    position[c] as f64 + u * dim_x[c] as f64 + v * dim_y[c] as f64 - p[c] as f64
                });
                let r2 = q.iter().map(|x| x * x).sum::<f64>();
                let r = r2.sqrt();
                let cos_x = (0..3).map(|c| q[c] * n[c] as f64).sum::<f64>() / r;
                let cos_l = -(0..3).map(|c| q[c] * direction[c] as f64).sum::<f64>() / r;
                if cos_x > 0.0 && cos_l > 0.0 {
                    sum += cos_x * cos_l / r2;
                }
            }
        }
        sum * area / (m * m) as f64 * radiance.x as f64
    }

    /// Irradiance at `p` by `sample_scene_light` on a stratified grid of `u`.
    fn irradiance_by_sampling(light: &Light, p: Vec3, n: Vec3) -> f64 {
        let m = 512;
        let mut sum = 0.0f64;
        for i in 0..m {
            for j in 0..m {
                let u = [(i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32];
                if let Some(s) = sample_scene_light(light, p, n, u) {
                    let cos_x = s.wi.dot(n).max(0.0);
                    sum += (s.li.x * cos_x / s.pdf) as f64;
                }
            }
        }
        sum / (m * m) as f64
    }

    #[test]
    fn area_light_samples_integrate_to_the_irradiance() {
        let (light, points) = light_and_points();
        for (p, n) in points {
            let reference = irradiance_by_quadrature(&light, p, n);
            let sampled = irradiance_by_sampling(&light, p, n);
            let err = (sampled - reference).abs() / reference.max(1e-30);
            assert!(err < 1e-3, "at {p}: sampled {sampled}, quadrature {reference}");
        }
    }

    #[test]
    fn area_light_samples_do_not_depend_on_the_scene_units() {
        // Irradiance does not change when the light and the receiver are scaled together; at
        // 1e-8 and 1e8 the corners' weights (1 / distance^3) would overflow and underflow the
        // draws' squares if they were not normalised (NaN and lost light: checked).
        let (light, points) = light_and_points();
        let Light::Area { position, direction, dim_x, dim_y, radiance } = light else {
            unreachable!()
        };
        for scale in [1e-8f32, 1e8] {
            let scaled = Light::Area {
                position: position * scale,
                direction,
                dim_x: dim_x * scale,
                dim_y: dim_y * scale,
                radiance,
            };
            for &(p, n) in &points[..5] {
                let reference = irradiance_by_sampling(&light, p, n);
                let sampled = irradiance_by_sampling(&scaled, p * scale, n);
                let err = (sampled - reference).abs() / reference;
                assert!(err < 1e-3, "scale {scale} at {p}: {sampled} against {reference}");
            }
        }
    }

    #[test]
    fn area_light_samples_lie_on_the_light_and_their_pdf_integrates_to_one() {
        let (light, points) = light_and_points();
        let Light::Area { position, direction, dim_x, dim_y, .. } = light else { unreachable!() };
        let r = Rectangle::new(position, direction, dim_x, dim_y);
        for (p, n) in &points {
            // The mean of 1 / pdf over the samples is the light's solid angle (analytic, in
            // f64) when the pdf is the density the points are drawn with.
            let m = 2048;
            let mut sum = 0.0f64;
            for i in 0..m {
                for j in 0..m {
                    let u = [(i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32];
                    let ls = r.sample(Vec3::ONE, *p, *n, u).unwrap();
                    let q = *p + ls.wi * ls.dist - position;
                    let (a, b) = (
                        q.dot(dim_x) / dim_x.length_squared(),
                        q.dot(dim_y) / dim_y.length_squared(),
                    );
                    assert!(
                        a.abs() <= 0.5 + 1e-4 && b.abs() <= 0.5 + 1e-4,
                        "off the light: {a} {b}"
                    );
                    assert!(q.dot(direction).abs() < 1e-4, "off the light's plane");
                    sum += 1.0 / ls.pdf as f64;
                }
            }
            let exact = solid_angle_f64(position, dim_x, dim_y, *p);
            let err = (sum / (m * m) as f64 - exact).abs() / exact;
            assert!(
                err < 1e-3,
                "at {p}: mean 1 / pdf {} against the solid angle {exact}",
                sum / (m * m) as f64
            );
        }
    }

    #[test]
    fn linear_samples_follow_their_density() {
        for (a, b) in [(1.0f32, 1.0f32), (0.01, 1.0), (3.0, 0.02), (1e-6, 1e-6), (2.0, 2.5)] {
            // The CDF at x is (a x + (b - a) x^2 / 2) / ((a + b) / 2): invert it and compare.
            for k in 0..1000 {
                let xi = k as f32 / 1000.0;
                let x = sample_linear(xi, a, b) as f64;
                let (a, b) = (a as f64, b as f64);
                let cdf = (a * x + (b - a) * x * x / 2.0) / ((a + b) / 2.0);
                assert!((cdf - xi as f64).abs() < 1e-5, "a {a} b {b} xi {xi}: x {x} has CDF {cdf}");
            }
        }
    }

    /// The solid angle of the rectangle from `p`, as two triangles (Van Oosterom and Strackee).
    fn solid_angle_f64(position: Vec3, dim_x: Vec3, dim_y: Vec3, p: Vec3) -> f64 {
        let corner = |u: f64, v: f64| -> [f64; 3] {
            [0, 1, 2].map(|c| {
                position[c] as f64 + u * dim_x[c] as f64 + v * dim_y[c] as f64 - p[c] as f64
            })
        };
        let tri = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| -> f64 {
            let len = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let dot = |v: [f64; 3], w: [f64; 3]| v[0] * w[0] + v[1] * w[1] + v[2] * w[2];
            let cross =
                [b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]];
            let (la, lb, lc) = (len(a), len(b), len(c));
            let num = dot(a, cross).abs();
            let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
            2.0 * num.atan2(den)
        };
        let (a, b, c, d) =
            (corner(-0.5, -0.5), corner(0.5, -0.5), corner(0.5, 0.5), corner(-0.5, 0.5));
        tri(a, b, c) + tri(a, c, d)
    }
}
