//! The SoA arrays the wavefront's stages pass between each other, and the integrator writes.
//!
//! Path state is stored column by column (one `Vec` per field) so a stage touches only the
//! fields it needs. Queue entries hold a whole `Ray` record (32 bytes, read whole by traversal)
//! plus the index of the path it belongs to.

use crate::math::{Ray, Vec3};
use crate::sampler::PathSampler;

/// One entry per path (pixel sample) of the current batch.
#[derive(Default)]
pub struct PathState {
    /// Pixel index within the tile.
    pub pixel: Vec<u32>,
    /// Product of BSDF weights along the path so far.
    pub throughput: Vec<Vec3>,
    /// Radiance gathered so far.
    pub radiance: Vec<Vec3>,
    /// Solid-angle pdf of the BSDF sample that made the current ray; 0 for camera rays and
    /// specular bounces (MIS and the emission rules read it).
    pub bsdf_pdf: Vec<f32>,
    /// Each path's random numbers (see `sampler`).
    pub sampler: Vec<PathSampler>,
    /// The weight of the emission its camera ray sees: 1, or 1 / (K + 1) where K extra camera
    /// rays share that estimate (emitter outlines, `wavefront::stages::generate`).
    pub zero_bounce_weight: Vec<f32>,
}

impl PathState {
    /// Empties every column, keeping the allocations.
    pub fn clear(&mut self) {
        self.pixel.clear();
        self.throughput.clear();
        self.radiance.clear();
        self.bsdf_pdf.clear();
        self.sampler.clear();
        self.zero_bounce_weight.clear();
    }

    /// Adds a path for pixel `pixel` with throughput 1, no radiance, a `bsdf_pdf` of 0 and a
    /// zero-bounce weight of 1; returns its index.
    pub fn push(&mut self, pixel: u32, sampler: PathSampler) -> u32 {
        let id = self.pixel.len() as u32;
        self.pixel.push(pixel);
        self.throughput.push(Vec3::ONE);
        self.radiance.push(Vec3::ZERO);
        self.bsdf_pdf.push(0.0);
        self.sampler.push(sampler);
        self.zero_bounce_weight.push(1.0);
        id
    }

    /// The number of paths.
    pub fn len(&self) -> usize {
        self.pixel.len()
    }

    /// Whether there are no paths.
    pub fn is_empty(&self) -> bool {
        self.pixel.is_empty()
    }
}

/// Rays waiting for a closest-hit query.
#[derive(Default)]
pub struct RayQueue {
    /// The rays, as whole `Ray` records.
    pub rays: Vec<Ray>,
    /// The path each ray belongs to (index into `PathState`).
    pub path: Vec<u32>,
}

impl RayQueue {
    /// Empties the queue, keeping the allocations.
    pub fn clear(&mut self) {
        self.rays.clear();
        self.path.clear();
    }

    /// Queues `ray` for path `path`.
    pub fn push(&mut self, ray: Ray, path: u32) {
        self.rays.push(ray);
        self.path.push(path);
    }

    /// The number of queued rays.
    pub fn len(&self) -> usize {
        self.rays.len()
    }

    /// Whether no ray is queued.
    pub fn is_empty(&self) -> bool {
        self.rays.is_empty()
    }
}

/// Direct-light rays. As shadow rays (any hit): if `rays[i]` is unblocked, `radiance[i]` is
/// added to path `path[i]`. As emission probes (closest hit, uniform hemisphere sampling):
/// `radiance[i]` is a weight, multiplied by the emission of whatever front face the ray hits.
#[derive(Default)]
pub struct ShadowQueue {
    /// The rays, as whole `Ray` records.
    pub rays: Vec<Ray>,
    /// Per ray: the radiance it adds (shadow rays) or the weight of the emission it finds (probes).
    pub radiance: Vec<Vec3>,
    /// The path each ray belongs to (index into `PathState`).
    pub path: Vec<u32>,
}

impl ShadowQueue {
    /// Empties the queue, keeping the allocations.
    pub fn clear(&mut self) {
        self.rays.clear();
        self.radiance.clear();
        self.path.clear();
    }

    /// Queues `ray` with its radiance (or weight) for path `path`.
    pub fn push(&mut self, ray: Ray, radiance: Vec3, path: u32) {
        self.rays.push(ray);
        self.radiance.push(radiance);
        self.path.push(path);
    }

    /// The number of queued rays.
    pub fn len(&self) -> usize {
        self.rays.len()
    }

    /// Whether no ray is queued.
    pub fn is_empty(&self) -> bool {
        self.rays.is_empty()
    }
}
