//! What next-event estimation samples, and with which pdf.
//!
//! Two sources of light exist in a course scene (SCENE_FORMAT.md): *scene lights* (area, point,
//! directional, ambient), which are not geometry and are reached only by light sampling, and
//! *emissive geometry*, which camera and BSDF rays see. In the course's semantics light
//! sampling samples the scene lights. In the emissive-geometry mode the emissive triangles and
//! spheres themselves are the area lights (picked by power, sampled by area) and the scene's CGL
//! area lights are left out, since in the course files they duplicate the emissive quads.

use std::f32::consts::PI;

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

/// An emissive triangle as `sample_emitter` sees it.
#[derive(Debug, Clone, Copy, Default)]
pub struct TriangleEmitter {
    /// First corner.
    pub a: Vec3,
    /// Second corner.
    pub b: Vec3,
    /// Third corner.
    pub c: Vec3,
    /// The emitted radiance.
    pub radiance: Vec3,
    /// The probability of picking it (its share of the emitters' power).
    pub pick_pdf: f32,
    /// Its area.
    pub area: f32,
}

/// The lights of one render.
#[derive(Debug, Clone, Default)]
pub struct LightSet {
    /// Scene lights sampled one by one (all of them in course mode; all but `Area` in the
    /// emissive-geometry mode).
    pub scene_lights: Vec<Light>,
    emitters: Vec<Emitter>,
    /// Per emitter, what `pick_triangle_emitter` hands out (a default for spheres): computed
    /// once here rather than per pick, where the corners' loads, two areas and the pick pdf
    /// were a tenth of a `-m 5 --shading mis` render (PERF.md, "Whole renders").
    triangle_records: Vec<TriangleEmitter>,
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
        let below = 1.0 - f32::EPSILON;
        Some(if f < keep {
            (i, (f / keep).min(below))
        } else {
            (alias as usize, ((f - keep) / (1.0 - keep)).min(below))
        })
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
        set.triangle_records =
            set.emitters.iter().map(|&e| set.triangle_record(scene, e)).collect();
        set
    }

    /// What picking emitter `e` gives `diffuse::shade_diffuse` (a default for a sphere).
    fn triangle_record(&self, scene: &Scene, e: Emitter) -> TriangleEmitter {
        let Emitter::Triangle(t) = e else { return TriangleEmitter::default() };
        let [a, b, c] = scene.triangle(t as usize);
        let radiance = emitter_radiance(scene, e);
        let (pick_pdf, area) = (self.emitter_pick_pdf(scene, e), emitter_area(scene, e));
        TriangleEmitter { a, b, c, radiance, pick_pdf, area }
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

    /// The first half of `sample_emitter` for triangle emitters: the emitter `u0` picks, and
    /// `u0` rescaled within its share; the same values `sample_emitter` computes.
    #[inline]
    pub fn pick_triangle_emitter(&self, u0: f32) -> Option<(TriangleEmitter, f32)> {
        let (i, u0) = self.emitter_table.sample(u0)?;
        let Emitter::Triangle(_) = self.emitters[i] else { return None };
        Some((self.triangle_records[i], u0))
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
            let q = position + (u[0] - 0.5) * dim_x + (u[1] - 0.5) * dim_y;
            let d = q - p;
            let dist = d.length();
            let wi = d / dist;
            // One-sided: it radiates only into the half-space `direction` points to.
            let cos_l = -direction.dot(wi);
            let area = dim_x.cross(dim_y).length();
            (cos_l > 0.0 && dist > 0.0 && area > 0.0).then(|| LightSample {
                wi,
                dist,
                li: radiance,
                pdf: dist * dist / (area * cos_l),
                cos_light: cos_l,
            })
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
}
