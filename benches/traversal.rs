//! Criterion: the standard ray sets (BENCHMARK.md) on CBbunny, primary / diffuse / shadow x
//! single (streamed, as `pathtracer bench` runs it, and one ray at a time) / packet4 /
//! packet8 / packet16, one thread. Skips (with a message) without the course scenes.
//! The `pathtracer bench` command is the reported measurement; this is for quick A/B work:
//! `cargo bench --bench traversal`.

use std::hint::black_box;

mod common;

use common::scene_path;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use pathtracer::accel::{Accel, AccelKind, TraceStats};
use pathtracer::bench::{generate_ray_sets, triangles_only, RaySet, Traversal};
use pathtracer::math::Ray;

/// Hits (or blocked rays) of `rays` with `traversal`, as `pathtracer bench` traces them:
/// single rays as a stream (several in flight per thread), packets `W` rays at a time.
fn trace(accel: &Accel, rays: &[Ray], set: RaySet, traversal: Traversal) -> u64 {
    let mut stats = TraceStats::default();
    if traversal == Traversal::Single {
        return if set.is_occlusion() {
            let mut blocked = vec![false; rays.len()];
            accel.occluded_stream(rays, &mut blocked, &mut stats);
            blocked.iter().filter(|&&b| b).count() as u64
        } else {
            let mut hits = vec![None; rays.len()];
            accel.intersect_stream(rays, &mut hits, &mut stats);
            hits.iter().flatten().count() as u64
        };
    }
    let (mut hits, mut blocked) = ([None; 16], [false; 16]);
    let mut n = 0;
    for group in rays.chunks(traversal.width()) {
        let k = group.len();
        match (traversal, set.is_occlusion()) {
            (Traversal::Packet4, true) => {
                accel.occluded_packet::<4>(group, &mut blocked, &mut stats)
            }
            (Traversal::Packet4, false) => {
                accel.intersect_packet::<4>(group, &mut hits, &mut stats)
            }
            (Traversal::Packet8, true) => {
                accel.occluded_packet::<8>(group, &mut blocked, &mut stats)
            }
            (Traversal::Packet8, false) => {
                accel.intersect_packet::<8>(group, &mut hits, &mut stats)
            }
            (_, true) => accel.occluded_packet::<16>(group, &mut blocked, &mut stats),
            (_, false) => accel.intersect_packet::<16>(group, &mut hits, &mut stats),
        }
        n += if set.is_occlusion() {
            blocked[..k].iter().filter(|&&b| b).count()
        } else {
            hits[..k].iter().flatten().count()
        } as u64;
    }
    n
}

/// Single rays one at a time (`Accel::intersect` / `occluded`), for comparison with the stream.
fn trace_one_at_a_time(accel: &Accel, rays: &[Ray], set: RaySet) -> u64 {
    let mut stats = TraceStats::default();
    if set.is_occlusion() {
        rays.iter().filter(|r| accel.occluded(r, &mut stats)).count() as u64
    } else {
        rays.iter().filter(|r| accel.intersect(r, &mut stats).is_some()).count() as u64
    }
}

fn traversal(c: &mut Criterion) {
    let Some(path) = scene_path("sky/CBbunny.dae") else { return };
    let scene = triangles_only(&pathtracer::scene::collada::load(&path).expect("CBbunny loads"));
    let accel = Accel::build(&scene, AccelKind::Bvh);
    let sets = generate_ray_sets(&scene, &accel);
    for set in RaySet::ALL {
        let rays = sets.get(set);
        let mut g = c.benchmark_group(format!("CBbunny/{}", set.name()));
        g.throughput(Throughput::Elements(rays.len() as u64));
        g.sample_size(10);
        for t in Traversal::ALL {
            g.bench_function(t.name(), |b| b.iter(|| trace(&accel, black_box(rays), set, t)));
        }
        g.bench_function("single, one at a time", |b| {
            b.iter(|| trace_one_at_a_time(&accel, black_box(rays), set))
        });
        g.finish();
    }
}

criterion_group!(benches, traversal);
criterion_main!(benches);
