//! The standard ray benchmark (`../shared/docs/BENCHMARK.md`): deterministic ray sets, the
//! shared ray-file format, and a timed trace loop with exact counters and checksums.

use std::io::Write;
use std::path::Path;
use std::time::Duration;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

pub mod ray_sets;
pub mod record;
pub mod timing;
pub use ray_sets::{
    generate_ray_sets, generate_ray_sets_in, packet_order, Frame, RaySet, RaySets, HEIGHT,
    RAY_SEED, WIDTH,
};
pub use record::BenchRecord;
pub use timing::{TimedBy, Timing};

use crate::accel::traverse_packet::default_fallback;
use crate::accel::{Accel, TraceStats};
use crate::math::{Hit, Ray, Vec3};
use crate::scene::Scene;

/// The scene's triangles only: spheres are left out of the ray benchmark.
pub fn triangles_only(scene: &Scene) -> Scene {
    Scene { spheres: Vec::new(), ..scene.clone() }
}

/// Bytes per ray record: `ox oy oz dx dy dz tmin tmax` as little-endian f32.
const RECORD: usize = 32;

/// Writes rays in the shared ray-file format, atomically (temp file + rename).
pub fn write_rays(path: &Path, rays: &[Ray]) -> crate::Result<()> {
    let mut outputs = crate::staged::Outputs::new();
    stage_rays(&mut outputs, path, rays)?;
    outputs.commit()
}

/// [`write_rays`] as one file of a set written together.
pub fn stage_rays(
    outputs: &mut crate::staged::Outputs,
    path: &Path,
    rays: &[Ray],
) -> crate::Result<()> {
    outputs.stage(path, |w| {
        for r in rays {
            for f in r.record() {
                w.write_all(&f.to_le_bytes())?;
            }
        }
        Ok::<(), std::io::Error>(())
    })
}

/// The largest ray file `read_rays` accepts: 2^26 rays (2 GiB), eight times the largest
/// standard set, so that a device or a pipe (`/dev/zero`) cannot grow without bound.
pub const MAX_RAY_FILE_BYTES: u64 = (RECORD as u64) << 26;

/// Reads a ray file; every record must be whole and every origin and direction finite.
pub fn read_rays(path: &Path) -> crate::Result<Vec<Ray>> {
    let too_large = || {
        let message = format!("larger than the ray file limit of {MAX_RAY_FILE_BYTES} bytes");
        crate::Error::new(message).in_scene(Some(path))
    };
    let bytes = crate::error::read_capped(path, MAX_RAY_FILE_BYTES, too_large)?;
    if bytes.len() % RECORD != 0 {
        crate::bail!(
            "{}: {} bytes is not a whole number of 32-byte ray records",
            path.display(),
            bytes.len()
        );
    }
    let f = |b: &[u8], i: usize| {
        f32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]])
    };
    bytes
        .chunks_exact(RECORD)
        .enumerate()
        .map(|(i, b)| {
            let ray = Ray::segment(
                Vec3::new(f(b, 0), f(b, 1), f(b, 2)),
                Vec3::new(f(b, 3), f(b, 4), f(b, 5)),
                f(b, 6),
                f(b, 7),
            );
            if !ray.origin.is_finite()
                || !ray.dir.is_finite()
                || ray.t_min.is_nan()
                || ray.t_max.is_nan()
            {
                crate::bail!(
                    "{}: ray {i} has a non-finite origin, direction or interval",
                    path.display()
                );
            }
            Ok(ray)
        })
        .collect()
}

/// How rays are traversed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Traversal {
    /// One ray at a time (what `Accel::intersect` does).
    Single,
    /// 4 rays per packet (`wide::f32x4`).
    Packet4,
    /// 8 rays per packet (`wide::f32x8`).
    Packet8,
    /// 16 rays per packet (`simd::F32x16`: one 512-bit register in AVX-512 builds, two 8-wide
    /// halves below it).
    Packet16,
}

impl Traversal {
    /// The traversals a benchmark runs by default, and every one `--traversal` accepts.
    pub const ALL: [Traversal; 4] =
        [Traversal::Single, Traversal::Packet4, Traversal::Packet8, Traversal::Packet16];

    /// The traversal's name in records and `--traversal`.
    pub fn name(self) -> &'static str {
        match self {
            Traversal::Single => "single",
            Traversal::Packet4 => "packet4",
            Traversal::Packet8 => "packet8",
            Traversal::Packet16 => "packet16",
        }
    }

    /// Packet width (1 for single rays).
    pub fn width(self) -> usize {
        match self {
            Traversal::Single => 1,
            Traversal::Packet4 => 4,
            Traversal::Packet8 => 8,
            Traversal::Packet16 => 16,
        }
    }

    /// The traversal called `s` (as [`name`](Traversal::name) spells it); anything else is
    /// an error listing the names.
    pub fn parse(s: &str) -> crate::Result<Traversal> {
        Traversal::ALL.into_iter().find(|t| t.name() == s).ok_or_else(|| {
            crate::Error::new(format!(
                "unknown traversal '{s}' (expected single, packet4, packet8 or packet16)"
            ))
        })
    }
}

/// What one traversal of one ray set produced: checksums and exact counters.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TraceTotals {
    /// Closest-hit sets: rays that hit. Shadow set: rays that are occluded.
    pub hits: u64,
    /// Sum of hit distances (0 for the shadow set), accumulated in f64 in ray order.
    pub t_sum: f64,
    /// 64-bit FNV-1a over every ray's exact answer in trace order (`BenchRecord::answers`).
    pub answers: u64,
    /// The exact work counters of the traversal.
    pub stats: TraceStats,
}

/// Rays per unit of parallel work, as the peer harness shares its rays out (its `CHUNK`): a
/// multiple of 16, so packets are whole, and small enough that the last chunk keeps one of two
/// threads waiting only briefly.
const CHUNK: usize = 512;

/// Every ray's answer, in buffers allocated before the clock starts (as the peer harness
/// allocates its output array before timing): closest hits for `primary` / `diffuse`,
/// occlusion for `shadow`.
pub(crate) struct TraceOutputs {
    hits: Vec<Option<Hit>>,
    blocked: Vec<bool>,
}

impl TraceOutputs {
    /// Buffers for `rays` answers of `set`: occlusion flags for the shadow set, closest hits
    /// for the others.
    pub(crate) fn new(set: RaySet, rays: usize) -> TraceOutputs {
        let (h, b) = if set.is_occlusion() { (0, rays) } else { (rays, 0) };
        TraceOutputs { hits: vec![None; h], blocked: vec![false; b] }
    }

    /// The checksums of the last trace and its counters: hits (occluded rays for `shadow`)
    /// and the sum of hit distances in ray order, in f64.
    pub(crate) fn totals(&self, stats: TraceStats) -> TraceTotals {
        let mut t = TraceTotals { stats, ..TraceTotals::default() };
        t.hits = self.blocked.iter().filter(|&&b| b).count() as u64;
        for h in self.hits.iter().flatten() {
            t.hits += 1;
            t.t_sum += h.t as f64;
        }
        let mut digest = Fnv1a::default();
        for &b in &self.blocked {
            digest.word(b as u32);
        }
        for h in &self.hits {
            match h {
                Some(h) => [1, h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim]
                    .into_iter()
                    .for_each(|w| digest.word(w)),
                None => digest.word(0),
            }
        }
        t.answers = digest.0;
        t
    }

    /// The answer buffers cut into `CHUNK`-sized jobs beside their rays, each behind its own
    /// lock so that whichever worker claims a job can fill it. Made by each trace, inside the
    /// clock: one allocation of a few hundred small entries, where the harness shares its one
    /// output array through a raw pointer instead.
    fn jobs<'a>(&'a mut self, rays: &'a [Ray]) -> Vec<Mutex<Job<'a>>> {
        let hits = self.hits.chunks_mut(CHUNK).map(Answers::Hits);
        let blocked = self.blocked.chunks_mut(CHUNK).map(Answers::Blocked);
        rays.chunks(CHUNK).zip(hits.chain(blocked)).map(|(r, a)| Mutex::new((r, a))).collect()
    }
}

/// A chunk of rays and the slice its answers go to.
type Job<'a> = (&'a [Ray], Answers<'a>);

/// Where a chunk's answers go.
enum Answers<'a> {
    Hits(&'a mut [Option<Hit>]),
    Blocked(&'a mut [bool]),
}

/// 64-bit FNV-1a, fed 32-bit words (little-endian bytes).
struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Fnv1a {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    fn word(&mut self, w: u32) {
        for b in w.to_le_bytes() {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

/// Traces `rays` once on every worker of `pool` (made by the caller), writing every ray's
/// answer to `out` (made by `TraceOutputs::new` for this set and ray count); returns the
/// counters and the CPU time the workers spent tracing (`None` where a thread's CPU time cannot
/// be read). Only this is timed: the checksums come from `out` afterwards.
///
/// The rays are shared out as the peer harness shares them: every worker takes the next
/// `CHUNK` from a common counter until none is left, and its CPU time is read when it starts
/// and when it runs out of chunks, so the time counted is tracing, not waiting for a chunk.
/// `fallback`: the packets' single-ray fallback threshold (`None`: the default of the width).
pub(crate) fn trace_once(
    accel: &Accel,
    rays: &[Ray],
    traversal: Traversal,
    fallback: Option<u32>,
    pool: &rayon::ThreadPool,
    out: &mut TraceOutputs,
) -> (TraceStats, Option<Duration>) {
    let fallback = fallback.unwrap_or(default_fallback(traversal.width()));
    let jobs = out.jobs(rays);
    let next = AtomicUsize::new(0);
    let per_worker = pool.broadcast(|_| {
        let start = timing::thread_cpu_time();
        let mut stats = TraceStats::default();
        while let Some(job) = jobs.get(next.fetch_add(1, Ordering::Relaxed)) {
            // Each job is claimed once, so its lock is never contended (nor poisoned: a
            // panicking trace ends the benchmark).
            let mut job = job.lock().unwrap_or_else(|e| e.into_inner());
            let (r, answers) = &mut *job;
            let s = match answers {
                Answers::Hits(h) => intersect_chunk(accel, r, traversal, fallback, h),
                Answers::Blocked(b) => occluded_chunk(accel, r, traversal, fallback, b),
            };
            stats.add(&s);
        }
        (stats, timing::thread_cpu_time_since(start))
    });
    let mut stats = TraceStats::default();
    per_worker.iter().for_each(|(s, _)| stats.add(s));
    (stats, per_worker.iter().map(|&(_, cpu)| cpu).sum())
}

// Packets take the rays in slice order, W at a time; CHUNK is a multiple of 16, so only the
// set's last packet can be partly filled.
const _: () = assert!(CHUNK.is_multiple_of(16));

fn occluded_chunk(
    accel: &Accel,
    rays: &[Ray],
    traversal: Traversal,
    fallback: u32,
    blocked: &mut [bool],
) -> TraceStats {
    let mut stats = TraceStats::default();
    let s = &mut stats;
    match traversal {
        Traversal::Single => accel.occluded_stream(rays, blocked, s),
        Traversal::Packet4 => accel.occluded_packets_with::<4>(rays, fallback, blocked, s),
        Traversal::Packet8 => accel.occluded_packets_with::<8>(rays, fallback, blocked, s),
        Traversal::Packet16 => accel.occluded_packets_with::<16>(rays, fallback, blocked, s),
    }
    stats
}

fn intersect_chunk(
    accel: &Accel,
    rays: &[Ray],
    traversal: Traversal,
    fallback: u32,
    hits: &mut [Option<Hit>],
) -> TraceStats {
    let mut stats = TraceStats::default();
    let s = &mut stats;
    match traversal {
        Traversal::Single => accel.intersect_stream(rays, hits, s),
        Traversal::Packet4 => accel.intersect_packets_with::<4>(rays, fallback, hits, s),
        Traversal::Packet8 => accel.intersect_packets_with::<8>(rays, fallback, hits, s),
        Traversal::Packet16 => accel.intersect_packets_with::<16>(rays, fallback, hits, s),
    }
    stats
}

/// One benchmark measurement, in the units of BENCHMARK.md.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchResult {
    /// The scene's name (its file name).
    pub scene: String,
    /// Triangles in the scene.
    pub triangles: usize,
    /// The ray set traced.
    pub ray_set: RaySet,
    /// Rays in the set.
    pub rays: usize,
    /// Worker threads for the build and the trace.
    pub threads: usize,
    /// How the rays were traversed.
    pub traversal: Traversal,
    /// The frame of the primary rays (`Frame`).
    pub frame: Frame,
    /// Build time of the acceleration structure, in milliseconds.
    pub build_ms: f64,
    /// How the trace was timed (`timing`); `mrays_per_s` follows from it.
    pub timing: Timing,
    /// Checksums and exact counters of the trace.
    pub totals: TraceTotals,
    /// Bytes of the acceleration structure (`Accel::memory_bytes`) per triangle.
    pub bytes_per_triangle: f64,
}

impl BenchResult {
    /// Millions of rays per second, by the peer harness's rule (`timing`).
    pub fn mrays_per_s(&self) -> f64 {
        mrays(self.rays, self.timing.best)
    }

    /// Millions of rays per second of the best wall time of any repetition.
    pub fn wall_mrays_per_s(&self) -> f64 {
        mrays(self.rays, self.timing.best_wall)
    }

    /// Ray-box tests per ray of the set.
    pub fn node_tests_per_ray(&self) -> f64 {
        self.totals.stats.node_tests as f64 / self.rays.max(1) as f64
    }

    /// Ray-triangle tests per ray of the set.
    pub fn triangle_tests_per_ray(&self) -> f64 {
        self.totals.stats.triangle_tests as f64 / self.rays.max(1) as f64
    }

    /// The record `bench --json` writes for this result.
    pub fn record(&self) -> BenchRecord {
        BenchRecord {
            scene: self.scene.clone(),
            triangles: self.triangles,
            ray_set: self.ray_set.name().into(),
            rays: self.rays,
            threads: self.threads,
            traversal: self.traversal.name().into(),
            frame: self.frame.name(),
            build_ms: self.build_ms,
            mrays_per_s: self.mrays_per_s(),
            timed_by: self.timing.timed_by.name().into(),
            wall_mrays_per_s: self.wall_mrays_per_s(),
            clean_reps: self.timing.clean,
            reps_made: self.timing.attempts,
            node_tests_per_ray: self.node_tests_per_ray(),
            triangle_tests_per_ray: self.triangle_tests_per_ray(),
            hits: self.totals.hits,
            t_sum: self.totals.t_sum,
            bytes_per_triangle: self.bytes_per_triangle,
            node_tests: self.totals.stats.node_tests,
            triangle_tests: self.totals.stats.triangle_tests,
            answers: format!("{:016x}", self.totals.answers),
            isa: crate::simd::isa::Isa::compiled().name().into(),
        }
    }
}

/// Millions of `rays` per `time`.
fn mrays(rays: usize, time: Duration) -> f64 {
    rays as f64 / time.as_secs_f64().max(1e-12) / 1e6
}

/// Rays one timed repetition traces at least: a smaller set is traced several times over per
/// repetition, as the peer harness does (`ceil(400k / n)` times), so that a thread pool's
/// wake-up and the last chunk's wait weigh the same in both figures. On two threads a
/// 100k-ray set takes about 5 ms, and those fixed costs were a tenth of it.
const RAYS_PER_REP: usize = 400_000;

/// How many times one timed repetition traces a set of `rays` rays.
fn traces_per_rep(rays: usize) -> usize {
    if rays == 0 {
        return 1;
    }
    RAYS_PER_REP.div_ceil(rays)
}

/// Traces once to warm caches, then repeats the trace under the peer harness's rule
/// (`timing::time_repetitions`: `reps` clean repetitions wanted, at most twice as many made);
/// returns the timing of one trace and the totals (identical every repetition: the counters
/// are deterministic). The clock runs around `trace_once` alone: output buffers are allocated
/// before it and checksums summed after it, as the peer harness times its kernels; a set under
/// `RAYS_PER_REP` rays is traced `traces_per_rep` times per repetition, and the time is that
/// repetition's mean per trace.
pub fn time_trace(
    accel: &Accel,
    rays: &[Ray],
    set: RaySet,
    traversal: Traversal,
    fallback: Option<u32>,
    pool: &rayon::ThreadPool,
    reps: usize,
) -> (Timing, TraceTotals) {
    let mut out = TraceOutputs::new(set, rays.len());
    let (stats, _) = trace_once(accel, rays, traversal, fallback, pool, &mut out);
    let totals = out.totals(stats);
    let times = traces_per_rep(rays.len());
    let mut timing = timing::time_repetitions(pool.current_num_threads(), reps, || {
        (0..times)
            .map(|_| {
                let (again, cpu) = trace_once(accel, rays, traversal, fallback, pool, &mut out);
                debug_assert_eq!(again, stats);
                cpu
            })
            .sum()
    });
    timing.best /= times as u32;
    timing.best_wall /= times as u32;
    (timing, totals)
}

#[cfg(test)]
mod tests {
    use super::traces_per_rep;

    #[test]
    fn small_sets_are_traced_to_the_harness_count() {
        // The peer harness's rule: ceil(400k / n) traces per repetition, one for larger sets.
        assert_eq!(traces_per_rep(480_000), 1);
        assert_eq!(traces_per_rep(400_000), 1);
        assert_eq!(traces_per_rep(159_160), 3);
        assert_eq!(traces_per_rep(97_840), 5);
        assert_eq!(traces_per_rep(1), 400_000);
        assert_eq!(traces_per_rep(0), 1);
    }
}
