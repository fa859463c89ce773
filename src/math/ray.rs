//! Rays with their valid interval, and the hit a closest-hit query returns.

use glam::Vec3;

/// A ray with its valid parameter interval [t_min, t_max]. A closest-hit query shrinks `t_max`
/// to the hit distance, so later tests only accept nearer hits (the course convention).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Where the ray starts (`t = 0`).
    pub origin: Vec3,
    /// The direction; distances `t` are in multiples of its length.
    pub dir: Vec3,
    /// Start of the valid interval.
    pub t_min: f32,
    /// End of the valid interval.
    pub t_max: f32,
}

impl Ray {
    /// A ray over [0, inf).
    pub fn new(origin: Vec3, dir: Vec3) -> Ray {
        Ray { origin, dir, t_min: 0.0, t_max: f32::INFINITY }
    }

    /// A ray over [t_min, t_max].
    pub fn segment(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Ray {
        Ray { origin, dir, t_min, t_max }
    }

    /// The ray as a record of 8 floats: origin, direction, t_min, t_max (the layout of ray
    /// files and of the transposes that turn records into SIMD lanes).
    #[inline(always)]
    pub fn record(&self) -> [f32; 8] {
        let (o, d) = (self.origin, self.dir);
        [o.x, o.y, o.z, d.x, d.y, d.z, self.t_min, self.t_max]
    }

    /// The ray of a `record`.
    #[inline(always)]
    pub fn from_record(r: &[f32; 8]) -> Ray {
        Ray::segment(Vec3::new(r[0], r[1], r[2]), Vec3::new(r[3], r[4], r[5]), r[6], r[7])
    }

    /// The point `origin + t * dir`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }
}

/// `None` for every ray of `out`, by copies of a constant block: LLVM vectorises
/// `fill(None)`, which writes only each record's tag, into 8-lane scatters, slow on AMD's
/// AVX-512 (PERF.md, "On an AMD EPYC with AVX-512 (Zen 4)").
pub fn fill_no_hits(out: &mut [Option<Hit>]) {
    for c in out.chunks_mut(NO_HITS.len()) {
        c.copy_from_slice(&NO_HITS[..c.len()]);
    }
}

/// `hits` as `n` records of `None` (as `fill_no_hits`).
pub fn reset_hits(hits: &mut Vec<Option<Hit>>, n: usize) {
    hits.clear();
    hits.reserve(n);
    while hits.len() < n {
        let k = (n - hits.len()).min(NO_HITS.len());
        hits.extend_from_slice(&NO_HITS[..k]);
    }
}

const NO_HITS: [Option<Hit>; 16] = [None; 16];

/// The closest hit found so far. `prim` is a primitive id as defined by `geometry::prim`
/// (a scene triangle index, or a sphere index with `SPHERE_BIT` set); `u`, `v` are the
/// barycentric coordinates of vertices 1 and 2 for triangles (unused for spheres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the ray ([`Ray::at`] gives the point).
    pub t: f32,
    /// Barycentric weight of vertex 1 (triangles).
    pub u: f32,
    /// Barycentric weight of vertex 2 (triangles).
    pub v: f32,
    /// The primitive id (`geometry::prim`).
    pub prim: u32,
}
