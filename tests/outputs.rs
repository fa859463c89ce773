//! Commands with several outputs write all or none; a signal removes the temporaries; a
//! temporary's name never makes a legal file name too long.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pt-outputs-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn cornell() -> String {
    format!("{}/assets/cornell.dae", env!("CARGO_MANIFEST_DIR"))
}

fn pathtracer(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pathtracer")).args(args).output().expect("run pathtracer")
}

/// Runs pathtracer unable to write a file of more than 2048 bytes (`ulimit -f`, with
/// SIGXFSZ ignored so the write fails with EFBIG instead of killing the process).
fn pathtracer_with_small_files(args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 4; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_pathtracer"))
        .args(args)
        .output()
        .expect("run pathtracer")
}

fn assert_one_line_error(out: &Output, want: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "status {:?}, stderr: {stderr}", out.status);
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.starts_with("[converge]")).collect();
    assert_eq!(lines.len(), 1, "want one line, got: {stderr}");
    assert!(lines[0].starts_with("error: ") && lines[0].contains(want), "{stderr}");
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn converge_writes_its_reference_and_table_together_or_neither() {
    let dir = scratch_dir("converge");
    let (csv, reference) = (dir.join("c.csv"), dir.join("ref.exr"));
    let spps: String = (1..=40).map(|n| n.to_string()).collect::<Vec<_>>().join(",");
    let (c, r, s) = (csv.to_str().unwrap(), reference.to_str().unwrap(), cornell());
    let args = ["converge", &s, "--spp", &spps, "--ref-spp", "4", "-r", "4", "3", "-t", "2"];
    let mut all = args.to_vec();
    all.extend(["--csv", c, "--write-reference", r]);
    // The 4x3 reference (about 600 bytes) fits in 2048 bytes; the 40-row table does not.
    let out = pathtracer_with_small_files(&all);
    assert_one_line_error(&out, "c.csv: cannot write");
    assert_eq!(names(&dir), Vec::<String>::new(), "a file was left");
    // Without the limit both are written.
    let ok = pathtracer(&all);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    assert_eq!(names(&dir), ["c.csv", "ref.exr"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bench_writes_its_three_ray_files_together_or_none() {
    let dir = scratch_dir("bench");
    let prefix = dir.join("rays");
    let s = cornell();
    let args =
        ["bench", &s, "--rays-out", prefix.to_str().unwrap(), "--reps", "1", "--ray-set", "shadow"];
    assert_one_line_error(&pathtracer_with_small_files(&args), "rays.primary.rays: cannot write");
    assert_eq!(names(&dir), Vec::<String>::new());
    let ok = pathtracer(&[&args[..], &["--traversal", "single"]].concat());
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    assert_eq!(names(&dir), ["rays.diffuse.rays", "rays.primary.rays", "rays.shadow.rays"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_rate_image_name_too_long_is_refused_before_rendering_and_replaces_nothing() {
    let dir = scratch_dir("rate-name");
    // NAME.png is a legal 251 + 4 bytes; NAME_rate.png would be 260.
    let image = dir.join(format!("{}.png", "x".repeat(251)));
    std::fs::write(&image, "old").unwrap();
    let s = cornell();
    let args = ["-r", "16", "12", "-s", "4", "-a", "2", "0.1", "-f", image.to_str().unwrap(), &s];
    let out = pathtracer(&args);
    assert_one_line_error(&out, "_rate.png: the file name is longer than 255 bytes");
    assert!(!String::from_utf8_lossy(&out.stdout).contains("Rendering..."), "rendered first");
    assert_eq!(std::fs::read_to_string(&image).unwrap(), "old");
    assert_eq!(names(&dir).len(), 1);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_longest_legal_output_name_is_written() {
    let dir = scratch_dir("long-name");
    for name in [format!("{}.png", "y".repeat(251)), format!("{}.exr", "é".repeat(125))] {
        let image = dir.join(&name);
        let s = cornell();
        let out = pathtracer(&["-r", "16", "12", "-q", "-f", image.to_str().unwrap(), &s]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let img = image::open(&image).unwrap();
        assert_eq!((img.width(), img.height()), (16, 12));
    }
    assert_eq!(names(&dir).len(), 2, "{:?}", names(&dir));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Waits (up to a minute) until `ready` holds, polling every 5 ms.
fn wait_until(mut ready: impl FnMut() -> bool) {
    let start = Instant::now();
    while !ready() {
        assert!(start.elapsed() < Duration::from_secs(60), "timed out");
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn send(child: &std::process::Child, signal: libc::c_int) {
    // SAFETY: a signal to our own child process, by its id.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
}

#[test]
fn sigterm_while_an_output_is_staged_removes_the_temporary() {
    let dir = scratch_dir("sigterm");
    let (csv, reference) = (dir.join("c.csv"), dir.join("ref.exr"));
    let s = cornell();
    // The reference is staged as soon as it is rendered; the sweep after it runs for minutes.
    let spps = ["1024"; 40].join(",");
    let args = ["converge", &s, "--spp", &spps, "--ref-spp", "4", "-r", "64", "48", "-m", "4"];
    let mut child = Command::new(env!("CARGO_BIN_EXE_pathtracer"))
        .args(args)
        .args(["-t", "2", "--csv", csv.to_str().unwrap()])
        .args(["--write-reference", reference.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_until(|| !names(&dir).is_empty());
    send(&child, libc::SIGTERM);
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(143), "{status:?}");
    assert_eq!(names(&dir), Vec::<String>::new(), "left behind");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn sigint_during_a_render_exits_130_without_files() {
    let dir = scratch_dir("sigint");
    let image = dir.join("big.png");
    let s = cornell();
    let mut command = Command::new(env!("CARGO_BIN_EXE_pathtracer"));
    command
        .args(["-r", "800", "600", "-s", "4096", "-m", "5", "-t", "2", "-f"])
        .args([image.to_str().unwrap(), &s])
        .stdout(Stdio::piped())
        .stderr(Stdio::null());
    // The renderer keeps a SIGINT that its parent ignores (as a shell's background job
    // inherits it), so the child starts with the default action whatever this test inherited.
    // SAFETY: only `signal`, which is async-signal-safe, runs between fork and exec.
    unsafe {
        std::os::unix::process::CommandExt::pre_exec(&mut command, || {
            libc::signal(libc::SIGINT, libc::SIG_DFL);
            Ok(())
        });
    }
    let mut child = command.spawn().unwrap();
    // Rendering has begun once the BVH line is out.
    let mut stdout = child.stdout.take().unwrap();
    let mut seen = String::new();
    wait_until(|| {
        let mut buf = [0u8; 256];
        let n = std::io::Read::read(&mut stdout, &mut buf).unwrap();
        seen += &String::from_utf8_lossy(&buf[..n]);
        seen.contains("Building BVH") || n == 0
    });
    send(&child, libc::SIGINT);
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{status:?}");
    assert_eq!(names(&dir), Vec::<String>::new());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn chart_accuracy_leaves_no_half_written_chart() {
    let dir = scratch_dir("chart");
    let d = dir.to_str().unwrap();
    let s = cornell();
    let args = ["chart", "accuracy", &s, d, "-r", "8", "6", "--spp", "1,2", "--ref-spp", "4"];
    // A chart is about 30 kB: past the 2048-byte limit, so nothing may be left, not even the
    // first depth's chart or a truncated one (plotters used to write the SVG in place).
    let out = pathtracer_with_small_files(&args);
    assert_eq!(out.status.code(), Some(2));
    // Progress lines come first; the error is the last line, and the only one.
    let err = String::from_utf8_lossy(&out.stderr);
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{err}");
    assert!(errors[0].contains("accuracy_cornell_m1.svg: cannot write"), "{err}");
    assert_eq!(names(&dir), Vec::<String>::new(), "a file was left");
    let ok = pathtracer(&args);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let want = ["m1.csv", "m1.svg", "m5.csv", "m5.svg"].map(|n| format!("accuracy_cornell_{n}"));
    assert_eq!(names(&dir), want);
    std::fs::remove_dir_all(&dir).unwrap();
}
