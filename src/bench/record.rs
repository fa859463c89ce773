//! One benchmark record: what `bench --json` writes (one JSON object a line) and what the
//! scaling chart and `bench --baseline` read back, through one serde type.

use serde::{Deserialize, Serialize};

use super::Frame;
use crate::{Error, Result};

/// One measurement of one ray set with one traversal, in the units of BENCHMARK.md.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BenchRecord {
    /// The scene's name (its file name).
    pub scene: String,
    /// Triangles in the scene.
    pub triangles: usize,
    /// The ray set's name (`primary`, `diffuse` or `shadow`).
    pub ray_set: String,
    /// Rays in the set.
    pub rays: usize,
    /// Worker threads for the build and the trace.
    pub threads: usize,
    /// The traversal's name (`single`, `packet4`, `packet8` or `packet16`).
    pub traversal: String,
    /// The frame of the primary rays, `WxH` (`bench --frame`); empty when read from a line
    /// written before it was recorded, which means the standard 800x600.
    #[serde(default)]
    pub frame: String,
    /// Build time of the acceleration structure, in milliseconds.
    pub build_ms: f64,
    /// Millions of rays per second, by the peer harness's rule (`bench::timing`): the best
    /// wall time when every asked repetition was clean, else the CPU-time estimate.
    pub mrays_per_s: f64,
    /// Which time `mrays_per_s` comes from: `wall` or `cpu` (`bench::timing`); empty when
    /// read from a line written before it was recorded.
    #[serde(default)]
    pub timed_by: String,
    /// Millions of rays per second of the best wall time of any repetition, clean or not; 0
    /// when read from such an older line.
    #[serde(default)]
    pub wall_mrays_per_s: f64,
    /// Repetitions whose workers got their share of the CPU, and repetitions made; 0 when
    /// read from such an older line.
    #[serde(default)]
    pub clean_reps: usize,
    /// See `clean_reps`.
    #[serde(default)]
    pub reps_made: usize,
    /// Ray-box tests per ray.
    pub node_tests_per_ray: f64,
    /// Ray-triangle tests per ray.
    pub triangle_tests_per_ray: f64,
    /// Checksum: rays that hit (closest-hit sets) or are occluded (shadow set).
    pub hits: u64,
    /// Checksum: the sum of hit distances in ray order.
    pub t_sum: f64,
    /// Bytes of the acceleration structure per triangle.
    pub bytes_per_triangle: f64,
    /// Exact ray-box tests over the set; 0 when read from a line written before the totals
    /// were recorded.
    #[serde(default)]
    pub node_tests: u64,
    /// Exact ray-triangle tests over the set; 0 when read from such an older line.
    #[serde(default)]
    pub triangle_tests: u64,
    /// Checksum of every ray's exact answer in trace order (hit or miss, t, u, v and the
    /// primitive; occluded or not for the shadow set): 64-bit FNV-1a, in hex. Builds for
    /// different instruction sets must agree on it. Empty when read from an older line.
    #[serde(default)]
    pub answers: String,
    /// The instruction-set level that ran (`sse2`, `avx2`, `avx512`); empty when read from a
    /// line written before it was recorded.
    #[serde(default)]
    pub isa: String,
}

impl BenchRecord {
    /// One line of JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a record of numbers and strings serializes")
    }

    /// The records of a JSON-lines text (blank lines skipped); an error names `name:LINE`.
    pub fn parse_lines(text: &str, name: &str) -> Result<Vec<BenchRecord>> {
        text.lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
            .map(|(i, l)| {
                serde_json::from_str(l)
                    .map_err(|e| Error::new(format!("{name}:{}: {}", i + 1, json_error(&e))))
            })
            .collect()
    }

    /// Scene, ray set, traversal and frame: what a record measures.
    fn key(&self) -> (&str, &str, &str, &str) {
        (&self.scene, &self.ray_set, &self.traversal, self.frame_name())
    }

    /// The frame of the primary rays; the standard one for a line that does not say.
    fn frame_name(&self) -> &str {
        if self.frame.is_empty() {
            Frame::STANDARD_NAME
        } else {
            &self.frame
        }
    }
}

/// "scene X, ray set Y, traversal Z" (and ", frame F" for a frame other than the standard one).
fn describe(r: &BenchRecord) -> String {
    let (scene, set, traversal, frame) = r.key();
    let mut at = format!("scene {scene}, ray set {set}, traversal {traversal}");
    if frame != Frame::STANDARD_NAME {
        at += &format!(", frame {frame}");
    }
    at
}

/// serde_json's message, with a missing field said as "no field NAME".
fn json_error(e: &serde_json::Error) -> String {
    let text = e.to_string();
    match text.strip_prefix("missing field `").and_then(|r| r.split_once('`')) {
        Some((field, _)) => format!("no field {field}"),
        None => text,
    }
}

/// Every way `run` is worse than `baseline`, one line each. Cost counters (node and triangle
/// tests, exact totals) may fall freely and rise by at most `tolerance_pct` percent; the
/// checksums (rays, hits, t_sum) may move by at most that either way, and at tolerance 0 the
/// answer digests (when both records have one) must be equal. A baseline record the run did
/// not produce is a regression too.
pub fn regressions(
    baseline: &[BenchRecord],
    run: &[BenchRecord],
    tolerance_pct: f64,
) -> Vec<String> {
    let tol = tolerance_pct / 100.0;
    let mut out = Vec::new();
    for b in baseline {
        let at = describe(b);
        let Some(n) = run.iter().find(|r| r.key() == b.key()) else {
            out.push(format!("{at}: missing from this run"));
            continue;
        };
        if n.rays != b.rays {
            out.push(format!("{at}: rays {} vs baseline {} (the ray set changed)", n.rays, b.rays));
            continue;
        }
        for (what, new, base) in [
            ("node_tests", n.node_tests, b.node_tests),
            ("triangle_tests", n.triangle_tests, b.triangle_tests),
        ] {
            if new as f64 > base as f64 * (1.0 + tol) {
                let pct = 100.0 * (new as f64 / (base as f64).max(1.0) - 1.0);
                out.push(format!(
                    "{at}: {what} {new} vs baseline {base} (+{pct:.2}%, limit +{tolerance_pct}%)"
                ));
            }
        }
        if (n.hits as f64 - b.hits as f64).abs() > tol * b.hits as f64 {
            out.push(format!(
                "{at}: hits {} vs baseline {} (limit {tolerance_pct}%)",
                n.hits, b.hits
            ));
        }
        if (n.t_sum - b.t_sum).abs() > tol * b.t_sum.abs() || n.t_sum.is_nan() {
            out.push(format!(
                "{at}: t_sum {} vs baseline {} (limit {tolerance_pct}%)",
                n.t_sum, b.t_sum
            ));
        }
        let both_digested = !n.answers.is_empty() && !b.answers.is_empty();
        if tolerance_pct == 0.0 && both_digested && n.answers != b.answers {
            out.push(format!(
                "{at}: answers {} vs baseline {} (some ray's hit, t, u, v or primitive differs)",
                n.answers, b.answers
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(traversal: &str, node_tests: u64, hits: u64, t_sum: f64) -> BenchRecord {
        BenchRecord {
            scene: "s.dae".into(),
            triangles: 12,
            ray_set: "primary".into(),
            rays: 100,
            threads: 1,
            traversal: traversal.into(),
            frame: String::new(),
            build_ms: 1.0,
            mrays_per_s: 2.0,
            timed_by: "wall".into(),
            wall_mrays_per_s: 2.0,
            clean_reps: 5,
            reps_made: 5,
            node_tests_per_ray: node_tests as f64 / 100.0,
            triangle_tests_per_ray: 3.0,
            hits,
            t_sum,
            bytes_per_triangle: 70.0,
            node_tests,
            triangle_tests: 300,
            answers: "0123456789abcdef".into(),
            isa: "avx2".into(),
        }
    }

    #[test]
    fn records_round_trip_through_json() {
        let r = record("single", 1234, 50, 985504.9539709092);
        let back = BenchRecord::parse_lines(&format!("{}\n\n{}\n", r.to_json(), r.to_json()), "x");
        assert_eq!(back.unwrap(), vec![r.clone(), r]);
        let e = BenchRecord::parse_lines("{\"triangles\":12}", "f.jsonl").unwrap_err();
        assert_eq!(e.message(), "f.jsonl:1: no field scene");
    }

    #[test]
    fn counters_may_fall_but_not_rise_and_checksums_must_hold() {
        let base = [record("single", 1000, 50, 12.5), record("packet8", 1000, 50, 12.5)];
        let same = base.clone();
        assert!(regressions(&base, &same, 0.0).is_empty());
        let better = [record("single", 900, 50, 12.5), record("packet8", 1000, 50, 12.5)];
        assert!(regressions(&base, &better, 0.0).is_empty());
        let worse = [record("single", 1011, 50, 12.5), record("packet8", 1000, 51, 12.7)];
        let r = regressions(&base, &worse, 1.0);
        assert_eq!(r.len(), 3, "{r:?}");
        assert!(r[0].starts_with("scene s.dae, ray set primary, traversal single: node_tests 1011"));
        assert!(r[1].contains("traversal packet8: hits 51 vs baseline 50"), "{r:?}");
        assert!(r[2].contains("t_sum 12.7"), "{r:?}");
        assert!(regressions(&base, &worse, 2.0).is_empty());
        let mut other = base.clone();
        other[0].answers = "fedcba9876543210".into();
        let r = regressions(&base, &other, 0.0);
        assert_eq!(r.len(), 1, "{r:?}");
        assert!(r[0].contains("answers fedcba9876543210 vs baseline 0123456789abcdef"), "{r:?}");
        assert!(regressions(&base, &other, 1.0).is_empty());
        other[0].answers.clear();
        assert!(regressions(&base, &other, 0.0).is_empty());
        let r = regressions(&base, &base[..1], 0.0);
        assert_eq!(r, ["scene s.dae, ray set primary, traversal packet8: missing from this run"]);
    }

    /// A line without a frame is the standard frame; a record of another frame answers only
    /// a baseline of that frame.
    #[test]
    fn records_of_other_frames_are_other_measurements() {
        let base = [record("single", 1000, 50, 12.5)];
        let mut standard = base.clone();
        standard[0].frame = "800x600".into();
        assert!(regressions(&base, &standard, 0.0).is_empty());
        let mut small = base.clone();
        small[0].frame = "400x300".into();
        let r = regressions(&base, &small, 0.0);
        assert_eq!(r, ["scene s.dae, ray set primary, traversal single: missing from this run"]);
        let r = regressions(&small, &base, 0.0);
        assert_eq!(
            r,
            ["scene s.dae, ray set primary, traversal single, frame 400x300: missing from this run"]
        );
        assert!(regressions(&small, &small, 0.0).is_empty());
    }
}
