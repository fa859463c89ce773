use glam::Vec3;

/// A ray with its valid parameter interval [t_min, t_max]. A closest-hit query shrinks `t_max`
/// to the hit distance, so later tests only accept nearer hits (the course convention).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}

impl Ray {
    pub fn new(origin: Vec3, dir: Vec3) -> Ray {
        Ray { origin, dir, t_min: 0.0, t_max: f32::INFINITY }
    }

    pub fn segment(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Ray {
        Ray { origin, dir, t_min, t_max }
    }

    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }
}

/// The closest hit found so far. `prim` is a primitive id as defined by `geometry::prim`
/// (a scene triangle index, or a sphere index with `SPHERE_BIT` set); `u`, `v` are the
/// barycentric coordinates of vertices 1 and 2 for triangles (unused for spheres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
    pub prim: u32,
}
