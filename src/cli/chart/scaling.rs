//! How cost grows with triangle count: Mrays/s per ray set and traversal, BVH build time, and
//! bytes per triangle against triangle count, from `pathtracer bench --json` lines, as SVG
//! (PERF.md, "Scaling").
//!
//! ```sh
//! for n in 10000 100000 1000000 4000000; do
//!   target/release/pathtracer gen tori $n --seed 1 -o out/tori$n.dae
//!   target/release/pathtracer bench out/tori$n.dae --threads 1 --json >> out/scaling.jsonl
//! done
//! target/release/pathtracer chart scaling out/scaling.jsonl assets/charts/scaling.svg
//! ```
//!
//! `--peer PEERS.csv` (repeatable) adds another ray tracer measured at the same sizes by the
//! peer harness (`peer_csv.rs`): its best variant per ray set as dashed lines, its MEDIUM
//! build time beside ours, and one printed line per size, ray set and thread count with our
//! best traversal's ratio to it.

use std::collections::BTreeMap;

use clap::Args;
use pathtracer::bench::BenchRecord;
use plotters::element::DashedPathElement;

use super::peer_csv::{self, PeerTable};
use plotters::prelude::*;

/// The fields of one bench line that the chart uses.
struct Row {
    triangles: f64,
    series: String,
    mrays: f64,
    build_ms: f64,
    bytes_per_triangle: f64,
}

/// `pathtracer chart scaling`.
#[derive(Args, Debug, Clone)]
#[command(
    about = "Mrays/s, build time and bytes per triangle against triangle count, from `pathtracer \
bench --json` lines"
)]
pub struct ScalingArgs {
    /// `pathtracer bench --json` lines
    #[arg(value_name = "BENCH.jsonl")]
    input: String,
    /// The chart to write
    #[arg(value_name = "OUT.svg")]
    output: String,
    /// The peer harness's CSV (`peer-bench --csv`) at the same sizes, repeatable: each peer's
    /// best variant drawn dashed, and our ratio to it printed
    #[arg(long = "peer", value_name = "PEERS.csv")]
    peers: Vec<String>,
}

/// `pathtracer chart scaling ...`: errors become the CLI's one-line errors.
pub fn run(args: ScalingArgs) -> pathtracer::Result<()> {
    run_with(&args).map_err(pathtracer::Error::new)
}

fn run_with(args: &ScalingArgs) -> Result<(), String> {
    let ScalingArgs { input, output, peers } = args;
    let text = std::fs::read_to_string(input).map_err(|e| format!("{input}: {e}"))?;
    let records = BenchRecord::parse_lines(&text, input).map_err(|e| e.to_string())?;
    let mut rows: Vec<Row> = records.iter().map(row).collect();
    if rows.is_empty() {
        return Err(format!("{input}: no bench lines"));
    }
    let peer_table = if peers.is_empty() { PeerTable::new() } else { peer_csv::read(peers)? };
    let mut ratios = Vec::new();
    for (peer, sizes) in &peer_table {
        for (&triangles, point) in sizes {
            for ((set, threads), &theirs) in &point.mrays {
                let ours = records
                    .iter()
                    .filter(|r| r.triangles as u64 == triangles)
                    .filter(|r| &r.ray_set == set && r.threads == *threads)
                    .max_by(|a, b| a.mrays_per_s.total_cmp(&b.mrays_per_s));
                let Some(ours) = ours else { continue };
                rows.push(Row {
                    triangles: triangles as f64,
                    series: format!("{peer} best {set} ({threads}t)"),
                    mrays: theirs,
                    build_ms: f64::NAN,
                    bytes_per_triangle: f64::NAN,
                });
                ratios.push(format!(
                    "{} {set} {threads}t: ours {:.1} ({}) / {peer} best {theirs:.1} = {:.2}x",
                    count_label(triangles as f64),
                    ours.mrays_per_s,
                    ours.traversal,
                    ours.mrays_per_s / theirs.max(1e-12)
                ));
            }
        }
    }
    let peer_builds: Vec<(String, f64, f64)> = peer_table
        .iter()
        .flat_map(|(peer, sizes)| {
            sizes.iter().filter_map(move |(&t, p)| p.build_ms.map(|b| (peer.clone(), t as f64, b)))
        })
        .collect();
    draw(&rows, &peer_builds, output).map_err(|e| format!("{output}: {e}"))?;
    for line in ratios {
        outln!("{line}").map_err(|e| e.to_string())?;
    }
    outln!("wrote {output}").map_err(|e| e.to_string())
}

/// What the chart draws of one bench record.
fn row(r: &BenchRecord) -> Row {
    Row {
        triangles: r.triangles as f64,
        series: format!("{} {} ({}t)", r.ray_set, r.traversal, r.threads),
        mrays: r.mrays_per_s,
        build_ms: r.build_ms,
        bytes_per_triangle: r.bytes_per_triangle,
    }
}

/// 10000 -> "10k", 4000000 -> "4M".
fn count_label(x: f64) -> String {
    match x {
        x if x >= 1e6 => format!("{}M", (x / 1e6 * 10.0).round() / 10.0),
        x if x >= 1e3 => format!("{}k", (x / 1e3).round()),
        x => format!("{x:.0}"),
    }
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

/// Draws our rows (peer rows are those whose build time is NaN: dashed, no build point) and
/// the peers' build times (peer, triangles, ms).
fn draw(rows: &[Row], peer_builds: &[(String, f64, f64)], path: &str) -> DrawResult {
    let root = SVGBackend::new(path, (1200, 450)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(700);
    let tris = rows.iter().map(|r| r.triangles);
    let (t_lo, t_hi) =
        (tris.clone().fold(f64::MAX, f64::min) / 1.5, tris.fold(0.0, f64::max) * 1.5);

    // Throughput, one line per (ray set, traversal, threads), peers' dashed.
    let mut series: BTreeMap<(bool, &str), Vec<(f64, f64)>> = BTreeMap::new();
    for r in rows {
        series.entry((r.build_ms.is_nan(), &r.series)).or_default().push((r.triangles, r.mrays));
    }
    let m_hi = rows.iter().map(|r| r.mrays).fold(0.0, f64::max) * 1.15;
    let mut chart = ChartBuilder::on(&left)
        .caption("Throughput vs triangle count (tori scenes)", ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d((t_lo..t_hi).log_scale(), 0.0..m_hi)?;
    chart
        .configure_mesh()
        .x_desc("triangles")
        .y_desc("Mrays/s")
        .x_labels(4)
        .x_label_formatter(&|x| count_label(*x))
        .draw()?;
    for (i, ((peer, name), mut pts)) in series.into_iter().enumerate() {
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let color = Palette99::pick(i).to_rgba();
        if peer {
            chart
                .draw_series(DashedLineSeries::new(pts.clone(), 6, 4, color.stroke_width(2)))?
                .label(name)
                .legend(move |(x, y)| {
                    DashedPathElement::new(vec![(x, y), (x + 18, y)], 4, 2, color.stroke_width(2))
                });
            chart.draw_series(pts.iter().map(|&p| TriangleMarker::new(p, 4, color.filled())))?;
        } else {
            chart
                .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
                .label(name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
        }
    }
    chart.configure_series_labels().background_style(WHITE.mix(0.8)).border_style(BLACK).draw()?;

    // Build time and memory: one point per scene (they do not depend on the ray set).
    let mut per_scene: BTreeMap<u64, (f64, f64)> = BTreeMap::new();
    for r in rows.iter().filter(|r| !r.build_ms.is_nan()) {
        per_scene.insert(r.triangles as u64, (r.build_ms, r.bytes_per_triangle));
    }
    let all_ms = per_scene.values().map(|v| v.0).chain(peer_builds.iter().map(|p| p.2));
    let b_hi = all_ms.clone().fold(1.0, f64::max) * 2.0;
    let b_lo = all_ms.fold(f64::MAX, f64::min).max(0.01) / 2.0;
    let mut chart = ChartBuilder::on(&right)
        .caption("BVH build time (bytes/triangle at each point)", ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d((t_lo..t_hi).log_scale(), (b_lo..b_hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("triangles")
        .y_desc("build ms")
        .x_labels(4)
        .x_label_formatter(&|x| count_label(*x))
        .y_label_formatter(&|y| format!("{y:.0}"))
        .draw()?;
    let pts: Vec<(f64, f64)> = per_scene.iter().map(|(&t, v)| (t as f64, v.0)).collect();
    chart
        .draw_series(LineSeries::new(pts.clone(), BLUE.stroke_width(2)))?
        .label("ours")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLUE.stroke_width(2)));
    let mut peer_pts: BTreeMap<&str, Vec<(f64, f64)>> = BTreeMap::new();
    for (peer, t, ms) in peer_builds {
        peer_pts.entry(peer).or_default().push((*t, *ms));
    }
    for (i, (peer, mut pts)) in peer_pts.into_iter().enumerate() {
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let color = Palette99::pick(i + 1).to_rgba();
        chart
            .draw_series(DashedLineSeries::new(pts.clone(), 6, 4, color.stroke_width(2)))?
            .label(format!("{peer} MEDIUM (1 thread, CPU time)"))
            .legend(move |(x, y)| {
                DashedPathElement::new(vec![(x, y), (x + 18, y)], 4, 2, color.stroke_width(2))
            });
        chart.draw_series(pts.iter().map(|&p| TriangleMarker::new(p, 4, color.filled())))?;
    }
    chart.draw_series(per_scene.iter().map(|(&t, v)| {
        EmptyElement::at((t as f64, v.0))
            + Circle::new((0, 0), 3, BLUE.filled())
            + Text::new(format!("{:.0} B", v.1), (6, -14), ("sans-serif", 13))
    }))?;
    if !peer_builds.is_empty() {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()?;
    Ok(())
}
