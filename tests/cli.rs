//! The command line end to end: bad input gives one line on stderr, exit code 2, no panic, and
//! no output file; good input writes the image and prints the course's statistics.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

use common::cli::{
    assert_one_line_error, closed_pipe, cornell, dev_full, pathtracer, pathtracer_with_stdout,
    scratch_dir, write,
};

#[test]
fn bad_scene_files_fail_cleanly_without_output() {
    let dir = scratch_dir("bad");
    let out_png = dir.join("out.png");
    let cases: Vec<(PathBuf, &str)> = vec![
        (dir.join("missing.dae"), "missing.dae"),
        (write(&dir, "notxml.dae", "this is not xml <"), "notxml.dae"),
        (write(&dir, "notcollada.dae", "<html><body/></html>"), "COLLADA"),
        (
            write(
                &dir,
                "dangling.dae",
                r##"<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
                <library_visual_scenes><visual_scene id="S"><node id="n">
                <instance_geometry url="#nothing"/></node></visual_scene></library_visual_scenes>
                <scene><instance_visual_scene url="#S"/></scene></COLLADA>"##,
            ),
            "nothing",
        ),
    ];
    for (scene, want) in cases {
        let out = pathtracer(&["-f", out_png.to_str().unwrap(), scene.to_str().unwrap()]);
        assert_one_line_error(&out, want);
        assert!(!out_png.exists(), "{} left an output file", scene.display());
    }
}

#[test]
fn bad_flags_fail_cleanly() {
    let scene = cornell();
    let s = scene.to_str().unwrap();
    for (args, want) in [
        (vec!["-r", "0", "600", s], "out of range"),
        (vec!["-r", "-3", "600", s], "out of range"),
        (vec!["-s", "many", s], "not a valid number"),
        (vec!["--frobnicate", s], "unknown option"),
        (vec!["--sampler", "halton", s], "unknown sampler 'halton'"),
        (vec![s, "--sampler"], "--sampler needs a value"),
        (vec!["--edge-samples", "1000", s], "--edge-samples: 1000 is out of range"),
        (vec!["-f", "out.jpg", s], ".png or .exr"),
        (vec!["-f", "/no/such/dir/x.png", s], "does not exist"),
        (vec![], "no scene file"),
    ] {
        assert_one_line_error(&pathtracer(&args), want);
    }
}

#[test]
fn renders_the_cornell_box_and_prints_statistics() {
    let dir = scratch_dir("ok");
    let out_png = dir.join("cornell.png");
    let out = pathtracer(&[
        "-t",
        "2",
        "-r",
        "64",
        "48",
        "--quiet",
        "-f",
        out_png.to_str().unwrap(),
        cornell().to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    for want in [
        "Building BVH from",
        "Building the emitters' BVH from 2 primitives",
        "rays",
        "million rays per second",
        "intersection tests per ray",
    ] {
        assert!(stdout.contains(want), "missing '{want}' in:\n{stdout}");
    }
    let img = image::open(&out_png).unwrap();
    assert_eq!((img.width(), img.height()), (64, 48));
}

/// `--no-bvh` is the write-up's brute-force comparison: every ray tests every primitive, also the
/// rays that can only add emission (which otherwise look for the emitters first).
#[test]
fn no_bvh_tests_every_primitive_for_every_ray() {
    let dir = scratch_dir("no_bvh");
    let out_png = dir.join("cornell.png");
    for flags in [&["--shading", "mis", "-m", "1"][..], &["-H", "-m", "2"], &["-m", "1"]] {
        let mut args = vec!["-t", "2", "-r", "64", "48", "-s", "2", "--quiet", "--no-bvh"];
        args.extend(flags);
        let (png, scene) = (out_png.to_str().unwrap(), cornell());
        args.extend(["-f", png, scene.to_str().unwrap()]);
        let out = pathtracer(&args);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{flags:?}: {stdout}");
        let number_before = |text: &str, end: &str| -> f64 {
            let line = stdout.lines().find(|l| l.contains(end)).expect(end);
            let head = &line[..line.find(end).unwrap()];
            head.rsplit([' ', '('])
                .next()
                .unwrap()
                .trim()
                .parse()
                .unwrap_or_else(|_| panic!("{text}: {line}"))
        };
        let prims = number_before("primitives", " primitives tested per ray");
        let tested = number_before("tests", " primitive tests)");
        assert!(prims >= 14.0, "{flags:?}: {stdout}");
        assert!(!stdout.contains("emitters' BVH"), "{flags:?}: {stdout}");
        assert_eq!(tested, prims, "{flags:?}: {stdout}");
    }
}

#[test]
fn info_reports_the_course_scene() {
    let Some(scene) = common::course_scene("sky/CBspheres_lambertian.dae") else {
        return;
    };
    let out = pathtracer(&["--info", scene.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("12"), "{stdout}");
}

#[test]
fn gen_writes_loadable_scenes_and_rejects_bad_requests() {
    let dir = scratch_dir("gen");
    let out = dir.join("tori.dae");
    let ok = pathtracer(&["gen", "tori", "10000", "--seed", "2", "-o", out.to_str().unwrap()]);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let info = pathtracer(&["--info", out.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&info.stdout);
    let want = format!("triangles: {}", pathtracer::procedural::tori_triangle_count(10_000));
    assert!(text.contains(&want), "{text}");

    let o = dir.join("x.dae");
    let o = o.to_str().unwrap();
    for (args, want) in [
        (vec!["gen", "tori", "5", "-o", o], "out of range"),
        (vec!["gen", "tori", "-o", o], "how many triangles"),
        (vec!["gen", "teapot", "-o", o], "unknown scene"),
        (vec!["gen", "cornell"], "no output file"),
        (vec!["gen", "cornell", "-o", "/no/such/dir/c.dae"], "cannot write"),
    ] {
        assert_one_line_error(&pathtracer(&args), want);
    }
    assert!(!dir.join("x.dae").exists());
}

#[test]
fn exr_output_and_adaptive_rate_image() {
    let dir = scratch_dir("exr");
    let exr = dir.join("box.exr");
    // The full course frame, so that the emitter is in view.
    let args = ["-t", "2", "-s", "4", "-a", "2", "0.5", "--quiet"];
    let mut all: Vec<&str> = args.to_vec();
    let cornell = cornell();
    all.extend(["-f", exr.to_str().unwrap(), cornell.to_str().unwrap()]);
    let out = pathtracer(&all);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let img = image::open(&exr).unwrap().into_rgb32f();
    assert_eq!(img.dimensions(), (800, 600));
    // Linear radiance: the emitter seen directly is far above the PNG range.
    let max = img.pixels().flat_map(|p| p.0).fold(0.0f32, f32::max);
    assert!(max > 2.0, "max radiance {max}");
    let rate = image::open(dir.join("box_rate.png")).unwrap();
    assert_eq!((rate.width(), rate.height()), (800, 600));
}

#[test]
fn compare_and_converge_measure_errors_and_fail_cleanly() {
    let dir = scratch_dir("compare");
    let scene = cornell();
    let scene = scene.to_str().unwrap();
    let path = |n: &str| dir.join(n).to_str().unwrap().to_string();
    let (a, b, small) = (path("a.exr"), path("b.exr"), path("small.exr"));
    for (spp, seed, res, out) in
        [("1", "1", "16 12", &a), ("4", "2", "16 12", &b), ("1", "1", "8 6", &small)]
    {
        let mut args = vec!["-s", spp, "--seed", seed, "-r"];
        args.extend(res.split(' '));
        args.extend(["-f", out, scene]);
        assert!(pathtracer(&args).status.success(), "render {out}");
    }
    let stdout = |o: &Output| String::from_utf8_lossy(&o.stdout).into_owned();

    let same = pathtracer(&["compare", &a, &a]);
    assert!(same.status.success());
    let row = stdout(&same).lines().find(|l| l.contains(" all ")).unwrap().to_string();
    assert!(row.contains("0.000000e0"), "identical images: {row}");
    let diff = pathtracer(&["compare", &a, &b]);
    assert!(diff.status.success());
    assert!(!stdout(&diff).lines().any(|l| l.starts_with("image") && l.contains(" 0.000000e0 ")));

    // A mask selecting the left half.
    let mut mask = image::GrayImage::new(16, 12);
    for (x, _, p) in mask.enumerate_pixels_mut() {
        p.0[0] = if x < 8 { 255 } else { 0 };
    }
    let mask_path = path("mask.png");
    mask.save(&mask_path).unwrap();
    let masked = pathtracer(&["compare", &a, &b, "--mask", &mask_path]);
    assert!(masked.status.success());
    assert!(stdout(&masked).lines().any(|l| l.starts_with("mask") && l.contains(" 96 ")));
    image::GrayImage::new(16, 12).save(path("black.png")).unwrap();
    image::GrayImage::from_pixel(8, 6, image::Luma([255])).save(path("small_mask.png")).unwrap();
    std::fs::write(path("junk.exr"), "not an image").unwrap();

    for (args, want) in [
        (vec!["compare", &a, &small], "sizes differ"),
        (vec!["compare", &a], "expected two images"),
        (vec!["compare", &a, &path("missing.exr")], "missing.exr"),
        (vec!["compare", &a, &path("junk.exr")], "junk.exr"),
        (vec!["compare", &a, &b, "--mask", &path("black.png")], "no nonzero pixel"),
        (vec!["compare", &a, &b, "--mask", &path("small_mask.png")], "mask"),
        (vec!["converge", scene, "--spp", "1", "--reference", &small, "-r", "16", "12"], "8x6"),
        (vec!["converge", scene, "--reference", &a], "--spp LIST is required"),
        (vec!["converge", scene, "--spp", "1", "--ref-spp", "2", "-f", "x.png"], "-f is not used"),
        (vec!["converge", "--spp", "1", "--ref-spp", "2"], "no scene file"),
    ] {
        assert_one_line_error(&pathtracer(&args), want);
    }

    let (csv, reference) = (path("c.csv"), path("ref.exr"));
    let conv = pathtracer(&[
        "converge",
        scene,
        "--spp",
        "1,2,4",
        "--ref-spp",
        "16",
        "-r",
        "16",
        "12",
        "--csv",
        &csv,
        "--write-reference",
        &reference,
    ]);
    assert!(conv.status.success(), "{}", String::from_utf8_lossy(&conv.stderr));
    assert!(stdout(&conv).contains("fitted slope"));
    assert_eq!(std::fs::read_to_string(&csv).unwrap().lines().count(), 4);
    assert!(pathtracer(&["compare", &a, &reference]).status.success());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn chart_rejects_bad_input_and_draws_scaling() {
    let dir = scratch_dir("chart");
    let svg = dir.join("s.svg");
    let s = svg.to_str().unwrap();
    let empty = write(&dir, "empty.jsonl", "");
    let junk = write(&dir, "junk.jsonl", "{\"triangles\":12}\n");
    for (args, want) in [
        (vec!["chart", "pie"], "unknown chart"),
        (vec!["chart", "scaling", "/no/such.jsonl", s], "/no/such.jsonl"),
        (vec!["chart", "scaling", empty.to_str().unwrap(), s], "no bench lines"),
        (vec!["chart", "scaling", junk.to_str().unwrap(), s], "no field"),
    ] {
        assert_one_line_error(&pathtracer(&args), want);
    }
    assert!(!svg.exists());
    let line = r#"{"scene":"t.dae","triangles":1000,"ray_set":"primary","rays":10,"threads":1,"traversal":"single","build_ms":1.5,"mrays_per_s":3.0,"node_tests_per_ray":1,"triangle_tests_per_ray":1,"hits":1,"t_sum":1.0,"bytes_per_triangle":70.0}"#;
    let ok = write(&dir, "ok.jsonl", &format!("{line}\n{}\n", line.replace("1000", "10000")));
    let out = pathtracer(&["chart", "scaling", ok.to_str().unwrap(), s]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
}

#[test]
fn chart_accuracy_checks_peer_files_first_and_draws_peer_runs() {
    let dir = scratch_dir("peer");
    let out = dir.join("charts");
    std::fs::create_dir(&out).unwrap();
    let scene = cornell();
    let line = |renderer: &str, m: u32, spp: u32, seconds: f64, rel: f64| {
        format!(
            r#"{{"scene": "cornell.dae", "size": "400x300", "m": {m}, "spp": {spp}, "renderer": "{renderer}", "mitsuba_mapping": "quad", "seconds": {seconds}, "rel_noise": {rel}, "noise_sqrt_seconds": 0.2, "threads": 2}}"#
        )
    };
    let good = line("mitsuba3 path (quad)", 1, 16, 2.4, 0.12);
    let path = |p: PathBuf| p.to_str().unwrap().to_string();
    let cases = [
        (dir.join("no-such.jsonl"), "no-such.jsonl".to_string()),
        (
            write(&dir, "cut.jsonl", &format!("{good}\n{}\n", &good[..60])),
            "cut.jsonl:2: column".to_string(),
        ),
        (
            write(
                &dir,
                "field.jsonl",
                &format!("{good}\n\n{}\n", good.replace("\"rel_noise\"", "\"noise\"")),
            ),
            "field.jsonl:3: missing field 'rel_noise'".to_string(),
        ),
        (
            write(&dir, "null.jsonl", &good.replace("2.4", "null")),
            "null.jsonl:1: column".to_string(),
        ),
        (
            write(&dir, "other.jsonl", &good.replace("cornell.dae", "CBbunny.dae")),
            "other.jsonl: no record for scene 'cornell.dae'".to_string(),
        ),
        (write(&dir, "empty.jsonl", ""), "empty.jsonl: no record".to_string()),
    ];
    let tiny = ["-r", "16", "12", "--spp", "1,2", "--ref-spp", "4", "--depths", "1"];
    for (peer, want) in &cases {
        let (s, o, p) = (path(scene.clone()), path(out.clone()), path(peer.clone()));
        let mut args = vec!["chart", "accuracy", &s, &o];
        args.extend(tiny);
        args.extend(["--peer", &p]);
        let run = pathtracer(&args);
        assert_one_line_error(&run, want);
        assert!(!String::from_utf8_lossy(&run.stdout).contains("-m 1"), "rendered before failing");
        assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0, "{want}: wrote output");
    }
    let (s, o) = (path(scene.clone()), path(out.clone()));
    assert_one_line_error(&pathtracer(&["chart", "accuracy", &s, &o, "--peer"]), "--peer");

    let peer = write(
        &dir,
        "peer.jsonl",
        &[
            good.clone(),
            line("mitsuba3 path (quad)", 1, 4, 0.61, 0.25),
            line("ours mis", 1, 16, 1.3, 0.09),
            line("only at depth five", 5, 16, 9.0, 0.5),
            good.replace("cornell.dae", "CBbunny.dae").replace("(quad)", "(other scene)"),
        ]
        .join("\n"),
    );
    let p = path(peer);
    let mut args = vec!["chart", "accuracy", &s, &o];
    args.extend(tiny);
    args.extend(["--peer", &p]);
    let run = pathtracer(&args);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let svg = std::fs::read_to_string(out.join("accuracy_cornell_m1.svg")).unwrap();
    for want in ["mitsuba3 path (quad), peer run 400x300", "ours mis, peer run 400x300", "MIS"] {
        assert!(svg.contains(want), "no '{want}' in the SVG");
    }
    for absent in ["only at depth five", "other scene"] {
        assert!(!svg.contains(absent), "'{absent}' drawn");
    }
    let csv = std::fs::read_to_string(out.join("accuracy_cornell_m1.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "integrator,spp,mean_spp,seconds,rays,rmse,rel_rmse,bias,source");
    assert_eq!(rows.len(), 1 + 4 * 2 + 3, "{csv}");
    assert!(rows[1..9].iter().all(|r| r.ends_with(",ours") && r.split(',').count() == 9));
    let peer_rows: Vec<&str> =
        rows[9..].iter().map(|r| r.split(",peer ").next().unwrap()).collect();
    assert_eq!(
        peer_rows,
        [
            "mitsuba3 path (quad),4,4,0.61,,,2.5e-1,",
            "mitsuba3 path (quad),16,16,2.4,,,1.2e-1,",
            "ours mis,16,16,1.3,,,9e-2,"
        ]
    );
    assert!(rows[9].ends_with("peer.jsonl:2"), "{}", rows[9]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Renders 16x12 at 1 spp of the Cornell box: enough to tell whether rendering started.
fn rendered(out: &Output) -> bool {
    String::from_utf8_lossy(&out.stdout).contains("Rendering...")
}

#[test]
fn outputs_that_name_an_input_are_refused_before_rendering() {
    let dir = scratch_dir("clobber");
    let scene_text = std::fs::read_to_string(cornell()).unwrap();
    // A COLLADA file named scene.png: the default output name is the scene's own name.
    let png_scene = write(&dir, "scene.png", &scene_text);
    let dae = write(&dir, "box.dae", &scene_text);
    let link = dir.join("link.png");
    std::os::unix::fs::symlink(&dae, &link).unwrap();
    let cwd_run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_pathtracer"))
            .current_dir(&dir)
            .args(args)
            .output()
            .expect("run pathtracer")
    };
    let p = |q: &Path| q.to_str().unwrap().to_string();
    for (out, want) in [
        (cwd_run(&["-r", "16", "12", "scene.png"]), "scene.png"),
        (pathtracer(&["-r", "16", "12", "-f", &p(&png_scene), &p(&png_scene)]), "same file"),
        (cwd_run(&["-r", "16", "12", "-f", "./scene.png", "scene.png"]), "same file"),
        (pathtracer(&["-r", "16", "12", "-f", &p(&link), &p(&dae)]), "link.png"),
    ] {
        assert_one_line_error(&out, want);
        assert!(!rendered(&out), "rendered before failing");
    }
    assert_eq!(std::fs::read_to_string(&png_scene).unwrap(), scene_text);
    assert_eq!(std::fs::read_to_string(&dae).unwrap(), scene_text);

    // converge: the table and the reference must not replace the scene or the reference.
    let reference = dir.join("ref.exr");
    let ok = pathtracer(&["-r", "16", "12", "-q", "-f", &p(&reference), &p(&dae)]);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let ref_bytes = std::fs::read(&reference).unwrap();
    let (s, r) = (p(&dae), p(&reference));
    for (args, want) in [
        (vec!["converge", &s, "--spp", "1", "--reference", &r, "--csv", &r], "same file"),
        (vec!["converge", &s, "--spp", "1", "--reference", &r, "--csv", &s], "same file"),
        (vec!["converge", &s, "--spp", "1", "--ref-spp", "2", "--csv", &p(&dir)], "regular file"),
    ] {
        assert_one_line_error(&pathtracer(&args), want);
    }
    assert_eq!(std::fs::read(&reference).unwrap(), ref_bytes);
    assert_eq!(std::fs::read_to_string(&dae).unwrap(), scene_text);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn outputs_that_are_not_regular_files_are_refused_before_rendering() {
    let dir = scratch_dir("notfile");
    let sub = dir.join("sub.png");
    std::fs::create_dir(&sub).unwrap();
    let out =
        pathtracer(&["-r", "16", "12", "-f", sub.to_str().unwrap(), cornell().to_str().unwrap()]);
    assert_one_line_error(&out, "not a regular file");
    assert!(!rendered(&out), "rendered before failing");
    assert!(sub.is_dir());
    let out = pathtracer(&["gen", "cornell", "-o", sub.to_str().unwrap()]);
    assert_one_line_error(&out, "not a regular file");
    assert!(sub.is_dir());
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "left a temporary file");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn compare_refuses_non_finite_pixels_and_mixed_formats() {
    let dir = scratch_dir("nan");
    let path = |n: &str| dir.join(n).to_str().unwrap().to_string();
    let mut img = image::Rgb32FImage::from_pixel(4, 3, image::Rgb([0.5, 0.5, 0.5]));
    img.save(path("good.exr")).unwrap();
    img.put_pixel(2, 1, image::Rgb([0.5, f32::NAN, 0.5]));
    img.put_pixel(3, 2, image::Rgb([0.5, f32::INFINITY, 0.5]));
    img.save(path("nan.exr")).unwrap();
    let mut inf = image::Rgb32FImage::from_pixel(4, 3, image::Rgb([0.5, 0.5, 0.5]));
    inf.put_pixel(1, 2, image::Rgb([f32::INFINITY, 0.5, 0.5]));
    inf.save(path("inf.exr")).unwrap();
    image::RgbImage::new(4, 3).save(path("disp.png")).unwrap();
    for (args, want) in [
        (vec!["compare", &path("nan.exr"), &path("good.exr")], "(2, 1)"),
        (vec!["compare", &path("good.exr"), &path("nan.exr")], "nan.exr"),
        (vec!["compare", &path("good.exr"), &path("inf.exr")], "(1, 2)"),
        (vec!["compare", &path("disp.png"), &path("good.exr")], "like with like"),
        (vec!["compare", &path("good.exr"), &path("disp.png")], "like with like"),
    ] {
        assert_one_line_error(&pathtracer(&args), want);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn gen_and_chart_accuracy_errors_say_what_is_wrong() {
    let dir = scratch_dir("msgs");
    let o = dir.join("t.dae");
    let o = o.to_str().unwrap();
    assert_one_line_error(&pathtracer(&["gen", "cornell", "5", "-o", o]), "takes no count");
    assert_one_line_error(&pathtracer(&["gen", "tori", "many", "-o", o]), "gen tori");
    assert!(!dir.join("t.dae").exists());
    let scene = cornell();
    let (s, d) = (scene.to_str().unwrap(), dir.to_str().unwrap());
    for (extra, want) in [
        (vec!["-r", "0", "6"], "-r width: expected a positive number, got '0'"),
        (vec!["-r", "8", "x"], "-r height: expected a positive number, got 'x'"),
        (vec!["-r", "8"], "-r height"),
        (vec!["-t", "0"], "-t: "),
        (vec!["--ref-spp", "-1"], "--ref-spp: "),
        (vec!["--spp", "0"], "--spp: "),
        (vec!["--spp", "1,0,4"], "--spp: "),
        (vec!["--spp", ""], "--spp: "),
        (vec!["--spp"], "--spp"),
        (vec!["--depths", "1,a"], "--depths: "),
    ] {
        let mut args = vec!["chart", "accuracy", s, d, "-r", "16", "12", "--ref-spp", "2"];
        args.extend(extra);
        let out = pathtracer(&args);
        assert_one_line_error(&out, want);
        assert!(String::from_utf8_lossy(&out.stdout).is_empty());
    }
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Runs pathtracer with `stdout` as its standard output (stderr captured).
#[test]
fn completions_print_a_script_for_each_shell() {
    for shell in ["bash", "zsh", "fish"] {
        let out = pathtracer(&["completions", shell]);
        let script = String::from_utf8_lossy(&out.stdout);
        assert_eq!(out.status.code(), Some(0), "{shell}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(out.stderr.is_empty(), "{shell}");
        // A render flag, a subcommand and one of its flags.
        for want in ["max-scene-bytes", "converge", "ref-spp"] {
            assert!(script.contains(want), "{shell}: no '{want}' in the script");
        }
    }
    for (args, want) in [
        (vec!["completions", "tcsh"], "'tcsh'"),
        (vec!["completions"], "completions"),
        (vec!["completions", "bash", "zsh"], "'zsh'"),
    ] {
        assert_one_line_error(&pathtracer(&args), want);
    }
    // Through the same writes as every command: a full stdout is the one-line error, a closed
    // one a quiet exit.
    let full = pathtracer_with_stdout(&["completions", "bash"], dev_full());
    assert_one_line_error(&full, "writing to standard output: No space left on device");
    let closed = pathtracer_with_stdout(&["completions", "zsh"], closed_pipe());
    assert_eq!(closed.status.code(), Some(0));
    assert!(closed.stderr.is_empty());
}

#[test]
fn every_command_has_a_help() {
    let commands = [
        vec![],
        vec!["bench"],
        vec!["compare"],
        vec!["converge"],
        vec!["gen"],
        vec!["chart"],
        vec!["chart", "accuracy"],
        vec!["chart", "scaling"],
        vec!["merge"],
        vec!["part-info"],
        vec!["completions"],
    ];
    for command in commands {
        for help in ["--help", "-h"] {
            let mut args = command.clone();
            args.push(help);
            let out = pathtracer(&args);
            let text = String::from_utf8_lossy(&out.stdout);
            assert_eq!(
                out.status.code(),
                Some(0),
                "{args:?}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            assert!(out.stderr.is_empty(), "{args:?}");
            let usage = format!("Usage: pathtracer {}", command.join(" "));
            assert!(text.contains(usage.trim_end()), "{args:?}: no '{usage}' in:\n{text}");
        }
    }
    // The course flags are in the render command's help, as the course spells them.
    let help = String::from_utf8_lossy(&pathtracer(&["--help"]).stdout).into_owned();
    for flag in
        ["-t <N>", "-s <N>", "-l <N>", "-m <N>", "-H", "-f <FILE>", "-r <W> <H>", "-a <B> <TOL>"]
    {
        assert!(help.contains(flag), "no '{flag}' in --help");
    }
    // The version, then the instruction set that runs (tests/isa.rs checks which).
    let version = String::from_utf8_lossy(&pathtracer(&["--version"]).stdout).into_owned();
    let lines: Vec<&str> = version.lines().collect();
    assert_eq!(lines[0], format!("pathtracer {}", env!("CARGO_PKG_VERSION")), "{version}");
    assert!(lines.len() == 2 && lines[1].starts_with("isa: "), "{version}");
}

#[test]
fn bench_takes_build_reps_and_rejects_bad_counts() {
    let cornell = cornell();
    let s = cornell.to_str().unwrap();
    let args = ["bench", s, "--ray-set", "shadow", "--traversal", "single", "--reps", "1"];
    let mut ok = args.to_vec();
    ok.extend(["--build-reps", "4", "--json"]);
    let out = pathtracer(&ok);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let record: serde_json::Value =
        serde_json::from_slice(out.stdout.split(|&b| b == b'\n').next().unwrap()).unwrap();
    let ms = record["build_ms"].as_f64().unwrap();
    assert!(ms > 0.0 && ms.is_finite(), "build_ms {ms}");
    for bad in ["0", "1001", "x"] {
        let mut args = args.to_vec();
        args.extend(["--build-reps", bad]);
        assert_one_line_error(&pathtracer(&args), "--build-reps");
    }
}

/// `--stage-times` adds one line (each stage's thread time, each ray kind's speed, traversal's
/// share) and changes nothing else: the same image bytes and statistics as without it.
#[test]
fn stage_times_add_a_line_and_change_nothing_else() {
    let dir = scratch_dir("stage-times");
    let scene = cornell();
    let run = |flag: Option<&str>, name: &str| {
        let png = dir.join(name);
        let mut args = vec!["-t", "2", "-r", "48", "36", "-s", "4", "-m", "1", "--quiet", "-f"];
        args.extend([png.to_str().unwrap(), scene.to_str().unwrap()]);
        args.extend(flag);
        let out = pathtracer(&args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        (String::from_utf8_lossy(&out.stdout).into_owned(), std::fs::read(png).unwrap())
    };
    let (plain, plain_png) = run(None, "plain.png");
    let (timed, timed_png) = run(Some("--stage-times"), "timed.png");
    assert_eq!(plain_png, timed_png, "timing the stages changed the image");
    let counts = |s: &str| s.lines().filter(|l| l.contains("BVH traced")).collect::<String>();
    assert_eq!(counts(&plain), counts(&timed));
    assert!(!plain.contains("Stage times"), "{plain}");
    let line = timed.lines().find(|l| l.contains("Stage times")).expect("a stage line");
    assert!(line.starts_with("[PathTracer] Stage times (thread seconds): camera rays "), "{line}");
    // -m 1 has no bounces: their stage never runs.
    assert!(line.contains("bounce hits 0.0000 (0.00 Mrays/s)"), "{line}");
    let numbers: Vec<f64> = line
        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter_map(|w| w.trim_end_matches('.').parse().ok())
        .collect();
    // camera rays, camera hits (rate), shading, bounce hits (rate), shadow rays (rate),
    // probes, pixel sums, traversal %, total.
    assert_eq!(numbers.len(), 12, "{line}");
    assert!(numbers.iter().all(|x| x.is_finite() && *x >= 0.0), "{line}");
    let stages = [0, 1, 3, 4, 6, 8, 9].map(|i| numbers[i]).iter().sum::<f64>();
    assert!((stages - numbers[11]).abs() <= 4e-4, "the stages add up to the total: {line}");
    assert!(numbers[10] > 0.0 && numbers[10] <= 100.0, "{line}");
}
