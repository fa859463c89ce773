//! Extra camera rays on the outlines of visible emitters (`--edge-samples`): they must leave
//! every other pixel bit-identical, keep the outline pixels' expected value, and remove most
//! of their noise.
//!
//! The scene is an emissive square in front of a wall lit by a point light, rendered
//! at 64 x 48, 64 spp, `-m 1`, light sampling, with `--edge-samples` 0 and 8, seeds 1 and 2.
//! The outline is the set of pixels whose same-seed values differ between the two settings.
//! Each setting's noise comes from its two seeds: the per-pixel variance of a seed's estimate
//! is (A - B)^2 / 2, so the standard error of the outline's mean over both seeds is
//! sqrt(sum (A - B)^2 / 2) / (2 n). The means must agree within 5 combined standard errors,
//! and that bound must be under 1% of the mean, so that a wrong weight (1/K instead of
//! 1/(K+1) moves these pixels' emission by 12%) fails.

mod common;

use common::{render_output, SceneBuilder, LIGHT};
use pathtracer::math::Vec3;
use pathtracer::render::RenderOutput;
use pathtracer::scene::{Camera, Light, Material, Scene};
use pathtracer::wavefront::emitter_window;

const SEEDS: [u64; 2] = [1, 2];

/// A square of side 2 facing +z at depth `z`, centred on the z axis, scaled by `half`.
fn square(b: &mut SceneBuilder, z: f32, half: f32, material: u32) {
    let c = |x: f32, y: f32| Vec3::new(x * half, y * half, z);
    b.quad([c(-1.0, -1.0), c(1.0, -1.0), c(1.0, 1.0), c(-1.0, 1.0)], material);
}

/// A white wall at z = -1 facing the camera (+z), lit by a point light in front, with
/// `emitters(builder, emissive material)` added in front of it (radiance 8).
fn wall_with(emitters: impl FnOnce(&mut SceneBuilder, u32)) -> Scene {
    let mut b = SceneBuilder::new();
    b.scene.camera.view_dir = Vec3::new(0.1, 0.05, 1.0).normalize();
    let white = b.material(Material::Diffuse { albedo: Vec3::splat(0.7) });
    let emit = b.material(Material::Emission { radiance: Vec3::splat(8.0) });
    square(&mut b, -1.0, 1.0, white);
    emitters(&mut b, emit);
    b.light(Light::Point { position: Vec3::new(0.5, 0.5, 1.0), radiance: Vec3::splat(1.0) });
    b.build()
}

/// A small emissive square in front of the wall, facing the camera.
fn emitter_in_view() -> Scene {
    wall_with(|b, emit| square(b, -0.5, 0.1, emit))
}

fn render(edge_samples: u32, seed: u64) -> RenderOutput {
    render_output(&emitter_in_view(), LIGHT, |c| {
        (c.width, c.height, c.spp, c.max_depth) = (64, 48, 64, 1);
        c.seed = seed;
        c.edge_samples = edge_samples;
    })
}

fn luminance(p: pathtracer::math::Vec3) -> f64 {
    (p.x as f64 + p.y as f64 + p.z as f64) / 3.0
}

/// The mean over `pixels` of both seeds' images, and its standard error.
fn mean_and_se(runs: &[RenderOutput; 2], pixels: &[usize]) -> (f64, f64) {
    let n = pixels.len() as f64;
    let (mut sum, mut sq) = (0.0, 0.0);
    for &i in pixels {
        let (a, b) = (luminance(runs[0].pixels[i]), luminance(runs[1].pixels[i]));
        sum += a + b;
        sq += (a - b) * (a - b) / 2.0;
    }
    (sum / (2.0 * n), (sq * 2.0).sqrt() / (2.0 * n))
}

#[test]
fn outline_pixels_keep_their_mean_and_lose_their_noise() {
    let plain = SEEDS.map(|s| render(0, s));
    let split = SEEDS.map(|s| render(8, s));
    let n = plain[0].pixels.len();
    // Outline pixels whose samples all land on one side may come out the same bits either way,
    // so the outline is where either seed's images differ.
    let outline: Vec<usize> =
        (0..n).filter(|&i| (0..2).any(|s| plain[s].pixels[i] != split[s].pixels[i])).collect();
    assert!(
        outline.len() >= 20 && outline.len() * 10 < n,
        "{} outline pixels of {n}: the emitter's edge should be a thin line",
        outline.len()
    );
    // Corner rays and extra camera rays were traced, and only with extra rays asked for: with
    // 2 extra rays instead of 1 the same pixels take 64 more each (both within the tiles'
    // budget), so the difference counts the marked pixels, and the rest are corner rays,
    // 17 x 17 per tile near the emitter (`emitter_window`), at most all 12 tiles.
    assert_eq!(plain[0].stats.probe_rays, 0);
    let (one, two) = (render(1, SEEDS[0]).stats.probe_rays, render(2, SEEDS[0]).stats.probe_rays);
    let marked = (two - one) / 64;
    assert_eq!((two - one) % 64, 0);
    assert!(marked >= outline.len() as u64, "{marked} pixels marked, {} changed", outline.len());
    let corners = one - marked * 64;
    assert!(corners.is_multiple_of(17 * 17) && corners <= 12 * 17 * 17, "{corners} corner rays");
    let (m0, se0) = mean_and_se(&plain, &outline);
    let (m8, se8) = mean_and_se(&split, &outline);
    let bound = 5.0 * (se0 * se0 + se8 * se8).sqrt();
    eprintln!(
        "outline of {}: mean {m0:.5} +- {se0:.5} (plain) against {m8:.5} +- {se8:.5}",
        outline.len()
    );
    assert!(bound < 0.01 * m0, "the bound {bound} is not under 1% of the mean {m0}");
    assert!((m0 - m8).abs() <= bound, "means {m0} and {m8} differ by more than {bound}");
    // The extra rays take most of the outline's variance away (measured: standard error
    // 0.00048 against 0.00299).
    assert!(se8 < 0.5 * se0, "standard error {se8} with extra rays against {se0} without");
}

#[test]
fn one_sample_per_pixel_goes_through_the_centre_alone() {
    let one = |edge_samples| {
        render_output(&emitter_in_view(), LIGHT, |c| {
            (c.width, c.height, c.spp) = (32, 24, 1);
            c.edge_samples = edge_samples;
        })
    };
    let (plain, split) = (one(0), one(8));
    assert_eq!(plain.pixels, split.pixels);
    assert_eq!(split.stats.probe_rays, 0);
}

#[test]
fn only_tiles_near_the_emitters_look_for_outlines() {
    let scene = emitter_in_view();
    let camera = Camera::new(&scene.camera, scene.bounds(), 64, 48);
    let [x0, y0, x1, y1] = emitter_window(&scene, &camera).expect("the scene has an emitter");
    // The emissive square sits in the middle of the view, well inside the image.
    assert!(0.0 < x0 && x0 < x1 && x1 < 64.0 && 0.0 < y0 && y0 < y1 && y1 < 48.0);
    // Its four corners' pixels fall inside the window.
    for (x, y) in [(-0.1, -0.1), (0.1, -0.1), (0.1, 0.1), (-0.1, 0.1)] {
        let [px, py] = camera.pixel_of(Vec3::new(x, y, -0.5)).unwrap();
        assert!((x0..=x1).contains(&px) && (y0..=y1).contains(&py));
    }
    // Without emitters there is no window, and no corner ray is traced.
    let mut dark = scene.clone();
    dark.materials[1] = Material::Diffuse { albedo: Vec3::splat(0.5) };
    let camera = Camera::new(&dark.camera, dark.bounds(), 64, 48);
    assert_eq!(emitter_window(&dark, &camera), None);
    let out = render_output(&dark, LIGHT, |c| {
        (c.width, c.height, c.spp) = (64, 48, 4);
    });
    assert_eq!(out.stats.probe_rays, 0);
}

/// Thirty thin emissive strips in front of the wall: most pixels lie on an outline.
fn striped_emitter() -> Scene {
    wall_with(|b, emit| {
        for i in 0..30 {
            let x = -0.3 + 0.02 * i as f32;
            let c = |x: f32, y: f32| Vec3::new(x, y, -0.5);
            b.quad([c(x, -0.3), c(x + 0.01, -0.3), c(x + 0.01, 0.3), c(x, 0.3)], emit);
        }
    })
}

#[test]
fn a_tile_full_of_outlines_traces_at_most_twice_its_camera_rays() {
    let out = render_output(&striped_emitter(), LIGHT, |c| {
        (c.width, c.height, c.spp) = (64, 48, 8);
    });
    let corners_at_most = 12 * 17 * 17;
    let camera = out.stats.camera_rays;
    assert_eq!(camera, 64 * 48 * 8);
    assert!(
        out.stats.probe_rays <= corners_at_most + camera,
        "{} probe rays for {camera} camera rays",
        out.stats.probe_rays
    );
    // The strips are outlines, so extra rays were traced, only fewer of them per pixel.
    assert!(out.stats.probe_rays > corners_at_most, "{} probe rays", out.stats.probe_rays);
}
