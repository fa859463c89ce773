//! Helpers of the command-line tests (`tests/cli.rs`, `tests/cli_streams.rs`).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the binary with `args` and collects its output.
pub fn pathtracer(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pathtracer")).args(args).output().expect("run pathtracer")
}

/// A fresh directory for test `name`.
pub fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pt-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The repository's Cornell box.
pub fn cornell() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/cornell.dae")
}

/// Asserts a clean failure: exit 2, exactly one line on stderr containing `want`, no panic.
pub fn assert_one_line_error(out: &Output, want: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "want one line, got: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    assert!(lines[0].contains(want), "want '{want}' in: {stderr}");
}

/// Writes `text` to `dir/name`.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

pub fn pathtracer_with_stdout(args: &[&str], stdout: std::process::Stdio) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pathtracer"))
        .args(args)
        .stdout(stdout)
        .output()
        .expect("run pathtracer")
}

/// `/dev/full`: every write fails with "No space left on device".
pub fn dev_full() -> std::process::Stdio {
    let file = std::fs::OpenOptions::new().write(true).open("/dev/full").expect("open /dev/full");
    std::process::Stdio::from(file)
}

/// A pipe whose read end is already closed: every write fails with a broken pipe.
pub fn closed_pipe() -> std::process::Stdio {
    let (reader, writer) = std::io::pipe().expect("pipe");
    drop(reader);
    std::process::Stdio::from(writer)
}
