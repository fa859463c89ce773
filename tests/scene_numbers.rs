//! Scene numbers the renderer cannot use, end to end through the command line: negative
//! colours and boxes too large to frame are one-line errors; finite but absurd colours that
//! overflow f32 during the render give the image and a warning. Never a panic.

mod common;

use common::cli::{assert_one_line_error, cornell, pathtracer, scratch_dir, write};

#[test]
fn absurd_scene_numbers_are_errors_or_warnings_never_panics() {
    let dir = scratch_dir("absurd");
    let cornell = std::fs::read_to_string(cornell()).unwrap();
    let white = "<color sid=\"diffuse\">0.725 0.725 0.725 1</color>";
    assert!(cornell.contains(white));
    let floor = "-1 0 -1 -1 0 1 1 0 1 1 0 -1";
    assert!(cornell.contains(floor));
    let png = dir.join("out.png");
    let run = |name: &str, text: String| {
        let scene = write(&dir, name, &text);
        pathtracer(&[
            "-r",
            "16",
            "12",
            "-s",
            "2",
            "-m",
            "4",
            "-f",
            png.to_str().unwrap(),
            scene.to_str().unwrap(),
        ])
    };
    // A negative colour is refused when the scene loads.
    let negative = cornell.replace(white, "<color sid=\"diffuse\">0.7 -0.25 0.7 1</color>");
    assert_one_line_error(&run("negative.dae", negative), "diffuse color: -0.25 is negative");
    assert!(!png.exists());
    // A box that f32 cannot hold cannot be framed: an error before rendering.
    let huge = cornell.replace(floor, "-3e38 0 -3e38 -3e38 0 3e38 3e38 0 3e38 3e38 0 -3e38");
    assert_one_line_error(&run("huge.dae", huge), "cannot place the camera");
    assert!(!png.exists());
    // A finite colour of 3.4e38 overflows within a bounce or two: the image is written, and a
    // warning says why some of its pixels are not numbers.
    let bright = cornell.replace(white, "<color sid=\"diffuse\">3.4e38 3.4e38 3.4e38 1</color>");
    let out = run("bright.dae", bright);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("pixels are NaN or infinite"), "{stderr}");
    assert!(png.exists());
}
