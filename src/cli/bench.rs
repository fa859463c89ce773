//! `pathtracer bench`: the standard ray benchmark of `../shared/docs/BENCHMARK.md`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::Args;

use super::{parse_byte_count, parse_in_range, parse_number};
use pathtracer::accel::{Accel, AccelKind};
use pathtracer::bench::{self, BenchRecord, BenchResult, Frame, RaySet, TimedBy, Traversal};
use pathtracer::staged::Outputs;
use pathtracer::{bail, scene, Error, Result};

/// `pathtracer bench`.
#[derive(Args, Debug, Clone)]
#[command(
    about = "Trace the standard ray sets of BENCHMARK.md and report throughput and exact counters",
    long_about = "Traces the standard ray sets (BENCHMARK.md) and reports throughput, exact node \
and triangle test counts per ray, and the checksums hits and t_sum. Spheres are left out.",
    after_help = "Primary rays go in 2x2, 4x2, 4x4 pixel blocks for the packet traversals."
)]
pub struct BenchArgs {
    /// The COLLADA scene
    #[arg(value_name = "SCENE.dae")]
    scene: Option<PathBuf>,
    /// One set (default: all three); shadow rays are any-hit
    #[arg(long, value_name = "primary|diffuse|shadow",
          value_parser = |s: &str| RaySet::parse(s).map_err(|e| e.context("bench: --ray-set")))]
    ray_set: Option<RaySet>,
    /// Trace the rays of FILE (32-byte records) instead; needs --ray-set
    #[arg(long, value_name = "FILE")]
    rays_in: Option<PathBuf>,
    /// Also write PREFIX.{primary,diffuse,shadow}.rays
    #[arg(long, value_name = "PREFIX")]
    rays_out: Option<PathBuf>,
    /// Primary rays through the pixel centres of a WxH image instead of the standard 800x600
    /// (e.g. a render's -r 400 300, whose camera rays all hit the Cornell box: the course
    /// camera keeps a pixel's angle, so a smaller image is a tighter view). With --rays-in, the
    /// frame of a primary ray file, for the packets' pixel blocks
    #[arg(long, value_name = "WxH", default_value = "800x600",
          value_parser = |s: &str| Frame::parse(s).map_err(|e| e.context("bench: --frame")))]
    frame: Frame,
    /// single|packet4|packet8|packet16, repeatable (default: all four; packet16 is 16 rays in
    /// one 512-bit register where the CPU has AVX-512, two 8-wide halves below it)
    #[arg(long = "traversal", value_name = "KIND",
          value_parser = |s: &str| Traversal::parse(s).map_err(|e| e.context("bench: --traversal")))]
    traversals: Vec<Traversal>,
    /// Worker threads
    #[arg(long, value_name = "N", default_value = "1",
          value_parser = |s: &str| parse_in_range("--threads", s, 1, 1024).map(|n| n as usize))]
    threads: usize,
    /// Packets hand interior subtrees entered by <= N lanes to single rays (default: the tuned
    /// value; for measuring it)
    #[arg(long = "packet-fallback", value_name = "N",
          value_parser = |s: &str| parse_in_range("--packet-fallback", s, 0, 8))]
    fallback: Option<u32>,
    /// Timed repetitions after a warm-up; the best counts. A set under 400k rays is traced
    /// ceil(400k / rays) times per repetition, and a repetition whose threads traced for less
    /// than 97% of threads x its wall time (taken away by other processes, or idle before or
    /// after their share of the rays) is made again (at most 2N in all), as the peer harness
    /// does
    #[arg(long, value_name = "N", default_value = "5",
          value_parser = |s: &str| parse_in_range("--reps", s, 1, 10_000).map(|n| n as usize))]
    reps: usize,
    /// Builds of the structure; `build_ms` is the fastest (the peer harness's rule: best of its
    /// `--build-reps`, 3 by default). The first build also pays for fresh memory and cold
    /// caches, which a render pays once
    #[arg(long, value_name = "N", default_value = "3",
          value_parser = |s: &str| parse_in_range("--build-reps", s, 1, 1000).map(|n| n as usize))]
    build_reps: usize,
    /// One JSON object per line on stdout (the table goes to stderr)
    #[arg(long)]
    json: bool,
    /// Compare the exact counters and checksums with FILE (written by --json): each regression
    /// on one line, then exit code 1
    #[arg(long, value_name = "FILE")]
    baseline: Option<PathBuf>,
    /// With --baseline: node and triangle tests may rise, and hits, t_sum and rays move, by at
    /// most PCT percent [default: 0, exact]
    #[arg(long = "tolerance", value_name = "PCT", value_parser = parse_percent)]
    tolerance_pct: Option<f64>,
    /// Refuse a scene file larger than N bytes [default: 1073741824, 1 GiB]
    #[arg(long, value_name = "N",
          value_parser = |s: &str| parse_byte_count("--max-scene-bytes", s))]
    max_scene_bytes: Option<u64>,
}

pub fn run(a: BenchArgs) -> Result<()> {
    let (a, scene_path) = check(a)?;
    // A bad baseline fails before the work, not after it.
    let baseline = a.baseline.as_deref().map(read_baseline).transpose()?;
    let max_bytes = a.max_scene_bytes.unwrap_or(scene::collada::DEFAULT_MAX_SCENE_BYTES);
    let loaded = scene::collada::load_with_limit(&scene_path, max_bytes)?;
    let scene = bench::triangles_only(&loaded);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads)
        .build()
        .map_err(|e| Error::new(format!("cannot start {} threads: {e}", a.threads)))?;
    // The build runs on the same `--threads` workers as the trace, so build_ms at 1 thread is
    // a single-threaded build.
    Accel::check_limits(&scene).map_err(|e| e.in_scene(Some(&scene_path)))?;
    let (accel, build_ms) = pool.install(|| best_build(&scene, a.build_reps));

    let sets: Vec<(RaySet, Vec<pathtracer::math::Ray>)> = match (&a.rays_in, a.ray_set) {
        (Some(path), Some(set)) => vec![(set, bench::read_rays(path)?)],
        (Some(_), None) => {
            bail!("--rays-in needs --ray-set: a ray file does not say what its rays want")
        }
        (None, only) => {
            let generated = bench::generate_ray_sets_in(&scene, &accel, a.frame);
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

    let name = scene_path
        .file_name()
        .map_or_else(|| scene_path.display().to_string(), |n| n.to_string_lossy().into_owned());
    let mut results = Vec::new();
    for (set, rays) in &sets {
        for &traversal in &a.traversals {
            let ordered = bench::packet_order(*set, traversal, rays, a.frame);
            let traced = ordered.as_deref().unwrap_or(rays);
            let (timing, totals) =
                bench::time_trace(&accel, traced, *set, traversal, a.fallback, &pool, a.reps);
            let r = BenchResult {
                scene: name.clone(),
                triangles: scene.triangles.len(),
                ray_set: *set,
                rays: rays.len(),
                threads: a.threads,
                traversal,
                frame: a.frame,
                build_ms,
                timing,
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
        report += &compare_with_baseline(base, path, &results, a.tolerance_pct.unwrap_or(0.0));
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
            "{:<18} {:>9} {:<8} {:>7} {:>3} {:<8} {:>9.1} {:>9} {:>10.2} {:>9.2} {:>8} {:>16.4} {:>6.1}\n",
            r.scene,
            r.triangles,
            r.ray_set.name(),
            r.rays,
            r.threads,
            r.traversal.name(),
            r.build_ms,
            mrays_cell(r),
            r.node_tests_per_ray(),
            r.triangle_tests_per_ray(),
            r.totals.hits,
            r.totals.t_sum,
            r.bytes_per_triangle
        );
    }
    if results.iter().any(|r| r.timing.timed_by == TimedBy::Cpu) {
        s += "* CPU-time estimate: fewer repetitions than --reps got their threads' share of the \
              CPU (the peer harness's rule)\n";
    }
    if let Some(r) = results.iter().find(|r| r.frame != Frame::STANDARD) {
        s += &format!("frame: {} (primary rays; the standard sets use 800x600)\n", r.frame.name());
    }
    let isa = pathtracer::simd::isa::Isa::compiled();
    s += &format!("isa: {isa} (the {} build)\n", isa.target_cpu());
    s
}

/// A result's Mrays/s, marked `*` when it is the CPU-time estimate (the peer harness's mark).
fn mrays_cell(r: &BenchResult) -> String {
    let mark = if r.timing.timed_by == TimedBy::Cpu { "*" } else { "" };
    format!("{:.2}{mark}", r.mrays_per_s())
}

fn parse_percent(text: &str) -> Result<f64> {
    let pct: f64 = parse_number("bench: --tolerance", text)?;
    if !(pct.is_finite() && pct >= 0.0) {
        bail!("bench: --tolerance: expected a percentage of 0 or more, got '{text}'");
    }
    Ok(pct)
}

/// The structure of `scene` from the last of `reps` builds, and the fastest build's time in
/// milliseconds.
fn best_build(scene: &scene::Scene, reps: usize) -> (Accel, f64) {
    let (accel, best) = best_of(reps, || Accel::build(scene, AccelKind::Bvh), Accel::build_time);
    (accel, best.as_secs_f64() * 1e3)
}

/// The last of `reps` (at least one) results of `make`, and the least of their `time`s. Each
/// result is dropped before the next is made: one is alive at a time.
fn best_of<T>(
    reps: usize,
    mut make: impl FnMut() -> T,
    time: impl Fn(&T) -> Duration,
) -> (T, Duration) {
    let mut last = make();
    let mut best = time(&last);
    for _ in 1..reps {
        drop(last);
        last = make();
        best = best.min(time(&last));
    }
    (last, best)
}

/// The checks of combinations; the scene's path.
fn check(mut a: BenchArgs) -> Result<(BenchArgs, PathBuf)> {
    let scene = a
        .scene
        .take()
        .ok_or_else(|| Error::new("bench: no scene file given (see pathtracer bench --help)"))?;
    if a.rays_in.is_some() && a.rays_out.is_some() {
        bail!("bench: --rays-out writes generated rays; it cannot be combined with --rays-in");
    }
    if a.tolerance_pct.is_some() && a.baseline.is_none() {
        bail!("bench: --tolerance needs --baseline");
    }
    if a.traversals.is_empty() {
        a.traversals = Traversal::ALL.to_vec();
    }
    Ok((a, scene))
}

#[cfg(test)]
mod tests {
    use super::best_of;
    use std::cell::Cell;
    use std::time::Duration;

    /// A result that counts how many of its kind are alive.
    struct Counted<'a> {
        alive: &'a Cell<u32>,
        ms: u64,
    }

    impl Drop for Counted<'_> {
        fn drop(&mut self) {
            self.alive.set(self.alive.get() - 1);
        }
    }

    #[test]
    fn best_of_keeps_the_last_result_and_the_least_time_with_one_alive() {
        let (alive, most) = (Cell::new(0), Cell::new(0));
        let mut times = [5u64, 2, 7, 3].into_iter();
        let make = || {
            alive.set(alive.get() + 1);
            most.set(most.get().max(alive.get()));
            Counted { alive: &alive, ms: times.next().unwrap() }
        };
        let (last, best) = best_of(4, make, |c| Duration::from_millis(c.ms));
        assert_eq!((last.ms, best), (3, Duration::from_millis(2)));
        assert_eq!((alive.get(), most.get()), (1, 1));
        let (one, best) = best_of(1, || 9u64, |&ms| Duration::from_millis(ms));
        assert_eq!((one, best), (9, Duration::from_millis(9)));
    }
}
