//! Parts of a render and their exact merge: any plan's parts merged give the same bytes as the
//! whole render; bad or mismatched parts are one-line errors and write nothing.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn pathtracer(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pathtracer")).args(args).output().expect("run pathtracer")
}

fn ok(args: &[&str]) {
    let out = pathtracer(args);
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pt-farm-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn cornell() -> String {
    format!("{}/assets/cornell.dae", env!("CARGO_MANIFEST_DIR"))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Asserts a clean failure: exit 2, one line on stderr starting `error:` and containing `want`.
fn assert_one_line_error(out: &Output, want: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "want one line, got: {stderr}");
    assert!(lines[0].starts_with("error: ") && lines[0].contains(want), "want '{want}': {stderr}");
}

/// Renders the whole image to `dir/whole.{png,exr}` with `flags`.
fn whole(dir: &Path, flags: &[&str]) -> (Vec<u8>, Vec<u8>) {
    let scene = cornell();
    for ext in ["png", "exr"] {
        let out = dir.join(format!("whole.{ext}"));
        ok(&[flags, &["--quiet", "-f", s(&out), &scene]].concat());
    }
    (std::fs::read(dir.join("whole.png")).unwrap(), std::fs::read(dir.join("whole.exr")).unwrap())
}

/// Merges `parts` to png and exr and returns both files' bytes.
fn merged(dir: &Path, parts: &[PathBuf]) -> (Vec<u8>, Vec<u8>) {
    let mut files = Vec::new();
    for ext in ["png", "exr"] {
        let out = dir.join(format!("merged.{ext}"));
        let mut args = vec!["merge"];
        args.extend(parts.iter().map(|p| s(p)));
        args.extend(["-f", s(&out)]);
        ok(&args);
        files.push(std::fs::read(&out).unwrap());
    }
    (files.remove(0), files.remove(0))
}

const FLAGS: &[&str] = &["-s", "8", "-m", "3", "-r", "64", "48"];

#[test]
fn crops_and_uneven_sample_ranges_merge_to_the_whole_render() {
    for extra in [
        &["--shading", "light"][..],
        &["--shading", "mis", "--seed", "7"],
        &["--sampler", "independent", "-l", "2"],
    ] {
        let dir = scratch_dir("crops");
        let flags = [FLAGS, extra].concat();
        let want = whole(&dir, &flags);
        let mut parts = Vec::new();
        let scene = cornell();
        let crops = [
            ["0", "0", "32", "24"],
            ["32", "0", "64", "24"],
            ["0", "24", "32", "48"],
            ["32", "24", "64", "48"],
        ];
        for (i, crop) in crops.iter().enumerate() {
            for (j, range) in ["0..1", "1..5", "5..8"].iter().enumerate() {
                let part = dir.join(format!("p{i}{j}.ptpart"));
                let threads = if (i + j) % 2 == 0 { "1" } else { "2" };
                let args = [
                    &flags[..],
                    &["-t", threads, "--crop"],
                    &crop[..],
                    &["--samples", range, "-f", s(&part), &scene],
                ]
                .concat();
                ok(&args);
                parts.push(part);
            }
        }
        parts.reverse(); // the order of the parts does not matter
        assert!(
            merged(&dir, &parts) == want,
            "{extra:?}: merged parts differ from the whole render"
        );
    }
}

#[test]
fn every_plan_merges_to_the_whole_render() {
    let dir = scratch_dir("plans");
    let want = whole(&dir, FLAGS);
    for n in [1, 2, 3, 4, 5, 6, 8] {
        let parts: Vec<PathBuf> = (0..n)
            .map(|k| {
                let part = dir.join(format!("n{n}-{k}.ptpart"));
                let spec = format!("{k}/{n}");
                ok(&[FLAGS, &["--part", &spec, "-f", s(&part), &cornell()]].concat());
                part
            })
            .collect();
        assert!(
            merged(&dir, &parts) == want,
            "--part K/{n}: merged parts differ from the whole render"
        );
    }
    // A whole render written as a part is the plan of one part.
    let one = dir.join("one.ptpart");
    ok(&[FLAGS, &["-f", s(&one), &cornell()]].concat());
    assert!(merged(&dir, &[one]) == want);
}

#[test]
fn adaptive_sampling_merges_tile_plans_and_refuses_sample_splits() {
    let dir = scratch_dir("adaptive");
    let flags = [FLAGS, &["-s", "32", "-a", "8", "0.2"]].concat();
    let want = whole(&dir, &flags);
    let want_rate = std::fs::read(dir.join("whole_rate.png")).unwrap();
    let parts: Vec<PathBuf> = (0..3)
        .map(|k| {
            let part = dir.join(format!("a{k}.ptpart"));
            ok(&[&flags[..], &["--part", &format!("{k}/3"), "-f", s(&part), &cornell()]].concat());
            part
        })
        .collect();
    assert!(merged(&dir, &parts) == want);
    assert!(std::fs::read(dir.join("merged_rate.png")).unwrap() == want_rate);
    let out = pathtracer(
        &[&flags[..], &["--part", "0/4", "-f", s(&dir.join("x.ptpart")), &cornell()]].concat(),
    );
    assert_one_line_error(&out, "adaptive sampling (-a) cannot");
    let out = pathtracer(
        &[&flags[..], &["--samples", "0..8", "-f", s(&dir.join("x.ptpart")), &cornell()]].concat(),
    );
    assert_one_line_error(&out, "adaptive sampling (-a) decides");
}

fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ b as u64).wrapping_mul(0x100_0000_01b3))
}

/// Rewrites one header line of a part (with a valid checksum): a part from elsewhere.
fn edit_header(from: &Path, to: &Path, old: &str, new: &str) {
    let bytes = std::fs::read(from).unwrap();
    let body = &bytes[..bytes.len() - 8];
    let end = body.windows(5).position(|w| w == b"\nend\n").unwrap();
    let header = String::from_utf8(body[..end].to_vec()).unwrap();
    assert!(header.contains(old), "{header}");
    let mut out = header.replacen(old, new, 1).into_bytes();
    out.extend_from_slice(&body[end..]);
    out.extend_from_slice(&fnv1a64(&out).to_le_bytes());
    std::fs::write(to, out).unwrap();
}

#[test]
fn bad_and_mismatched_parts_are_one_line_errors_and_write_nothing() {
    let dir = scratch_dir("bad");
    let part = |name: &str, extra: &[&str]| {
        let p = dir.join(name);
        ok(&[FLAGS, extra, &["-f", s(&p), &cornell()]].concat());
        p
    };
    let a = part("a.ptpart", &["--part", "0/2"]);
    let b = part("b.ptpart", &["--part", "1/2"]);
    let b_seed = part("b_seed.ptpart", &["--part", "1/2", "--seed", "3"]);
    let top_half = part("top.ptpart", &["--crop", "0", "0", "64", "24", "--samples", "0..8"]);
    let other_scene = dir.join("other.dae");
    ok(&["gen", "cornell", "-o", s(&other_scene)]);
    std::fs::write(&other_scene, std::fs::read_to_string(&other_scene).unwrap() + "\n").unwrap();
    let b_scene = dir.join("b_scene.ptpart");
    ok(&[FLAGS, &["--part", "1/2", "-f", s(&b_scene), s(&other_scene)]].concat());
    let b_version = dir.join("b_version.ptpart");
    edit_header(&b, &b_version, "renderer ", "renderer 0.0.0-old");
    let damaged = dir.join("damaged.ptpart");
    let mut bytes = std::fs::read(&b).unwrap();
    let i = bytes.len() / 2;
    bytes[i] ^= 0x40;
    std::fs::write(&damaged, &bytes).unwrap();
    let truncated = dir.join("truncated.ptpart");
    std::fs::write(&truncated, &bytes[..bytes.len() - 100]).unwrap();
    let image = dir.join("image.ptpart");
    std::fs::write(&image, b"\x89PNG\r\n").unwrap();

    let out = dir.join("out.png");
    for (parts, want) in [
        (vec![&a], "no part holds samples 0..8 of pixel (0, 16)"),
        (vec![&a, &b, &top_half], "top.ptpart both hold samples 0..8 of pixels (0, 0)-(64, 16)"),
        (vec![&a, &b_seed], "other flags"),
        (vec![&a, &b_scene], "another scene"),
        (vec![&a, &b_version], "0.0.0-old"),
        (vec![&a, &damaged], "damaged.ptpart: damaged part file (checksum"),
        (vec![&a, &truncated], "truncated.ptpart: truncated or damaged"),
        (vec![&a, &image], "image.ptpart: not a pathtracer part file"),
        (vec![&a, &dir.join("missing.ptpart")], "missing.ptpart: cannot read"),
    ] {
        let mut args = vec!["merge"];
        args.extend(parts.iter().map(|p| s(p)));
        args.extend(["-f", s(&out)]);
        assert_one_line_error(&pathtracer(&args), want);
        assert!(!out.exists(), "{want}: an output was written");
    }
    assert_one_line_error(&pathtracer(&["merge", s(&a), s(&b)]), "no output");
    assert_one_line_error(&pathtracer(&["merge", s(&a), s(&b), "-f", s(&a)]), ".png or .exr");
    let linked = dir.join("linked.png");
    std::fs::hard_link(&a, &linked).unwrap();
    let args = ["merge", s(&linked), s(&b), "-f", s(&linked)];
    assert_one_line_error(&pathtracer(&args), "same file as the input");
    assert_one_line_error(&pathtracer(&["part-info", s(&damaged)]), "checksum");
    let info = pathtracer(&["part-info", s(&a)]);
    assert!(String::from_utf8_lossy(&info.stdout).contains("\"samples\": [0, 8]"));
    // A part must go to a .ptpart file; nothing is left behind by a refused render.
    let out =
        pathtracer(&[FLAGS, &["--part", "0/2", "-f", s(&dir.join("p.png")), &cornell()]].concat());
    assert_one_line_error(&out, "written to a .ptpart file");
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.starts_with('.') && n != "p.png"), "{names:?}");
}
