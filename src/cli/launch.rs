//! Choosing the build to run, first thing in `main`: the highest instruction-set level this CPU
//! runs (or the lower one `PT_ISA` asks for) whose build sits beside this binary.
//!
//! `cargo build --release` makes `pathtracer` for the x86-64 baseline, which starts on any
//! x86-64 CPU; `.ci/build-isa-binaries` adds `pathtracer-avx2` (x86-64-v3) and
//! `pathtracer-avx512` (x86-64-v4) in the same directory. Whichever of them the user starts,
//! this replaces the process with the chosen build (`exec`, same arguments and environment),
//! or carries on when the chosen build is this one. Levels whose build is missing fall back to
//! the next lower one that is present; this build itself is the last resort.

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use pathtracer::simd::isa::Isa;
use pathtracer::{Error, Result};

/// The environment variable that caps the level (`avx512`, `avx2` or `sse`).
pub const ISA_VAR: &str = "PT_ISA";

/// The level to run: the CPU's best, or `PT_ISA`'s if it is set; asking for a level the CPU
/// lacks is an error.
pub fn wanted_level(var: Option<OsString>, cpu: Isa) -> Result<Isa> {
    let Some(var) = var else { return Ok(cpu) };
    let text = var.to_str().ok_or_else(|| Error::new(format!("{ISA_VAR} is not UTF-8")))?;
    let wanted = Isa::parse(text).map_err(|e| Error::new(format!("{ISA_VAR}: {e}")))?;
    if wanted > cpu {
        return Err(Error::new(format!(
            "{ISA_VAR}={text}: this CPU runs {cpu} at best (it lacks {})",
            wanted.features().iter().find(|f| !pathtracer::simd::isa::cpu_has(f)).unwrap_or(&"?")
        )));
    }
    Ok(wanted)
}

/// Where the build of `level` lives beside the binary at `exe` (`pathtracer-avx2` beside
/// `pathtracer`, `pathtracer` beside `pathtracer-avx512`).
pub fn sibling(exe: &Path, level: Isa) -> Option<PathBuf> {
    let name = exe.file_name()?.to_str()?;
    let base = Isa::ALL
        .iter()
        .filter(|l| !l.binary_suffix().is_empty())
        .find_map(|l| name.strip_suffix(l.binary_suffix()))
        .unwrap_or(name);
    Some(exe.with_file_name(format!("{base}{}", level.binary_suffix())))
}

/// Whether the build at `path` may run in place of `exe`: it exists and is not older than the
/// baseline build beside it (`pathtracer`, or `exe` itself where that is missing).
/// `.ci/build-isa-binaries` builds the baseline first, so a baseline rebuilt later by a plain
/// `cargo build` makes the other builds stale, and they are passed over rather than run with
/// older code (`--version` says so).
pub fn usable(exe: &Path, path: &Path) -> bool {
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let baseline = sibling(exe, Isa::Baseline).filter(|b| b.is_file());
    match (modified(path), baseline.as_deref().or(Some(exe)).and_then(modified)) {
        (Some(build), Some(reference)) => build >= reference,
        (Some(_), None) => true,
        (None, _) => false,
    }
}

/// Builds beside `exe` that exist but are older than its baseline build (`usable`).
fn stale_builds(exe: &Path) -> Vec<PathBuf> {
    Isa::ALL
        .into_iter()
        .filter(|&l| l != Isa::Baseline)
        .filter_map(|l| sibling(exe, l))
        .filter(|p| p.is_file() && !usable(exe, p))
        .collect()
}

/// What to do at start-up: carry on in this build, or start another.
#[derive(Debug, PartialEq, Eq)]
pub enum Choice {
    /// This build is the one to run.
    Here,
    /// Replace the process with the build at this path, of this level.
    Exec(PathBuf, Isa),
}

/// The build to run for `wanted`: the highest level at or below it whose build exists
/// (`exists`), this build (`compiled`) when that comes first. An error when every candidate is
/// missing and this build is above `wanted`. A candidate at this binary's own path is this
/// build, whatever its name says (an avx512 build copied to `pathtracer`): starting it would
/// start the same choice again, for ever.
pub fn choose(
    exe: &Path,
    compiled: Isa,
    wanted: Isa,
    exists: impl Fn(&Path) -> bool,
) -> Result<Choice> {
    for level in Isa::ALL.into_iter().rev().filter(|&l| l <= wanted) {
        if level == compiled {
            return Ok(Choice::Here);
        }
        if let Some(path) = sibling(exe, level).filter(|p| p != exe && exists(p)) {
            return Ok(Choice::Exec(path, level));
        }
    }
    Err(Error::new(format!(
        "{ISA_VAR} asks for {wanted}, but this is the {compiled} build and no build for \
         {wanted} or below sits beside it"
    )))
}

/// Runs the chosen build in place of this process, or returns to run here. Errors are one
/// line (a bad `PT_ISA`, a build that cannot be started).
pub fn run_chosen_build() -> Result<()> {
    let wanted = wanted_level(std::env::var_os(ISA_VAR), Isa::cpu_best())?;
    let compiled = Isa::compiled();
    if wanted == compiled {
        return Ok(());
    }
    let exe = std::env::current_exe()
        .map_err(|e| Error::new(format!("finding this binary's path: {e}")))?;
    match choose(&exe, compiled, wanted, |p| usable(&exe, p))? {
        Choice::Here => Ok(()),
        Choice::Exec(path, level) => exec(&path, level),
    }
}

/// Starts the build at `path` with this process's arguments, telling it the level chosen
/// (`PT_ISA`), so that it runs rather than choosing again.
#[cfg(unix)]
fn exec(path: &Path, level: Isa) -> Result<()> {
    use std::os::unix::process::CommandExt;
    let mut args = std::env::args_os();
    let mut cmd = std::process::Command::new(path);
    cmd.env(ISA_VAR, level.name());
    if let Some(arg0) = args.next() {
        cmd.arg0(arg0);
    }
    let e = cmd.args(args).exec();
    Err(Error::new(format!("starting {}: {e}", path.display())))
}

#[cfg(not(unix))]
fn exec(path: &Path, level: Isa) -> Result<()> {
    let status = std::process::Command::new(path)
        .env(ISA_VAR, level.name())
        .args(std::env::args_os().skip(1))
        .status()
        .map_err(|e| Error::new(format!("starting {}: {e}", path.display())))?;
    std::process::exit(status.code().unwrap_or(2));
}

/// The `--version` text: the package version, then the level that runs and the CPU's best.
pub fn version_text() -> &'static str {
    static TEXT: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TEXT.get_or_init(|| {
        let (isa, cpu) = (Isa::compiled(), Isa::cpu_best());
        let stale: Vec<String> = std::env::current_exe()
            .map(|exe| stale_builds(&exe))
            .unwrap_or_default()
            .iter()
            .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .collect();
        let note = if stale.is_empty() {
            String::new()
        } else {
            format!(
                "; not run: {}, older than the baseline build (rebuild with \
                 .ci/build-isa-binaries)",
                stale.join(", ")
            )
        };
        format!(
            "{}\nisa: {isa} (built for {}; this CPU runs up to {cpu}{note})",
            env!("CARGO_PKG_VERSION"),
            isa.target_cpu()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pt_isa_caps_the_level_and_cannot_raise_it() {
        assert_eq!(wanted_level(None, Isa::Avx2).unwrap(), Isa::Avx2);
        assert_eq!(wanted_level(Some("sse".into()), Isa::Avx512).unwrap(), Isa::Baseline);
        assert_eq!(wanted_level(Some("avx2".into()), Isa::Avx512).unwrap(), Isa::Avx2);
        let e = wanted_level(Some("avx512".into()), Isa::Avx2).unwrap_err().to_string();
        assert!(e.starts_with("PT_ISA=avx512: this CPU runs avx2 at best"), "{e}");
        let e = wanted_level(Some("neon".into()), Isa::Avx2).unwrap_err().to_string();
        assert!(e.contains("PT_ISA: unknown instruction set 'neon'"), "{e}");
    }

    #[test]
    fn siblings_share_the_base_name() {
        let p = Path::new("/x/pathtracer");
        assert_eq!(sibling(p, Isa::Avx512).unwrap(), Path::new("/x/pathtracer-avx512"));
        let p = Path::new("/x/pathtracer-avx512");
        assert_eq!(sibling(p, Isa::Baseline).unwrap(), Path::new("/x/pathtracer"));
        assert_eq!(sibling(p, Isa::Avx2).unwrap(), Path::new("/x/pathtracer-avx2"));
    }

    #[test]
    fn builds_older_than_the_baseline_are_not_used() {
        let dir = std::env::temp_dir().join(format!("pt-launch-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (base, fast) = (dir.join("pathtracer"), dir.join("pathtracer-avx512"));
        let at = |p: &Path, secs: u64| {
            let f = std::fs::File::create(p).unwrap();
            f.set_modified(std::time::UNIX_EPOCH + std::time::Duration::from_secs(secs)).unwrap();
        };
        at(&base, 1000);
        at(&fast, 2000);
        assert!(usable(&base, &fast) && usable(&fast, &base));
        assert!(stale_builds(&base).is_empty());
        at(&base, 3000); // the baseline rebuilt after the others
        assert!(!usable(&base, &fast) && !usable(&fast, &fast));
        assert_eq!(stale_builds(&base), std::slice::from_ref(&fast));
        assert!(!usable(&base, &dir.join("pathtracer-avx2")), "a missing build");
        std::fs::remove_file(&base).unwrap(); // no baseline: the build itself is the reference
        assert!(usable(&fast, &fast));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_highest_present_build_at_or_below_the_wanted_level_runs() {
        let exe = Path::new("/x/pathtracer");
        let only =
            |names: &'static [&'static str]| move |p: &Path| names.iter().any(|n| p.ends_with(n));
        let all = only(&["pathtracer", "pathtracer-avx2", "pathtracer-avx512"]);
        let exec = |n: &str| {
            let level = Isa::ALL.into_iter().rev().find(|l| n.ends_with(l.binary_suffix()));
            Choice::Exec(PathBuf::from(format!("/x/{n}")), level.unwrap())
        };
        assert_eq!(
            choose(exe, Isa::Baseline, Isa::Avx512, all).unwrap(),
            exec("pathtracer-avx512")
        );
        assert_eq!(choose(exe, Isa::Baseline, Isa::Avx2, all).unwrap(), exec("pathtracer-avx2"));
        assert_eq!(choose(exe, Isa::Baseline, Isa::Baseline, all).unwrap(), Choice::Here);
        // The avx512 build missing: the avx2 one; both missing: this one.
        let v3 = only(&["pathtracer", "pathtracer-avx2"]);
        assert_eq!(choose(exe, Isa::Baseline, Isa::Avx512, v3).unwrap(), exec("pathtracer-avx2"));
        assert_eq!(choose(exe, Isa::Baseline, Isa::Avx512, only(&[])).unwrap(), Choice::Here);
        // Started as the avx512 build and asked for less: the lower build, or an error.
        let exe = Path::new("/x/pathtracer-avx512");
        assert_eq!(choose(exe, Isa::Avx512, Isa::Avx2, all).unwrap(), exec("pathtracer-avx2"));
        assert_eq!(choose(exe, Isa::Avx512, Isa::Avx2, v3).unwrap(), exec("pathtracer-avx2"));
        assert_eq!(choose(exe, Isa::Avx512, Isa::Baseline, all).unwrap(), exec("pathtracer"));
        let e = choose(exe, Isa::Avx512, Isa::Avx2, only(&[])).unwrap_err().to_string();
        assert!(e.contains("no build for avx2 or below"), "{e}");
        // An avx512 build under the baseline's name is not started again as the baseline.
        let exe = Path::new("/x/pathtracer");
        let e = choose(exe, Isa::Avx512, Isa::Baseline, all).unwrap_err().to_string();
        assert!(e.contains("asks for sse2, but this is the avx512 build"), "{e}");
        assert_eq!(choose(exe, Isa::Avx512, Isa::Avx2, all).unwrap(), exec("pathtracer-avx2"));
    }
}
