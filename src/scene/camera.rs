//! The course pinhole camera (SCENE_FORMAT.md, "Camera"): it ignores the camera node's position
//! and frames the scene's bounding box along the camera's view direction.

use wide::f32x8;

use crate::math::{Aabb, Ray, Vec3};

/// The camera as the file describes it, before framing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraDesc {
    /// Horizontal field of view `xfov`, degrees.
    pub hfov_deg: f32,
    /// Vertical field of view (`yfov`, or derived from `xfov` and `aspect_ratio`), degrees.
    pub vfov_deg: f32,
    /// c = unit(world transform applied to (0, 0, -1) as a point): the course's view direction.
    pub view_dir: Vec3,
}

impl Default for CameraDesc {
    /// Used when a file has no camera: looking down -Z with the course's default 50-degree-ish
    /// horizontal field of view at 4:3.
    fn default() -> Self {
        let hfov: f32 = 50.0;
        let vfov = 2.0 * ((hfov.to_radians() / 2.0).tan() * 0.75).atan();
        CameraDesc { hfov_deg: hfov, vfov_deg: vfov.to_degrees(), view_dir: Vec3::NEG_Z }
    }
}

/// The course renderer's default screen, to which the field of view is first fitted.
const FIT_W: f32 = 800.0;
const FIT_H: f32 = 600.0;

/// A framed camera for one image size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Where the rays start.
    pub eye: Vec3,
    /// The point the camera looks at (the bounding box's centre).
    pub target: Vec3,
    /// Camera-to-world basis: x right, y up, z towards the viewer (the camera looks along -z).
    pub x: Vec3,
    /// The basis' up axis.
    pub y: Vec3,
    /// The basis' axis towards the viewer.
    pub z: Vec3,
    /// tan(hFov / 2) for this image size.
    pub tan_half_h: f32,
    /// tan(vFov / 2) for this image size.
    pub tan_half_v: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Camera {
    /// Frames `bounds` as the course does and sizes the view for a `width` x `height` image.
    pub fn new(desc: &CameraDesc, bounds: Aabb, width: u32, height: u32) -> Camera {
        let d = screen_distance(desc);
        let tan_half_h = width as f32 / (2.0 * d);
        let tan_half_v = height as f32 / (2.0 * d);

        let (target, diag) = if bounds.is_empty() {
            (Vec3::ZERO, 1.0)
        } else {
            (bounds.center(), bounds.diagonal().max(f32::MIN_POSITIVE))
        };
        let r = (1.5 * diag).clamp(0.075 * diag, 15.0 * diag);

        let c = desc.view_dir.normalize_or(Vec3::NEG_Z);
        let mut phi = c.y.clamp(-1.0, 1.0).acos();
        if phi.sin() == 0.0 {
            phi += 1e-5;
        }
        let theta = c.x.atan2(c.z);
        let w = Vec3::new(phi.sin() * theta.sin(), phi.cos(), phi.sin() * theta.cos());
        let eye = target + r * w;

        let up = if phi.sin() < 0.0 { Vec3::NEG_Y } else { Vec3::Y };
        let x = up.cross(w).normalize();
        let y = w.cross(x).normalize();
        Camera { eye, target, x, y, z: w, tan_half_h, tan_half_v, width, height }
    }

    /// Whether the eye and the basis are finite numbers. A scene whose bounding box's diagonal
    /// overflows f32 puts the eye at infinity (1.5 diagonals from the centre), and every
    /// camera ray is then NaN: a black image that says nothing of why.
    pub fn is_finite(&self) -> bool {
        [self.eye, self.x, self.y, self.z].iter().all(|v| v.is_finite())
            && self.tan_half_h.is_finite()
            && self.tan_half_v.is_finite()
    }

    /// The ray through normalised image coordinates (sx, sy) in [0, 1]^2, sy = 0 at the bottom.
    #[inline]
    pub fn generate_ray(&self, sx: f32, sy: f32) -> Ray {
        let cx = (2.0 * sx - 1.0) * self.tan_half_h;
        let cy = (2.0 * sy - 1.0) * self.tan_half_v;
        let dir = (cx * self.x + cy * self.y - self.z).normalize();
        Ray::new(self.eye, dir)
    }

    /// The ray through image point (px, py) in pixels, py = 0 at the top row (film order).
    #[inline]
    pub fn ray_through_pixel(&self, px: f32, py: f32) -> Ray {
        self.generate_ray(px / self.width as f32, 1.0 - py / self.height as f32)
    }

    /// The directions of `ray_through_pixel` for `N` image points at once (x, y and z of
    /// each; `N` a multiple of 8), in SIMD lanes that repeat its operations in its order, so
    /// each equals the scalar ray's bit for bit. Each 8 lanes are one chain of two divisions,
    /// a square root and a third division; with 16 points the two chains overlap (camera-ray
    /// generation 0.032 -> 0.029 s at `-m 1`: PERF.md, "Whole renders").
    #[inline]
    pub fn dirs_through_pixels<const N: usize>(&self, px: [f32; N], py: [f32; N]) -> [[f32; N]; 3] {
        const { assert!(N.is_multiple_of(8)) };
        let mut out = [[0.0; N]; 3];
        for k in (0..N).step_by(8) {
            let eight = |a: &[f32; N]| -> [f32; 8] { std::array::from_fn(|l| a[k + l]) };
            let dirs = self.dirs_through_8(eight(&px), eight(&py));
            for (o, d) in out.iter_mut().zip(dirs) {
                o[k..k + 8].copy_from_slice(&d);
            }
        }
        out
    }

    /// `dirs_through_pixels` for 8 points.
    #[inline(always)]
    fn dirs_through_8(&self, px: [f32; 8], py: [f32; 8]) -> [[f32; 8]; 3] {
        let one = f32x8::splat(1.0);
        let two = f32x8::splat(2.0);
        let sx = f32x8::from(px) / f32x8::splat(self.width as f32);
        let sy = one - f32x8::from(py) / f32x8::splat(self.height as f32);
        let cx = (two * sx - one) * f32x8::splat(self.tan_half_h);
        let cy = (two * sy - one) * f32x8::splat(self.tan_half_v);
        let axis = |c: fn(Vec3) -> f32| {
            cx * f32x8::splat(c(self.x)) + cy * f32x8::splat(c(self.y)) - f32x8::splat(c(self.z))
        };
        let (x, y, z) = (axis(|v| v.x), axis(|v| v.y), axis(|v| v.z));
        // glam's `normalize`: times the reciprocal of the length, dot product summed x, y, z.
        let recip = one / (x * x + y * y + z * z).sqrt();
        [(x * recip).to_array(), (y * recip).to_array(), (z * recip).to_array()]
    }

    /// The image point (px, py) in pixels (as `ray_through_pixel` takes it) where `p` appears,
    /// or `None` if `p` is not in front of the camera (on or behind the eye's plane).
    pub fn pixel_of(&self, p: Vec3) -> Option<[f32; 2]> {
        let v = p - self.eye;
        let depth = -v.dot(self.z);
        if depth <= 0.0 || !depth.is_finite() {
            return None;
        }
        let (cx, cy) = (v.dot(self.x) / depth, v.dot(self.y) / depth);
        let sx = (cx / self.tan_half_h + 1.0) / 2.0;
        let sy = (cy / self.tan_half_v + 1.0) / 2.0;
        Some([sx * self.width as f32, (1.0 - sy) * self.height as f32])
    }

    /// Horizontal and vertical field of view for this image size, degrees.
    pub fn fov_deg(&self) -> (f32, f32) {
        (2.0 * self.tan_half_h.atan().to_degrees(), 2.0 * self.tan_half_v.atan().to_degrees())
    }
}

/// Screen distance in pixels after fitting the file's field of view to the 800 x 600 screen:
/// the smaller of the two angles is widened so the aspect matches, then d = 600 / (2 tan(v/2)).
fn screen_distance(desc: &CameraDesc) -> f32 {
    let th = (desc.hfov_deg.to_radians() / 2.0).tan();
    let mut tv = (desc.vfov_deg.to_radians() / 2.0).tan();
    let aspect = FIT_W / FIT_H;
    if th / tv > aspect {
        tv = th / aspect;
    }
    // (If th / tv < aspect the horizontal angle widens instead, which leaves tv and d unchanged.)
    FIT_H / (2.0 * tv)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> Aabb {
        Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) }
    }

    /// `pixel_of` inverts `ray_through_pixel`: a point on the ray through (px, py) appears at
    /// (px, py); the eye's plane and what lies behind it appear nowhere.
    #[test]
    fn points_appear_where_their_camera_ray_goes() {
        let desc =
            CameraDesc { view_dir: Vec3::new(0.3, 0.4, 1.0).normalize(), ..CameraDesc::default() };
        let cam = Camera::new(&desc, unit_box(), 400, 300);
        for (px, py) in [(0.0, 0.0), (200.5, 150.25), (399.9, 12.0), (17.0, 299.0)] {
            let r = cam.ray_through_pixel(px, py);
            let [x, y] = cam.pixel_of(r.origin + 3.0 * r.dir).unwrap();
            assert!((x - px).abs() < 1e-3 && (y - py).abs() < 1e-3, "({px}, {py}) -> ({x}, {y})");
        }
        assert_eq!(cam.pixel_of(cam.eye), None);
        assert_eq!(cam.pixel_of(cam.eye + cam.z), None);
    }

    /// The lane directions are the scalar rays' directions bit for bit (camera-ray generation
    /// relies on it: images do not change), over many image points and two framings.
    #[test]
    fn lane_directions_equal_scalar_rays() {
        let mut rng = crate::sampler::Pcg32::new(3, 4);
        for (desc, w, h) in [
            (CameraDesc::default(), 400, 300),
            (
                CameraDesc { hfov_deg: 70.0, vfov_deg: 20.0, view_dir: Vec3::new(0.3, -0.4, -1.0) },
                123,
                77,
            ),
        ] {
            let camera = Camera::new(&desc, unit_box(), w, h);
            for _ in 0..2000 {
                let px: [f32; 16] = std::array::from_fn(|_| rng.next_f32() * w as f32);
                let py: [f32; 16] = std::array::from_fn(|_| rng.next_f32() * h as f32);
                let [x, y, z] = camera.dirs_through_pixels(px, py);
                for i in 0..16 {
                    let want = camera.ray_through_pixel(px[i], py[i]).dir;
                    let got = [x[i], y[i], z[i]];
                    assert_eq!(got.map(f32::to_bits), want.to_array().map(f32::to_bits));
                }
            }
        }
    }

    #[test]
    fn pixel_angle_is_kept_across_resolutions() {
        let desc = CameraDesc { hfov_deg: 49.13434, vfov_deg: 30.0, view_dir: Vec3::NEG_Z };
        let a = Camera::new(&desc, unit_box(), 800, 600);
        let b = Camera::new(&desc, unit_box(), 480, 360);
        // Same screen distance: tan scales with the pixel count.
        assert!((a.tan_half_h / 800.0 - b.tan_half_h / 480.0).abs() < 1e-7);
        assert!((a.tan_half_v / 600.0 - b.tan_half_v / 360.0).abs() < 1e-7);
        // At 800x600 the fitted aspect is exactly 4:3.
        assert!((a.tan_half_h / a.tan_half_v - 4.0 / 3.0).abs() < 1e-6);
    }

    #[test]
    fn wide_file_fov_widens_the_vertical_angle() {
        // 16:9 file camera: vertical angle is widened so that 800x600 keeps the full width.
        let th = (49.13434f32.to_radians() / 2.0).tan();
        let vfov = 2.0 * (th / 1.777778).atan();
        let desc =
            CameraDesc { hfov_deg: 49.13434, vfov_deg: vfov.to_degrees(), view_dir: Vec3::NEG_Z };
        let cam = Camera::new(&desc, unit_box(), 800, 600);
        assert!((cam.tan_half_h - th).abs() < 1e-5);
    }

    #[test]
    fn eye_sits_behind_the_view_direction_at_one_and_a_half_diagonals() {
        let desc = CameraDesc { view_dir: Vec3::new(0.0, 0.0, -1.0), ..Default::default() };
        let cam = Camera::new(&desc, unit_box(), 800, 600);
        let r = 1.5 * unit_box().diagonal();
        // theta = atan2(0, -1) = pi, phi = pi/2 => w = (0, 0, -1): the eye is on -z.
        assert!((cam.eye - Vec3::new(0.0, 0.0, -r)).length() < 1e-4, "{}", cam.eye);
        // The centre ray looks at the target.
        let ray = cam.generate_ray(0.5, 0.5);
        assert!((ray.dir - (cam.target - cam.eye).normalize()).length() < 1e-5);
        // sy = 1 is the top: its ray points more upward than the centre.
        assert!(cam.generate_ray(0.5, 1.0).dir.y > ray.dir.y);
    }
}
