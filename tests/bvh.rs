//! The BVH against brute force (the oracle), tree invariants, and builds over degenerate input.

mod common;

use pathtracer::accel::build::{build, BuildParams, MAX_DEPTH};
use pathtracer::accel::{Accel, AccelKind, BvhNode, TraceStats};
use pathtracer::math::{Aabb, Ray, Vec3};
use pathtracer::sampler::Pcg32;
use pathtracer::scene::{collada, Scene};

/// Random rays with origins in the scene's bounding box (grown by 10%) and uniform directions,
/// plus segments between two random points (shadow-ray-like, finite t_max).
fn random_rays(bounds: Aabb, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg32::new(seed, 7);
    let point = |rng: &mut Pcg32| {
        let e = bounds.extent() * 1.2;
        bounds.min - 0.1 * bounds.extent()
            + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * e
    };
    (0..n)
        .map(|i| {
            let o = point(&mut rng);
            if i % 4 == 3 {
                let to = point(&mut rng) - o;
                return Ray::segment(o, to.normalize(), 0.0, to.length());
            }
            let z = 2.0 * rng.next_f32() - 1.0;
            let phi = std::f32::consts::TAU * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            Ray::new(o, Vec3::new(r * phi.cos(), r * phi.sin(), z))
        })
        .collect()
}

/// Closest hits and occlusion of the BVH equal brute force for every ray: same distance
/// bit for bit (both run the same triangle-test arithmetic), and the same primitive unless
/// two primitives tie at that distance.
fn assert_bvh_matches_brute_force(name: &str, scene: &Scene, rays: usize) {
    let bvh = Accel::build(scene, AccelKind::Bvh);
    let brute = Accel::build(scene, AccelKind::BruteForce);
    let (mut s_bvh, mut s_brute) = (TraceStats::default(), TraceStats::default());
    let mut hits = 0;
    for (i, ray) in random_rays(scene.bounds(), rays, 11).iter().enumerate() {
        let a = bvh.intersect(ray, &mut s_bvh);
        let b = brute.intersect(ray, &mut s_brute);
        match (a, b) {
            (None, None) => {}
            (Some(a), Some(b)) => {
                hits += 1;
                assert_eq!(a.t.to_bits(), b.t.to_bits(), "{name} ray {i}: t {} vs {}", a.t, b.t);
                if a.prim != b.prim {
                    let mut r = *ray;
                    r.t_max = a.t;
                    assert!(
                        brute.intersect(&r, &mut s_brute).is_some(),
                        "{name} ray {i}: prims differ"
                    );
                }
            }
            _ => panic!("{name} ray {i}: BVH {a:?} vs brute force {b:?}"),
        }
        assert_eq!(bvh.occluded(ray, &mut s_bvh), b.is_some(), "{name} ray {i}: occlusion");
    }
    // The oracle only means something if rays hit and the BVH saved work.
    assert!(hits > rays / 20, "{name}: only {hits} of {rays} rays hit");
    if scene.triangles.len() > 1000 {
        assert!(
            s_bvh.triangle_tests * 20 < s_brute.triangle_tests,
            "{name}: BVH {} vs brute {} triangle tests",
            s_bvh.triangle_tests,
            s_brute.triangle_tests
        );
    }
}

#[test]
fn bvh_agrees_with_brute_force_on_course_scenes() {
    for rel in [
        "sky/CBspheres.dae",
        "sky/CBgems.dae",
        "keenan/banana.dae",
        "meshedit/cow.dae",
        "sky/CBbunny.dae",
    ] {
        let Some(path) = common::course_scene(rel) else { return };
        let scene = collada::load(&path).unwrap();
        assert_bvh_matches_brute_force(rel, &scene, 3000);
    }
}

#[test]
fn bvh_agrees_with_brute_force_on_own_scenes() {
    let cornell = collada::parse(&pathtracer::procedural::cornell_box()).unwrap();
    assert_bvh_matches_brute_force("cornell", &cornell, 3000);
    let tori = collada::parse(&pathtracer::procedural::tori(10_000, 5)).unwrap();
    assert_bvh_matches_brute_force("tori 10k", &tori, 3000);
}

/// Every triangle in exactly one leaf; children inside parents; depth bounded.
fn check_tree(nodes: &[BvhNode], order: &[u32], n: usize, boxes: &[Aabb]) {
    let mut seen = vec![0u32; n];
    let mut stack = vec![(0usize, 0usize)];
    while let Some((i, depth)) = stack.pop() {
        assert!(depth < MAX_DEPTH, "depth {depth}");
        let node = nodes[i];
        let inside = |b: Aabb| {
            (0..3).all(|k| b.is_empty() || (b.min[k] >= node.min[k] && b.max[k] <= node.max[k]))
        };
        if node.is_leaf() || n == 0 {
            for &p in &order[node.index as usize..(node.index + node.count) as usize] {
                seen[p as usize] += 1;
                assert!(inside(boxes[p as usize]), "triangle {p} outside its leaf");
            }
        } else {
            for child in [i + 1, node.index as usize] {
                let c = nodes[child];
                assert!(
                    inside(Aabb { min: c.min.into(), max: c.max.into() }),
                    "child {child} outside {i}"
                );
                stack.push((child, depth + 1));
            }
        }
    }
    assert!(seen.iter().all(|&k| k == 1), "triangles referenced {:?} times", seen.iter().max());
}

fn tri_box(a: Vec3, b: Vec3, c: Vec3) -> Aabb {
    Aabb::from_points(&[a, b, c])
}

#[test]
fn degenerate_inputs_build_valid_trees() {
    let params = BuildParams::default();
    let cases: Vec<(&str, Vec<Aabb>)> = vec![
        ("empty", vec![]),
        ("one triangle", vec![tri_box(Vec3::ZERO, Vec3::X, Vec3::Y)]),
        // Ten thousand copies of one triangle: every centroid equal, no SAH split exists.
        ("identical", vec![tri_box(Vec3::ZERO, Vec3::X, Vec3::Y); 10_000]),
        // Flat in y and z: only one axis has extent.
        (
            "collinear",
            (0..5000)
                .map(|i| {
                    tri_box(
                        Vec3::new(i as f32, 0.0, 0.0),
                        Vec3::new(i as f32 + 0.5, 0.0, 0.0),
                        Vec3::new(i as f32 + 1.0, 0.0, 0.0),
                    )
                })
                .collect(),
        ),
        // Points (zero-area, zero-extent boxes) on a few clusters.
        (
            "points",
            (0..4000)
                .map(|i| {
                    let p = Vec3::splat((i % 3) as f32);
                    tri_box(p, p, p)
                })
                .collect(),
        ),
    ];
    for (name, boxes) in cases {
        let built = build(&boxes, params);
        assert!(!built.nodes.is_empty(), "{name}");
        check_tree(&built.nodes, &built.order, boxes.len(), &boxes);
        let max_leaf =
            built.nodes.iter().filter(|n| n.is_leaf()).map(|n| n.count).max().unwrap_or(0);
        assert!(max_leaf as usize <= params.max_leaf.max(1), "{name}: leaf of {max_leaf}");
    }
}

#[test]
fn course_scene_trees_are_valid_and_shallow() {
    let Some(path) = common::course_scene("meshedit/maxplanck.dae") else { return };
    let scene = collada::load(&path).unwrap();
    let boxes: Vec<Aabb> =
        (0..scene.triangles.len()).map(|i| Aabb::from_points(&scene.triangle(i))).collect();
    let built = build(&boxes, BuildParams::default());
    check_tree(&built.nodes, &built.order, boxes.len(), &boxes);
    let accel = Accel::build(&scene, AccelKind::Bvh);
    // Bytes per triangle, both node arrays included: 40 are the SoA triangle itself, about 36
    // the binary nodes (packets) and 35 the 4-wide nodes (single rays). A guard against a
    // layout or leaf-size regression; `bench` reports the figure (PERF.md, "Memory").
    let per_tri = accel.memory_bytes() as f64 / scene.triangles.len() as f64;
    assert!(per_tri <= 120.0, "{per_tri:.1} bytes per triangle");
}

#[test]
fn committed_cornell_box_is_what_the_generator_writes() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/cornell.dae");
    let committed = std::fs::read_to_string(path).unwrap();
    assert!(
        committed == pathtracer::procedural::cornell_box(),
        "assets/cornell.dae differs from `pathtracer gen cornell`: regenerate it with \
         `cargo run --release -- gen cornell -o assets/cornell.dae`"
    );
}
