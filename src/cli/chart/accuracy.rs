//! Speed versus accuracy: relative RMSE against render time for each integrator, one chart per
//! ray depth, written as SVG (PERF.md, "Speed versus accuracy").
//!
//! ```sh
//! pathtracer chart accuracy ../shared/scenes/cs184/sky/CBbunny.dae assets/charts
//! ```
//!
//! Options after the two paths: `-r W H` (default 160 120), `--ref-spp N` (default 1024),
//! `--spp LIST` (default 1,2,4,8,16,32,64), `-t N` (default 2), `--depths LIST` (default 1,5).
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

use pathtracer::accel::{Accel, AccelKind};
use pathtracer::convergence::{self, Point};
use pathtracer::integrator::{DirectLighting, Integrator};
use pathtracer::metrics::Image;
use pathtracer::render::RenderConfig;
use pathtracer::scene::{self, Scene};
use plotters::prelude::*;

struct Curve {
    name: &'static str,
    color: RGBColor,
    points: Vec<Point>,
}

/// `pathtracer chart accuracy ...`: errors become the CLI's one-line errors.
pub fn run(args: &[String]) -> pathtracer::Result<()> {
    run_with(args).map_err(pathtracer::Error::new)
}

fn run_with(args: &[String]) -> Result<(), String> {
    let scene_path = PathBuf::from(
        args.first().cloned().unwrap_or("../shared/scenes/cs184/sky/CBbunny.dae".into()),
    );
    let out_dir = PathBuf::from(args.get(1).cloned().unwrap_or("assets/charts".into()));
    let (mut w, mut h, mut ref_spp, mut threads) = (160u32, 120u32, 1024u32, 2usize);
    let mut spps: Vec<u32> = vec![1, 2, 4, 8, 16, 32, 64];
    let mut depths: Vec<u32> = vec![1, 5];
    let num = |s: Option<&String>| -> Result<u32, String> {
        s.and_then(|v| v.parse().ok()).filter(|&v| v > 0).ok_or("expected a positive number".into())
    };
    let list = |s: Option<&String>| -> Result<Vec<u32>, String> {
        s.ok_or("expected a list")?
            .split(',')
            .map(|t| t.parse().map_err(|_| format!("'{t}' is not a number")))
            .collect()
    };
    let mut i = 2;
    while i < args.len() {
        match args[i].as_str() {
            "-r" => {
                (w, h) = (num(args.get(i + 1))?, num(args.get(i + 2))?);
                i += 1;
            }
            "--ref-spp" => ref_spp = num(args.get(i + 1))?,
            "--spp" => spps = list(args.get(i + 1))?,
            "--depths" => depths = list(args.get(i + 1))?,
            "-t" => threads = num(args.get(i + 1))? as usize,
            other => return Err(format!("unknown option '{other}'")),
        }
        i += 2;
    }
    if !out_dir.is_dir() {
        return Err(format!("{}: not a directory", out_dir.display()));
    }
    let scene = scene::collada::load(&scene_path).map_err(|e| e.to_string())?;
    let accel = Accel::build(&scene, AccelKind::Bvh);
    let name = scene_path.file_stem().map_or("scene".into(), |s| s.to_string_lossy().into_owned());

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
            eprintln!(
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
        let svg = out_dir.join(format!("accuracy_{name}_m{depth}.svg"));
        plot(&svg, &title, &curves).map_err(|e| format!("{}: {e}", svg.display()))?;
        let csv = out_dir.join(format!("accuracy_{name}_m{depth}.csv"));
        std::fs::write(&csv, to_csv(&curves)).map_err(|e| format!("{}: {e}", csv.display()))?;
        print_summary(depth, &scene, &curves);
        eprintln!("wrote {} and {}", svg.display(), csv.display());
    }
    Ok(())
}

/// Fits err = c / sqrt(t) to each curve (the Monte Carlo rate) and prints c, how many times
/// lower the error is than hemisphere sampling's at equal time, and how many times less time it
/// needs for equal error (the square).
fn print_summary(depth: u32, scene: &Scene, curves: &[Curve]) {
    let c_of = |pts: &[Point]| {
        let logs: Vec<f64> =
            pts.iter().map(|p| (p.error.image.rel_rmse_all * p.seconds.sqrt()).ln()).collect();
        (logs.iter().sum::<f64>() / logs.len() as f64).exp()
    };
    let c_hemi = c_of(&curves[0].points);
    println!("-m {depth} ({} triangles):", scene.triangles.len());
    println!(
        "  {:<22} {:>12} {:>16} {:>18} {:>16}",
        "integrator", "slope(spp)", "err*sqrt(s)", "hemi err / err", "hemi time / time"
    );
    for c in curves {
        let k = c_of(&c.points);
        let slope = convergence::log_log_slope(
            &c.points.iter().map(|p| (p.mean_spp, p.error.image.rmse_all)).collect::<Vec<_>>(),
        )
        .unwrap_or(f64::NAN);
        println!(
            "  {:<22} {:>12.3} {:>16.5} {:>17.2}x {:>15.2}x",
            c.name,
            slope,
            k,
            c_hemi / k,
            (c_hemi / k).powi(2)
        );
    }
}

fn to_csv(curves: &[Curve]) -> String {
    let mut s = String::from("integrator,spp,mean_spp,seconds,rays,rmse,rel_rmse,bias\n");
    for c in curves {
        for p in &c.points {
            let e = &p.error.image;
            s += &format!(
                "{},{},{},{},{},{:e},{:e},{:e}\n",
                c.name,
                p.spp,
                p.mean_spp,
                p.seconds,
                p.rays,
                e.rmse_all,
                e.rel_rmse_all,
                e.bias_all
            );
        }
    }
    s
}

fn plot(path: &Path, title: &str, curves: &[Curve]) -> Result<(), Box<dyn std::error::Error>> {
    let all = curves.iter().flat_map(|c| &c.points);
    let (mut t0, mut t1, mut e0, mut e1) = (f64::MAX, 0f64, f64::MAX, 0f64);
    for p in all {
        t0 = t0.min(p.seconds);
        t1 = t1.max(p.seconds);
        e0 = e0.min(p.error.image.rel_rmse_all);
        e1 = e1.max(p.error.image.rel_rmse_all);
    }
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
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
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}
