//! The loader on the course scenes (skipped without them) and on small inline documents.

mod common;

use pathtracer::math::Vec3;
use pathtracer::scene::{collada, Light, Material, Scene};

fn course(rel: &str) -> Option<Scene> {
    let path = common::course_scene(rel)?;
    Some(collada::load(&path).unwrap_or_else(|e| panic!("{e}")))
}

#[test]
fn every_course_scene_loads_with_unit_finite_normals() {
    let all = common::all_course_scenes();
    if common::scenes_dir().is_some() {
        assert!(all.len() >= 20, "expected the course's scenes, found {}", all.len());
    }
    for path in all {
        let scene = collada::load(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            !scene.triangles.is_empty() || !scene.spheres.is_empty(),
            "{} is empty",
            path.display()
        );
        for n in &scene.normals {
            assert!(
                n.is_finite() && (n.length() - 1.0).abs() < 1e-4,
                "{}: normal {n}",
                path.display()
            );
        }
    }
}

#[test]
fn course_triangle_counts() {
    for (rel, tris, spheres) in [
        ("sky/CBempty.dae", 12, 0),
        ("sky/CBspheres_lambertian.dae", 12, 2),
        ("sky/CBgems.dae", 252, 0),
        ("sky/CBbunny.dae", 28_588, 0),
        ("sky/bunny.dae", 33_696, 0),
        ("keenan/banana.dae", 2_458, 0),
        ("meshedit/teapot.dae", 2_464, 0),
        ("meshedit/cow.dae", 5_856, 0),
        ("meshedit/maxplanck.dae", 50_801, 0),
        ("basic/sphere_mirror.dae", 0, 1),
    ] {
        let Some(scene) = course(rel) else { return };
        assert_eq!((scene.triangles.len(), scene.spheres.len()), (tris, spheres), "{rel}");
    }
}

#[test]
fn cbspheres_materials_and_area_light() {
    let Some(scene) = course("sky/CBspheres.dae") else { return };
    let kinds: Vec<&str> =
        scene.spheres.iter().map(|s| scene.materials[s.material as usize].kind()).collect();
    assert!(kinds.contains(&"mirror") && kinds.contains(&"glass"), "{kinds:?}");
    for s in &scene.spheres {
        assert!((s.radius - 0.3).abs() < 1e-6);
        assert!((s.center.y - 0.3).abs() < 1e-5, "spheres rest on the floor: {}", s.center);
    }
    let Light::Area { position, direction, dim_x, dim_y, radiance } = scene.lights[0] else {
        panic!("first light should be an area light: {:?}", scene.lights[0])
    };
    assert!((position.y - 1.49).abs() < 1e-5 && (direction - Vec3::NEG_Y).length() < 1e-5);
    assert!((dim_x.length() - 0.6).abs() < 1e-5 && (dim_y.length() - 0.8).abs() < 1e-5);
    assert_eq!(radiance, Vec3::splat(10.0));
}

#[test]
fn cbbunny_has_the_emissive_quad_rotated_against_its_area_light() {
    let Some(scene) = course("sky/CBbunny.dae") else { return };
    // SCENE_FORMAT.md: light 0.6 (x) by 0.8 (z); emissive quad 0.8 (x) by 0.6 (z), both at 1.49.
    let emissive: Vec<usize> = (0..scene.triangles.len())
        .filter(|&i| {
            matches!(
                scene.materials[scene.triangle_materials[i] as usize],
                Material::Emission { .. }
            )
        })
        .collect();
    assert_eq!(emissive.len(), 2);
    let corners: Vec<Vec3> = emissive.iter().flat_map(|&i| scene.triangle(i)).collect();
    let (lo, hi) = corners
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| (a.min(p), b.max(p)));
    assert!((hi.x - lo.x - 0.8).abs() < 1e-4 && (hi.z - lo.z - 0.6).abs() < 1e-4, "{lo} {hi}");
    assert!((lo.y - 1.49).abs() < 1e-4 && (hi.y - 1.49).abs() < 1e-4);
    // Its front (winding normal) faces down into the room.
    let [a, b, c] = scene.triangle(emissive[0]);
    assert!((b - a).cross(c - a).y < 0.0);
    let Light::Area { dim_x, dim_y, .. } = scene.lights[0] else { panic!() };
    assert!((dim_x.x.abs() - 0.6).abs() < 1e-5 && (dim_y.z.abs() - 0.8).abs() < 1e-5);
}

#[test]
fn z_up_puts_the_cornell_floor_at_the_bottom() {
    let Some(scene) = course("sky/CBempty.dae") else { return };
    let b = scene.bounds();
    assert!(b.min.y.abs() < 1e-5 && (b.max.y - 1.5).abs() < 1e-5, "{b:?}");
    // The camera looks at the open side: its view direction points from the box towards +z.
    assert!(scene.camera.view_dir.z > 0.9, "{}", scene.camera.view_dir);
}

#[test]
fn microfacet_and_ambient_materials_of_the_bunny() {
    let Some(scene) = course("sky/bunny_microfacet_cu.dae") else { return };
    assert!(scene.materials.iter().any(|m| matches!(m, Material::Microfacet { .. })));
    assert!(matches!(scene.lights[0], Light::Ambient { .. }));
}

const HEADER: &str =
    r#"<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">"#;

/// A document with one geometry `G` whose primitive XML is given, instanced by `nodes`.
fn doc(up: &str, geometry: &str, nodes: &str) -> String {
    format!(
        r##"{HEADER}<asset><up_axis>{up}</up_axis></asset>
        <library_effects><effect id="red-fx"><profile_COMMON><technique sid="common"><phong>
          <diffuse><color>0.8 0.1 0.1 1</color></diffuse></phong></technique></profile_COMMON></effect></library_effects>
        <library_materials><material id="red"><instance_effect url="#red-fx"/></material></library_materials>
        <library_geometries><geometry id="G"><mesh>
          <source id="P"><float_array id="PA" count="15">0 0 0 1 0 0 1 1 0 0 1 0 0.5 1.5 0</float_array>
            <technique_common><accessor source="#PA" count="5" stride="3"/></technique_common></source>
          <source id="N"><float_array id="NA" count="3">0 0 1</float_array></source>
          <vertices id="V"><input semantic="POSITION" source="#P"/></vertices>
          {geometry}
        </mesh></geometry></library_geometries>
        <library_visual_scenes><visual_scene id="S">{nodes}</visual_scene></library_visual_scenes>
        <scene><instance_visual_scene url="#S"/></scene></COLLADA>"##
    )
}

fn instance(matrix: &str) -> String {
    format!(
        r##"<node id="n"><matrix>{matrix}</matrix><instance_geometry url="#G"><bind_material><technique_common>
        <instance_material symbol="mat" target="#red"/></technique_common></bind_material></instance_geometry></node>"##
    )
}

const IDENTITY: &str = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1";

#[test]
fn fan_triangulation_offsets_and_triangles() {
    // A quad and a pentagon with NORMAL at offset 0 and VERTEX at offset 1.
    let poly = r##"<polylist material="mat" count="2"><input semantic="NORMAL" source="#N" offset="0"/>
        <input semantic="VERTEX" source="#V" offset="1"/><vcount>4 5</vcount>
        <p>0 0 0 1 0 2 0 3  0 0 0 1 0 2 0 4 0 3</p></polylist>"##;
    let s = collada::parse(&doc("Y_UP", poly, &instance(IDENTITY))).unwrap();
    assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 4], [0, 4, 3]]);
    assert_eq!(s.materials, vec![Material::Diffuse { albedo: Vec3::new(0.8, 0.1, 0.1) }]);
    let tris = r##"<triangles material="mat" count="2"><input semantic="VERTEX" source="#V" offset="0"/>
        <p>0 1 2 0 2 3</p></triangles>"##;
    let s = collada::parse(&doc("Y_UP", tris, &instance(IDENTITY))).unwrap();
    assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3]]);
}

#[test]
fn instancing_twice_makes_two_copies_with_nested_transforms() {
    let tris = r##"<triangles material="mat" count="1"><input semantic="VERTEX" source="#V" offset="0"/><p>0 1 2</p></triangles>"##;
    let nested = format!(
        r##"<node id="outer"><translate>10 0 0</translate>{}<node id="inner"><scale>2 2 2</scale>
        <instance_geometry url="#G"/></node></node>"##,
        instance(IDENTITY)
    );
    let s = collada::parse(&doc("Y_UP", tris, &nested)).unwrap();
    assert_eq!(s.triangles.len(), 2);
    // The first copy: translated by the outer node; the second: scaled then translated.
    assert_eq!(s.triangle(0)[1], Vec3::new(11.0, 0.0, 0.0));
    assert_eq!(s.triangle(1)[1], Vec3::new(12.0, 0.0, 0.0));
    // The unbound copy gets the default grey.
    assert!(s.materials.contains(&Material::Diffuse { albedo: Vec3::splat(0.5) }));
}

#[test]
fn up_axes_rotate_the_world() {
    let tris = r##"<triangles count="1"><input semantic="VERTEX" source="#V" offset="0"/><p>0 1 2</p></triangles>"##;
    let z = collada::parse(&doc("Z_UP", tris, &instance(IDENTITY))).unwrap();
    assert_eq!(z.triangle(0)[2], Vec3::new(-1.0, 0.0, 1.0)); // (1,1,0) -> (-1, 0, 1)
    let x = collada::parse(&doc("X_UP", tris, &instance(IDENTITY))).unwrap();
    assert_eq!(x.triangle(0)[2], Vec3::new(1.0, 1.0, 0.0)); // (1,1,0) -> (1, 1, -0)
}

/// Every malformed input is an error naming the problem, never a panic.
#[test]
fn malformed_documents_are_one_line_errors() {
    let tris = |p: &str| {
        format!(
            r##"<triangles material="mat" count="1"><input semantic="VERTEX" source="#V" offset="0"/><p>{p}</p></triangles>"##
        )
    };
    let cases: Vec<(String, &str)> = vec![
        ("not xml <<".into(), "not valid XML"),
        ("<html/>".into(), "not a COLLADA file"),
        (format!("{HEADER}</COLLADA>"), "no <visual_scene>"),
        (doc("Y_UP", &tris("0 1 9"), &instance(IDENTITY)), "index 9 out of range"),
        (doc("Y_UP", &tris("0 1"), &instance(IDENTITY)), "not a multiple"),
        (doc("Y_UP", &tris("0 -1 2"), &instance(IDENTITY)), "not a non-negative integer"),
        (
            doc("Y_UP", &tris("0 1 2"), &instance("1 0 0 nan 0 1 0 0 0 0 1 0 0 0 0 1")),
            "not a finite number",
        ),
        (
            doc("Y_UP", &tris("0 1 2"), &instance("1 0 0 abc 0 1 0 0 0 0 1 0 0 0 0 1")),
            "not a number",
        ),
        (doc("Y_UP", &tris("0 1 2"), &instance("1 0 0 0 0 1 0 0 0 0 1 0")), "nothing"),
        (doc("Y_UP", &tris("0 1 2"), &instance("1 0 0")), "expected 16"),
        (
            doc("Y_UP", &tris("0 1 2"), &instance(IDENTITY).replace("#G", "#missing")),
            "'#missing', which does not exist",
        ),
        (
            doc("Y_UP", &tris("0 1 2"), &instance(IDENTITY).replace("#red", "#nored")),
            "'#nored', which does not exist",
        ),
        (
            doc("Y_UP", &tris("0 1 2").replace("#V", "#nowhere"), &instance(IDENTITY)),
            "'#nowhere', which does not exist",
        ),
        (
            doc("Y_UP", &tris("0 1 2"), &instance(IDENTITY))
                .replace("0.5 1.5 0</float_array>", "0.5 1.5 inf</float_array>"),
            "not a finite number",
        ),
        (
            doc("Y_UP", &tris("0 1 2"), &instance(IDENTITY)).replace("count=\"5\"", "count=\"9\""),
            "does not fit",
        ),
        (doc("W_UP", &tris("0 1 2"), &instance(IDENTITY)), "unknown up_axis"),
        (
            doc(
                "Y_UP",
                r##"<polylist count="1"><input semantic="VERTEX" source="#V" offset="0"/><vcount>4</vcount><p>0 1 2</p></polylist>"##,
                &instance(IDENTITY),
            ),
            "needs 4 indices",
        ),
    ];
    for (text, want) in cases {
        match collada::parse(&text) {
            Ok(_) if want == "nothing" => {} // a 12-number matrix is padded with a warning
            Ok(_) => panic!("accepted a document that should fail with '{want}'"),
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains(want), "want '{want}', got '{msg}'");
                assert!(!msg.contains('\n'));
            }
        }
    }
}

#[test]
fn a_missing_file_names_the_file() {
    let e = collada::load(std::path::Path::new("/no/such/scene.dae")).unwrap_err().to_string();
    assert!(e.contains("/no/such/scene.dae") && e.contains("cannot read"), "{e}");
}

/// A scene with more triangles than the acceleration structure can address is refused with
/// a one-line error before the build (the limit is the acceleration structure's, not the
/// scene's: `Accel::check_limits`).
#[test]
fn too_many_triangles_is_a_clear_error() {
    let mut scene = pathtracer::scene::Scene::default();
    scene.positions = vec![pathtracer::math::Vec3::ZERO; 3];
    scene.normals = scene.positions.clone();
    let n = pathtracer::accel::MAX_TRIANGLES + 1;
    scene.triangles = vec![[0, 1, 2]; n];
    scene.triangle_materials = vec![0; n];
    let err = pathtracer::accel::Accel::check_limits(&scene).unwrap_err().to_string();
    assert!(err.contains("at most 16777216"), "{err}");
    assert!(!err.contains('\n'));
}
