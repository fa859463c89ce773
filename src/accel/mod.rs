//! Acceleration structure: the public surface every stage uses.
//!
//! Triangles live in a binned-SAH BVH (flat, depth-first, 32-byte nodes) over SoA triangle
//! columns in leaf order. The course scenes hold at most a handful of analytic spheres, so
//! they are a short list tested after the triangles rather than BVH primitives.

pub mod build;
pub mod node;
pub mod traverse_single;

use std::time::{Duration, Instant};

use crate::geometry::sphere::intersect_sphere;
use crate::geometry::TriangleSoa;
use crate::math::{Aabb, Hit, Ray};
use crate::scene::{Scene, Sphere};

pub use build::BuildParams;
pub use node::BvhNode;

/// Sphere hits carry this bit in `Hit::prim`; the low bits are the sphere index.
pub const SPHERE_BIT: u32 = 1 << 31;

/// Which structure to build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AccelKind {
    #[default]
    Bvh,
    /// Every triangle in one leaf, tested for every ray (`--no-bvh`): the oracle for tests
    /// and the write-up's timing comparison.
    BruteForce,
}

/// Exact work counters. `node_tests` counts ray-box tests, `triangle_tests` ray-triangle tests
/// (a SIMD leaf test of k triangles counts k), `sphere_tests` ray-sphere tests, `rays` queries.
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
    nodes: Vec<BvhNode>,
    tris: TriangleSoa,
    spheres: Vec<Sphere>,
    bounds: Aabb,
    build_time: Duration,
}

impl Accel {
    pub fn build(scene: &Scene, kind: AccelKind) -> Accel {
        Accel::build_with(scene, kind, BuildParams::default())
    }

    pub fn build_with(scene: &Scene, kind: AccelKind, params: BuildParams) -> Accel {
        let t0 = Instant::now();
        let corners: Vec<[glam::Vec3; 3]> =
            (0..scene.triangles.len()).map(|i| scene.triangle(i)).collect();
        let (nodes, order) = match kind {
            AccelKind::Bvh => {
                let boxes: Vec<Aabb> = corners.iter().map(|c| Aabb::from_points(c)).collect();
                let built = build::build(&boxes, params);
                (built.nodes, built.order)
            }
            AccelKind::BruteForce => {
                let b = corners.iter().fold(Aabb::EMPTY, |b, c| b.union(Aabb::from_points(c)));
                let (min, max) =
                    if b.is_empty() { ([0.0; 3], [0.0; 3]) } else { (b.min.into(), b.max.into()) };
                let n = corners.len() as u32;
                (vec![BvhNode { min, index: 0, max, count: n }], (0..n).collect())
            }
        };
        let tris = TriangleSoa::from_order(&corners, &order);
        let nodes = if tris.is_empty() { Vec::new() } else { nodes };
        Accel {
            nodes,
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

    pub fn nodes(&self) -> &[BvhNode] {
        &self.nodes
    }

    pub fn triangles(&self) -> &TriangleSoa {
        &self.tris
    }

    /// Bytes held by the structure: nodes plus triangle columns.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<BvhNode>() + self.tris.memory_bytes()
    }

    /// The closest hit along the ray within [t_min, t_max].
    pub fn intersect(&self, ray: &Ray, stats: &mut TraceStats) -> Option<Hit> {
        stats.rays += 1;
        let mut r = *ray;
        let mut best = traverse_single::intersect(&self.nodes, &self.tris, &mut r, stats);
        for (i, s) in self.spheres.iter().enumerate() {
            stats.sphere_tests += 1;
            if let Some(t) = intersect_sphere(&r, s) {
                r.t_max = t;
                best = Some(Hit { t, u: 0.0, v: 0.0, prim: SPHERE_BIT | i as u32 });
            }
        }
        best
    }

    /// Whether anything blocks the ray within [t_min, t_max].
    pub fn occluded(&self, ray: &Ray, stats: &mut TraceStats) -> bool {
        stats.rays += 1;
        if traverse_single::occluded(&self.nodes, &self.tris, ray, stats) {
            return true;
        }
        self.spheres.iter().any(|s| {
            stats.sphere_tests += 1;
            intersect_sphere(ray, s).is_some()
        })
    }
}
