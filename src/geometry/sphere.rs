//! Ray-sphere intersection by the quadratic (the course's analytic spheres).

use crate::math::Ray;
use crate::scene::Sphere;

/// The nearest root of |o + t d - c|^2 = r^2 inside [t_min, t_max]: the near root, or the far
/// one when the near root is outside the interval (e.g. the ray starts inside the sphere).
#[inline]
pub fn intersect_sphere(ray: &Ray, s: &Sphere) -> Option<f32> {
    let oc = ray.origin - s.center;
    let a = ray.dir.length_squared();
    let half_b = oc.dot(ray.dir);
    let c = oc.length_squared() - s.radius * s.radius;
    let disc = half_b * half_b - a * c;
    if !(disc >= 0.0) || a == 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    // The numerically stable pair of roots (no cancellation between half_b and sq).
    let q = -(half_b + sq.copysign(half_b));
    let (mut t0, mut t1) = (q / a, if q != 0.0 { c / q } else { q / a });
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    [t0, t1].into_iter().find(|&t| t >= ray.t_min && t <= ray.t_max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn unit() -> Sphere {
        Sphere { center: Vec3::new(0.0, 0.0, 5.0), radius: 1.0, material: 0 }
    }

    #[test]
    fn near_root_from_outside_far_root_from_inside() {
        let r = Ray::new(Vec3::ZERO, Vec3::Z);
        assert!((intersect_sphere(&r, &unit()).unwrap() - 4.0).abs() < 1e-6);
        let inside = Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::Z);
        assert!((intersect_sphere(&inside, &unit()).unwrap() - 1.0).abs() < 1e-6);
        // The interval excludes the near root: the far one is returned.
        let r2 = Ray::segment(Vec3::ZERO, Vec3::Z, 4.5, 100.0);
        assert!((intersect_sphere(&r2, &unit()).unwrap() - 6.0).abs() < 1e-5);
        // Both outside the interval, or missing entirely.
        assert!(intersect_sphere(&Ray::segment(Vec3::ZERO, Vec3::Z, 0.0, 3.9), &unit()).is_none());
        assert!(intersect_sphere(&Ray::new(Vec3::ZERO, Vec3::X), &unit()).is_none());
        assert!(intersect_sphere(&Ray::new(Vec3::ZERO, Vec3::ZERO), &unit()).is_none());
    }
}
