//! Hostile input cannot take unbounded memory: limits are checked before the work (instanced
//! geometry counted before it is expanded, the scene file read only up to a cap), and an
//! allocation whose size the user chose fails with the one-line error, never an abort.
//!
//! The memory tests run the binary under `ulimit -v` (an address-space limit), so that work
//! done before a limit is checked shows up as an abort instead of a slow success.

use std::path::PathBuf;
use std::process::{Command, Output};

use pathtracer::scene::collada;

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pt-limits-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn cornell() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/cornell.dae")
}

/// Runs pathtracer with at most `mib` MiB of address space.
fn pathtracer_within(mib: u64, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {}; exec \"$0\" \"$@\"", mib * 1024))
        .arg(env!("CARGO_BIN_EXE_pathtracer"))
        .args(args)
        .output()
        .expect("run pathtracer")
}

fn pathtracer(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pathtracer")).args(args).output().expect("run pathtracer")
}

/// Asserts a clean failure: exit 2, exactly one line on stderr containing `want`, no panic
/// and no abort (which leaves no exit code).
fn assert_one_line_error(out: &Output, want: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "status {:?}, stderr: {stderr}", out.status);
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "want one line, got: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    assert!(lines[0].contains(want), "want '{want}' in: {stderr}");
}

/// A scene that instances one `corners`-gon `fanout^levels` times through nested
/// `instance_node`s: tiny text, `(corners - 2) * fanout^levels` triangles once expanded.
fn instancing_scene(corners: usize, fanout: usize, levels: usize) -> String {
    let points: String = (0..corners)
        .map(|i| {
            let a = i as f32 / corners as f32 * std::f32::consts::TAU;
            format!("{} {} 0 ", a.cos(), a.sin())
        })
        .collect();
    let indices: String = (0..corners).map(|i| format!("{i} ")).collect();
    let mut nodes = String::from(r##"<node id="n0"><instance_geometry url="#g"/></node>"##);
    for level in 1..=levels {
        let children = format!(r##"<instance_node url="#n{}"/>"##, level - 1).repeat(fanout);
        nodes += &format!(r#"<node id="n{level}">{children}</node>"#);
    }
    format!(
        r##"<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<library_geometries><geometry id="g"><mesh>
<source id="p"><float_array id="pa" count="{n}">{points}</float_array>
<technique_common><accessor source="#pa" count="{corners}" stride="3"/></technique_common></source>
<vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
<polylist count="1"><input semantic="VERTEX" source="#v" offset="0"/>
<vcount>{corners}</vcount><p>{indices}</p></polylist>
</mesh></geometry></library_geometries>
<library_nodes>{nodes}</library_nodes>
<library_visual_scenes><visual_scene id="s"><node id="root">
<instance_node url="#n{levels}"/></node></visual_scene></library_visual_scenes>
<scene><instance_visual_scene url="#s"/></scene></COLLADA>"##,
        n = 3 * corners
    )
}

#[test]
fn instanced_geometry_is_counted_before_it_is_expanded() {
    // 998 triangles instanced 32^3 times: 32.7 million triangles from 40 kB of text.
    let text = instancing_scene(1000, 32, 3);
    assert!(text.len() < 50_000);
    let e = collada::parse(&text).unwrap_err().to_string();
    assert!(e.contains("32702464 triangles (counting every instance)"), "{e}");
    assert!(e.contains("at most 16777216"), "{e}");

    // The same through the command line with 400 MiB of address space: expanding before
    // counting would need more than twice that and abort.
    let dir = scratch_dir("instancing");
    let scene = dir.join("instanced.dae");
    std::fs::write(&scene, &text).unwrap();
    let out_png = dir.join("out.png");
    let (s, o) = (scene.to_str().unwrap(), out_png.to_str().unwrap());
    for args in [vec!["--info", s], vec!["-r", "16", "12", "-f", o, s]] {
        assert_one_line_error(&pathtracer_within(400, &args), "32702464 triangles");
    }
    assert!(!out_png.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_count_before_expansion_is_exact() {
    // 5-gons (3 triangles) instanced 4^3 times load to exactly the counted triangles.
    let scene = collada::parse(&instancing_scene(5, 4, 3)).unwrap();
    assert_eq!(scene.triangles.len(), 3 * 64);
    // One polygon corner above the limit (256 * 16^4 = 2^24) is refused, counted exactly.
    let e = collada::parse(&instancing_scene(259, 16, 4)).unwrap_err().to_string();
    assert!(e.contains("16842752 triangles"), "{e}");
}

#[test]
fn instanced_spheres_and_lights_are_counted_too() {
    // A node holding 600 lights, instanced 32^3 times: 19.7 million lights.
    let lights = r##"<instance_light url="#l"/>"##.repeat(600);
    let mut nodes = format!(r#"<node id="n0">{lights}</node>"#);
    for level in 1..=3 {
        let children = format!(r##"<instance_node url="#n{}"/>"##, level - 1).repeat(32);
        nodes += &format!(r#"<node id="n{level}">{children}</node>"#);
    }
    let text = format!(
        r##"<COLLADA><library_lights><light id="l"><technique_common><point><color>1 1 1</color>
        </point></technique_common></light></library_lights><library_nodes>{nodes}</library_nodes>
        <library_visual_scenes><visual_scene id="s"><node id="r"><instance_node url="#n3"/>
        </node></visual_scene></library_visual_scenes></COLLADA>"##
    );
    let e = collada::parse(&text).unwrap_err().to_string();
    assert!(e.contains("19660800 spheres and lights"), "{e}");
}

#[test]
fn the_scene_file_is_read_only_up_to_its_size_limit() {
    let scene = cornell();
    let s = scene.to_str().unwrap();
    let size = std::fs::metadata(&scene).unwrap().len().to_string();
    let below = (std::fs::metadata(&scene).unwrap().len() - 1).to_string();
    let out = pathtracer(&["--info", "--max-scene-bytes", &below, s]);
    assert_one_line_error(&out, &format!("scene size limit of {below} bytes"));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cornell.dae"));
    let ok = pathtracer(&["--info", "--max-scene-bytes", &size, s]);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));

    // An endless device stops at the limit (with little memory: it is never read whole).
    let zero = pathtracer_within(200, &["--info", "--max-scene-bytes", "50000000", "/dev/zero"]);
    assert_one_line_error(&zero, "/dev/zero: larger than the scene size limit of 50000000");
    assert_one_line_error(&pathtracer(&["--max-scene-bytes", "0", s]), "--max-scene-bytes");
    // converge takes the render flags, this one too.
    let converge = ["converge", s, "--spp", "1", "--ref-spp", "2", "--max-scene-bytes", &below];
    assert_one_line_error(&pathtracer(&converge), "scene size limit");
    // So do bench and chart accuracy, which load scenes too.
    let bench = ["bench", s, "--reps", "1", "--max-scene-bytes", &below];
    assert_one_line_error(&pathtracer(&bench), "scene size limit");
    let dir = scratch_dir("chart-limit");
    let d = dir.to_str().unwrap();
    let chart =
        ["chart", "accuracy", s, d, "--spp", "1", "--ref-spp", "2", "--max-scene-bytes", &below];
    assert_one_line_error(&pathtracer(&chart), "scene size limit");
    assert_one_line_error(
        &pathtracer(&["bench", s, "--max-scene-bytes", "0"]),
        "--max-scene-bytes",
    );
}

#[test]
fn a_fifo_is_read_only_up_to_the_size_limit() {
    let dir = scratch_dir("fifo");
    let fifo = dir.join("scene.dae");
    let made = Command::new("mkfifo").arg(&fifo).status().expect("mkfifo");
    assert!(made.success());
    // dd writes 4 MB into the FIFO (blocking until pathtracer opens it).
    let mut writer = Command::new("dd")
        .args(["if=/dev/zero", "bs=65536", "count=64"])
        .arg(format!("of={}", fifo.display()))
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("dd");
    let out = pathtracer(&["--info", "--max-scene-bytes", "1000000", fifo.to_str().unwrap()]);
    let _ = writer.kill(); // Our own child: it may still wait for a reader that has gone.
    let _ = writer.wait();
    assert_one_line_error(&out, "larger than the scene size limit of 1000000 bytes");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn an_image_too_large_for_memory_is_a_one_line_error_before_rendering() {
    let dir = scratch_dir("huge-image");
    let out_png = dir.join("huge.png");
    let (s, o) = (cornell(), out_png.to_str().unwrap().to_string());
    // 16384 x 8192 is within the size limits but needs 2 GiB of buffers.
    let args = ["-t", "2", "-r", "16384", "8192", "--shading", "normals", "-f", &o];
    let mut all: Vec<&str> = args.to_vec();
    all.push(s.to_str().unwrap());
    let out = pathtracer_within(1024, &all);
    assert_one_line_error(&out, "out of memory: cannot allocate 1.5 GiB for the 16384x8192 image");
    assert!(!String::from_utf8_lossy(&out.stdout).contains("Rendering..."));
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "left a file");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn skinned_instances_are_counted_too() {
    let controller = r##"<library_controllers><controller id="c"><skin source="#g">
        <bind_shape_matrix>1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1</bind_shape_matrix></skin>
        </controller></library_controllers><library_nodes>"##;
    let text = instancing_scene(1000, 32, 3)
        .replace(r##"<instance_geometry url="#g"/>"##, r##"<instance_controller url="#c"/>"##)
        .replace("<library_nodes>", controller);
    let e = collada::parse(&text).unwrap_err().to_string();
    assert!(e.contains("32702464 triangles (counting every instance)"), "{e}");
}

#[test]
fn a_ray_file_from_an_endless_device_is_a_one_line_error() {
    let scene = cornell();
    let s = scene.to_str().unwrap();
    // Reading stops at the memory it can have (or at the 2 GiB cap), never an abort.
    let args = ["bench", s, "--ray-set", "primary", "--rays-in", "/dev/zero", "--reps", "1"];
    let out = pathtracer_within(200, &args);
    assert_one_line_error(&out, "/dev/zero: cannot read: out of memory after");
}
