//! The SoA arrays the wavefront's stages pass between each other, and the integrator writes.
//!
//! Path state is stored column by column (one `Vec` per field) so a stage touches only the
//! fields it needs. Queue entries hold a whole `Ray` record (32 bytes, read whole by traversal)
//! plus the index of the path it belongs to.

use crate::math::{Ray, Vec3};
use crate::sampler::PathSampler;

/// A pixel's samples in a full wavefront pass (`wavefront::SAMPLE_BATCH`, which asserts that
/// the two agree): the number that `PathState::push_pixel_samples` starts with fixed-size
/// copies.
pub(crate) const FILL: usize = 16;

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

    /// Adds one path per sampler in `samplers`, all for pixel `pixel`, each with throughput 1,
    /// no radiance, a `bsdf_pdf` of 0 and a zero-bounce weight of 1. A pixel's samples are
    /// started together so that each column grows once per pixel, not once per path (pushed
    /// path by path, the columns' capacity checks were a third of camera-ray generation:
    /// PERF.md, "Whole renders").
    pub fn push_pixel_samples(
        &mut self,
        pixel: u32,
        samplers: impl ExactSizeIterator<Item = PathSampler>,
    ) {
        let n = samplers.len();
        let end = self.len() + n;
        self.sampler.extend(samplers);
        if n == FILL {
            // Copies of a fixed size compile to a few vector stores, where `resize` stored the
            // values one by one: camera-ray generation 0.036 -> 0.032 s at `-m 1` (PERF.md,
            // "Whole renders").
            self.pixel.extend_from_slice(&[pixel; FILL]);
            self.throughput.extend_from_slice(&[Vec3::ONE; FILL]);
            self.radiance.extend_from_slice(&[Vec3::ZERO; FILL]);
            self.bsdf_pdf.extend_from_slice(&[0.0; FILL]);
            self.zero_bounce_weight.extend_from_slice(&[1.0; FILL]);
            return;
        }
        self.pixel.resize(end, pixel);
        self.throughput.resize(end, Vec3::ONE);
        self.radiance.resize(end, Vec3::ZERO);
        self.bsdf_pdf.resize(end, 0.0);
        self.zero_bounce_weight.resize(end, 1.0);
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

    /// Makes room for `n` more rays.
    pub fn reserve(&mut self, n: usize) {
        self.rays.reserve(n);
        self.path.reserve(n);
    }

    /// Queues `ray` for path `path`.
    pub fn push(&mut self, ray: Ray, path: u32) {
        self.rays.push(ray);
        self.path.push(path);
    }

    /// Queues ray `i` of `records` (`Ray::record`) for path `path[i]`, for every `i`, in
    /// order: each column grows once.
    pub fn push_records(&mut self, records: &[[f32; 8]], path: &[u32]) {
        self.rays.extend(records.iter().map(Ray::from_record));
        self.path.extend_from_slice(path);
    }

    /// Queues `rays` for the consecutive paths `first_path`, `first_path + 1`, ...: each
    /// column grows once for the run.
    pub fn push_run(&mut self, rays: impl ExactSizeIterator<Item = Ray>, first_path: u32) {
        let n = rays.len() as u32;
        self.rays.extend(rays);
        self.path.extend(first_path..first_path + n);
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

    /// Makes room for `n` more rays.
    pub fn reserve(&mut self, n: usize) {
        self.rays.reserve(n);
        self.radiance.reserve(n);
        self.path.reserve(n);
    }

    /// Queues `ray` with its radiance (or weight) for path `path`.
    pub fn push(&mut self, ray: Ray, radiance: Vec3, path: u32) {
        self.rays.push(ray);
        self.radiance.push(radiance);
        self.path.push(path);
    }

    /// Queues ray `i` of `records` (`Ray::record`) with radiance `(r[i], g[i], b[i])` for path
    /// `path[i]`, for every `i`, in order: each column grows once.
    pub fn push_records(&mut self, records: &[[f32; 8]], [r, g, b]: [&[f32]; 3], path: &[u32]) {
        self.rays.extend(records.iter().map(Ray::from_record));
        let rgb = r.iter().zip(g).zip(b);
        self.radiance.extend(rgb.map(|((&r, &g), &b)| Vec3::new(r, g, b)));
        self.path.extend_from_slice(path);
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
