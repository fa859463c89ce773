//! Rays that can only add emission (a path's last segment under MIS or after a specular bounce,
//! hemisphere probes, extra camera rays on emitter outlines) look for the emitters first and
//! then test occlusion up to them (`integrator::EmitterAccel`). The images must be the bytes
//! the whole scene's closest hits give.

mod common;

use common::{SceneBuilder, HEMISPHERE, LIGHT, MIS};
use pathtracer::accel::{Accel, AccelKind, TraceStats};
use pathtracer::integrator::EmitterAccel;
use pathtracer::math::{Ray, Vec3};
use pathtracer::render::{render, RenderConfig, RenderOutput};
use pathtracer::scene::{Material, Scene};

/// `config` rendered with the emitters first and without.
fn render_both(scene: &Scene, accel: &Accel, config: RenderConfig) -> (RenderOutput, RenderOutput) {
    let with = |first| RenderConfig { emitters_first: first, ..config.clone() };
    (render(scene, accel, &with(true)).unwrap(), render(scene, accel, &with(false)).unwrap())
}

/// The pixels' bits, for byte-for-byte comparison.
fn bits(pixels: &[Vec3]) -> Vec<u32> {
    pixels.iter().flat_map(|x| x.to_array().map(f32::to_bits)).collect()
}

/// Every course scene and the project's Cornell box, under each estimator, give the same bytes
/// and the same ray counts with and without the emitters first; and the emitters-first renders
/// did less traversal work where the scene has emitters (so the path was taken).
#[test]
fn emission_only_rays_give_the_same_image_with_the_emitters_first() {
    let scenes = common::course_scenes_and_cornell();
    let mut cheaper = 0;
    for path in &scenes {
        let scene = pathtracer::scene::collada::load(path).unwrap();
        let accel = Accel::build(&scene, AccelKind::Bvh);
        let has_emitters = scene.materials.iter().any(|m| m.emission() != Vec3::ZERO);
        let runs = [(MIS, 1, 1), (MIS, 5, 2), (HEMISPHERE, 2, 1), (LIGHT, 5, 1), (LIGHT, 1, 1)];
        for (integrator, m, l) in runs {
            let config = common::small_render(integrator, m, l, 7);
            let (a, b) = render_both(&scene, &accel, config);
            let name = format!("{} {} -m {m}", path.display(), integrator.name());
            assert!(bits(&a.pixels) == bits(&b.pixels), "{name}: the image changed");
            let (mut sa, mut sb) = (a.stats, b.stats);
            let work = |t: &TraceStats| t.node_tests + t.triangle_tests + t.sphere_tests;
            if has_emitters && work(&sa.trace) < work(&sb.trace) {
                cheaper += 1;
            }
            (sa.trace, sb.trace) = (TraceStats::default(), TraceStats::default());
            assert_eq!(sa, sb, "{name}: the ray counts changed");
        }
    }
    // MIS at -m 1 and -m 5 and hemisphere sampling on the Cornell box alone.
    assert!(cheaper >= 3, "the emitters-first path was cheaper in only {cheaper} renders");
}

/// The emitters' own structure finds an emitter at the bits of the whole scene's hit, under
/// the scene's id; a scene without emitters has an empty one, and one made mostly of emitters
/// has none (its rays keep the whole scene's walk).
#[test]
fn the_emitters_structure_answers_with_scene_ids_and_only_where_emitters_are_few() {
    let mut b = SceneBuilder::new();
    let grey = b.material(Material::Diffuse { albedo: Vec3::splat(0.5) });
    let light = b.material(Material::Emission { radiance: Vec3::ONE });
    for k in 0..4 {
        b.horizontal_quad(k as f32, (-1.0, 1.0), (-1.0, 1.0), true, grey);
    }
    b.horizontal_quad(4.5, (-0.5, 0.5), (-0.5, 0.5), false, light);
    let scene = b.build();
    let emitters = EmitterAccel::for_scene(&scene).expect("2 emitters of 10 triangles");
    let whole = Accel::new(&scene);
    let mut stats = TraceStats::default();
    let mut found = 0;
    for i in 0..64 {
        let (x, z) = ((i % 8) as f32 / 8.0 - 0.45, (i / 8) as f32 / 8.0 - 0.45);
        let ray =
            Ray::new(Vec3::new(x * 0.9, 3.5, z * 0.9), Vec3::new(0.1, 1.0, -0.05).normalize());
        // Nothing lies above the origins but the light: both walks hit it or both miss.
        let (e, w) = match (
            emitters.accel().unwrap().intersect(&ray, &mut stats),
            whole.intersect(&ray, &mut stats),
        ) {
            (Some(e), Some(w)) => (e, w),
            (None, None) => continue,
            other => panic!("ray {i}: emitters' walk and whole scene disagree: {other:?}"),
        };
        let e = emitters.scene_hit(e);
        assert_eq!(
            (e.t.to_bits(), e.u.to_bits(), e.v.to_bits(), e.prim),
            (w.t.to_bits(), w.u.to_bits(), w.v.to_bits(), w.prim)
        );
        assert_eq!(
            scene.materials[scene.triangle_materials[e.prim as usize] as usize],
            Material::Emission { radiance: Vec3::ONE }
        );
        found += 1;
    }
    assert!(found >= 32, "only {found} of 64 rays reached the light");

    let mut dark = SceneBuilder::new();
    let grey = dark.material(Material::Diffuse { albedo: Vec3::splat(0.5) });
    dark.horizontal_quad(0.0, (-1.0, 1.0), (-1.0, 1.0), true, grey);
    let dark = dark.build();
    assert!(EmitterAccel::for_scene(&dark)
        .expect("no emitters: an empty structure")
        .accel()
        .is_none());

    let mut bright = SceneBuilder::new();
    let grey = bright.material(Material::Diffuse { albedo: Vec3::splat(0.5) });
    let light = bright.material(Material::Emission { radiance: Vec3::ONE });
    bright.horizontal_quad(0.0, (-1.0, 1.0), (-1.0, 1.0), true, grey);
    bright.horizontal_quad(1.0, (-1.0, 1.0), (-1.0, 1.0), false, light);
    assert!(EmitterAccel::for_scene(&bright.build()).is_none(), "half the triangles emit");
}

/// An emissive sphere (no emissive triangle): its tree holds the sphere alone, and a render
/// through it gives the same bytes as the whole scene's walk, under MIS and hemisphere sampling.
#[test]
fn an_emissive_sphere_alone_is_found_first_with_the_same_image() {
    use pathtracer::scene::Sphere;
    let mut b = SceneBuilder::new();
    let grey = b.material(Material::Diffuse { albedo: Vec3::splat(0.5) });
    let light = b.material(Material::Emission { radiance: Vec3::splat(4.0) });
    for k in 0..4 {
        b.horizontal_quad(-(k as f32), (-2.0, 2.0), (-2.0, 2.0), true, grey);
    }
    // The light is the second sphere, so that its id in the emitters' tree (0) differs.
    b.scene.spheres.push(Sphere { center: Vec3::new(0.8, 0.4, 0.0), radius: 0.3, material: grey });
    b.scene.spheres.push(Sphere { center: Vec3::new(0.0, 1.5, 0.0), radius: 0.3, material: light });
    let scene = b.build();
    let emitters = EmitterAccel::for_scene(&scene).expect("1 emitter of 10 primitives");
    let ray = Ray::new(Vec3::new(0.0, 0.5, 0.0), Vec3::Y);
    let hit = emitters.accel().unwrap().intersect(&ray, &mut TraceStats::default()).unwrap();
    let whole = Accel::new(&scene).intersect(&ray, &mut TraceStats::default()).unwrap();
    assert_eq!(emitters.scene_hit(hit), whole);
    let accel = Accel::new(&scene);
    for (integrator, m) in [(MIS, 1), (MIS, 3), (HEMISPHERE, 2)] {
        let config = RenderConfig {
            integrator,
            width: 32,
            height: 24,
            spp: 8,
            max_depth: m,
            threads: 2,
            seed: 3,
            ..RenderConfig::default()
        };
        let (a, b) = render_both(&scene, &accel, config);
        assert!(
            a.pixels.iter().any(|p| p.max_element() > 0.0),
            "{} -m {m}: black",
            integrator.name()
        );
        assert!(
            bits(&a.pixels) == bits(&b.pixels),
            "{} -m {m}: the image changed",
            integrator.name()
        );
    }
}
