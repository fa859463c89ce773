//! Criterion: BVH build time (binned SAH, flat nodes, SoA triangles) on CBbunny and
//! maxplanck. Skips (with a message) without the course scenes: `cargo bench --bench build`.

mod common;

use common::scene_path;
use criterion::{criterion_group, criterion_main, Criterion};
use pathtracer::accel::{Accel, AccelKind};
use pathtracer::bench::triangles_only;

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
