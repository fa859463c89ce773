//! `pathtracer converge SCENE.dae --spp 1,2,4,... (--reference REF.exr | --ref-spp N)`:
//! renders the scene at each sample count, times it, and prints its error against a reference.

use std::path::{Path, PathBuf};

use clap::Args;

use super::render::{available_threads, lighting_warnings};
use super::render_args::RenderArgs;
use super::{check_output, parse_in_range, parse_number};
use pathtracer::accel::Accel;
use pathtracer::convergence::{self, Point};
use pathtracer::metrics::{self, Image};
use pathtracer::render::RenderConfig;
use pathtracer::staged::Outputs;
use pathtracer::{bail, scene, Result};

/// `pathtracer converge`: its own flags and the renderer's.
#[derive(Args, Debug, Clone)]
#[command(
    about = "Error and time against samples per pixel, against a reference",
    long_about = "Renders SCENE at each sample count of LIST (comma-separated, e.g. 1,2,4,8,16), \
times each render (the render loop only), and prints RMSE, relative RMSE and bias against the \
reference (see pathtracer compare --help), with the fitted slope of log RMSE against log spp (an \
unbiased estimator gives -0.5 until the reference's own noise is reached).",
    after_help = "The render options are the renderer's (not -s, -f, --info). Each render uses \
seed + spp, the reference seed + 2^32, so their noise is independent."
)]
pub struct ConvergeArgs {
    /// Sample counts, comma-separated (required)
    #[arg(long = "spp", value_name = "LIST", help_heading = "Convergence options")]
    spps: Option<String>,
    /// Linear EXR reference of the same size (e.g. rendered with -f REF.exr)
    #[arg(long, value_name = "FILE", help_heading = "Convergence options")]
    reference: Option<PathBuf>,
    /// Render the reference here, with N spp and the same options
    #[arg(long, value_name = "N", help_heading = "Convergence options",
          value_parser = |s: &str| parse_in_range("--ref-spp", s, 1, 1 << 20))]
    ref_spp: Option<u32>,
    /// Save that reference as linear EXR
    #[arg(long, value_name = "FILE", help_heading = "Convergence options",
          value_parser = parse_exr_path)]
    write_reference: Option<PathBuf>,
    /// Also report errors over the mask's nonzero pixels
    #[arg(long, value_name = "FILE", help_heading = "Convergence options")]
    mask: Option<PathBuf>,
    /// Write the table as CSV
    #[arg(long, value_name = "FILE", help_heading = "Convergence options")]
    csv: Option<PathBuf>,
    #[command(flatten)]
    render: RenderArgs,
}

/// The checked flags.
#[derive(Debug)]
struct Checked {
    spps: Vec<u32>,
    reference: Option<PathBuf>,
    ref_spp: Option<u32>,
    write_reference: Option<PathBuf>,
    mask: Option<PathBuf>,
    csv: Option<PathBuf>,
    render: RenderArgs,
}

pub fn run(args: ConvergeArgs) -> Result<()> {
    let a = check(args)?;
    let mut cli = a.render.clone().into_cli().map_err(|e| e.context("converge"))?;
    if cli.info {
        bail!("converge: --info is not a convergence option");
    }
    if cli.output.is_some() {
        bail!("converge: -f is not used (the reference is --write-reference, the table --csv)");
    }
    if cli.config.threads == 0 {
        cli.config.threads = available_threads();
    }
    cli.config.progress = false;
    // Fail on bad reference, mask or output paths before minutes of rendering.
    let reference_file = a.reference.as_deref().map(metrics::read_image).transpose()?;
    if let (Some(p), Some(r)) = (&a.reference, &reference_file) {
        super::compare::check_finite(p, r)?;
    }
    let mask = match &a.mask {
        Some(p) => Some(metrics::read_mask(p)?),
        None => None,
    };
    let mut inputs: Vec<&Path> = vec![&cli.scene];
    inputs.extend(a.reference.as_deref());
    inputs.extend(a.mask.as_deref());
    if let Some(p) = &a.csv {
        check_parent(p)?;
        check_output("converge: --csv", p, &inputs)?;
    }
    if let Some(p) = &a.write_reference {
        check_parent(p)?;
        inputs.extend(a.csv.as_deref());
        check_output("converge: --write-reference", p, &inputs)?;
    }

    let scene = scene::collada::load_with_limit(&cli.scene, cli.max_scene_bytes)?;
    Accel::check_limits(&scene).map_err(|e| e.in_scene(Some(&cli.scene)))?;
    for w in scene.warnings.iter().chain(&lighting_warnings(&scene, cli.config.integrator)) {
        errln!("warning: {}: {w}", cli.scene.display());
    }
    let accel = Accel::build(&scene, cli.accel);
    // The reference and the CSV are written together at the end: all or none.
    let mut outputs = Outputs::new();
    let reference = match (reference_file, a.ref_spp) {
        (Some(r), _) => r,
        (None, Some(n)) => {
            let config = RenderConfig {
                spp: n,
                seed: cli.config.seed.wrapping_add(1 << 32),
                ..cli.config.clone()
            };
            let (image, out) = convergence::render_image(&scene, &accel, &config)?;
            errln!("[converge] reference: {n} spp in {:.2} s", out.time.as_secs_f64());
            if let Some(p) = &a.write_reference {
                metrics::stage_exr(&mut outputs, p, &image)?;
            }
            image
        }
        (None, None) => unreachable!("parse requires --reference or --ref-spp"),
    };
    let (w, h) = (cli.config.width, cli.config.height);
    if (reference.width, reference.height) != (w, h) {
        bail!(
            "converge: the reference is {}x{} but the render is {w}x{h} (give -r {} {})",
            reference.width,
            reference.height,
            reference.width,
            reference.height
        );
    }
    let mask = match mask {
        Some((mw, mh, _)) if (mw, mh) != (w, h) => {
            bail!("converge: the mask is {mw}x{mh} but the render is {w}x{h}")
        }
        Some((_, _, m)) => Some(m),
        None => None,
    };
    let points =
        convergence::sweep(&scene, &accel, &cli.config, &reference, mask.as_deref(), &a.spps)?;
    // The CSV first: a table that cannot be printed (a full disk, `| head -1`) loses no file.
    if let Some(p) = &a.csv {
        outputs.stage_bytes(p, csv(&points).as_bytes())?;
    }
    outputs.commit()?;
    out!("{}", format_table(&points, &reference))
}

fn check(a: ConvergeArgs) -> Result<Checked> {
    if a.render.pixel_samples.is_some() {
        bail!("converge: -s is replaced by --spp LIST");
    }
    let spps = match &a.spps {
        Some(list) => parse_spp_list(list)?,
        None => bail!("converge: --spp LIST is required (e.g. --spp 1,2,4,8,16)"),
    };
    match (&a.reference, a.ref_spp) {
        (None, None) => bail!("converge: give --reference FILE or --ref-spp N"),
        (Some(_), Some(_)) => bail!("converge: give either --reference or --ref-spp, not both"),
        (Some(_), None) if a.write_reference.is_some() => {
            bail!("converge: --write-reference needs --ref-spp (the reference is rendered here)")
        }
        _ => {}
    }
    Ok(Checked {
        spps,
        reference: a.reference,
        ref_spp: a.ref_spp,
        write_reference: a.write_reference,
        mask: a.mask,
        csv: a.csv,
        render: a.render,
    })
}

fn parse_exr_path(text: &str) -> Result<PathBuf> {
    let p = PathBuf::from(text);
    if !p.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        bail!("converge: --write-reference {}: must end in .exr", p.display());
    }
    Ok(p)
}

fn parse_spp_list(text: &str) -> Result<Vec<u32>> {
    let spps: Vec<u32> = text
        .split(',')
        .map(|t| {
            let v: i64 = parse_number("--spp", t.trim())?;
            if !(1..=1 << 20).contains(&v) {
                bail!("--spp: {v} is out of range (expected 1 to {})", 1 << 20);
            }
            Ok(v as u32)
        })
        .collect::<Result<_>>()?;
    Ok(spps)
}

fn check_parent(path: &Path) -> Result<()> {
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !parent.is_dir() {
        bail!("{}: directory {} does not exist", path.display(), parent.display());
    }
    Ok(())
}

fn format_table(points: &[Point], reference: &Image) -> String {
    let mut s = format!(
        "{:>7} {:>9} {:>10} {:>12} {:>10} {:>13} {:>7}\n",
        "spp", "mean_spp", "seconds", "rmse", "rel_rmse", "bias", "slope"
    );
    let mut prev: Option<&Point> = None;
    for p in points {
        let e = &p.error.image;
        // Local slope against the previous row: -0.5 while noise dominates.
        let slope = prev
            .and_then(|q| {
                convergence::log_log_slope(&[
                    (q.mean_spp, q.error.image.rmse_all),
                    (p.mean_spp, e.rmse_all),
                ])
            })
            .map_or("".into(), |v| format!("{v:.3}"));
        s += &format!(
            "{:>7} {:>9.2} {:>10.4} {:>12.6e} {:>10.6} {:>+13.6e} {:>7}\n",
            p.spp, p.mean_spp, p.seconds, e.rmse_all, e.rel_rmse_all, e.bias_all, slope
        );
        prev = Some(p);
    }
    let fit: Vec<(f64, f64)> =
        points.iter().map(|p| (p.mean_spp, p.error.image.rmse_all)).collect();
    if let Some(slope) = convergence::log_log_slope(&fit) {
        s += &format!(
            "fitted slope of log RMSE against log spp: {slope:.3} (unbiased Monte Carlo: -0.5); \
             reference {}x{}\n",
            reference.width, reference.height
        );
    }
    if points.iter().any(|p| p.error.masked.is_some()) {
        s += &format!("{:>7} {:>12} {:>10} {:>13}  (mask)\n", "spp", "rmse", "rel_rmse", "bias");
        for p in points {
            if let Some(m) = &p.error.masked {
                s += &format!(
                    "{:>7} {:>12.6e} {:>10.6} {:>+13.6e}\n",
                    p.spp, m.rmse_all, m.rel_rmse_all, m.bias_all
                );
            }
        }
    }
    s
}

fn csv(points: &[Point]) -> String {
    let mut s = String::from(
        "spp,mean_spp,seconds,rays,rmse,rel_rmse,bias,rmse_r,rmse_g,rmse_b,mask_rmse,mask_rel_rmse,mask_bias\n",
    );
    for p in points {
        let e = &p.error.image;
        let m = p.error.masked.map_or(",,".to_string(), |m| {
            format!("{:e},{:e},{:e}", m.rmse_all, m.rel_rmse_all, m.bias_all)
        });
        s += &format!(
            "{},{},{},{},{:e},{:e},{:e},{:e},{:e},{:e},{m}\n",
            p.spp,
            p.mean_spp,
            p.seconds,
            p.rays,
            e.rmse_all,
            e.rel_rmse_all,
            e.bias_all,
            e.rmse[0],
            e.rmse[1],
            e.rmse[2]
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Checked> {
        let args: Vec<String> =
            ["converge"].into_iter().chain(s.split_whitespace()).map(String::from).collect();
        match crate::cli::command::parse(&args)? {
            crate::cli::command::Command::Converge(a) => check(a),
            _ => unreachable!(),
        }
    }

    #[test]
    fn arguments() {
        let a = parse("x.dae --spp 1,2,4 --ref-spp 64 -m 5 -H --csv o.csv").unwrap();
        assert_eq!(a.spps, vec![1, 2, 4]);
        assert_eq!(a.ref_spp, Some(64));
        let cli = a.render.into_cli().unwrap();
        assert_eq!((cli.scene.to_str(), cli.config.max_depth), (Some("x.dae"), 5));
        assert_eq!(cli.config.integrator.name(), "hemisphere");
        for (bad, want) in [
            ("x.dae --ref-spp 4", "--spp LIST is required"),
            ("x.dae --spp 1,2", "--reference FILE or --ref-spp"),
            ("x.dae --spp 1,0 --ref-spp 4", "out of range"),
            ("x.dae --spp 1,a --ref-spp 4", "not a valid number"),
            ("x.dae --spp 1 --ref-spp 4 --reference r.exr", "not both"),
            ("x.dae --spp 1 --reference r.exr --write-reference w.exr", "needs --ref-spp"),
            ("x.dae --spp 1 --ref-spp 4 --write-reference w.png", "must end in .exr"),
            ("x.dae --spp 1 --ref-spp 4 -s 8", "replaced by --spp"),
            ("x.dae --spp", "needs a value"),
        ] {
            let e = parse(bad).unwrap_err().to_string();
            assert!(e.contains(want), "{bad}: {e}");
        }
    }
}
