//! `pathtracer bench`: the standard ray benchmark of `../shared/docs/BENCHMARK.md`.

use std::path::{Path, PathBuf};

use super::{parse_byte_count, parse_in_range, parse_number};
use pathtracer::accel::{Accel, AccelKind};
use pathtracer::bench::{self, BenchRecord, BenchResult, RaySet, Traversal};
use pathtracer::staged::Outputs;
use pathtracer::{bail, scene, Error, Result};

const USAGE: &str = "\
Usage: pathtracer bench SCENE.dae [OPTIONS]

Traces the standard ray sets (BENCHMARK.md) and reports throughput, exact node and triangle
test counts per ray, and the checksums hits and t_sum. Spheres are left out.

Options:
  --ray-set primary|diffuse|shadow   one set (default: all three); shadow rays are any-hit
  --rays-in FILE        trace the rays of FILE (32-byte records) instead; needs --ray-set
  --rays-out PREFIX     also write PREFIX.{primary,diffuse,shadow}.rays
  --traversal single|packet4|packet8|packet16   (default: all four; packet16 is 16 rays
                        as two 8-wide halves; primary rays go in 2x2, 4x2, 4x4 pixel blocks)
  --threads N           worker threads (default 1)
  --packet-fallback N   packets hand subtrees entered by <= N lanes to single rays
                        (default: the tuned value; for measuring it)
  --reps N              timed repetitions after a warm-up; the best counts (default 5)
  --json                one JSON object per line on stdout (the table goes to stderr)
  --baseline FILE       compare the exact counters and checksums with FILE (written by
                        --json): each regression on one line, then exit code 1
  --tolerance PCT       with --baseline: node and triangle tests may rise, and hits, t_sum
                        and rays move, by at most PCT percent (default 0: exact)
  --max-scene-bytes N   refuse a scene file larger than N bytes (default 1073741824, 1 GiB)";

struct BenchArgs {
    scene: PathBuf,
    ray_set: Option<RaySet>,
    rays_in: Option<PathBuf>,
    rays_out: Option<PathBuf>,
    traversals: Vec<Traversal>,
    threads: usize,
    reps: usize,
    json: bool,
    fallback: Option<u32>,
    baseline: Option<PathBuf>,
    tolerance_pct: f64,
    max_scene_bytes: u64,
}

pub fn run(args: &[String]) -> Result<()> {
    if args.iter().any(|a| a == "-h" || a == "--help") {
        return outln!("{USAGE}");
    }
    let a = parse(args)?;
    // A bad baseline fails before the work, not after it.
    let baseline = a.baseline.as_deref().map(read_baseline).transpose()?;
    let loaded = scene::collada::load_with_limit(&a.scene, a.max_scene_bytes)?;
    let scene = bench::triangles_only(&loaded);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads)
        .build()
        .map_err(|e| Error::new(format!("cannot start {} threads: {e}", a.threads)))?;
    // The build runs on the same `--threads` workers as the trace, so build_ms at 1 thread is
    // a single-threaded build.
    Accel::check_limits(&scene).map_err(|e| e.in_scene(Some(&a.scene)))?;
    let accel = pool.install(|| Accel::build(&scene, AccelKind::Bvh));
    let build_ms = accel.build_time().as_secs_f64() * 1e3;

    let sets: Vec<(RaySet, Vec<pathtracer::math::Ray>)> = match (&a.rays_in, a.ray_set) {
        (Some(path), Some(set)) => vec![(set, bench::read_rays(path)?)],
        (Some(_), None) => {
            bail!("--rays-in needs --ray-set: a ray file does not say what its rays want")
        }
        (None, only) => {
            let generated = bench::generate_ray_sets(&scene, &accel);
            if let Some(prefix) = &a.rays_out {
                // All three files or none.
                let mut outputs = Outputs::new();
                for set in RaySet::ALL {
                    bench::stage_rays(
                        &mut outputs,
                        &rays_out_path(prefix, set),
                        generated.get(set),
                    )?;
                }
                outputs.commit()?;
            }
            RaySet::ALL
                .into_iter()
                .filter(|s| only.is_none_or(|o| o == *s))
                .map(|s| (s, generated.get(s).to_vec()))
                .collect()
        }
    };

    let name = a
        .scene
        .file_name()
        .map_or_else(|| a.scene.display().to_string(), |n| n.to_string_lossy().into_owned());
    let mut results = Vec::new();
    for (set, rays) in &sets {
        for &traversal in &a.traversals {
            let ordered = bench::packet_order(*set, traversal, rays);
            let traced = ordered.as_deref().unwrap_or(rays);
            let (best, totals) =
                bench::time_trace(&accel, traced, *set, traversal, a.fallback, &pool, a.reps);
            let r = BenchResult {
                scene: name.clone(),
                triangles: scene.triangles.len(),
                ray_set: *set,
                rays: rays.len(),
                threads: a.threads,
                traversal,
                build_ms,
                mrays_per_s: rays.len() as f64 / best.as_secs_f64().max(1e-12) / 1e6,
                totals,
                bytes_per_triangle: accel.memory_bytes() as f64
                    / scene.triangles.len().max(1) as f64,
            };
            if a.json {
                outln!("{}", r.record().to_json())?;
            }
            results.push(r);
        }
    }
    let mut report = format_table(&results);
    if let (Some(base), Some(path)) = (&baseline, &a.baseline) {
        report += &compare_with_baseline(base, path, &results, a.tolerance_pct);
    }
    if a.json {
        super::write_stderr(format_args!("{report}"));
        Ok(())
    } else {
        out!("{report}")
    }
}

fn read_baseline(path: &Path) -> Result<Vec<BenchRecord>> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::new(format!("bench: --baseline {name}: {e}")))?;
    let records =
        BenchRecord::parse_lines(&text, &name).map_err(|e| e.context("bench: --baseline"))?;
    if records.is_empty() {
        bail!("bench: --baseline {name}: no records (write one with bench --json)");
    }
    Ok(records)
}

/// One line per regression (and the exit code 1 through [`super::fail_check`]), or one line
/// saying the run matches.
fn compare_with_baseline(
    baseline: &[BenchRecord],
    path: &Path,
    results: &[BenchResult],
    tolerance_pct: f64,
) -> String {
    let run: Vec<BenchRecord> = results.iter().map(BenchResult::record).collect();
    let found = bench::record::regressions(baseline, &run, tolerance_pct);
    if found.is_empty() {
        return format!(
            "baseline: {} records match {} (tolerance {tolerance_pct}%)\n",
            baseline.len(),
            path.display()
        );
    }
    super::fail_check();
    found.iter().map(|r| format!("regression: {r}\n")).collect()
}

/// `PREFIX.primary.rays` and so on.
fn rays_out_path(prefix: &Path, set: RaySet) -> PathBuf {
    PathBuf::from(format!("{}.{}.rays", prefix.display(), set.name()))
}

fn format_table(results: &[BenchResult]) -> String {
    let mut s = format!(
        "{:<18} {:>9} {:<8} {:>7} {:>3} {:<8} {:>9} {:>9} {:>10} {:>9} {:>8} {:>16} {:>6}\n",
        "scene",
        "tris",
        "set",
        "rays",
        "thr",
        "trav",
        "build ms",
        "Mrays/s",
        "nodes/ray",
        "tris/ray",
        "hits",
        "t_sum",
        "B/tri"
    );
    for r in results {
        s += &format!(
            "{:<18} {:>9} {:<8} {:>7} {:>3} {:<8} {:>9.1} {:>9.2} {:>10.2} {:>9.2} {:>8} {:>16.4} {:>6.1}\n",
            r.scene,
            r.triangles,
            r.ray_set.name(),
            r.rays,
            r.threads,
            r.traversal.name(),
            r.build_ms,
            r.mrays_per_s,
            r.node_tests_per_ray(),
            r.triangle_tests_per_ray(),
            r.totals.hits,
            r.totals.t_sum,
            r.bytes_per_triangle
        );
    }
    s
}

fn parse_percent(text: &str) -> Result<f64> {
    let pct: f64 = parse_number("bench: --tolerance", text)?;
    if !(pct.is_finite() && pct >= 0.0) {
        bail!("bench: --tolerance: expected a percentage of 0 or more, got '{text}'");
    }
    Ok(pct)
}

fn parse(args: &[String]) -> Result<BenchArgs> {
    let mut a = BenchArgs {
        scene: PathBuf::new(),
        ray_set: None,
        rays_in: None,
        rays_out: None,
        traversals: Vec::new(),
        threads: 1,
        reps: 5,
        json: false,
        fallback: None,
        baseline: None,
        tolerance_pct: 0.0,
        max_scene_bytes: scene::collada::DEFAULT_MAX_SCENE_BYTES,
    };
    let mut tolerance = None;
    let mut scene = None;
    let mut it = args.iter().map(String::as_str);
    while let Some(arg) = it.next() {
        let mut value = |name: &str| {
            it.next().ok_or_else(|| Error::new(format!("bench: {name} needs a value")))
        };
        match arg {
            "--ray-set" => a.ray_set = Some(RaySet::parse(value("--ray-set")?)?),
            "--rays-in" => a.rays_in = Some(PathBuf::from(value("--rays-in")?)),
            "--rays-out" => a.rays_out = Some(PathBuf::from(value("--rays-out")?)),
            "--traversal" => {
                a.traversals.push(Traversal::parse(value("--traversal")?)?);
            }
            "--threads" => {
                a.threads = parse_in_range("--threads", value("--threads")?, 1, 1024)? as usize
            }
            "--reps" => a.reps = parse_in_range("--reps", value("--reps")?, 1, 10_000)? as usize,
            "--json" => a.json = true,
            "--max-scene-bytes" => {
                a.max_scene_bytes =
                    parse_byte_count("--max-scene-bytes", value("--max-scene-bytes")?)?
            }
            "--baseline" => a.baseline = Some(PathBuf::from(value("--baseline")?)),
            "--tolerance" => tolerance = Some(parse_percent(value("--tolerance")?)?),
            "--packet-fallback" => {
                a.fallback =
                    Some(parse_in_range("--packet-fallback", value("--packet-fallback")?, 0, 8)?
                        as u32)
            }
            s if s.starts_with('-') && s.len() > 1 => {
                bail!("bench: unknown option '{s}' (see pathtracer bench --help)")
            }
            path => {
                if let Some(first) = scene.replace(PathBuf::from(path)) {
                    bail!("bench: more than one scene given: '{}' and '{path}'", first.display());
                }
            }
        }
    }
    a.scene = scene
        .ok_or_else(|| Error::new("bench: no scene file given (see pathtracer bench --help)"))?;
    if a.rays_in.is_some() && a.rays_out.is_some() {
        bail!("bench: --rays-out writes generated rays; it cannot be combined with --rays-in");
    }
    match (tolerance, &a.baseline) {
        (Some(_), None) => bail!("bench: --tolerance needs --baseline"),
        (Some(t), Some(_)) => a.tolerance_pct = t,
        (None, _) => {}
    }
    if a.traversals.is_empty() {
        a.traversals = Traversal::ALL.to_vec();
    }
    Ok(a)
}
