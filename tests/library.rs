//! The crate's front door as an embedding program uses it: `Scene::load`, `Accel::new`, the
//! traversal queries without a statistics argument (which answer exactly what the counting
//! ones do), and errors typed by what went wrong.

use std::path::{Path, PathBuf};

use pathtracer::{Accel, Error, Ray, Scene, TraceStats, Vec3};

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pt-library-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn cornell() -> Scene {
    Scene::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cornell.dae")).unwrap()
}

/// Rays from in front of the open box into it, some through the spheres, some out past the
/// walls, and some pointing away.
fn probe_rays() -> Vec<Ray> {
    let mut rays = Vec::new();
    for i in 0..13 {
        for j in 0..7 {
            let target = Vec3::new(-1.5 + 0.25 * i as f32, -0.25 + 0.375 * j as f32, -1.0);
            let origin = Vec3::new(0.1, 1.0, 4.0);
            let dir = if (i + j) % 5 == 0 { origin - target } else { target - origin };
            rays.push(Ray::new(origin, dir.normalize()));
        }
    }
    rays
}

#[test]
fn queries_without_statistics_answer_what_the_counting_ones_do() {
    let scene = cornell();
    let accel = Accel::new(&scene);
    let rays = probe_rays();
    let mut stats = TraceStats::default();
    let (mut hits, mut misses, mut blocked) = (0, 0, 0);
    for ray in &rays {
        let hit = accel.closest_hit(ray);
        assert_eq!(hit, accel.intersect(ray, &mut stats));
        assert_eq!(accel.any_hit(ray), accel.occluded(ray, &mut stats));
        assert_eq!(accel.any_hit(ray), hit.is_some());
        if hit.is_some() {
            hits += 1
        } else {
            misses += 1
        }
        blocked += accel.any_hit(ray) as u32;
    }
    assert!(hits > 20 && misses > 5 && blocked == hits, "{hits} hits, {misses} misses");
    assert_eq!(stats.rays, 2 * rays.len() as u64, "the counting variants still count");

    for chunk in rays.chunks(8) {
        let mut hits = [None; 8];
        let mut blocked = [false; 8];
        accel.closest_hit_packet::<8>(chunk, &mut hits);
        accel.any_hit_packet::<8>(chunk, &mut blocked);
        for (k, ray) in chunk.iter().enumerate() {
            assert_eq!(hits[k], accel.closest_hit(ray));
            assert_eq!(blocked[k], accel.any_hit(ray));
        }
    }
}

#[test]
fn errors_are_typed_by_what_went_wrong() {
    let dir = scratch_dir("errors");
    let missing = dir.join("missing.dae");
    match Scene::load(&missing) {
        Err(Error::Io { path, message }) => {
            assert_eq!(path, missing);
            assert!(message.starts_with("cannot read"), "{message}");
        }
        other => panic!("want Error::Io, got {other:?}"),
    }
    let not_xml = dir.join("notxml.dae");
    std::fs::write(&not_xml, "this is not xml <").unwrap();
    let err = Scene::load(&not_xml).unwrap_err();
    assert!(matches!(&err, Error::Scene { path: Some(p), .. } if *p == not_xml), "{err:?}");
    let line = err.to_string();
    assert!(line.starts_with(&not_xml.display().to_string()) && !line.contains('\n'), "{line}");
    let err = Scene::parse("<html><body/></html>").unwrap_err();
    assert!(matches!(&err, Error::Scene { path: None, message } if message.contains("COLLADA")));
    // An image that cannot be written is an I/O error naming it.
    let image = dir.join("no-such-dir").join("x.png");
    let err = pathtracer::write_image(&image, 1, 1, &[Vec3::ONE]).unwrap_err();
    assert!(matches!(&err, Error::Io { path, .. } if *path == image), "{err:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An embedding program asks for stage times with `RenderConfig::stage_times`: without it the
/// clock is never read (all zero); with it every stage the render ran has a time, and the
/// image and counts are the same.
#[test]
fn stage_times_only_when_asked_and_the_image_unchanged() {
    use pathtracer::{render, DirectLighting, Integrator, RenderConfig};
    let scene = cornell();
    let accel = Accel::new(&scene);
    let config = |stage_times| RenderConfig {
        width: 32,
        height: 24,
        spp: 4,
        max_depth: 3,
        threads: 2,
        integrator: Integrator::Path(DirectLighting::LightSampling),
        stage_times,
        ..RenderConfig::default()
    };
    let plain = render(&scene, &accel, &config(false)).unwrap();
    let timed = render(&scene, &accel, &config(true)).unwrap();
    assert_eq!(plain.stage_times.total(), std::time::Duration::ZERO);
    let t = timed.stage_times;
    for (stage, time) in [
        ("generate", t.generate),
        ("camera hits", t.camera_hits),
        ("bounce hits", t.bounce_hits),
        ("shade", t.shade),
        ("shadow rays", t.shadow_rays),
        ("accumulate", t.accumulate),
    ] {
        assert!(time > std::time::Duration::ZERO, "{stage} ran but took no time");
    }
    assert_eq!(plain.pixels, timed.pixels);
    assert_eq!(plain.stats, timed.stats);
}
