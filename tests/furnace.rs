//! Analytic answers: furnace-type scenes whose radiance is known in closed form.

mod common;

use common::{render_output, SceneBuilder, LIGHT};
use pathtracer::math::Vec3;
use pathtracer::scene::{Camera, Light, Material, Scene, Sphere};
use std::f32::consts::PI;

/// A closed diffuse sphere of albedo `a` with a falloff-free point light of intensity `i` at
/// its centre, and the camera inside. Every point of the wall receives irradiance i directly,
/// and since a sphere lit uniformly stays uniform, each bounce multiplies radiance by a:
/// L(m) = a/pi * i * (1 + a + ... + a^(m-1)), -> a/pi * i / (1 - a) for unlimited depth.
fn furnace(albedo: f32, intensity: f32) -> Scene {
    let mut b = SceneBuilder::new();
    let wall = b.material(Material::Diffuse { albedo: Vec3::splat(albedo) });
    b.scene.spheres.push(Sphere { center: Vec3::ZERO, radius: 1.0, material: wall });
    b.light(Light::Point { position: Vec3::ZERO, radiance: Vec3::splat(intensity) });
    b.build()
}

/// A camera inside the sphere, off centre, so the wall is seen at many angles and distances.
/// (The course camera always sits outside the geometry, 1.5 diagonals from its centre.)
fn inside_camera(scene: &Scene) -> Camera {
    let mut cam = Camera::new(&scene.camera, scene.bounds(), 16, 16);
    cam.tan_half_h = 1.0;
    cam.tan_half_v = 1.0;
    cam.eye = Vec3::new(0.3, -0.2, 0.1);
    cam
}

fn mean_radiance(scene: &Scene, depth: u32, spp: u32) -> (f64, f64) {
    let camera = Some(inside_camera(scene));
    let out = render_output(scene, LIGHT, |c| {
        (c.width, c.height, c.spp, c.max_depth, c.camera) = (16, 16, spp, depth, camera)
    });
    let v: Vec<f64> = out.pixels.iter().map(|p| p.x as f64).collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

#[test]
fn direct_light_inside_the_furnace_is_exact() {
    let (a, i) = (0.5, 2.0);
    let (mean, err) = mean_radiance(&furnace(a, i), 1, 1);
    let want = (a / PI * i) as f64;
    assert!((mean - want).abs() < 1e-4 * want && err < 1e-5, "{mean} +- {err} vs {want}");
}

#[test]
fn furnace_radiance_follows_the_geometric_series() {
    let (a, i) = (0.5f32, 2.0f32);
    let scene = furnace(a, i);
    let direct = a / PI * i;
    for (depth, spp) in [(2u32, 64u32), (4, 64), (64, 256)] {
        let want = (direct * (1.0 - a.powi(depth as i32)) / (1.0 - a)) as f64;
        let (mean, err) = mean_radiance(&scene, depth, spp);
        let bound = 4.0 * err + 1e-4 * want;
        eprintln!("-m {depth}: {mean:.5} +- {err:.5} vs {want:.5}");
        assert!((mean - want).abs() < bound, "-m {depth}: {mean} +- {err} vs {want}");
        assert!(err < 0.01 * want, "-m {depth}: too noisy to be a test ({err})");
    }
}

#[test]
fn diffuse_plane_under_ambient_sky_gives_albedo_times_radiance() {
    let mut b = SceneBuilder::new();
    let m = b.material(Material::Diffuse { albedo: Vec3::new(0.2, 0.5, 0.8) });
    b.horizontal_quad(0.0, (-1.0, 1.0), (-1.0, 1.0), true, m);
    b.light(Light::Ambient { radiance: Vec3::new(1.0, 2.0, 3.0) });
    let out = render_output(&b.build(), LIGHT, |c| {
        (c.width, c.height, c.spp, c.light_samples) = (16, 16, 4, 4)
    });
    let want = Vec3::new(0.2, 1.0, 2.4);
    for p in &out.pixels {
        assert!((*p - want).abs().max_element() < 1e-5, "{p} vs {want}");
    }
}

/// A whiter furnace (albedo 0.9) at effectively unlimited depth: the series sums ten bounces'
/// worth of light, so Russian roulette must terminate paths without bias. L = direct / (1 - a).
#[test]
fn white_furnace_converges_to_direct_over_one_minus_albedo() {
    let (a, i) = (0.9f32, 2.0f32);
    let want = (a / PI * i / (1.0 - a)) as f64;
    let (mean, err) = mean_radiance(&furnace(a, i), 1000, 256);
    eprintln!("a = 0.9, -m 1000: {mean:.5} +- {err:.5} vs {want:.5}");
    assert!(err < 0.01 * want, "too noisy to be a test ({err})");
    assert!((mean - want).abs() < 4.0 * err + 1e-4 * want, "{mean} +- {err} vs {want}");
}
