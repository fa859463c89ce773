//! A CGL area light: a parallelogram that radiates into one half-space. Its points are drawn
//! with a density fitted to the direct light's integrand at the corners (`Rectangle::sample`),
//! and the same density is evaluated for a direction found otherwise (`Rectangle::hit_by`), so
//! that a glossy vertex can weigh its light samples against its BSDF sample (`path`).

use crate::math::Vec3;

use super::lights::LightSample;

/// A rectangular area light: a corner, the two edges, the normal of its emitting side.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Rectangle {
    pub(crate) corner: Vec3,
    pub(crate) dim_x: Vec3,
    pub(crate) dim_y: Vec3,
    pub(crate) direction: Vec3,
    pub(crate) area: f32,
}

/// Each corner's weight is at least this share of the largest, so that the density stays
/// positive over the whole light (the noise moved by under 0.3% between 0.001 and 0.2).
pub(crate) const CORNER_WEIGHT_FLOOR: f32 = 0.01;

impl Rectangle {
    /// The light `position + u dim_x + v dim_y` (u, v in [-1/2, 1/2]) facing `direction`.
    pub(crate) fn new(position: Vec3, direction: Vec3, dim_x: Vec3, dim_y: Vec3) -> Rectangle {
        Rectangle {
            corner: position - 0.5 * dim_x - 0.5 * dim_y,
            dim_x,
            dim_y,
            direction,
            area: dim_x.cross(dim_y).length(),
        }
    }

    /// A point of the light for `u` in [0, 1)^2 seen from `p` (shading normal `n`). Its
    /// coordinates along the two edges are drawn independently, each with a density linear
    /// between the weights of the light's two ends along that edge, where a corner's weight
    /// is the direct light's integrand there, cos(receiver) cos(light) / distance^2 (a
    /// separable form of the bilinear warp of Hart, Pharr, Mueller, Lopes, McGuire and Wyman
    /// 2020, "Practical Product Sampling by Fitting and Composing Warps", which left the same
    /// noise on the course scenes with two independent draws instead of a chained one). Far
    /// from the light the weights are equal and this is uniform area sampling; close to it,
    /// or seen at a slant, the samples go where the light arrives. Any positive density gives
    /// the same expected value and the returned pdf is the exact one, so the image converges
    /// to the same result.
    pub(crate) fn sample(
        &self,
        radiance: Vec3,
        p: Vec3,
        n: Vec3,
        u: [f32; 2],
    ) -> Option<LightSample> {
        let w = self.corner_weights(p, n);
        let [a, b, c, d] = edge_weights(w);
        let (s, t) = (sample_linear(u[0], a, b), sample_linear(u[1], c, d));
        let q = self.corner + s * self.dim_x + t * self.dim_y;
        let v = q - p;
        let dist = v.length();
        let wi = v / dist;
        // One-sided: it radiates only into the half-space `direction` points to.
        let cos_l = -self.direction.dot(wi);
        (cos_l > 0.0 && dist > 0.0 && self.area > 0.0).then(|| LightSample {
            wi,
            dist,
            li: radiance,
            pdf: self.pdf_at(w, s, t, dist, cos_l),
            cos_light: cos_l,
        })
    }

    /// `sample`'s pdf at the light's point of edge coordinates (`s`, `t`), `dist` from the
    /// receiver whose corner weights are `w`, seen at cosine `cos_l` to `direction`: the product
    /// of the two linear densities over the area, turned into solid angle.
    fn pdf_at(&self, w: [f32; 4], s: f32, t: f32, dist: f32, cos_l: f32) -> f32 {
        let [a, b, c, d] = edge_weights(w);
        let weight = ((1.0 - s) * a + s * b) * ((1.0 - t) * c + t * d);
        let norm = (0.5 * (a + b)) * (0.5 * (c + d));
        weight * (dist * dist) / (norm * (self.area * cos_l))
    }

    /// The cosine between unit `wi` and the light's plane normal (`sample`'s pdf takes its
    /// cosine to `direction`, which the course's transforms need not keep normal to the plane).
    fn plane_cos(&self, wi: Vec3) -> f32 {
        self.dim_x.cross(self.dim_y).normalize_or_zero().dot(wi).abs()
    }

    /// A light sample's pdf per solid angle, as BSDF sampling's pdf is measured.
    pub(crate) fn solid_angle_pdf(&self, ls: &LightSample) -> f32 {
        ls.pdf * ls.cos_light / self.plane_cos(ls.wi)
    }

    /// Where the ray from `p` along unit `dir` meets the light's emitting side, as a light
    /// sample for the receiver `p` with shading normal `n`: its solid-angle pdf had `sample`
    /// drawn that point (`solid_angle_pdf`), and the radiance that makes a BSDF sample's
    /// estimate count what `sample`'s estimate counts; `None` if the ray misses the light.
    pub(crate) fn hit_by(
        &self,
        radiance: Vec3,
        p: Vec3,
        n: Vec3,
        dir: Vec3,
    ) -> Option<LightSample> {
        let normal = self.dim_x.cross(self.dim_y);
        let dist = normal.dot(self.corner - p) / normal.dot(dir);
        let cos_l = -self.direction.dot(dir);
        if !(dist > 0.0 && dist < f32::INFINITY && cos_l > 0.0 && self.area > 0.0) {
            return None;
        }
        // Edge coordinates of the hit: r = s dim_x + t dim_y, solved with cross products.
        let r = p + dist * dir - self.corner;
        let nn = normal.dot(normal);
        let (s, t) = (r.cross(self.dim_y).dot(normal) / nn, self.dim_x.cross(r).dot(normal) / nn);
        if !((0.0..1.0).contains(&s) && (0.0..1.0).contains(&t)) {
            return None;
        }
        let cos_plane = self.plane_cos(dir);
        let pdf = self.pdf_at(self.corner_weights(p, n), s, t, dist, cos_l);
        Some(LightSample {
            wi: dir,
            dist,
            li: radiance * (cos_l / cos_plane),
            pdf: pdf * cos_l / cos_plane,
            cos_light: cos_plane,
        })
    }

    /// The corners' weights (00, 10, 01, 11: steps along `dim_x`, `dim_y`), cos(receiver)+ /
    /// distance^4: the light's cosine at a corner is its distance from `p`'s ... plane over
    /// the corner's distance, and that numerator is the same at all four corners, so it drops
    /// out. They are divided by the largest and raised to `CORNER_WEIGHT_FLOOR`; all are 1
    /// when no corner is above the receiver's horizon (every sample is then rejected by its
    /// cosine) or the largest is not finite (a receiver within 1e-9 of a corner).
    fn corner_weights(&self, p: Vec3, n: Vec3) -> [f32; 4] {
        let c10 = self.corner + self.dim_x;
        let v = [self.corner, c10, self.corner + self.dim_y, c10 + self.dim_y].map(|q| q - p);
        let r2 = v.map(|v| v.dot(v));
        // 1 / r^2 of two corners from one division (an overflow gives zero or NaN weights,
        // which the floor below replaces).
        let (i01, i23) = (1.0 / (r2[0] * r2[1]), 1.0 / (r2[2] * r2[3]));
        let inv = [r2[1] * i01, r2[0] * i01, r2[3] * i23, r2[2] * i23];
        let w: [f32; 4] = std::array::from_fn(|k| max_of(v[k].dot(n), 0.0) * inv[k] * inv[k]);
        // Scaled to the largest, so that the draws' squares neither overflow nor underflow
        // whatever the scene's units.
        let largest = max_of(max_of(w[0], w[1]), max_of(w[2], w[3]));
        if largest > 0.0 && largest < f32::INFINITY {
            let scale = 1.0 / largest;
            w.map(|x| max_of(x * scale, CORNER_WEIGHT_FLOOR))
        } else {
            [1.0; 4]
        }
    }
}

/// The weights of the light's two ends along each edge (a, b: along `dim_x`; c, d: along
/// `dim_y`) from the corners' (00, 10, 01, 11).
fn edge_weights(w: [f32; 4]) -> [f32; 4] {
    let [w00, w10, w01, w11] = w;
    [w00 + w01, w10 + w11, w00 + w10, w01 + w11]
}

/// x in [0, 1) with density proportional to (1 - x) a + x b (a, b > 0), for `xi` in [0, 1):
/// the inverse of its CDF, written without dividing by b - a.
#[inline]
pub(crate) fn sample_linear(xi: f32, a: f32, b: f32) -> f32 {
    let x = xi * (a + b) / (a + ((1.0 - xi) * a * a + xi * b * b).sqrt());
    min_of(x, 1.0 - f32::EPSILON / 2.0)
}

/// `if a > b { a } else { b }`, as the lanes compute it.
#[inline]
fn max_of(a: f32, b: f32) -> f32 {
    if b < a {
        a
    } else {
        b
    }
}

/// `if a < b { a } else { b }`, as the lanes compute it.
#[inline]
fn min_of(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The course's Cornell-box light, and one whose `direction` is tilted off its plane's
    /// normal (a sheared transform).
    fn lights() -> [Rectangle; 2] {
        let (dim_x, dim_y) = (Vec3::new(-0.6, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.8));
        let position = Vec3::new(0.1, 1.49, -0.2);
        let tilted = Vec3::new(0.3, -1.0, 0.2).normalize();
        [
            Rectangle::new(position, Vec3::NEG_Y, dim_x, dim_y),
            Rectangle::new(position, tilted, dim_x, dim_y),
        ]
    }

    fn receivers() -> [(Vec3, Vec3); 4] {
        [
            (Vec3::ZERO, Vec3::Y),
            (Vec3::new(0.55, 1.2, 0.3), Vec3::new(-1.0, 0.2, 0.0).normalize()),
            (Vec3::new(-0.9, 0.3, 0.9), Vec3::new(1.0, 1.0, -0.5).normalize()),
            (Vec3::new(0.1, 1.3, -0.2), Vec3::Y),
        ]
    }

    /// Along the direction of each point `sample` draws, `hit_by` finds the same point, the
    /// same pdf per solid angle, and the same estimate (radiance over pdf): the two halves of a
    /// glossy vertex's weighing measure one light alike.
    #[test]
    fn hit_by_finds_the_point_sample_drew_with_its_pdf() {
        let radiance = Vec3::new(10.0, 5.0, 2.0);
        let mut checked = 0;
        for r in lights() {
            for (p, n) in receivers() {
                for i in 0..16 {
                    for j in 0..16 {
                        let u = [(i as f32 + 0.5) / 16.0, (j as f32 + 0.5) / 16.0];
                        let Some(ls) = r.sample(radiance, p, n, u) else { continue };
                        let h = r.hit_by(radiance, p, n, ls.wi).expect("the sampled point");
                        let close = |a: f32, b: f32| (a - b).abs() <= 2e-4 * a.abs().max(b.abs());
                        assert!(close(h.dist, ls.dist), "{} {}", h.dist, ls.dist);
                        assert!(close(h.pdf, r.solid_angle_pdf(&ls)), "{} {}", h.pdf, ls.pdf);
                        let (a, b) = (h.li / h.pdf, ls.li / ls.pdf);
                        assert!((0..3).all(|k| close(a[k], b[k])), "{a} {b}");
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 1500, "{checked}");
    }

    /// Rays beside the light, and rays reaching its dark side, find nothing.
    #[test]
    fn hit_by_misses_beside_and_behind() {
        let [r, _] = lights();
        let beside = (Vec3::new(0.1, 1.49, 2.0) - Vec3::ZERO).normalize();
        assert!(r.hit_by(Vec3::ONE, Vec3::ZERO, Vec3::Y, beside).is_none());
        let above = Vec3::new(0.1, 3.0, -0.2);
        assert!(r.hit_by(Vec3::ONE, above, -Vec3::Y, -Vec3::Y).is_none());
        assert!(r.hit_by(Vec3::ONE, Vec3::ZERO, Vec3::Y, -Vec3::Y).is_none());
        assert!(r.hit_by(Vec3::ONE, Vec3::new(0.1, 0.0, -0.2), Vec3::Y, Vec3::Y).is_some());
    }

    /// What directions find (the radiance `hit_by` gives, integrated over the hemisphere
    /// against the receiver's cosine) equals what `sample` estimates (its integrand over the
    /// light's area), also for the tilted light, whose pdf is not per solid angle.
    #[test]
    fn directions_and_area_samples_integrate_to_the_same_light() {
        let radiance = Vec3::ONE;
        for r in lights() {
            for (p, n) in receivers() {
                // Over the light's area: cos(receiver) cos(light) / d^2, as `sample`'s pdf counts
                // the light's cosine.
                let m = 600;
                let mut by_area = 0.0f64;
                for i in 0..m {
                    for j in 0..m {
                        let (s, t) = ((i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / m as f32);
                        let v = r.corner + s * r.dim_x + t * r.dim_y - p;
                        let d = v.length();
                        let wi = v / d;
                        let (cr, cl) = (n.dot(wi), -r.direction.dot(wi));
                        if cr > 0.0 && cl > 0.0 {
                            by_area += (cr * cl / (d * d)) as f64;
                        }
                    }
                }
                by_area *= (r.area / (m * m) as f32) as f64;
                // Over the receiver's hemisphere, uniform in (cos, angle).
                let (t, b) = crate::math::orthonormal_basis(n);
                let k = 1500;
                let mut by_direction = 0.0f64;
                for i in 0..k {
                    for j in 0..k {
                        let z = (i as f32 + 0.5) / k as f32;
                        let phi = 2.0 * std::f32::consts::PI * (j as f32 + 0.5) / k as f32;
                        let sxy = (1.0 - z * z).sqrt();
                        let wi = sxy * phi.cos() * t + sxy * phi.sin() * b + z * n;
                        if let Some(h) = r.hit_by(radiance, p, n, wi) {
                            by_direction += (h.li.x * z) as f64;
                        }
                    }
                }
                by_direction *= 2.0 * std::f64::consts::PI / (k * k) as f64;
                let tol = 0.01 * by_area.max(1e-3);
                assert!((by_area - by_direction).abs() < tol, "{p} {by_area} {by_direction}");
            }
        }
    }
}
