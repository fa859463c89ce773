//! The write-up's BVH previews (`--bvh-node PATH`): a pass over a rendered image that tints the
//! pixels whose primary hit is a triangle of one node of the binary SAH tree and outlines the
//! node's box, as the course viewer highlights a node. The node comes from the accel
//! (`accel::binary_node`); this pass traces its own pixel-centre rays, so the renderer and its
//! stages know nothing of it.

use rayon::prelude::*;

use crate::accel::{Accel, BinaryNode, TraceStats};
use crate::geometry::prim;
use crate::math::{Aabb, Vec3};
use crate::render::RenderConfig;
use crate::scene::{Camera, Scene};

/// The colour mixed into the node's pixels, and how much of it.
pub(crate) const TINT: Vec3 = Vec3::new(1.0, 0.35, 0.05);
/// The weight of [`TINT`] in a node pixel's colour (the rest is the rendered colour).
pub(crate) const TINT_WEIGHT: f32 = 0.6;
/// The colour of the box's edges (no normal colour 0.5 n + 0.5 is pure yellow).
pub(crate) const OUTLINE: Vec3 = Vec3::new(1.0, 1.0, 0.0);

/// The camera `render::render` uses for `config`: the explicit one, else the course framing.
pub fn camera_for(scene: &Scene, config: &RenderConfig) -> Camera {
    config
        .camera
        .unwrap_or_else(|| Camera::new(&scene.camera, scene.bounds(), config.width, config.height))
}

/// Tints `node`'s pixels in `image` (row-major, `camera.width` x `camera.height`, row 0 at the
/// top) and draws its box's edges over them.
pub fn mark_node(image: &mut [Vec3], camera: &Camera, accel: &Accel, node: &BinaryNode) {
    let inside = node_pixels(camera, accel, node);
    for (pixel, _) in image.iter_mut().zip(&inside).filter(|(_, &hit)| hit) {
        *pixel = pixel.lerp(TINT, TINT_WEIGHT);
    }
    if node.bounds.is_empty() {
        return;
    }
    for [a, b] in box_edges(camera, node.bounds) {
        draw_segment(image, camera.width, camera.height, a, b);
    }
}

/// For every pixel, whether the closest hit of the ray through its centre (the ray of a
/// one-sample render) is a triangle of `node`.
pub(crate) fn node_pixels(camera: &Camera, accel: &Accel, node: &BinaryNode) -> Vec<bool> {
    let (w, h) = (camera.width, camera.height);
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let ray = camera.ray_through_pixel((i % w) as f32 + 0.5, (i / w) as f32 + 0.5);
            let hit = accel.intersect(&ray, &mut TraceStats::default());
            hit.is_some_and(|h| {
                !prim::is_sphere(h.prim) && node.prims.binary_search(&h.prim).is_ok()
            })
        })
        .collect()
}

/// The twelve edges of `b` in pixel coordinates (x right, y down from the top-left corner),
/// each cut to the part in front of the camera; edges wholly behind it are left out.
pub(crate) fn box_edges(camera: &Camera, b: Aabb) -> Vec<[(f32, f32); 2]> {
    let corner = |i: usize| {
        let pick = |bit: usize, lo: f32, hi: f32| if i & bit == 0 { lo } else { hi };
        Vec3::new(pick(1, b.min.x, b.max.x), pick(2, b.min.y, b.max.y), pick(4, b.min.z, b.max.z))
    };
    // Corners differing in one bit share an edge.
    let edges = (0..8).flat_map(|i| [1, 2, 4].map(|bit| (i, i | bit))).filter(|(i, j)| i != j);
    // Points closer than this to the eye's plane would project far off the image.
    let near = 1e-4 * (camera.target - camera.eye).length().max(f32::MIN_POSITIVE);
    edges
        .filter_map(|(i, j)| {
            let (a, b) =
                clip_to_front(to_camera(camera, corner(i)), to_camera(camera, corner(j)), near)?;
            Some([to_pixel(camera, a), to_pixel(camera, b)])
        })
        .collect()
}

/// Camera coordinates: right, up, and depth along the view direction.
fn to_camera(camera: &Camera, p: Vec3) -> Vec3 {
    let v = p - camera.eye;
    Vec3::new(v.dot(camera.x), v.dot(camera.y), -v.dot(camera.z))
}

/// The inverse of `Camera::ray_through_pixel` for a point at positive depth.
fn to_pixel(camera: &Camera, c: Vec3) -> (f32, f32) {
    let sx = (c.x / c.z / camera.tan_half_h + 1.0) / 2.0;
    let sy = (c.y / c.z / camera.tan_half_v + 1.0) / 2.0;
    (sx * camera.width as f32, (1.0 - sy) * camera.height as f32)
}

/// The part of segment a-b at depth >= `near`, if any.
fn clip_to_front(a: Vec3, b: Vec3, near: f32) -> Option<(Vec3, Vec3)> {
    let cut = |inside: Vec3, outside: Vec3| {
        inside + (outside - inside) * ((inside.z - near) / (inside.z - outside.z))
    };
    match (a.z >= near, b.z >= near) {
        (true, true) => Some((a, b)),
        (true, false) => Some((a, cut(a, b))),
        (false, true) => Some((cut(b, a), b)),
        (false, false) => None,
    }
}

/// Paints every pixel the segment passes through (one step per pixel along its longer axis),
/// after cutting it to the image so a nearly edge-on box cannot take millions of steps.
fn draw_segment(image: &mut [Vec3], width: u32, height: u32, a: (f32, f32), b: (f32, f32)) {
    let Some((a, b)) = clip_to_rect(a, b, width as f32, height as f32) else {
        return;
    };
    let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil().max(1.0) as u32;
    for k in 0..=steps {
        let t = k as f32 / steps as f32;
        let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
        let (x, y) = (x.floor() as i64, y.floor() as i64);
        if (0..width as i64).contains(&x) && (0..height as i64).contains(&y) {
            image[(y * width as i64 + x) as usize] = OUTLINE;
        }
    }
}

/// Liang-Barsky: the part of segment a-b inside [0, w] x [0, h], if any.
fn clip_to_rect(a: (f32, f32), b: (f32, f32), w: f32, h: f32) -> Option<((f32, f32), (f32, f32))> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    for (p, q) in [(-dx, a.0), (dx, w - a.0), (-dy, a.1), (dy, h - a.1)] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    if !(t0 <= t1) {
        return None;
    }
    Some(((a.0 + t0 * dx, a.1 + t0 * dy), (a.0 + t1 * dx, a.1 + t1 * dy)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_are_cut_to_the_image_and_to_the_front() {
        let r = clip_to_rect((-10.0, 5.0), (30.0, 5.0), 20.0, 10.0).unwrap();
        assert_eq!(r, ((0.0, 5.0), (20.0, 5.0)));
        assert!(clip_to_rect((-10.0, -1.0), (30.0, -1.0), 20.0, 10.0).is_none());
        assert!(clip_to_rect((25.0, 0.0), (30.0, 8.0), 20.0, 10.0).is_none());
        let (a, b) =
            clip_to_front(Vec3::new(0.0, 0.0, 2.0), Vec3::new(2.0, 0.0, -2.0), 1.0).unwrap();
        assert_eq!((a, b), (Vec3::new(0.0, 0.0, 2.0), Vec3::new(0.5, 0.0, 1.0)));
        assert!(clip_to_front(Vec3::new(0.0, 0.0, -1.0), Vec3::new(0.0, 0.0, 0.5), 1.0).is_none());
    }

    #[test]
    fn a_drawn_segment_covers_every_pixel_it_crosses_and_nothing_else() {
        let (w, h) = (8, 6);
        let mut image = vec![Vec3::ZERO; w * h];
        draw_segment(&mut image, w as u32, h as u32, (0.5, 2.5), (7.5, 2.5));
        let painted: Vec<usize> = (0..w * h).filter(|&i| image[i] == OUTLINE).collect();
        assert_eq!(painted, (2 * w..3 * w).collect::<Vec<_>>());
    }

    #[test]
    fn projection_inverts_the_pixel_ray() {
        let desc = crate::scene::CameraDesc::default();
        let b = Aabb { min: Vec3::splat(-1.0), max: Vec3::splat(1.0) };
        let camera = Camera::new(&desc, b, 64, 48);
        for (px, py) in [(0.5, 0.5), (10.25, 40.0), (63.0, 1.0)] {
            let ray = camera.ray_through_pixel(px, py);
            let (x, y) = to_pixel(&camera, to_camera(&camera, ray.at(3.0)));
            assert!((x - px).abs() < 1e-3 && (y - py).abs() < 1e-3, "{px},{py} -> {x},{y}");
        }
    }
}
