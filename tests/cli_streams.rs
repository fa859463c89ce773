//! The command line's standard streams: a full or closed stdout or stderr is a one-line error
//! (or a quiet exit for a closed pipe), never a panic, and never loses the files a command
//! writes.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

use common::cli::{
    assert_one_line_error, closed_pipe, cornell, dev_full, pathtracer, pathtracer_with_stdout,
    scratch_dir,
};

/// Drops converge's progress note ("[converge] reference: ...") from stderr.
fn without_progress_notes(mut out: Output) -> Output {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let kept: Vec<&str> = stderr.lines().filter(|l| !l.starts_with("[converge] ")).collect();
    out.stderr = kept.iter().map(|l| format!("{l}\n")).collect::<String>().into_bytes();
    out
}

/// The files in `dir` whose name holds "tmp" (a temporary file left behind).
fn temporary_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("tmp"))
        .collect()
}

/// The commands of the stdout tests, each writing (if at all) into `dir`.
fn stdout_commands(dir: &Path) -> Vec<(&'static str, Vec<String>)> {
    let scene = cornell().to_str().unwrap().to_string();
    let d = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let image = d("a.png");
    let strings = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    vec![
        ("render", strings(&["-t", "2", "-r", "16", "12", "--quiet", "-f", &d("r.png"), &scene])),
        ("--info", strings(&["--info", &scene])),
        ("compare", strings(&["compare", &image, &image])),
        ("gen", strings(&["gen", "cornell", "-o", &d("g.dae")])),
        (
            "converge",
            strings(&[
                "converge",
                &scene,
                "--spp",
                "1,2",
                "--ref-spp",
                "4",
                "-r",
                "16",
                "12",
                "-t",
                "2",
                "--csv",
                &d("c.csv"),
            ]),
        ),
        (
            "part",
            strings(&["-s", "2", "-r", "16", "12", "--part", "0/2", "-f", &d("q.ptpart"), &scene]),
        ),
        ("merge", strings(&["merge", &d("p0.ptpart"), &d("p1.ptpart"), "-f", &d("m.png")])),
        ("part-info", strings(&["part-info", &d("p0.ptpart")])),
        ("--help", strings(&["--help"])),
        ("--version", strings(&["--version"])),
        ("bench --help", strings(&["bench", "--help"])),
        ("compare --help", strings(&["compare", "--help"])),
        ("converge --help", strings(&["converge", "--help"])),
        ("gen --help", strings(&["gen", "--help"])),
        ("chart --help", strings(&["chart", "--help"])),
        ("merge --help", strings(&["merge", "--help"])),
    ]
}

/// Renders the 16 x 12 image `a.png` the stdout tests compare, and the two parts
/// `p0.ptpart`, `p1.ptpart` they merge.
fn stdout_test_dir(name: &str) -> PathBuf {
    let dir = scratch_dir(name);
    let image = dir.join("a.png");
    let scene = cornell();
    let args =
        ["-r", "16", "12", "--quiet", "-f", image.to_str().unwrap(), scene.to_str().unwrap()];
    let out = pathtracer(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for k in 0..2 {
        let part = dir.join(format!("p{k}.ptpart"));
        let spec = format!("{k}/2");
        let args = ["-s", "2", "-r", "16", "12", "--part", &spec, "-f", part.to_str().unwrap()];
        let out = pathtracer(&[&args[..], &[scene.to_str().unwrap()]].concat());
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    dir
}

/// The part and the merged image of `stdout_commands` are complete.
fn assert_parts_written(dir: &Path) {
    let merged = image::open(dir.join("m.png")).unwrap();
    assert_eq!((merged.width(), merged.height()), (16, 12));
    let info = pathtracer(&["part-info", dir.join("q.ptpart").to_str().unwrap()]);
    assert!(info.status.success(), "{}", String::from_utf8_lossy(&info.stderr));
}

#[test]
fn a_full_stdout_is_a_one_line_error_and_the_files_are_still_written() {
    let dir = stdout_test_dir("stdout-full");
    for (name, args) in stdout_commands(&dir) {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = without_progress_notes(pathtracer_with_stdout(&args, dev_full()));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
        assert_one_line_error(&out, "writing to standard output: No space left on device");
    }
    // The image and the scene are complete: printing failed, writing did not.
    let img = image::open(dir.join("r.png")).unwrap();
    assert_eq!((img.width(), img.height()), (16, 12));
    let scene = std::fs::read_to_string(dir.join("g.dae")).unwrap();
    assert!(scene.trim_end().ends_with("</COLLADA>"), "{scene}");
    assert!(std::fs::read_to_string(dir.join("c.csv")).unwrap().lines().count() >= 3);
    assert_parts_written(&dir);
    assert_eq!(temporary_files(&dir), Vec::<String>::new());
}

#[test]
fn a_closed_stdout_ends_quietly_and_the_files_are_still_written() {
    let dir = stdout_test_dir("stdout-closed");
    for (name, args) in stdout_commands(&dir) {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = without_progress_notes(pathtracer_with_stdout(&args, closed_pipe()));
        let stderr = String::from_utf8_lossy(&out.stderr);
        // Exit 0 (not killed by SIGPIPE: a signal would leave no exit code), no message.
        assert_eq!(out.status.code(), Some(0), "{name}: {stderr}");
        assert_eq!(stderr, "", "{name}");
    }
    let img = image::open(dir.join("r.png")).unwrap();
    assert_eq!((img.width(), img.height()), (16, 12));
    assert!(std::fs::read_to_string(dir.join("g.dae")).unwrap().contains("</COLLADA>"));
    assert_parts_written(&dir);
    assert_eq!(temporary_files(&dir), Vec::<String>::new());
}

#[test]
fn a_full_stderr_is_exit_code_2_without_a_panic() {
    let dir = scratch_dir("stderr-full");
    let image = dir.join("h.png");
    let scene = cornell();
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_pathtracer"))
            .args(args)
            .stderr(dev_full())
            .output()
            .expect("run pathtracer")
    };
    // A bad flag: the error cannot be shown, but the exit code says it (a panic would be 101).
    assert_eq!(run(&["-s", "many", scene.to_str().unwrap()]).status.code(), Some(2));
    // -H on the Cornell box warns on stderr: exit 2, and the image is written all the same.
    let out =
        run(&["-H", "-r", "16", "12", "-f", image.to_str().unwrap(), scene.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stdout).contains("Job completed"));
    assert!(image.exists());
}
