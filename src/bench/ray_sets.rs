//! The standard ray sets of BENCHMARK.md: primary rays through the pixel centres of a frame,
//! then a diffuse bounce and a shadow ray from each primary hit, and the order packets take
//! them in.

use super::Traversal;
use crate::accel::{Accel, TraceStats};
use crate::math::{orthonormal_basis, Ray, Vec3};
use crate::sampler::Pcg32;
use crate::scene::{Camera, Light, Scene};

/// The seed of the ray sets' PCG32 stream (the peer harness uses the same one).
pub const RAY_SEED: u64 = 0x5EED_184B_E7C4_0001;
/// The benchmark's image size.
pub const WIDTH: u32 = 800;
/// The benchmark's image height.
pub const HEIGHT: u32 = 600;

/// The image whose pixel centres the primary rays go through. The standard sets use 800 x 600
/// (BENCHMARK.md); `bench --frame` takes a render's own size. The course camera keeps the
/// angle a pixel spans (SCENE_FORMAT.md, "Camera"), so a smaller frame is a tighter view: at
/// 400 x 300 every CBbunny camera ray hits the box, at 800 x 600 two in three miss it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame {
    /// Pixels across.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
}

impl Frame {
    /// The frame of the standard ray sets.
    pub const STANDARD: Frame = Frame { width: WIDTH, height: HEIGHT };
    /// The standard frame's `name`, for records that do not say theirs.
    pub const STANDARD_NAME: &'static str = "800x600";

    /// `WxH`, as records and `--frame` spell it.
    pub fn name(self) -> String {
        format!("{}x{}", self.width, self.height)
    }

    /// The frame `WxH` (each side 1 to 4096 pixels, so the sets stay under a gigabyte); anything else is an error that says
    /// what was expected.
    pub fn parse(s: &str) -> crate::Result<Frame> {
        let side = |t: &str| t.parse::<u32>().ok().filter(|n| (1..=4096).contains(n));
        match s.split_once(['x', 'X']).map(|(w, h)| (side(w), side(h))) {
            Some((Some(width), Some(height))) => Ok(Frame { width, height }),
            _ => Err(crate::Error::new(format!(
                "bad frame '{s}' (expected WIDTHxHEIGHT, each 1 to 4096, e.g. 400x300)"
            ))),
        }
    }

    /// Pixels in the frame.
    pub fn pixels(self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// One of the three standard ray sets (`generate_ray_sets`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RaySet {
    /// Camera rays through the pixel centres.
    Primary,
    /// One cosine-weighted bounce from each primary hit (closest hit wanted).
    Diffuse,
    /// From each primary hit towards the benchmark light point (occlusion only).
    Shadow,
}

impl RaySet {
    /// Every ray set, in the order they are generated and reported.
    pub const ALL: [RaySet; 3] = [RaySet::Primary, RaySet::Diffuse, RaySet::Shadow];

    /// The set's name in records, ray-file names and `--ray-set`.
    pub fn name(self) -> &'static str {
        match self {
            RaySet::Primary => "primary",
            RaySet::Diffuse => "diffuse",
            RaySet::Shadow => "shadow",
        }
    }

    /// The set called `s` (as [`name`](RaySet::name) spells it); anything else is an error
    /// listing the names.
    pub fn parse(s: &str) -> crate::Result<RaySet> {
        RaySet::ALL.into_iter().find(|r| r.name() == s).ok_or_else(|| {
            crate::Error::new(format!(
                "unknown ray set '{s}' (expected primary, diffuse or shadow)"
            ))
        })
    }

    /// Shadow rays want only occlusion (any hit); the others the closest hit.
    pub fn is_occlusion(self) -> bool {
        self == RaySet::Shadow
    }
}

/// The three standard ray sets of a scene.
pub struct RaySets {
    /// Camera rays, one per pixel in row order.
    pub primary: Vec<Ray>,
    /// One diffuse bounce per primary hit, in primary order.
    pub diffuse: Vec<Ray>,
    /// One shadow ray per primary hit, in primary order.
    pub shadow: Vec<Ray>,
}

impl RaySets {
    /// The rays of `set`.
    pub fn get(&self, set: RaySet) -> &[Ray] {
        match set {
            RaySet::Primary => &self.primary,
            RaySet::Diffuse => &self.diffuse,
            RaySet::Shadow => &self.shadow,
        }
    }
}

/// Generates the standard ray sets: primary rays through the pixel centres of the 800 x 600
/// course camera (row 0 at the top), then from each primary hit one cosine-weighted diffuse
/// ray about the geometric normal facing the incoming ray, and one shadow ray towards the
/// benchmark light point.
pub fn generate_ray_sets(scene: &Scene, accel: &Accel) -> RaySets {
    generate_ray_sets_in(scene, accel, Frame::STANDARD)
}

/// The ray sets of [`generate_ray_sets`] with the primary rays through the pixels of `frame`.
pub fn generate_ray_sets_in(scene: &Scene, accel: &Accel, frame: Frame) -> RaySets {
    let camera = Camera::new(&scene.camera, scene.bounds(), frame.width, frame.height);
    let mut primary = Vec::with_capacity(frame.pixels());
    for y in 0..frame.height {
        for x in 0..frame.width {
            primary.push(camera.ray_through_pixel(x as f32 + 0.5, y as f32 + 0.5));
        }
    }
    let eps = 1e-4 * scene.bounds().diagonal();
    let light = shadow_target(scene);
    let mut rng = Pcg32::new(RAY_SEED, 54);
    let (mut diffuse, mut shadow) = (Vec::new(), Vec::new());
    let mut stats = TraceStats::default();
    for r in &primary {
        let Some(hit) = accel.intersect(r, &mut stats) else { continue };
        let p = r.at(hit.t);
        let [a, b, c] = scene.triangle(hit.prim as usize);
        let mut n = (b - a).cross(c - a).normalize_or(Vec3::Y);
        if n.dot(r.dir) > 0.0 {
            n = -n;
        }
        let (u1, u2) = (rng.next_f32(), rng.next_f32());
        let (t, bt) = orthonormal_basis(n);
        let l = crate::integrator::bsdf::cosine_hemisphere(u1, u2);
        let d = (l.x * t + l.y * bt + l.z * n).normalize();
        diffuse.push(Ray::segment(p, d, eps, f32::INFINITY));
        let to = light - p;
        let dist = to.length();
        shadow.push(Ray::segment(p, to / dist, eps, dist * (1.0 - 1e-4)));
    }
    RaySets { primary, diffuse, shadow }
}

/// The shadow rays' target: the centre of the first area light, else the first point light,
/// else the centre of the bounding box's top face raised by a quarter of its height.
pub(crate) fn shadow_target(scene: &Scene) -> Vec3 {
    let area = scene.lights.iter().find_map(|l| match l {
        Light::Area { position, .. } => Some(*position),
        _ => None,
    });
    let point = || {
        scene.lights.iter().find_map(|l| match l {
            Light::Point { position, .. } => Some(*position),
            _ => None,
        })
    };
    area.or_else(point).unwrap_or_else(|| {
        let b = scene.bounds();
        Vec3::new(b.center().x, b.max.y + 0.25 * (b.max.y - b.min.y), b.center().z)
    })
}

/// The order in which a traversal takes the rays of a set. Packets take primary rays of a
/// full frame (one ray per pixel of `frame`) in pixel blocks (4 x 4 for 16 lanes, 4 x 2 for 8,
/// 2 x 2 for 4; cut short at the right and bottom edges), as a renderer generates camera
/// packets and as the peer harness feeds Embree's packets; a row of 8 pixels is a wider, less
/// coherent bundle. Other sets, and single rays, keep file order. Returns the rays reordered,
/// or `None` to keep the order.
pub fn packet_order(
    set: RaySet,
    traversal: Traversal,
    rays: &[Ray],
    frame: Frame,
) -> Option<Vec<Ray>> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let (bw, bh) = match traversal.width() {
        16 => (4, 4),
        8 => (4, 2),
        4 => (2, 2),
        _ => return None,
    };
    if set != RaySet::Primary || rays.len() != w * h {
        return None;
    }
    let mut out = Vec::with_capacity(rays.len());
    for by in (0..h).step_by(bh) {
        for bx in (0..w).step_by(bw) {
            for y in by..(by + bh).min(h) {
                out.extend_from_slice(&rays[y * w + bx..y * w + (bx + bw).min(w)]);
            }
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::{packet_order, Frame, RaySet, Traversal};
    use crate::math::{Ray, Vec3};

    #[test]
    fn frames_parse_as_width_x_height() {
        assert_eq!(Frame::parse("400x300").unwrap(), Frame { width: 400, height: 300 });
        assert_eq!(Frame::parse("800X600").unwrap(), Frame::STANDARD);
        assert_eq!(Frame::STANDARD.name(), "800x600");
        assert_eq!(Frame::STANDARD.name(), Frame::STANDARD_NAME);
        for bad in ["", "400", "400x", "x300", "0x300", "400x0", "-4x3", "4097x1", "4x3x2", "ax3"] {
            let e = Frame::parse(bad).unwrap_err();
            assert!(e.message().starts_with(&format!("bad frame '{bad}'")), "{}", e.message());
        }
    }

    /// Packets take a frame's primary rays in pixel blocks, cut short at the edges of a frame
    /// the blocks do not divide: every ray once, each block's rays together.
    #[test]
    fn packet_order_takes_every_pixel_once_in_blocks() {
        let frame = Frame { width: 7, height: 5 };
        // Ray i starts at x = i, so the order can be read back.
        let rays: Vec<Ray> = (0..frame.pixels())
            .map(|i| Ray::segment(Vec3::new(i as f32, 0.0, 0.0), Vec3::Z, 0.0, 1.0))
            .collect();
        let order = |t| -> Vec<usize> {
            let out = packet_order(RaySet::Primary, t, &rays, frame).expect("a whole frame");
            out.iter().map(|r| r.origin.x as usize).collect()
        };
        let p8 = order(Traversal::Packet8);
        assert_eq!(&p8[..8], &[0, 1, 2, 3, 7, 8, 9, 10]);
        assert_eq!(&p8[8..14], &[4, 5, 6, 11, 12, 13]);
        let mut sorted = p8.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..35).collect::<Vec<_>>());
        let mut p16 = order(Traversal::Packet16);
        p16.sort_unstable();
        assert_eq!(p16, sorted);
        assert!(packet_order(RaySet::Primary, Traversal::Single, &rays, frame).is_none());
        assert!(packet_order(RaySet::Diffuse, Traversal::Packet8, &rays, frame).is_none());
        assert!(packet_order(RaySet::Primary, Traversal::Packet8, &rays[1..], frame).is_none());
    }
}
