//! Speed versus accuracy: relative RMSE against render time for each integrator, one chart per
//! ray depth, written as SVG (PERF.md, "Speed versus accuracy").
//!
//! ```sh
//! pathtracer chart accuracy ../shared/scenes/cs184/sky/CBbunny.dae assets/charts
//! pathtracer chart accuracy ../shared/scenes/cs184/sky/CBbunny.dae out --depths 5 --peer runs.jsonl
//! ```
//!
//! Options after the two paths: `-r W H` (default 160 120), `--ref-spp N` (default 1024),
//! `--spp LIST` (default 1,2,4,8,16,32,64), `-t N` (default 2), `--depths LIST` (default 1,5),
//! `--peer FILE.jsonl`, `--max-scene-bytes N` (default 1 GiB, as for rendering).
//!
//! Peer runs. `--peer FILE.jsonl` adds another renderer's measurements (JSON Lines from an
//! external measuring tool, one render per line; the fields are in `peer.rs`): on the chart of
//! depth m, the records whose `scene` is the scene file's name (e.g. `CBbunny.dae`) and whose
//! `m` is m, one dashed series per renderer and image size, labelled e.g. "mitsuba3 path
//! (quad), peer run 400x300", at (`seconds`, `rel_noise`). `rel_noise` is one render's relative
//! noise measured from two seeds, which for an unbiased renderer compares with relative RMSE
//! against the converged image; the peer's time is its own machine, size and thread count, as
//! the label's size reminds. The CSV then gains a last column, `source` (`ours`, or `peer
//! SIZE FILE:LINE`); peer rows leave `rays`, `rmse` and `bias` empty and put `rel_noise` in
//! `rel_rmse`. The whole file is read and checked before anything renders: an unreadable file,
//! a malformed line, a missing or mistyped field, or no record for the scene is a one-line
//! error naming the file (and line); a depth with no record only gets a note on stderr. The
//! printed fit (`err*sqrt(s)` and the ratios to hemisphere sampling) lists the peer series too.
//!
//! References. On the course scenes light sampling and hemisphere sampling converge to
//! different images by design (SCENE_FORMAT.md, "Careful": the scene's area light and the
//! visible emissive quad are different rectangles). So each estimator is measured against the
//! image it converges to: light sampling and adaptive sampling (light sampling that stops
//! converged pixels) against a light-sampling reference; hemisphere sampling and MIS (whose
//! light is the emissive geometry) against an MIS reference, the lowest-noise estimator of that
//! same image. The reference's own noise adds MSE/ref_spp * spp to a point's MSE: at most 1/16
//! (3% of RMSE) at 64 spp against 1024.

use std::path::{Path, PathBuf};

use clap::{ArgAction, Args};
use pathtracer::accel::{Accel, AccelKind};
use pathtracer::convergence::{self, Point};
use pathtracer::integrator::{DirectLighting, Integrator};
use pathtracer::metrics::Image;
use pathtracer::render::RenderConfig;
use pathtracer::scene::{self, Scene};
use pathtracer::staged::Outputs;
use plotters::element::DashedPathElement;
use plotters::prelude::*;

use super::peer::{self, Series};
use crate::cli::Report;

struct Curve {
    name: &'static str,
    color: RGBColor,
    points: Vec<Point>,
}

/// `pathtracer chart accuracy`.
#[derive(Args, Debug, Clone)]
#[command(
    about = "Relative RMSE against render time for every integrator, one SVG (and CSV) per depth",
    long_about = "Relative RMSE against render time for every integrator, one SVG (and CSV) per \
ray depth, in OUT_DIR.\n\n--peer FILE.jsonl adds another renderer's runs as dashed series: the \
lines (one flat JSON object each, with scene, size, m, spp, renderer, seconds, rel_noise) whose \
scene is SCENE's file name, at each chart's depth m, one series per renderer and size; the file \
is checked before anything renders."
)]
pub struct AccuracyArgs {
    /// The scene
    #[arg(value_name = "SCENE.dae", default_value = "../shared/scenes/cs184/sky/CBbunny.dae")]
    scene: PathBuf,
    /// Where the charts go (an existing directory)
    #[arg(value_name = "OUT_DIR", default_value = "assets/charts")]
    out_dir: PathBuf,
    /// Image size [default: 160 120]
    #[arg(short = 'r', value_names = ["W", "H"], num_args = 2, action = ArgAction::Set)]
    resolution: Option<Vec<String>>,
    /// Samples per pixel of the references
    #[arg(long, value_name = "N", default_value = "1024", value_parser = |s: &str| num("--ref-spp", s))]
    ref_spp: u32,
    /// Sample counts, comma-separated [default: 1,2,4,8,16,32,64]
    #[arg(long = "spp", value_name = "LIST")]
    spps: Option<String>,
    /// Worker threads
    #[arg(short = 't', value_name = "N", default_value = "2", value_parser = |s: &str| num("-t", s))]
    threads: u32,
    /// Ray depths, one chart each, comma-separated [default: 1,5]
    #[arg(long, value_name = "LIST")]
    depths: Option<String>,
    /// Another renderer's runs (JSON Lines) drawn as dashed series
    #[arg(long, value_name = "FILE.jsonl")]
    peer: Option<PathBuf>,
    /// Refuse a scene file larger than N bytes [default: 1073741824, 1 GiB]
    #[arg(long, value_name = "N",
          value_parser = |s: &str| crate::cli::parse_byte_count("--max-scene-bytes", s))]
    max_scene_bytes: Option<u64>,
}

/// A positive number for `flag`; the error names the flag and the text it got.
fn num(flag: &str, s: &str) -> Result<u32, pathtracer::Error> {
    s.parse().ok().filter(|&v| v > 0).ok_or_else(|| {
        pathtracer::Error::new(format!("{flag}: expected a positive number, got '{s}'"))
    })
}

/// A comma-separated list of numbers of at least `min` (spp: 1, depths: 0).
fn list(flag: &str, s: &str, min: u32) -> Result<Vec<u32>, String> {
    s.split(',')
        .map(|t| {
            t.trim().parse::<u32>().ok().filter(|&v| v >= min).ok_or(format!(
                "{flag}: expected a comma-separated list of numbers of at least {min}, got '{s}'"
            ))
        })
        .collect()
}

/// `pathtracer chart accuracy ...`: errors become the CLI's one-line errors.
pub fn run(args: AccuracyArgs) -> pathtracer::Result<()> {
    run_with(args).map_err(pathtracer::Error::new)
}

fn run_with(args: AccuracyArgs) -> Result<(), String> {
    let AccuracyArgs { scene: scene_path, out_dir, ref_spp, peer: peer_path, .. } = args;
    let (w, h) = match &args.resolution {
        Some(r) => (num("-r width", &r[0]), num("-r height", &r[1])),
        None => (Ok(160), Ok(120)),
    };
    let (w, h) = (w.map_err(|e| e.to_string())?, h.map_err(|e| e.to_string())?);
    let threads = args.threads as usize;
    let spps =
        args.spps.as_deref().map_or(Ok(vec![1, 2, 4, 8, 16, 32, 64]), |s| list("--spp", s, 1))?;
    let depths = args.depths.as_deref().map_or(Ok(vec![1, 5]), |s| list("--depths", s, 0))?;
    let max_scene_bytes = args.max_scene_bytes.unwrap_or(scene::collada::DEFAULT_MAX_SCENE_BYTES);
    if !out_dir.is_dir() {
        return Err(format!("{}: not a directory", out_dir.display()));
    }
    // Read and check the peer file before anything is loaded or rendered.
    let peer_records = match &peer_path {
        Some(path) => {
            let file_name = scene_path.file_name().map(|s| s.to_string_lossy().into_owned());
            let records = peer::read(path, file_name.as_deref().unwrap_or(""))?;
            for &depth in &depths {
                if !records.iter().any(|r| r.m == depth) {
                    errln!("note: {}: no record at -m {depth}", path.display());
                }
            }
            records
        }
        None => Vec::new(),
    };
    let scene =
        scene::collada::load_with_limit(&scene_path, max_scene_bytes).map_err(|e| e.to_string())?;
    Accel::check_limits(&scene).map_err(|e| e.in_scene(Some(&scene_path)).to_string())?;
    let accel = Accel::build(&scene, AccelKind::Bvh);
    let name = scene_path.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());

    // The summaries go to stdout through a Report: a failed print does not stop the charts.
    let mut report = Report::default();
    let mut outputs = Outputs::new();
    let mut written = Vec::new();
    for &depth in &depths {
        let base = RenderConfig {
            width: w,
            height: h,
            max_depth: depth,
            threads,
            seed: 17,
            ..RenderConfig::default()
        };
        let light = Integrator::Path(DirectLighting::LightSampling);
        let mis = Integrator::Path(DirectLighting::Mis);
        let hemi = Integrator::Path(DirectLighting::Hemisphere);
        let reference = |integrator| -> Result<Image, String> {
            let c = RenderConfig { integrator, spp: ref_spp, seed: 1 << 40, ..base.clone() };
            let (img, out) =
                convergence::render_image(&scene, &accel, &c).map_err(|e| e.to_string())?;
            errln!(
                "-m {depth}: {} reference, {ref_spp} spp: {:.1} s",
                integrator.name(),
                out.time.as_secs_f64()
            );
            Ok(img)
        };
        let (ref_light, ref_mis) = (reference(light)?, reference(mis)?);
        let with = |integrator| RenderConfig { integrator, ..base.clone() };
        let adaptive = RenderConfig { adaptive: Some((4, 0.05)), ..with(light) };
        let mut curves = vec![
            Curve { name: "hemisphere (-H)", color: RED, points: Vec::new() },
            Curve { name: "light sampling", color: BLUE, points: Vec::new() },
            Curve { name: "MIS (--shading mis)", color: GREEN, points: Vec::new() },
            Curve { name: "adaptive (-a 4 0.05)", color: MAGENTA, points: Vec::new() },
        ];
        let configs = [
            (with(hemi), &ref_mis),
            (with(light), &ref_light),
            (with(mis), &ref_mis),
            (adaptive, &ref_light),
        ];
        // The machine is shared: interleave the curves (and rotate their order) at each sample
        // count, so a slow spell slows every curve alike instead of one whole curve.
        for (k, &spp) in spps.iter().enumerate() {
            for j in 0..configs.len() {
                let i = (j + k) % configs.len();
                let (config, reference) = &configs[i];
                let p = convergence::sweep(&scene, &accel, config, reference, None, &[spp])
                    .map_err(|e| e.to_string())?;
                curves[i].points.extend(p);
            }
        }
        let title = format!(
            "{name} -m {depth} ({}), {w}x{h}, {threads} threads: error vs render time",
            if depth == 1 { "direct light" } else { "path tracing" }
        );
        let peers = peer::series(&peer_records, depth);
        let svg = out_dir.join(format!("accuracy_{name}_m{depth}.svg"));
        let mut text = String::new();
        plot(&mut text, &title, &curves, &peers).map_err(|e| format!("{}: {e}", svg.display()))?;
        outputs.stage_bytes(&svg, text.as_bytes()).map_err(|e| e.to_string())?;
        let csv = out_dir.join(format!("accuracy_{name}_m{depth}.csv"));
        let peer_csv = peer_path.as_deref().map(|p| (p, peers.as_slice()));
        let table = to_csv(&curves, peer_csv);
        outputs.stage_bytes(&csv, table.as_bytes()).map_err(|e| e.to_string())?;
        print_summary(&mut report, depth, &scene, &curves, &peers);
        written.push(format!("{} and {}", svg.display(), csv.display()));
    }
    // Every chart and table of the run, or none of them.
    outputs.commit().map_err(|e| e.to_string())?;
    for w in written {
        errln!("wrote {w}");
    }
    report.finish().map_err(|e| e.to_string())
}

/// Fits err = c / sqrt(t) to each curve (the Monte Carlo rate) and prints c, how many times
/// lower the error is than hemisphere sampling's at equal time, and how many times less time it
/// needs for equal error (the square). Peer series follow, fitted the same way from their own
/// times (their size, machine and threads may differ from ours).
fn print_summary(
    report: &mut Report,
    depth: u32,
    scene: &Scene,
    curves: &[Curve],
    peers: &[Series],
) {
    // (spp, seconds, relative error) per point.
    let c_of = |pts: &[(f64, f64, f64)]| {
        let logs: Vec<f64> = pts.iter().map(|p| (p.2 * p.1.sqrt()).ln()).collect();
        (logs.iter().sum::<f64>() / logs.len() as f64).exp()
    };
    let ours = |c: &Curve| -> Vec<(f64, f64, f64)> {
        c.points.iter().map(|p| (p.mean_spp, p.seconds, p.error.image.rel_rmse_all)).collect()
    };
    let c_hemi = c_of(&ours(&curves[0]));
    let rows: Vec<(String, Vec<_>)> = curves
        .iter()
        .map(|c| (c.name.to_string(), ours(c)))
        .chain(peers.iter().map(|s| {
            let pts = s.points.iter().map(|r| (r.spp as f64, r.seconds, r.rel_noise)).collect();
            (s.label.clone(), pts)
        }))
        .collect();
    let width = rows.iter().map(|r| r.0.chars().count()).max().unwrap_or(0).max(22);
    report.print(format_args!("-m {depth} ({} triangles):\n", scene.triangles.len()));
    report.print(format_args!(
        "  {:<width$} {:>12} {:>16} {:>18} {:>16}\n",
        "integrator", "slope(spp)", "err*sqrt(s)", "hemi err / err", "hemi time / time"
    ));
    for (name, pts) in rows {
        let k = c_of(&pts);
        let slope = convergence::log_log_slope(&pts.iter().map(|p| (p.0, p.2)).collect::<Vec<_>>())
            .unwrap_or(f64::NAN);
        report.print(format_args!(
            "  {:<width$} {:>12.3} {:>16.5} {:>17.2}x {:>15.2}x\n",
            name,
            slope,
            k,
            c_hemi / k,
            (c_hemi / k).powi(2)
        ));
    }
}

/// A CSV field, quoted if it holds a comma, a quote or a line break (RFC 4180).
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// Our points, in the columns the command has always written. With a peer file (`peer`: its
/// path and this depth's series) every row gains a last column, `source`: `ours`, or `peer
/// SIZE FILE:LINE` for the peer's rows, which give spp, seconds and `rel_noise` as `rel_rmse`
/// and leave the columns they do not measure empty.
fn to_csv(curves: &[Curve], peer: Option<(&Path, &[Series])>) -> String {
    let mut s = String::from("integrator,spp,mean_spp,seconds,rays,rmse,rel_rmse,bias");
    s += if peer.is_some() { ",source\n" } else { "\n" };
    for c in curves {
        for p in &c.points {
            let e = &p.error.image;
            s += &format!(
                "{},{},{},{},{},{:e},{:e},{:e}",
                c.name,
                p.spp,
                p.mean_spp,
                p.seconds,
                p.rays,
                e.rmse_all,
                e.rel_rmse_all,
                e.bias_all
            );
            s += if peer.is_some() { ",ours\n" } else { "\n" };
        }
    }
    if let Some((path, series)) = peer {
        for r in series.iter().flat_map(|s| &s.points) {
            let source = format!("peer {} {}:{}", r.size, path.display(), r.line);
            s += &format!(
                "{},{},{},{},,,{:e},,{}\n",
                csv_field(&r.renderer),
                r.spp,
                r.spp,
                r.seconds,
                r.rel_noise,
                csv_field(&source)
            );
        }
    }
    s
}

/// Colours of the peer series (ours are red, blue, green and magenta), taken in turn.
const PEER_COLORS: [RGBColor; 6] = [
    RGBColor(0, 0, 0),
    RGBColor(230, 120, 0),
    RGBColor(0, 150, 150),
    RGBColor(140, 70, 20),
    RGBColor(120, 0, 170),
    RGBColor(120, 120, 120),
];

fn plot(
    out: &mut String,
    title: &str,
    curves: &[Curve],
    peers: &[Series],
) -> Result<(), Box<dyn std::error::Error>> {
    let ours =
        curves.iter().flat_map(|c| &c.points).map(|p| (p.seconds, p.error.image.rel_rmse_all));
    let theirs = peers.iter().flat_map(|s| &s.points).map(|r| (r.seconds, r.rel_noise));
    let (mut t0, mut t1, mut e0, mut e1) = (f64::MAX, 0f64, f64::MAX, 0f64);
    for (t, e) in ours.chain(theirs) {
        t0 = t0.min(t);
        t1 = t1.max(t);
        e0 = e0.min(e);
        e1 = e1.max(e);
    }
    let root = SVGBackend::with_string(out, (900, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((t0 / 1.3..t1 * 1.3).log_scale(), (e0 / 1.3..e1 * 1.3).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("render time (s, log)")
        .y_desc("relative RMSE vs reference (log)")
        .y_labels(20)
        .y_label_formatter(&|v| format!("{v:.2}"))
        .draw()?;
    for c in curves {
        let pts: Vec<(f64, f64)> =
            c.points.iter().map(|p| (p.seconds, p.error.image.rel_rmse_all)).collect();
        let color = c.color;
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
            .label(c.name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))?;
    }
    // Peer runs: thin dashed lines through triangles, hollow squares or crosses (ours are solid
    // lines through filled circles), one colour and marker each.
    for (k, s) in peers.iter().enumerate() {
        let pts: Vec<(f64, f64)> = s.points.iter().map(|r| (r.seconds, r.rel_noise)).collect();
        let color = PEER_COLORS[k % PEER_COLORS.len()];
        let style = color.stroke_width(2);
        let dashes = move |len: i32| {
            DashedPathElement::new(vec![(0, 0), (len, 0)], 4, 2, color.stroke_width(1))
        };
        // Each shape is its own element type, so the drawing code is a macro; `marker` makes
        // the shape at a pixel offset from the point it is attached to.
        macro_rules! draw {
            ($marker:expr) => {{
                let marker = $marker;
                chart
                    .draw_series(DashedLineSeries::new(pts.clone(), 6, 4, color.stroke_width(1)))?
                    .label(s.label.as_str())
                    .legend(move |(x, y)| EmptyElement::at((x, y)) + dashes(20) + marker((10, 0)));
                chart.draw_series(pts.iter().map(|&p| EmptyElement::at(p) + marker((0, 0))))?;
            }};
        }
        match k % 3 {
            0 => draw!(move |c: (i32, i32)| TriangleMarker::new(c, 6, style)),
            1 => draw!(move |(x, y): (i32, i32)| Rectangle::new(
                [(x - 4, y - 4), (x + 4, y + 4)],
                style
            )),
            _ => draw!(move |c: (i32, i32)| Cross::new(c, 4, style)),
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}
