//! Glossy vertices weigh their area-light samples against their BSDF sample
//! (`integrator` `path::weighs_area_lights`): the image converges to the one plain light
//! sampling converges to, with less noise.

mod common;

use common::{LIGHT, MIS};
use pathtracer::accel::{Accel, AccelKind};
use pathtracer::integrator::Integrator;
use pathtracer::render::{render, RenderConfig};
use pathtracer::scene::Scene;

/// The course's Cornell box with a smooth aluminium and a rough silver ball, and its BVH; `None`
/// (skipped) without the course scenes.
fn glossy_course_scene() -> Option<(Scene, Accel)> {
    let path = common::course_scene("sky/CBspheres_microfacet_al_ag.dae")?;
    let scene = pathtracer::scene::collada::load(&path).unwrap();
    assert!(scene.materials.iter().any(pathtracer::integrator::is_glossy));
    let accel = Accel::build(&scene, AccelKind::Bvh);
    Some((scene, accel))
}

/// Each quadrant's mean over `seeds` renders: (mean of the means, its standard error).
fn quadrant_means(
    scene: &Scene,
    accel: &Accel,
    integrator: Integrator,
    max_depth: u32,
    weigh: bool,
) -> Vec<(f64, f64)> {
    let (w, h, seeds) = (160usize, 120usize, 6u64);
    let per_seed: Vec<[f64; 4]> = (0..seeds)
        .map(|seed| {
            let config = RenderConfig {
                integrator,
                width: w as u32,
                height: h as u32,
                spp: 16,
                max_depth,
                threads: 2,
                seed: 100 + seed,
                glossy_light_mis: weigh,
                ..RenderConfig::default()
            };
            let px = render(scene, accel, &config).unwrap().pixels;
            let mut q = [0.0f64; 4];
            for (i, p) in px.iter().enumerate() {
                let (x, y) = (i % w, i / w);
                q[(x * 2 / w) + 2 * (y * 2 / h)] += p.element_sum() as f64 / (w * h / 4) as f64;
            }
            q
        })
        .collect();
    (0..4)
        .map(|k| {
            let v: Vec<f64> = per_seed.iter().map(|q| q[k]).collect();
            let n = v.len() as f64;
            let mean = v.iter().sum::<f64>() / n;
            let var = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
            (mean, (var / n).sqrt())
        })
        .collect()
}

/// Weighed and plain light sampling agree on every quadrant's mean within four standard errors
/// of their difference (the seeds' spread), under light sampling at -m 1 and -m 5, on
/// the course's Cornell box with a smooth aluminium and a rough silver ball (`alpha` 0.025 and
/// 0.25, lit by a large area light); and the weighing leaves at most half of plain sampling's
/// spread (the balls' reflections of the light, plain sampling's fireflies).
#[test]
fn weighed_glossy_vertices_converge_to_plain_light_sampling() {
    let Some((scene, accel)) = glossy_course_scene() else {
        return;
    };
    // Under MIS the emissive quads are the lights and the CGL area lights are left out, so only
    // light sampling weighs (the same bytes either way there).
    let integrator = LIGHT;
    {
        for m in [1, 5] {
            let weighed = quadrant_means(&scene, &accel, integrator, m, true);
            let plain = quadrant_means(&scene, &accel, integrator, m, false);
            let (mut se_weighed, mut se_plain) = (0.0, 0.0);
            let name = integrator.name();
            for (k, (&(a, sa), &(b, sb))) in weighed.iter().zip(&plain).enumerate() {
                let bound = 4.0 * (sa * sa + sb * sb).sqrt();
                eprintln!(
                    "{name} -m {m} quadrant {k}: {a:.5} +- {sa:.2e} against {b:.5} +- {sb:.2e}"
                );
                assert!(a > 0.0 && (a - b).abs() <= bound, "{name} -m {m} quadrant {k}");
                se_weighed += sa / a;
                se_plain += sb / b;
            }
            eprintln!("{name} -m {m}: relative spread {se_weighed:.2e} against {se_plain:.2e}");
            assert!(se_weighed <= 0.5 * se_plain, "{name} -m {m}: {se_weighed} against {se_plain}");
        }
    }
}

/// Under MIS the CGL area lights are not sampled (the emissive geometry is the light), so no
/// vertex weighs: the same bytes with the weighing on and off.
#[test]
fn mis_renders_do_not_weigh_area_lights() {
    let Some((scene, accel)) = glossy_course_scene() else {
        return;
    };
    let config = |weigh| RenderConfig {
        integrator: MIS,
        width: 40,
        height: 30,
        spp: 8,
        max_depth: 5,
        threads: 2,
        seed: 3,
        glossy_light_mis: weigh,
        ..RenderConfig::default()
    };
    let (a, b) = (
        render(&scene, &accel, &config(true)).unwrap(),
        render(&scene, &accel, &config(false)).unwrap(),
    );
    assert!(a.pixels == b.pixels && a.stats == b.stats);
}

/// The weighing keeps the image a function of the seed alone: the same bytes for 1, 2 and 3
/// threads.
#[test]
fn weighed_renders_are_the_same_bytes_for_any_thread_count() {
    let Some((scene, accel)) = glossy_course_scene() else {
        return;
    };
    let run = |threads| {
        let config = RenderConfig {
            integrator: LIGHT,
            width: 37,
            height: 29,
            spp: 4,
            max_depth: 4,
            threads,
            seed: 9,
            ..RenderConfig::default()
        };
        render(&scene, &accel, &config).unwrap().pixels
    };
    let one = run(1);
    assert!(one == run(2) && one == run(3));
    assert!(one.iter().all(|p| p.is_finite()) && one.iter().any(|p| p.max_element() > 0.0));
}
