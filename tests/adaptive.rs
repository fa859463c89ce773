//! Adaptive sampling (`-a batch tolerance`): converged pixels leave the queue.

mod common;

use common::{render_output, SceneBuilder, LIGHT};
use pathtracer::math::Vec3;
use pathtracer::scene::{Light, Material};

/// A floor under an area light with a black patch (radiance exactly 0) and a blocker whose
/// soft shadow falls in view. (The course camera keeps the 800 x 600 pixel angle, so a small
/// image sees the centre of the floor.)
fn penumbra_scene() -> pathtracer::scene::Scene {
    let mut b = SceneBuilder::new();
    let white = b.material(Material::Diffuse { albedo: Vec3::splat(0.6) });
    let black = b.material(Material::Diffuse { albedo: Vec3::ZERO });
    b.horizontal_quad(0.0, (-1.0, 1.0), (-1.0, 1.0), true, white);
    b.horizontal_quad(0.001, (-0.15, 0.15), (0.05, 0.25), true, black);
    b.horizontal_quad(0.3, (0.1, 0.5), (-0.6, -0.1), true, white);
    b.light(Light::Area {
        position: Vec3::new(0.0, 1.0, 0.0),
        direction: Vec3::NEG_Y,
        dim_x: Vec3::new(0.5, 0.0, 0.0),
        dim_y: Vec3::new(0.0, 0.0, 0.5),
        radiance: Vec3::splat(5.0),
    });
    b.build()
}

#[test]
fn adaptive_sampling_spends_samples_where_the_noise_is() {
    let scene = penumbra_scene();
    let out = render_output(&scene, LIGHT, |c| {
        (c.width, c.height, c.spp, c.adaptive) = (200, 150, 256, Some((16, 0.05)))
    });
    let counts = &out.samples;
    assert!(
        counts.iter().all(|&n| (16..=256).contains(&n) && n % 16 == 0),
        "counts are whole batches"
    );
    // Black pixels (radiance exactly 0) converge after the first batch.
    let background: Vec<u32> =
        out.pixels.iter().zip(counts).filter(|(p, _)| **p == Vec3::ZERO).map(|(_, &n)| n).collect();
    assert!(!background.is_empty() && background.iter().all(|&n| n == 16), "{background:?}");
    // Penumbra pixels are noisy and keep sampling; some reach the cap.
    let max = *counts.iter().max().unwrap();
    eprintln!(
        "black pixels {}, max {max}, mean {}",
        background.len(),
        counts.iter().map(|&n| n as f64).sum::<f64>() / counts.len() as f64
    );
    assert!(max > 64, "max samples {max}");
    let total: u64 = counts.iter().map(|&n| n as u64).sum();
    assert!(total < 256 * counts.len() as u64 / 2, "adaptive sampling saved less than half");
    assert_eq!(out.stats.camera_rays, total, "every sample is one camera ray");
}

#[test]
fn adaptive_sampling_is_deterministic_across_threads() {
    let scene = penumbra_scene();
    let run = |threads| {
        let o = render_output(&scene, LIGHT, |c| {
            (c.width, c.height, c.spp, c.adaptive, c.threads) =
                (40, 30, 64, Some((8, 0.1)), threads)
        });
        (o.pixels, o.samples)
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn without_adaptive_sampling_every_pixel_takes_all_samples() {
    let scene = penumbra_scene();
    let out = render_output(&scene, LIGHT, |c| (c.width, c.height, c.spp) = (20, 10, 24));
    assert!(out.samples.iter().all(|&n| n == 24));
}
