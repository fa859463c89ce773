//! `bench --baseline`: the exact counters and checksums of a run against a baseline written by
//! `bench --json`; each regression is one line and the exit code is 1.

use std::path::PathBuf;
use std::process::{Command, Output};

use pathtracer::bench::BenchRecord;

fn bench(extra: &[&str]) -> Output {
    let scene = format!("{}/assets/cornell.dae", env!("CARGO_MANIFEST_DIR"));
    Command::new(env!("CARGO_BIN_EXE_pathtracer"))
        .args(["bench", &scene, "--reps", "1", "--traversal", "single"])
        .args(extra)
        .output()
        .expect("run pathtracer")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pt-baseline-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The baseline's records with `edit` applied, written to `name` in `dir`.
fn edited(
    dir: &std::path::Path,
    name: &str,
    base: &[BenchRecord],
    edit: impl Fn(&mut BenchRecord),
) -> String {
    let mut records = base.to_vec();
    records.iter_mut().for_each(edit);
    let lines: String = records.iter().map(|r| r.to_json() + "\n").collect();
    let path = dir.join(name);
    std::fs::write(&path, lines).unwrap();
    path.to_str().unwrap().to_string()
}

fn regression_lines(out: &Output) -> Vec<String> {
    text(&out.stdout).lines().filter(|l| l.starts_with("regression: ")).map(String::from).collect()
}

#[test]
fn a_run_is_compared_with_its_baseline() {
    let dir = scratch_dir("compare");
    let json = bench(&["--json"]);
    assert!(json.status.success(), "{}", text(&json.stderr));
    let base = BenchRecord::parse_lines(&text(&json.stdout), "stdout").unwrap();
    assert_eq!(base.len(), 3, "one record per ray set");
    assert!(base.iter().all(|r| r.node_tests > 0 && r.triangle_tests > 0), "{base:?}");
    let same = edited(&dir, "same.jsonl", &base, |_| {});
    let out = bench(&["--baseline", &same]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
    assert!(text(&out.stdout).contains(&format!("baseline: 3 records match {same} (tolerance 0%)")));

    // A baseline 10% cheaper in node tests: this run regressed by 11%.
    let cheaper = edited(&dir, "cheaper.jsonl", &base, |r| {
        if r.ray_set == "primary" {
            r.node_tests = r.node_tests * 9 / 10;
        }
    });
    let out = bench(&["--baseline", &cheaper]);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    let lines = regression_lines(&out);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains("ray set primary, traversal single: node_tests "), "{}", lines[0]);
    assert_eq!(bench(&["--baseline", &cheaper, "--tolerance", "20"]).status.code(), Some(0));

    // Checksums move either way; with --json the lines go to stderr and stdout stays JSON.
    let hits = edited(&dir, "hits.jsonl", &base, |r| r.hits += 1);
    let out = bench(&["--baseline", &hits, "--json"]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(BenchRecord::parse_lines(&text(&out.stdout), "stdout").unwrap().len(), 3);
    assert_eq!(text(&out.stderr).matches("regression: ").count(), 3, "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains(": hits "));

    let other = edited(&dir, "other.jsonl", &base[..1], |r| r.traversal = "packet8".into());
    let out = bench(&["--baseline", &other]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(regression_lines(&out), ["regression: scene cornell.dae, ray set primary, traversal packet8: missing from this run"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_baselines_and_tolerances_are_one_line_errors() {
    let dir = scratch_dir("bad");
    let junk = dir.join("junk.jsonl");
    std::fs::write(&junk, "{\"scene\": 3}\n").unwrap();
    let empty = dir.join("empty.jsonl");
    std::fs::write(&empty, "\n").unwrap();
    let (j, e) = (junk.to_str().unwrap(), empty.to_str().unwrap());
    for (args, want) in [
        (vec!["--baseline", "/no/such.jsonl"], "--baseline /no/such.jsonl"),
        (vec!["--baseline", j], "junk.jsonl:1: invalid type"),
        (vec!["--baseline", e], "no records"),
        (vec!["--tolerance", "5"], "--tolerance needs --baseline"),
        (vec!["--baseline", j, "--tolerance", "-1"], "--tolerance: expected a percentage"),
        (vec!["--frame", "400"], "--frame: bad frame '400'"),
        (vec!["--frame", "5000x10"], "--frame: bad frame '5000x10'"),
    ] {
        let out = bench(&args);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.starts_with("error: ") && stderr.contains(want), "want '{want}': {stderr}");
        assert!(text(&out.stdout).is_empty(), "ran before failing");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--frame`: the primary rays go through the pixels of another image, the record says which,
/// and a baseline of the standard frame does not answer for it.
#[test]
fn another_frame_is_another_ray_set() {
    let dir = scratch_dir("frame");
    let json = |extra: &[&str]| {
        let out = bench(&[&["--json", "--ray-set", "primary"], extra].concat());
        assert!(out.status.success(), "{}", text(&out.stderr));
        BenchRecord::parse_lines(&text(&out.stdout), "stdout").unwrap().remove(0)
    };
    let standard = json(&[]);
    assert_eq!((standard.rays, standard.frame.as_str()), (800 * 600, "800x600"));
    let small = json(&["--frame", "40x30"]);
    assert_eq!((small.rays, small.frame.as_str()), (40 * 30, "40x30"));
    // The course camera keeps a pixel's angle: the 40 x 30 view is the middle of the 800 x
    // 600 one, where the box is, so more of its rays hit.
    let share = |r: &BenchRecord| r.hits as f64 / r.rays as f64;
    assert!(share(&small) > share(&standard), "{small:?} {standard:?}");
    let base = edited(&dir, "standard.jsonl", &[standard], |_| {});
    let out = bench(&["--ray-set", "primary", "--frame", "40x30", "--baseline", &base]);
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(
        regression_lines(&out),
        ["regression: scene cornell.dae, ray set primary, traversal single: missing from this run"]
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
