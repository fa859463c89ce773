//! COLLADA from other tools: skinned meshes (`instance_controller`, as Blender exports
//! characters) load in their bind pose with one warning about what is ignored, and a scene
//! with nothing to render says so.

use std::path::PathBuf;
use std::process::Command;

use pathtracer::math::Vec3;
use pathtracer::scene::collada;

fn fixture() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/skinned_cube.dae")
}

#[test]
fn a_skinned_mesh_loads_in_its_bind_pose() {
    let scene = collada::load(&fixture()).unwrap();
    assert_eq!(scene.triangles.len(), 12);
    // The bind_shape_matrix moves the cube +2 in x; Z_UP then maps x to -x.
    let b = scene.bounds();
    assert!((b.min - Vec3::new(-3.0, -1.0, -1.0)).length() < 1e-6, "{b:?}");
    assert!((b.max - Vec3::new(-1.0, 1.0, 1.0)).length() < 1e-6, "{b:?}");
    assert_eq!(scene.materials[scene.triangle_materials[0] as usize].kind(), "diffuse");
}

#[test]
fn what_is_ignored_is_said_once() {
    let scene = collada::load(&fixture()).unwrap();
    let ignored: Vec<&String> = scene.warnings.iter().filter(|w| w.contains("ignored")).collect();
    assert_eq!(ignored.len(), 1, "{:?}", scene.warnings);
    for what in ["skinning (1 skinned mesh drawn in its bind pose)", "animation", "textures"] {
        assert!(ignored[0].contains(what), "no '{what}' in {}", ignored[0]);
    }
    assert!(!scene.warnings.iter().any(|w| w.contains("nothing to render")));
}

/// The fixture's text with every `from` replaced by `to`.
fn variant(from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(fixture()).unwrap();
    assert!(text.contains(from));
    text.replace(from, to)
}

/// The fixture with the controller dropped (as the loader did before it read controllers).
fn without_controller() -> String {
    variant("instance_controller", "instance_nothing")
}

#[test]
fn a_scene_with_nothing_to_render_says_so() {
    let scene = collada::parse(&without_controller()).unwrap();
    assert!(scene.triangles.is_empty());
    let empty: Vec<&String> =
        scene.warnings.iter().filter(|w| w.contains("nothing to render")).collect();
    assert_eq!(empty.len(), 1, "{:?}", scene.warnings);
    assert!(empty[0].contains("0 triangles and 0 spheres"), "{}", empty[0]);
}

#[test]
fn controller_errors_name_the_controller() {
    let no_skin = variant("<skin ", "<spline ").replace("</skin>", "</spline>");
    for (text, want) in [
        (variant(r##"source="#Cube-mesh">"##, r##"source="#Gone">"##), "'#Gone'"),
        (no_skin, "controller 'Armature_Cube-skin' has no <skin> or <morph>"),
        (variant("<bind_shape_matrix>1 0 0 2 ", "<bind_shape_matrix>"), "expected 16"),
    ] {
        let e = collada::parse(&text).unwrap_err().to_string();
        assert!(e.contains(want), "want '{want}' in: {e}");
        assert!(e.contains("node 'Cube'"), "{e}");
    }
}

#[test]
fn the_command_line_renders_it_and_warns() {
    let dir = std::env::temp_dir().join(format!("pt-skinned-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let image = dir.join("cube.png");
    let out = Command::new(env!("CARGO_BIN_EXE_pathtracer"))
        .args(["-r", "32", "24", "-q", "--shading", "normals", "-f", image.to_str().unwrap()])
        .arg(fixture())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr.matches("ignored: skinning").count(), 1, "{stderr}");
    assert!(stderr.lines().all(|l| l.starts_with("warning: ")), "{stderr}");
    let img = image::open(&image).unwrap().into_rgb8();
    let lit = img.pixels().filter(|p| p.0 != [0, 0, 0]).count();
    assert!(lit > 32 * 24 / 10, "only {lit} pixels show the cube");

    let empty = dir.join("empty.dae");
    std::fs::write(&empty, without_controller()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_pathtracer")).arg("--info").arg(&empty).output();
    let stdout = String::from_utf8_lossy(&out.as_ref().unwrap().stdout).into_owned();
    assert!(stdout.contains("warning:   nothing to render"), "{stdout}");
    let black = dir.join("black.png");
    let out = Command::new(env!("CARGO_BIN_EXE_pathtracer"))
        .args(["-r", "16", "12", "-q", "-f", black.to_str().unwrap()])
        .arg(&empty)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr.matches("warning: ").count(), stderr.lines().count(), "{stderr}");
    assert_eq!(stderr.matches("nothing to render").count(), 1, "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}
