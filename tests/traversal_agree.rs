//! Packets (4, 8 and 16 wide) and streams of interleaved single rays against single rays on the
//! same rays: the same hit or miss, bit-identical t, u, v and the same prim for every ray, and
//! the same occlusion answer for shadow rays.

mod common;

use pathtracer::accel::{traverse_single, Accel, AccelKind, PacketStack, RayPacket, TraceStats};
use pathtracer::bench::{generate_ray_sets, triangles_only};
use pathtracer::math::{Hit, Ray, Vec3};
use pathtracer::scene::{collada, Scene};
use pathtracer::simd::VFloat;

fn bits(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim))
}

/// Every ray's closest hit and occlusion agree between single rays, all packet widths and
/// streams of rays in flight (`Accel::intersect_stream`, which also counts exactly the same
/// work, `Accel::occluded_stream`, and the bare triangle streams at 3 rays in flight, with
/// prefetching, against the bare triangle traversals). Returns the number of closest hits found (so callers can check the rays test
/// something).
fn assert_agree(accel: &Accel, rays: &[Ray], what: &str) -> usize {
    let mut stats = TraceStats::default();
    let single: Vec<Option<Hit>> = rays.iter().map(|r| accel.intersect(r, &mut stats)).collect();
    let mut stream = vec![None; rays.len()];
    let mut stream_stats = TraceStats::default();
    accel.intersect_stream(rays, &mut stream, &mut stream_stats);
    assert_eq!(stream_stats, stats, "{what}: the stream counts the same work");
    let (nodes, tris) = (accel.wide_nodes(), accel.triangles());
    let bare: Vec<Option<Hit>> = rays
        .iter()
        .map(|r| traverse_single::intersect(nodes, tris, &mut r.clone(), &mut stats))
        .collect();
    let mut bare3 = vec![None; rays.len()];
    traverse_single::intersect_stream::<3, true>(nodes, tris, rays, &mut bare3, &mut stats);
    let single_occ: Vec<bool> = rays.iter().map(|r| accel.occluded(r, &mut stats)).collect();
    let mut stream_occ = vec![false; rays.len()];
    accel.occluded_stream(rays, &mut stream_occ, &mut stats);
    let bare_occ: Vec<bool> =
        rays.iter().map(|r| traverse_single::occluded(nodes, tris, r, &mut stats)).collect();
    let mut bare3_occ = vec![false; rays.len()];
    traverse_single::occluded_stream::<3>(nodes, tris, rays, &mut bare3_occ, &mut stats);
    let mut p4 = vec![None; rays.len()];
    let mut p8 = vec![None; rays.len()];
    let mut p16 = vec![None; rays.len()];
    accel.intersect_packets::<4>(rays, &mut p4, &mut stats);
    accel.intersect_packets::<8>(rays, &mut p8, &mut stats);
    accel.intersect_packets::<16>(rays, &mut p16, &mut stats);
    let mut o4 = vec![false; rays.len()];
    let mut o8 = vec![false; rays.len()];
    let mut o16 = vec![false; rays.len()];
    accel.occluded_packets::<4>(rays, &mut o4, &mut stats);
    accel.occluded_packets::<8>(rays, &mut o8, &mut stats);
    accel.occluded_packets::<16>(rays, &mut o16, &mut stats);
    for i in 0..rays.len() {
        let s = bits(single[i]);
        assert_eq!(s, bits(stream[i]), "{what}: ray {i} {:?}: the stream differs", rays[i]);
        assert_eq!(bits(bare[i]), bits(bare3[i]), "{what}: ray {i} {:?}: stream of 3", rays[i]);
        assert_eq!(s, bits(p4[i]), "{what}: ray {i} {:?}: packet4 differs", rays[i]);
        assert_eq!(s, bits(p8[i]), "{what}: ray {i} {:?}: packet8 differs", rays[i]);
        assert_eq!(s, bits(p16[i]), "{what}: ray {i} {:?}: packet16 differs", rays[i]);
        assert_eq!(single_occ[i], o16[i], "{what}: ray {i} {:?}: packet16 occlusion", rays[i]);
        assert_eq!(single_occ[i], o4[i], "{what}: ray {i} {:?}: packet4 occlusion", rays[i]);
        assert_eq!(single_occ[i], stream_occ[i], "{what}: ray {i} {:?}: stream occlusion", rays[i]);
        assert_eq!(bare_occ[i], bare3_occ[i], "{what}: ray {i} {:?}: stream of 3", rays[i]);
        assert_eq!(single_occ[i], o8[i], "{what}: ray {i} {:?}: packet8 occlusion", rays[i]);
    }
    single.iter().flatten().count()
}

fn course_scene_agrees(rel: &str, keep_spheres: bool) {
    let Some(path) = common::course_scene(rel) else { return };
    let loaded = collada::load(&path).unwrap();
    let tris_only = triangles_only(&loaded);
    let mut accel = Accel::build(&tris_only, AccelKind::Bvh);
    // The standard sets come from the triangles; with `keep_spheres` they are then traced
    // against the scene with its spheres.
    let sets = generate_ray_sets(&tris_only, &accel);
    if keep_spheres {
        assert!(!loaded.spheres.is_empty(), "{rel} has spheres");
        accel = Accel::build(&loaded, AccelKind::Bvh);
    }
    // An odd count so the last packet of every width is partly filled.
    let primary = &sets.primary[..sets.primary.len() - 3];
    let hits = assert_agree(&accel, primary, &format!("{rel} primary"));
    assert!(hits > 1000, "{rel}: primary rays must hit something ({hits})");
    assert_agree(&accel, &sets.diffuse, &format!("{rel} diffuse"));
    assert_agree(&accel, &sets.shadow, &format!("{rel} shadow"));
}

#[test]
fn cbbunny_packets_agree_with_single_rays() {
    course_scene_agrees("sky/CBbunny.dae", false);
}

#[test]
fn maxplanck_packets_agree_with_single_rays() {
    course_scene_agrees("meshedit/maxplanck.dae", false);
}

/// A small scene with analytic spheres: packets test the spheres after the triangles as
/// `intersect` does.
#[test]
fn cbspheres_packets_agree_with_single_rays() {
    course_scene_agrees("sky/CBspheres.dae", true);
}

/// A closed box built in code (no course scenes needed): axis-aligned walls give flat boxes
/// and rays through shared edges.
#[test]
fn built_box_packets_agree_with_single_rays() {
    let scene = common::coincident_light_box();
    let accel = Accel::build(&scene, AccelKind::Bvh);
    let sets = generate_ray_sets(&scene, &accel);
    let hits = assert_agree(&accel, &sets.primary, "box primary");
    assert!(hits > 1000, "the camera must see the box ({hits})");
    assert_agree(&accel, &sets.diffuse, "box diffuse");
    assert_agree(&accel, &sets.shadow, "box shadow");
    // Axis-parallel rays from points on the walls' planes and edges (zero direction
    // components, origins on box faces).
    let mut rays = Vec::new();
    for &o in &[
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(1.0, 2.0, 1.0),
        Vec3::new(0.25, 0.0, 0.5),
    ] {
        for &d in
            &[Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z, Vec3::new(1.0, 1.0, 0.0)]
        {
            rays.push(Ray::new(o, d));
            rays.push(Ray::segment(o, d, 0.5, 3.0));
        }
    }
    assert!(assert_agree(&accel, &rays, "box axis rays") > 0);
}

#[test]
fn empty_scene_never_hits() {
    let scene = Scene::default();
    let accel = Accel::build(&scene, AccelKind::Bvh);
    let rays: Vec<Ray> = (0..13).map(|i| Ray::new(Vec3::splat(i as f32), Vec3::Z)).collect();
    assert_eq!(assert_agree(&accel, &rays, "empty"), 0);
    let mut o = vec![true; rays.len()];
    accel.occluded_packets::<8>(&rays, &mut o, &mut TraceStats::default());
    assert!(o.iter().all(|&b| !b));
}

/// NaN and infinite components, zero directions and empty intervals mixed into packets with
/// ordinary rays: no panic, the ordinary lanes are unaffected, and every lane agrees with
/// single-ray traversal.
#[test]
fn bad_rays_in_packets() {
    let scene = common::coincident_light_box();
    let accel = Accel::build(&scene, AccelKind::Bvh);
    let good = |k: f32| Ray::new(Vec3::new(0.1 * k, 1.0, 0.3), Vec3::new(0.2, -1.0, 0.1 * k));
    let nan = f32::NAN;
    let inf = f32::INFINITY;
    let bad = [
        Ray::new(Vec3::new(nan, 1.0, 0.0), Vec3::Y),
        Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::new(nan, nan, nan)),
        Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::new(inf, 0.0, 0.0)),
        Ray::new(Vec3::new(-inf, 1.0, 0.0), Vec3::X),
        Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::ZERO),
        Ray::segment(Vec3::new(0.0, 1.0, 0.0), -Vec3::Y, 2.0, 1.0),
        Ray::segment(Vec3::new(0.0, 1.0, 0.0), -Vec3::Y, nan, nan),
        Ray::segment(Vec3::new(0.0, 1.0, 0.0), -Vec3::Y, -inf, inf),
    ];
    let mut rays = Vec::new();
    for (k, b) in bad.iter().enumerate() {
        rays.push(good(k as f32));
        rays.push(*b);
    }
    let hits = assert_agree(&accel, &rays, "bad rays");
    assert!(hits >= bad.len(), "the ordinary rays hit the floor ({hits})");
    let mut stats = TraceStats::default();
    for r in &rays[..2] {
        let _ = accel.intersect(r, &mut stats);
    }
}

/// Lanes switched off by the caller stay `None`/unblocked and do not count; the others
/// answer as single rays do.
#[test]
fn inactive_lanes_are_ignored() {
    let scene = common::coincident_light_box();
    let accel = Accel::build(&scene, AccelKind::Bvh);
    let rays: Vec<Ray> = (0..8)
        .map(|k| Ray::new(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.1 * k as f32 - 0.4, -1.0, 0.2)))
        .collect();
    for mask in [0u32, 0b1, 0b1010_0101, 0b1000_0000, 0xff] {
        let mut s8 = TraceStats::default();
        let mut hits = [None; 8];
        let p8 = RayPacket::<VFloat<8>>::from_rays_masked(&rays, mask);
        accel.intersect_ray_packet::<8>(p8, 0, &mut PacketStack::new(), &mut hits, &mut s8);
        let mut blocked = [false; 8];
        accel.occluded_ray_packet::<8>(&p8, 0, &mut PacketStack::new(), &mut blocked, &mut s8);
        let mut hits4 = [None; 4];
        let p4 = RayPacket::<VFloat<4>>::from_rays_masked(&rays[..4], mask);
        accel.intersect_ray_packet::<4>(p4, 0, &mut PacketStack::new(), &mut hits4, &mut s8);
        assert_eq!(s8.rays, 2 * mask.count_ones() as u64 + (mask & 0xf).count_ones() as u64);
        for i in 0..8 {
            let mut s = TraceStats::default();
            let on = mask & (1 << i) != 0;
            let expect = if on { bits(accel.intersect(&rays[i], &mut s)) } else { None };
            assert_eq!(bits(hits[i]), expect, "mask {mask:b} lane {i}");
            assert!(!on || expect.is_some(), "active lanes hit the floor");
            assert_eq!(blocked[i], on && accel.occluded(&rays[i], &mut s), "lane {i}");
            if i < 4 {
                assert_eq!(bits(hits4[i]), expect, "packet4 mask {mask:b} lane {i}");
            }
        }
        if mask == 0 {
            assert_eq!(s8, TraceStats::default(), "an all-inactive packet does no work");
        }
    }
}

/// The counters are exact: the same rays give the same counts every time, every fallback
/// threshold gives the same hits, and handing every lane to single-ray traversal at the root
/// counts exactly what single-ray traversal counts.
#[test]
fn counters_are_deterministic_and_fallback_does_not_change_hits() {
    let scene = common::coincident_light_box();
    let accel = Accel::build(&scene, AccelKind::Bvh);
    let rays = generate_ray_sets(&scene, &accel).diffuse;
    let run = |fallback: u32| {
        let mut stats = TraceStats::default();
        let mut out = Vec::new();
        for chunk in rays.chunks(8) {
            let mut h = [None; 8];
            let p = RayPacket::<VFloat<8>>::from_rays(chunk);
            accel.intersect_ray_packet::<8>(
                p,
                fallback,
                &mut PacketStack::new(),
                &mut h,
                &mut stats,
            );
            out.extend(h[..chunk.len()].iter().map(|h| bits(*h)));
        }
        (out, stats)
    };
    let (base, stats) = run(0);
    assert_eq!(run(0).1, stats);
    for fallback in [1, 3, 8] {
        assert_eq!(run(fallback).0, base, "fallback {fallback}");
    }
    let (mut single, mut again) = (TraceStats::default(), TraceStats::default());
    for r in &rays {
        let _ = accel.intersect(r, &mut single);
        let _ = accel.intersect(r, &mut again);
    }
    assert_eq!(single, again, "single-ray traversal counts deterministically");
    assert!(single.node_tests > 0 && single.triangle_tests > 0);
    assert_eq!(run(8).1, single, "all-fallback packets count as single rays");
}
