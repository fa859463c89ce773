//! Timed repetitions that notice when the host takes a tracing thread away.
//!
//! On a shared machine a repetition can lose a core to other processes for part of its wall
//! time, and its figure then measures the host, not the kernel. The peer harness
//! (`../shared/tools/peer-bench`) counts a repetition as clean only when its tracing threads got
//! at least `CLEAN_SHARE` of threads x wall time of CPU, makes up to twice the asked
//! repetitions to find that many clean ones, and when it finds fewer reports the CPU-time
//! estimate (rays / (CPU time / threads)) instead of the wall time. `bench` applies the same
//! rule to its own repetitions (`Repetitions`), so that its figures and the harness's come from
//! one estimator. The CPU time is counted as the harness counts it: each tracing thread's, from
//! when it starts taking rays to when it runs out (`bench::trace_once`). Time a thread spends
//! waiting to start, or idle after its last chunk, is in the wall time only, so a repetition can
//! fall short of the share without any preemption. (The harness starts its threads for every
//! trace; 174 of its 288 two-thread Embree figures in the seventeenth session's runs were
//! CPU-time estimates, 1 of our 192: PERF.md, "Against the peers".)

use std::time::{Duration, Instant};

/// Share of threads x wall time a repetition's workers must get for it to count as clean
/// (the peer harness's 97%).
pub const CLEAN_SHARE: f64 = 0.97;

/// How a figure was timed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimedBy {
    /// The best wall time of the clean repetitions: every asked repetition was clean.
    Wall,
    /// Fewer clean repetitions than asked: the best CPU time per thread.
    Cpu,
}

impl TimedBy {
    /// `wall` or `cpu`, as `bench --json` writes it.
    pub fn name(self) -> &'static str {
        match self {
            TimedBy::Wall => "wall",
            TimedBy::Cpu => "cpu",
        }
    }
}

/// The outcome of `Repetitions`: the time of one repetition and how it was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timing {
    /// The reported time of one repetition (see `TimedBy`).
    pub best: Duration,
    /// Which estimate `best` is.
    pub timed_by: TimedBy,
    /// The best wall time of any repetition, clean or not.
    pub best_wall: Duration,
    /// Repetitions whose workers got their share of the CPU.
    pub clean: usize,
    /// Repetitions made (at most twice the asked number).
    pub attempts: usize,
}

/// The harness's repetition rule, fed one measured repetition at a time.
#[derive(Debug, Clone)]
pub struct Repetitions {
    wanted: usize,
    threads: usize,
    clean: usize,
    attempts: usize,
    best_clean: Option<Duration>,
    best_wall: Option<Duration>,
    best_cpu: Option<Duration>,
}

impl Repetitions {
    /// `wanted` clean repetitions (at least one) on `threads` workers.
    pub fn new(wanted: usize, threads: usize) -> Repetitions {
        let wanted = wanted.max(1);
        Repetitions {
            wanted,
            threads: threads.max(1),
            clean: 0,
            attempts: 0,
            best_clean: None,
            best_wall: None,
            best_cpu: None,
        }
    }

    /// Whether another repetition is wanted: fewer clean ones than asked, and fewer than twice
    /// as many made.
    pub fn more(&self) -> bool {
        self.clean < self.wanted && self.attempts < 2 * self.wanted
    }

    /// Records a repetition of `wall` time in which the workers got `cpu` CPU time in all
    /// (`None` where the platform cannot tell: the repetition then counts as clean).
    pub fn record(&mut self, wall: Duration, cpu: Option<Duration>) {
        self.attempts += 1;
        let per_thread = cpu.map_or(wall, |c| c / self.threads as u32);
        let clean = cpu.is_none_or(|c| {
            c.as_secs_f64() >= CLEAN_SHARE * self.threads as f64 * wall.as_secs_f64()
        });
        if clean {
            self.clean += 1;
            keep_least(&mut self.best_clean, wall);
        }
        keep_least(&mut self.best_wall, wall);
        keep_least(&mut self.best_cpu, per_thread);
    }

    /// The figure to report: the best clean wall time when every asked repetition was clean,
    /// else the best CPU time per thread.
    pub fn timing(&self) -> Timing {
        let (best, timed_by) = match (self.clean >= self.wanted, self.best_clean) {
            (true, Some(b)) => (b, TimedBy::Wall),
            _ => (self.best_cpu.unwrap_or_default(), TimedBy::Cpu),
        };
        let best_wall = self.best_wall.unwrap_or_default();
        Timing { best, timed_by, best_wall, clean: self.clean, attempts: self.attempts }
    }
}

/// `best` becomes `d` if it is unset or larger.
fn keep_least(best: &mut Option<Duration>, d: Duration) {
    *best = Some(best.map_or(d, |b| b.min(d)));
}

/// Runs `rep` (one repetition on `threads` tracing threads, returning the CPU time they spent
/// tracing, `None` where unknown) under the harness's rule and returns the timing.
pub fn time_repetitions(
    threads: usize,
    wanted: usize,
    mut rep: impl FnMut() -> Option<Duration>,
) -> Timing {
    let mut reps = Repetitions::new(wanted, threads);
    while reps.more() {
        let t0 = Instant::now();
        let cpu = rep();
        let wall = t0.elapsed();
        reps.record(wall, cpu);
    }
    reps.timing()
}

/// The calling thread's CPU time since `start` (an earlier `thread_cpu_time()` of the same
/// thread); `None` where either reading is unknown.
pub(crate) fn thread_cpu_time_since(start: Option<Duration>) -> Option<Duration> {
    start.zip(thread_cpu_time()).map(|(a, b)| b.saturating_sub(a))
}

/// The calling thread's CPU time so far.
#[cfg(unix)]
pub(crate) fn thread_cpu_time() -> Option<Duration> {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes one timespec through the pointer, which points to a live
    // local; failure is reported through the return value.
    let ok = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) } == 0;
    ok.then(|| Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32))
}

/// The calling thread's CPU time so far: unknown on this platform.
#[cfg(not(unix))]
pub(crate) fn thread_cpu_time() -> Option<Duration> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn all_clean_reports_the_best_wall_time() {
        let mut r = Repetitions::new(3, 2);
        for wall in [12, 10, 11] {
            assert!(r.more());
            r.record(ms(wall), Some(ms(2 * wall)));
        }
        assert!(!r.more());
        let t = r.timing();
        assert_eq!((t.best, t.timed_by, t.clean, t.attempts), (ms(10), TimedBy::Wall, 3, 3));
    }

    /// A repetition whose two workers got 1.9 of 2 x 10 ms is preempted (95% < 97%); after
    /// twice the asked repetitions with too few clean ones, the best CPU time per thread is
    /// reported, as the harness does.
    #[test]
    fn preempted_repetitions_fall_back_to_cpu_time() {
        let mut r = Repetitions::new(2, 2);
        r.record(ms(10), Some(ms(19)));
        r.record(ms(9), Some(ms(18)));
        assert!(r.more(), "one clean of two: try again");
        r.record(ms(12), Some(ms(16)));
        r.record(ms(11), Some(ms(21)));
        assert!(!r.more(), "four attempts for two wanted");
        let t = r.timing();
        assert_eq!((t.timed_by, t.clean, t.attempts), (TimedBy::Cpu, 1, 4));
        assert_eq!(t.best, ms(8), "16 ms of CPU over two threads");
        assert_eq!(t.best_wall, ms(9));
    }

    #[test]
    fn unknown_cpu_time_counts_as_clean() {
        let mut r = Repetitions::new(1, 4);
        r.record(ms(7), None);
        assert!(!r.more());
        assert_eq!(r.timing().timed_by, TimedBy::Wall);
        assert_eq!(r.timing().best, ms(7));
    }

    /// A repetition's CPU time as `bench::trace_once` counts it: each worker's own, over the
    /// work it did. Two workers that each spin for 20 ms of wall time report CPU time where it
    /// can be read (less than 40 ms if the host preempted them, never more than the repetition's
    /// two threads could get), and the repetitions' estimate, wall or CPU, is never zero.
    #[test]
    fn a_pool_reports_its_workers_cpu_time() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let mut seen = Vec::new();
        let t = time_repetitions(2, 2, || {
            let t0 = Instant::now();
            let per_worker = pool.broadcast(|_| {
                let start = thread_cpu_time();
                spin(ms(20));
                thread_cpu_time_since(start)
            });
            let cpu = per_worker.into_iter().sum::<Option<Duration>>();
            seen.push((cpu, t0.elapsed()));
            cpu
        });
        assert!((2..=4).contains(&t.attempts) && t.clean <= t.attempts, "{t:?}");
        assert!(t.best_wall >= ms(20) && t.best > Duration::ZERO, "{t:?}");
        if cfg!(unix) {
            let plausible = |&(c, wall): &(Option<Duration>, Duration)| {
                c.is_some_and(|c| c >= ms(1) && c <= 2 * wall + ms(2))
            };
            assert!(seen.iter().all(plausible), "{seen:?}");
        }
    }

    /// Burns CPU for about `d`.
    fn spin(d: Duration) {
        let t0 = Instant::now();
        while t0.elapsed() < d {
            std::hint::black_box(0);
        }
    }
}
