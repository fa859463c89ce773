//! One binary for every x86-64 CPU: the plain build hands over to the best build beside it that
//! the CPU runs, `PT_ISA` caps the level, and every level answers every ray of the standard ray
//! sets identically (hit, t, u, v and primitive: `bench`'s answer digest, hits and t_sum).
//!
//! The `-avx2` and `-avx512` builds are made by `.ci/build-isa-binaries`; a level whose build
//! is missing, or which this CPU lacks, is skipped with a note, unless `PT_REQUIRE_ISA_BUILDS`
//! is set (as `.ci/run` does after building them), when a missing build fails.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::cli::assert_one_line_error;
use pathtracer::bench::record::BenchRecord;
use pathtracer::simd::isa::Isa;

fn launcher() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_pathtracer"))
}

fn build_of(level: Isa) -> PathBuf {
    let exe = launcher();
    let name = format!("pathtracer{}", level.binary_suffix());
    exe.with_file_name(name)
}

/// Whether the build at `path` exists and is not older than the baseline build (the launcher
/// passes over older ones: `src/cli/launch.rs`).
fn fresh(path: &Path) -> bool {
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    match (modified(path), modified(&launcher())) {
        (Some(build), Some(base)) => build >= base,
        _ => false,
    }
}

/// The levels to check: this CPU runs them and their build exists (or must exist).
fn levels() -> Vec<Isa> {
    let require = std::env::var_os("PT_REQUIRE_ISA_BUILDS").is_some();
    Isa::ALL
        .into_iter()
        .filter(|&l| {
            if !l.runs_here() {
                eprintln!("note: this CPU does not run {l}; not checked");
                return false;
            }
            let present = fresh(&build_of(l));
            assert!(
                present || !require,
                "PT_REQUIRE_ISA_BUILDS: {} is missing or older than the baseline build",
                build_of(l).display()
            );
            if !present {
                eprintln!(
                    "note: {} not built, or older than the baseline (.ci/build-isa-binaries); \
                     not checked",
                    build_of(l).display()
                );
            }
            present
        })
        .collect()
}

fn run_at(level: &str, args: &[&str]) -> Output {
    Command::new(launcher()).env("PT_ISA", level).args(args).output().expect("run pathtracer")
}

fn stdout(out: &Output) -> String {
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{text}\n{}", String::from_utf8_lossy(&out.stderr));
    text
}

#[test]
fn pt_isa_picks_the_build_that_runs() {
    for level in levels() {
        let text = stdout(&run_at(level.name(), &["--version"]));
        let want = format!("isa: {level} (built for {};", level.target_cpu());
        assert!(text.contains(&want), "PT_ISA={level}: {text}");
    }
    // Without PT_ISA: the best level that is both built and run by this CPU.
    let best = levels().into_iter().max().unwrap_or(Isa::Baseline);
    let out = Command::new(launcher()).env_remove("PT_ISA").arg("--version").output().unwrap();
    assert!(stdout(&out).contains(&format!("isa: {best} ")), "{}", stdout(&out));
}

#[test]
fn a_bad_pt_isa_is_one_line_and_exit_2() {
    assert_one_line_error(&run_at("avx1024", &["--version"]), "PT_ISA: unknown instruction set");
    if !Isa::Avx512.runs_here() {
        assert_one_line_error(&run_at("avx512", &["--version"]), "this CPU runs");
    }
}

/// The bench records of `scene` at `level`, keyed by (ray set, traversal).
fn bench_at(level: Isa, scene: &Path) -> BTreeMap<(String, String), BenchRecord> {
    let scene = scene.to_str().unwrap();
    let out = run_at(level.name(), &["bench", scene, "--threads", "2", "--reps", "1", "--json"]);
    let records = BenchRecord::parse_lines(&stdout(&out), scene).unwrap();
    assert_eq!(records.len(), 12, "{scene}: three sets times four traversals");
    records.into_iter().map(|r| ((r.ray_set.clone(), r.traversal.clone()), r)).collect()
}

#[test]
fn every_level_answers_every_ray_identically() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut scenes = vec![root.join("assets/cornell.dae")];
    scenes.extend(
        ["sky/CBbunny.dae", "meshedit/maxplanck.dae"]
            .iter()
            .filter_map(|s| common::course_scene(s)),
    );
    let levels = levels();
    for scene in &scenes {
        let base = bench_at(Isa::Baseline, scene);
        assert!(base.values().any(|r| r.hits > 0), "{}: nothing hit", scene.display());
        for &level in levels.iter().filter(|&&l| l != Isa::Baseline) {
            let other = bench_at(level, scene);
            for (key, b) in &base {
                let o = &other[key];
                let at = format!("{} {key:?}: {level} against sse2", scene.display());
                assert_eq!(b.isa, Isa::Baseline.name(), "{at}");
                assert_eq!(o.isa, level.name(), "{at}");
                assert_eq!(o.answers, b.answers, "{at}: answer digests");
                assert_eq!(o.hits, b.hits, "{at}: hits");
                assert_eq!(o.t_sum.to_bits(), b.t_sum.to_bits(), "{at}: t_sum");
            }
        }
    }
}

/// Renders are bit-identical at every level too (the shading has no fused operations, and its
/// `exp`, sine and cosine are our own polynomials; the traversal's answers are identical), so
/// an image does not depend on the machine. `assets/cornell.dae` (diffuse, mirror, glass), and
/// where the course scenes are present a glossy one (the microfacet lanes).
#[test]
fn every_level_renders_the_same_bytes() {
    let dir = std::env::temp_dir().join(format!("pt-isa-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut scenes = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cornell.dae")];
    scenes.extend(common::course_scene("sky/CBspheres_microfacet_al_ag.dae"));
    for scene in &scenes {
        let render = |level: Isa, extra: &[&str]| {
            let file = dir.join(format!("{level}.exr"));
            let mut args = vec!["-t", "2", "-r", "64", "48", "-s", "8", "-m", "5", "--quiet"];
            args.extend_from_slice(&["-f", file.to_str().unwrap()]);
            args.extend_from_slice(extra);
            args.push(scene.to_str().unwrap());
            stdout(&run_at(level.name(), &args));
            std::fs::read(&file).unwrap()
        };
        for extra in [&[][..], &["--shading", "mis"][..]] {
            let base = render(Isa::Baseline, extra);
            for level in levels().into_iter().filter(|&l| l != Isa::Baseline) {
                assert!(
                    render(level, extra) == base,
                    "{} {level} {extra:?}: the image differs from sse2's",
                    scene.display()
                );
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `qemu-x86_64` (Debian's qemu-user), if installed; a failure when `PT_REQUIRE_QEMU` is set
/// (as `.ci/run` does after installing it).
fn qemu() -> Option<PathBuf> {
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths).map(|d| d.join("qemu-x86_64")).find(|p| p.is_file())
    });
    if found.is_none() {
        assert!(std::env::var_os("PT_REQUIRE_QEMU").is_none(), "PT_REQUIRE_QEMU: no qemu-x86_64");
        eprintln!(
            "note: qemu-x86_64 not found (apt-get install qemu-user); older CPUs not checked"
        );
    }
    found
}

/// Runs `build` under qemu's model of an older CPU (`Nehalem`: SSE4.2, no AVX; `Haswell`:
/// AVX2 and FMA, no AVX-512), with `PT_ISA` unset.
fn on_cpu(qemu: &Path, cpu: &str, build: &Path, args: &[&str]) -> Output {
    Command::new(qemu)
        .args(["-cpu", cpu])
        .arg(build)
        .args(args)
        .env_remove("PT_ISA")
        .output()
        .expect("run qemu-x86_64")
}

/// On CPUs without AVX2 or AVX-512 the plain binary runs the build they can run (and renders),
/// and a faster build started by hand refuses with one line instead of dying on SIGILL.
#[test]
fn older_cpus_get_the_build_they_run() {
    let Some(qemu) = qemu() else { return };
    let base = launcher();
    let version = |cpu: &str| stdout(&on_cpu(&qemu, cpu, &base, &["--version"]));
    assert!(version("Nehalem").contains("isa: sse2 (built for x86-64; this CPU runs up to sse2"));
    let dir = std::env::temp_dir().join(format!("pt-isa-qemu-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("cornell.png");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cornell.dae");
    let args = ["-r", "16", "12", "-s", "2", "-m", "2", "--quiet", "-f"];
    let mut args: Vec<&str> = args.to_vec();
    args.extend([png.to_str().unwrap(), scene.to_str().unwrap()]);
    stdout(&on_cpu(&qemu, "Nehalem", &base, &args));
    assert!(std::fs::metadata(&png).unwrap().len() > 0);
    let _ = std::fs::remove_dir_all(&dir);
    let refused = |cpu: &str, level: Isa| {
        let out = on_cpu(&qemu, cpu, &build_of(level), &["--version"]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.starts_with("qemu-x86_64:")).collect();
        assert_eq!(out.status.code(), Some(2), "{level} on {cpu}: {stderr}");
        assert_eq!(lines.len(), 1, "{level} on {cpu}: {stderr}");
        assert!(lines[0].starts_with("error: this CPU lacks instructions this build"), "{stderr}");
    };
    let fast: Vec<Isa> = levels().into_iter().filter(|&l| l != Isa::Baseline).collect();
    if fast.contains(&Isa::Avx2) {
        // The exec'd build runs natively on this machine, told the level by PT_ISA.
        assert!(version("Haswell").contains("isa: avx2 (built for x86-64-v3;"));
        refused("Nehalem", Isa::Avx2);
    }
    if fast.contains(&Isa::Avx512) {
        refused("Nehalem", Isa::Avx512);
        refused("Haswell", Isa::Avx512);
    }
}
