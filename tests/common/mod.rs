//! Shared helpers for integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// The course scenes: `$PT_SCENES`, else `../shared/scenes/cs184` beside the repository.
/// Returns `None` (and prints "skipped: scenes not found") when they are absent, so tests that
/// need them skip cleanly on a clone without `shared/`. `.ci/run` always has them and sets
/// `PT_REQUIRE_SCENES=1`, which turns a missing directory into a failure.
pub fn scenes_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("PT_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/cs184"));
    if dir.is_dir() {
        Some(dir)
    } else if std::env::var_os("PT_REQUIRE_SCENES").is_some() {
        panic!("PT_REQUIRE_SCENES is set but {} does not exist", dir.display());
    } else {
        eprintln!("skipped: scenes not found at {}", dir.display());
        None
    }
}

/// A course scene by its path relative to the scenes directory, or `None` (skipped).
pub fn course_scene(rel: &str) -> Option<PathBuf> {
    scenes_dir().map(|d| d.join(rel))
}

/// Every `.dae` under the scenes directory, sorted.
pub fn all_course_scenes() -> Vec<PathBuf> {
    let Some(dir) = scenes_dir() else { return Vec::new() };
    let mut out = Vec::new();
    let mut stack = vec![dir];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "dae") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}
