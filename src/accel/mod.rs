//! Acceleration structure: the public surface every stage uses.
//!
//! PLACEHOLDER: brute force over the scene until the BVH lands (issue #2).

use std::time::Duration;

use crate::math::{Aabb, Hit, Ray};
use crate::scene::Scene;

/// Sphere hits carry this bit in `Hit::prim`; the low bits are the sphere index.
pub const SPHERE_BIT: u32 = 1 << 31;

/// Which structure to build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AccelKind {
    #[default]
    Bvh,
    /// Test every primitive for every ray (`--no-bvh`), the oracle for tests.
    BruteForce,
}

/// Exact work counters. `node_tests` counts ray-box tests, `triangle_tests` ray-triangle tests,
/// `sphere_tests` ray-sphere tests, `rays` the queries made.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TraceStats {
    pub rays: u64,
    pub node_tests: u64,
    pub triangle_tests: u64,
    pub sphere_tests: u64,
}

impl TraceStats {
    pub fn add(&mut self, o: &TraceStats) {
        self.rays += o.rays;
        self.node_tests += o.node_tests;
        self.triangle_tests += o.triangle_tests;
        self.sphere_tests += o.sphere_tests;
    }
}

pub struct Accel {
    tris: Vec<[glam::Vec3; 3]>,
    spheres: Vec<crate::scene::Sphere>,
    bounds: Aabb,
    build_time: Duration,
}

impl Accel {
    pub fn build(scene: &Scene, _kind: AccelKind) -> Accel {
        let t0 = std::time::Instant::now();
        let tris = (0..scene.triangles.len()).map(|i| scene.triangle(i)).collect();
        Accel {
            tris,
            spheres: scene.spheres.clone(),
            bounds: scene.bounds(),
            build_time: t0.elapsed(),
        }
    }

    pub fn build_time(&self) -> Duration {
        self.build_time
    }

    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Bytes held by the structure (triangles and nodes).
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of_val(self.tris.as_slice())
    }

    pub fn intersect(&self, ray: &Ray, stats: &mut TraceStats) -> Option<Hit> {
        stats.rays += 1;
        let mut r = *ray;
        let mut best = None;
        for (i, t) in self.tris.iter().enumerate() {
            stats.triangle_tests += 1;
            if let Some((tt, u, v)) = mt(&r, t) {
                r.t_max = tt;
                best = Some(Hit { t: tt, u, v, prim: i as u32 });
            }
        }
        for (i, s) in self.spheres.iter().enumerate() {
            stats.sphere_tests += 1;
            let oc = r.origin - s.center;
            let a = r.dir.dot(r.dir);
            let b = oc.dot(r.dir);
            let c = oc.dot(oc) - s.radius * s.radius;
            let disc = b * b - a * c;
            if disc < 0.0 {
                continue;
            }
            let sq = disc.sqrt();
            for t in [(-b - sq) / a, (-b + sq) / a] {
                if t >= r.t_min && t <= r.t_max {
                    r.t_max = t;
                    best = Some(Hit { t, u: 0.0, v: 0.0, prim: SPHERE_BIT | i as u32 });
                    break;
                }
            }
        }
        best
    }

    pub fn occluded(&self, ray: &Ray, stats: &mut TraceStats) -> bool {
        self.intersect(ray, stats).is_some()
    }
}

fn mt(r: &Ray, t: &[glam::Vec3; 3]) -> Option<(f32, f32, f32)> {
    let e1 = t[1] - t[0];
    let e2 = t[2] - t[0];
    let s = r.origin - t[0];
    let s1 = r.dir.cross(e2);
    let s2 = s.cross(e1);
    let det = s1.dot(e1);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let tt = s2.dot(e2) * inv;
    let u = s1.dot(s) * inv;
    let v = s2.dot(r.dir) * inv;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && tt >= r.t_min && tt <= r.t_max).then_some((tt, u, v))
}
