//! Ray-sphere intersection by the quadratic (the course's analytic spheres).

use crate::math::Ray;
use crate::scene::Sphere;

/// The nearest root of |o + t d - c|^2 = r^2 inside [t_min, t_max]: the near root, or the far
/// one when the near root is outside the interval (e.g. the ray starts inside the sphere).
///
/// The discriminant b^2 - a c is computed as a r^2 - |(o - c) x d|^2, an identity (Lagrange's)
/// in which neither term is much larger than the result (Haines et al., Ray Tracing Gems ch. 7,
/// compute the same distance from the centre to the ray's line another way): the two terms of
/// b^2 - a c are both about |o - c|^4 and cancel, which for a small sphere seen from afar left
/// an error of several per cent of r^2 (hits reported up to 2 % of the radius outside a sphere
/// of radius 0.012 seen from 6 units, PERF.md "Whole renders").
#[inline]
pub fn intersect_sphere(ray: &Ray, s: &Sphere) -> Option<f32> {
    let oc = ray.origin - s.center;
    let a = ray.dir.length_squared();
    let half_b = oc.dot(ray.dir);
    let c = oc.length_squared() - s.radius * s.radius;
    let disc = a * (s.radius * s.radius) - oc.cross(ray.dir).length_squared();
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

    /// A small sphere seen from afar: every reported hit lies on the sphere to within a
    /// thousandth of its radius (the textbook discriminant put them up to 2 % outside), and
    /// rays that pass within that distance of the rim are found.
    #[test]
    fn small_far_spheres_are_hit_where_they_are() {
        let s = Sphere {
            center: Vec3::new(-0.196344, 1.0026239, -0.68548197),
            radius: 0.012,
            material: 0,
        };
        let o = Vec3::new(0.0, 1.0, 5.2);
        let mut rng = crate::sampler::Pcg32::new(9, 9);
        let (mut hits, mut grazing) = (0, 0);
        for _ in 0..20_000 {
            let aim = s.center
                + 2.0
                    * s.radius
                    * (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5);
            let r = Ray::new(o, (aim - o).normalize());
            // Distance from the centre to the ray's line, in f64.
            let (oc, d) = ((o - s.center).as_dvec3(), r.dir.as_dvec3());
            let miss = (oc - oc.dot(d) * d).length() - s.radius as f64;
            match intersect_sphere(&r, &s) {
                Some(t) => {
                    let p = r.at(t).as_dvec3();
                    let off = ((p - s.center.as_dvec3()).length() - s.radius as f64).abs();
                    assert!(off < 1e-3 * s.radius as f64, "hit {off} off the sphere");
                    assert!(miss < 1e-3 * s.radius as f64, "hit a line {miss} outside");
                    hits += 1;
                }
                None => assert!(miss > -1e-3 * s.radius as f64, "missed a line {miss} inside"),
            }
            grazing += (miss.abs() < 0.02 * s.radius as f64) as u32;
        }
        assert!(hits > 5000 && grazing > 50, "{hits} hits, {grazing} grazing");
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
