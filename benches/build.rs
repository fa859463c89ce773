//! Criterion: BVH build time (binned SAH, flat nodes, SoA triangles) on CBbunny and
//! maxplanck. Skips (with a message) without the course scenes: `cargo bench --bench build`.

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use pathtracer::accel::{Accel, AccelKind};
use pathtracer::bench::triangles_only;

fn scene_path(rel: &str) -> Option<PathBuf> {
    let dir = std::env::var_os("PT_SCENES").map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/cs184")
    });
    let p = dir.join(rel);
    if p.is_file() {
        Some(p)
    } else {
        eprintln!("skipped: scenes not found ({})", p.display());
        None
    }
}

fn build(c: &mut Criterion) {
    let mut g = c.benchmark_group("bvh_build");
    g.sample_size(10);
    for rel in ["sky/CBbunny.dae", "meshedit/maxplanck.dae"] {
        let Some(path) = scene_path(rel) else { continue };
        let scene = triangles_only(&pathtracer::scene::collada::load(&path).expect("scene loads"));
        let name = rel.rsplit('/').next().unwrap_or(rel);
        g.bench_function(name, |b| b.iter(|| Accel::build(&scene, AccelKind::Bvh)));
    }
    g.finish();
}

criterion_group!(benches, build);
criterion_main!(benches);
