//! Stability where methods fail: far-from-origin and rescaled scenes (self-intersection, light
//! leaks), degenerate geometry (no NaN, ever), and estimators that cannot see a light.

mod common;

use common::{coincident_light_box, render_pixels, SceneBuilder, HEMISPHERE, LIGHT, MIS};
use pathtracer::integrator::Integrator;
use pathtracer::math::Vec3;
use pathtracer::scene::{Light, Material, Scene};

/// The scene mapped by p -> scale * p + offset (lights and spheres too).
fn transformed(scene: &Scene, scale: f32, offset: Vec3) -> Scene {
    let mut s = scene.clone();
    let map = |p: Vec3| scale * p + offset;
    s.positions.iter_mut().for_each(|p| *p = map(*p));
    for sphere in &mut s.spheres {
        sphere.center = map(sphere.center);
        sphere.radius *= scale;
    }
    for l in &mut s.lights {
        match l {
            Light::Area { position, dim_x, dim_y, .. } => {
                *position = map(*position);
                *dim_x *= scale;
                *dim_y *= scale;
            }
            Light::Point { position, .. } => *position = map(*position),
            Light::Directional { .. } | Light::Ambient { .. } => {}
        }
    }
    s
}

fn image(scene: &Scene, integrator: Integrator, seed: u64) -> Vec<f64> {
    render_pixels(scene, integrator, |c| {
        (c.width, c.height, c.spp, c.max_depth, c.seed) = (32, 24, 64, 3, seed)
    })
    .iter()
    .map(|p| (p.x + p.y + p.z) as f64 / 3.0)
    .collect()
}

fn rms_diff(a: &[f64], b: &[f64]) -> f64 {
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
}

/// With the same seed a transformed scene draws the same random numbers, so its image differs
/// from the original only where floating point changes a decision: acne (a ray hitting its own
/// surface) or leaks (a shadow ray slipping past) would change many pixels by a lot. The noise
/// floor, the RMS difference between two seeds, says what "a lot" is.
#[test]
fn moving_and_scaling_the_scene_changes_nothing_beyond_noise() {
    let base = coincident_light_box();
    // Offsets are chosen so that the box's coordinates stay representable: at 1e6 a float
    // is spaced 1/16, so the unit-sized box is moved there only at scale 1e3.
    let cases = [
        ("offset 1e4", 1.0, Vec3::new(1e4, -1e4, 1e4)),
        ("scale 2", 2.0, Vec3::ZERO),
        ("scale 1024", 1024.0, Vec3::ZERO),
        ("scale 1.001", 1.001, Vec3::ZERO),
        ("scale 1e-3", 1e-3, Vec3::ZERO),
        ("scale 1e3", 1e3, Vec3::ZERO),
        ("scale 1e3, offset 1e6", 1e3, Vec3::new(1e6, 1e6, -1e6)),
        ("scale 1e-3, offset 1", 1e-3, Vec3::new(1.0, 1.0, 1.0)),
    ];
    let mut failures = Vec::new();
    for integrator in [LIGHT, HEMISPHERE, MIS] {
        let reference = image(&base, integrator, 1);
        let noise = rms_diff(&reference, &image(&base, integrator, 2));
        let mean_ref = reference.iter().sum::<f64>() / reference.len() as f64;
        for (name, scale, offset) in cases {
            let img = image(&transformed(&base, scale, offset), integrator, 1);
            let diff = rms_diff(&reference, &img);
            let mean = img.iter().sum::<f64>() / img.len() as f64;
            eprintln!("{integrator:?} {name}: rms diff {diff:.5} (noise {noise:.5}), mean {mean:.5} vs {mean_ref:.5}");
            assert!(img.iter().all(|v| v.is_finite()), "{name}: NaN or inf");
            if diff >= 0.25 * noise || (mean - mean_ref).abs() >= 0.01 * mean_ref {
                failures.push(format!("{integrator:?} {name}: rms diff {diff} vs noise {noise}, mean {mean} vs {mean_ref}"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn degenerate_triangles_never_make_nan() {
    let mut b = SceneBuilder::new();
    b.scene.camera.view_dir = Vec3::new(0.2, 1.0, 0.3).normalize();
    let white = b.material(Material::Diffuse { albedo: Vec3::splat(0.7) });
    let emit = b.material(Material::Emission { radiance: Vec3::splat(4.0) });
    b.horizontal_quad(0.0, (-1.0, 1.0), (-1.0, 1.0), true, white);
    b.horizontal_quad(1.0, (-0.2, 0.2), (-0.2, 0.2), false, emit);
    // Zero-area, collinear and duplicate triangles, some exactly in the camera's view.
    let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    for (a, bb, c) in [
        (p(0.1, 0.2, 0.1), p(0.1, 0.2, 0.1), p(0.1, 0.2, 0.1)),
        (p(-0.5, 0.3, 0.0), p(0.0, 0.3, 0.0), p(0.5, 0.3, 0.0)),
        (p(0.0, 0.0, 0.0), p(0.0, 0.5, 0.0), p(0.0, 1.0, 0.0)),
    ] {
        let base = b.scene.positions.len() as u32;
        b.scene.positions.extend([a, bb, c]);
        b.scene.normals.extend([Vec3::Y; 3]);
        b.scene.triangles.push([base, base + 1, base + 2]);
        b.scene.triangle_materials.push(white);
    }
    b.quad([p(-0.3, 0.5, -0.3), p(0.3, 0.5, -0.3), p(0.3, 0.5, 0.3), p(-0.3, 0.5, 0.3)], white);
    b.quad([p(-0.3, 0.5, -0.3), p(0.3, 0.5, -0.3), p(0.3, 0.5, 0.3), p(-0.3, 0.5, 0.3)], white);
    b.light(Light::Area {
        position: p(0.0, 0.99, 0.0),
        direction: Vec3::NEG_Y,
        dim_x: p(0.4, 0.0, 0.0),
        dim_y: p(0.0, 0.0, 0.4),
        radiance: Vec3::splat(4.0),
    });
    let scene = b.build();
    for integrator in [Integrator::Normals, LIGHT, HEMISPHERE, MIS] {
        let px = render_pixels(&scene, integrator, |c| {
            (c.width, c.height, c.spp, c.max_depth) = (64, 48, 8, 4)
        });
        assert!(px.iter().all(|v| v.is_finite()), "{integrator:?} produced NaN/inf");
    }
}

#[test]
fn hemisphere_sampling_with_only_delta_lights_renders_black_without_crashing() {
    let mut b = SceneBuilder::new();
    let white = b.material(Material::Diffuse { albedo: Vec3::splat(0.7) });
    b.horizontal_quad(0.0, (-1.0, 1.0), (-1.0, 1.0), true, white);
    b.light(Light::Point { position: Vec3::Y, radiance: Vec3::ONE });
    b.light(Light::Directional { direction: Vec3::Y, radiance: Vec3::ONE });
    let scene = b.build();
    let px = render_pixels(&scene, HEMISPHERE, |c| {
        (c.width, c.height, c.spp, c.max_depth) = (16, 16, 4, 3)
    });
    assert!(px.iter().all(|v| *v == Vec3::ZERO));
    // Light sampling finds both.
    let lit = render_pixels(&scene, LIGHT, |c| (c.width, c.height) = (16, 16));
    assert!(lit.iter().all(|v| v.x > 0.0));
}

#[test]
fn coordinates_that_overflow_box_areas_still_build_a_tree() {
    // Boxes 1e22 across have areas past f32::MAX (and inf x 0 = NaN for flat ones), where
    // the wide tree's least-cost plan once chose no split and indexed out of bounds.
    let mut b = SceneBuilder::new();
    let white = b.material(Material::Diffuse { albedo: Vec3::splat(0.7) });
    b.horizontal_quad(0.0, (-1.0, 1.0), (-1.0, 1.0), true, white);
    for k in 0..12 {
        let (far, y) = (1e22 * (k as f32 + 1.0), -1.0 - k as f32);
        b.horizontal_quad(y, (-far, far), (-far, 0.0), true, white);
        b.quad(
            [
                Vec3::new(far, y, -1.0),
                Vec3::new(far, y, 1.0),
                Vec3::new(far, 1e20, 1.0),
                Vec3::new(far, 1e20, -1.0),
            ],
            white,
        );
    }
    b.light(Light::Point { position: Vec3::Y, radiance: Vec3::ONE });
    let scene = b.build();
    let accel = pathtracer::accel::Accel::new(&scene);
    let ray = pathtracer::math::Ray::new(Vec3::new(0.1, 1.0, 0.2), Vec3::NEG_Y);
    let hit = accel.intersect(&ray, &mut Default::default()).expect("the unit floor is hit");
    assert_eq!((hit.t, hit.prim), (1.0, 0));
    // The camera frames the whole scene, so the unit floor is far below a pixel: the render
    // must only run and stay finite.
    let px = render_pixels(&scene, LIGHT, |c| (c.width, c.height, c.spp) = (16, 12, 2));
    assert!(px.iter().all(|v| v.is_finite()));
}

#[test]
fn a_scene_too_large_to_frame_is_an_error_not_a_black_image() {
    // Corners at +-3e38: the bounding box's diagonal overflows f32, and the course camera sits
    // 1.5 diagonals from the centre.
    let mut b = SceneBuilder::new();
    let white = b.material(Material::Diffuse { albedo: Vec3::splat(0.7) });
    b.horizontal_quad(0.0, (-3e38, 3e38), (-3e38, 3e38), true, white);
    b.light(Light::Point { position: Vec3::Y, radiance: Vec3::ONE });
    let scene = b.build();
    let accel = pathtracer::accel::Accel::new(&scene);
    let config = pathtracer::RenderConfig { width: 8, height: 6, ..Default::default() };
    let e = pathtracer::render(&scene, &accel, &config).err().expect("an error").to_string();
    assert!(e.starts_with("cannot place the camera") && !e.contains('\n'), "{e}");
}
