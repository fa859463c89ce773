//! Shared by the criterion benches: where the course scenes are.

use std::path::PathBuf;

/// A course scene under `$PT_SCENES` (default `../shared/scenes/cs184`), or `None` with a
/// "skipped" line when it is absent, so the benches run (and do nothing) on a bare clone.
pub fn scene_path(rel: &str) -> Option<PathBuf> {
    let dir = std::env::var_os("PT_SCENES").map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/cs184")
    });
    let p = dir.join(rel);
    if p.is_file() {
        Some(p)
    } else {
        eprintln!("skipped: scenes not found ({})", p.display());
        None
    }
}
