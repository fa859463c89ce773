//! `pathtracer [OPTIONS] SCENE.dae`: render a scene to an image.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::{check_output, parse_byte_count, parse_in_range, parse_number, Report};
use pathtracer::accel::{binary_node, Accel, AccelKind, BinaryNode, BuildParams};
use pathtracer::film;
use pathtracer::integrator::{DirectLighting, Integrator};
use pathtracer::render::{render, Rect, RenderConfig};
use pathtracer::sampler::SamplerKind;
use pathtracer::staged::Outputs;
use pathtracer::{bail, bvh_preview, scene, Error, Result};

const USAGE: &str = "\
Usage: pathtracer [OPTIONS] SCENE.dae
       pathtracer --info SCENE.dae
       pathtracer bench SCENE.dae [BENCH OPTIONS]   (see pathtracer bench --help)
       pathtracer compare IMAGE REFERENCE [--mask MASK]   (error metrics)
       pathtracer converge SCENE.dae --spp LIST ...      (error and time against spp)
       pathtracer gen cornell|tori N -o FILE.dae     (see pathtracer gen --help)
       pathtracer chart accuracy|scaling ...         (see pathtracer chart --help)
       pathtracer --part K/N [OPTIONS] SCENE.dae -f PART.ptpart   (one part of a farm render)
       pathtracer merge PART.ptpart... -f OUT.png|OUT.exr      (see pathtracer merge --help)

Renders a CS184 COLLADA scene (course camera and lighting conventions).

Course options:
  -t N        worker threads (default: all cores)
  -s N        samples per pixel (default 1; one sample goes through the pixel centre)
  -l N        samples per area light (default 1)
  -m N        maximum ray depth (default 1)
  -H          uniform hemisphere sampling for direct light (instead of light sampling)
  -f FILE     output image: .png (course tone map) or .exr (linear) (default: SCENE.png)
  -r W H      image size in pixels (default 800 600)
  -a B TOL    adaptive sampling: test convergence every B samples, stop at tolerance TOL

Our options:
  --shading MODE      normals: shading normal as colour 0.5 n + 0.5;
                      light: sample the scene lights (default; -H switches to hemisphere);
                      hemisphere: uniform hemisphere sampling (same as -H);
                      mis: emissive geometry is the light, MIS with BSDF sampling
  --seed N            random seed (default 0); same seed, same image for any -t
  --sampler KIND      sobol: Owen-scrambled Sobol points per decision (default);
                      independent: independent uniform numbers
  --no-bvh            test every primitive for every ray (slow; for small scenes)
  --bvh-node PATH     normal shading with one node of the binary BVH tinted and its box
                      outlined; PATH is L/R steps from the root (LLR), or root; prints the
                      node's primitive count and SAH cost
  --max-scene-bytes N refuse a scene file larger than N bytes (default 1073741824, 1 GiB)
  --info              print what the scene holds and exit
  --quiet             no progress line

Parts of a render for many machines (written to a .ptpart file; pathtracer merge joins them):
  --part K/N          part K (0-based) of the plan of N parts (bands of pixels, sample ranges)
  --samples A..B      only samples A to B-1 of each pixel (not with -a)
  --crop X0 Y0 X1 Y1  only the pixels X0..X1-1, Y0..Y1-1 (from the top left)
  -h, --help          this help
  -V, --version       version";

/// Largest image we accept: 16384 pixels a side and 128 megapixels (1.6 GB of linear RGB).
const MAX_SIDE: u32 = 16_384;
const MAX_PIXELS: u64 = 1 << 27;

#[derive(Debug)]
pub(super) struct Cli {
    pub scene: PathBuf,
    pub output: Option<PathBuf>,
    pub info: bool,
    /// The largest scene file read (`--max-scene-bytes`).
    pub max_scene_bytes: u64,
    hemisphere: bool,
    /// `--part K/N`.
    part: Option<(u32, u32)>,
    pub accel: AccelKind,
    pub config: RenderConfig,
    /// `--bvh-node PATH`: the binary BVH node to preview.
    pub bvh_node: Option<String>,
}

pub fn run(args: &[String]) -> Result<()> {
    if args.iter().any(|a| a == "-h" || a == "--help") {
        return outln!("{USAGE}");
    }
    if args.iter().any(|a| a == "-V" || a == "--version") {
        return outln!("pathtracer {}", env!("CARGO_PKG_VERSION"));
    }
    let cli = parse_args(args)?;
    if cli.info {
        return print_info(&cli);
    }
    render_to_file(&cli)
}

fn print_info(cli: &Cli) -> Result<()> {
    let scene = scene::collada::load_with_limit(&cli.scene, cli.max_scene_bytes)?;
    out!("{}", scene::info::summary(&scene, cli.config.width, cli.config.height))
}

fn render_to_file(cli: &Cli) -> Result<()> {
    let output = cli.output.clone().unwrap_or_else(|| default_output(cli));
    check_output_path(&output, is_part(cli))?;
    let what = if cli.output.is_some() { "-f" } else { "output (the scene's name with .png)" };
    check_output(what, &output, &[&cli.scene])?;
    if cli.config.adaptive.is_some() && !is_part(cli) {
        let rate = pathtracer::film::rate_image_path(&output);
        check_output("rate image", &rate, &[&cli.scene])?;
    }
    let config = &RenderConfig { keep_sums: is_part(cli), ..cli.config.clone() };
    let threads = if config.threads == 0 { available_threads() } else { config.threads };
    // The statistics go to stdout through a Report: whether they can be printed (a full disk,
    // `| head -1`) does not decide whether the image is written. A failed print is reported
    // after the image is saved.
    let mut report = Report::default();
    report.print(format_args!("[PathTracer] Input scene file: {}\n", cli.scene.display()));
    report.print(format_args!("[PathTracer] Rendering using {threads} threads\n"));

    let t0 = Instant::now();
    let scene = scene::collada::load_with_limit(&cli.scene, cli.max_scene_bytes)?;
    Accel::check_limits(&scene).map_err(|e| e.in_scene(Some(&cli.scene)))?;
    report.print(format_args!(
        "[PathTracer] Collecting primitives... Done! ({:.4} sec)\n",
        t0.elapsed().as_secs_f64()
    ));
    for w in scene.warnings.iter().chain(&lighting_warnings(&scene, config.integrator)) {
        errln!("warning: {}: {w}", cli.scene.display());
    }

    // The previewed node is found before the render, so a path off the tree fails at once.
    let node = cli.bvh_node.as_deref().map(|path| preview_node(&scene, path)).transpose()?;
    if let Some(n) = &node {
        report.print(format_args!(
            "[PathTracer] BVH node {}: {} primitives, SAH cost {:.4}\n",
            n.path,
            n.prims.len(),
            n.sah_cost
        ));
    }

    let prims = scene.triangles.len() + scene.spheres.len();
    let accel = Accel::build(&scene, cli.accel);
    match cli.accel {
        AccelKind::Bvh => report.print(format_args!(
            "[PathTracer] Building BVH from {prims} primitives... Done! ({:.4} sec)\n",
            accel.build_time().as_secs_f64()
        )),
        AccelKind::BruteForce => report.print(format_args!(
            "[PathTracer] No BVH (--no-bvh): {prims} primitives tested per ray\n"
        )),
    }

    let mut out = render(&scene, &accel, config)?;
    if let Some(n) = &node {
        let camera = bvh_preview::camera_for(&scene, config);
        bvh_preview::mark_node(&mut out.pixels, &camera, &accel, n);
    }
    print_render_stats(&mut report, &out.stats, out.time);
    if is_part(cli) {
        report.print(format_args!("[PathTracer] Saving part to file: {}... ", output.display()));
        super::merge::write_part_file(&cli.scene, &output, config, cli.accel, &out)?;
        report.print(format_args!("Done!\n[PathTracer] Job completed.\n"));
        return report.finish();
    }

    report.print(format_args!("[PathTracer] Saving to file: {}... ", output.display()));
    // The image and the rate image are written together: if either fails, neither replaces
    // an existing file.
    let mut outputs = Outputs::new();
    film::stage_image(&mut outputs, &output, out.width, out.height, &out.pixels)?;
    let rate = film::rate_image_path(&output);
    if config.adaptive.is_some() {
        film::stage_rate_image(
            &mut outputs,
            &rate,
            out.width,
            out.height,
            &out.samples,
            config.spp,
        )?;
    }
    outputs.commit()?;
    report.print(format_args!("Done!\n"));
    if config.adaptive.is_some() {
        report.print(format_args!("[PathTracer] Sampling rate image: {}\n", rate.display()));
    }
    report.print(format_args!("[PathTracer] Job completed.\n"));
    report.finish()
}

fn preview_node(scene: &scene::Scene, path: &str) -> Result<BinaryNode> {
    binary_node(scene, path, BuildParams::default()).map_err(|e| e.context("--bvh-node"))
}

pub(super) fn print_render_stats(
    report: &mut Report,
    s: &pathtracer::wavefront::RenderStats,
    time: std::time::Duration,
) {
    let secs = time.as_secs_f64();
    let rays = s.total_rays();
    let per_ray = |n: u64| n as f64 / rays.max(1) as f64;
    report.print(format_args!("[PathTracer] Rendering... 100%! ({secs:.4}s)\n"));
    report.print(format_args!(
        "[PathTracer] BVH traced {rays} rays ({} camera, {} bounce, {} shadow, {} hemisphere).\n",
        s.camera_rays, s.bounce_rays, s.shadow_rays, s.probe_rays
    ));
    report.print(format_args!(
        "[PathTracer] Average speed {:.4} million rays per second.\n",
        rays as f64 / secs.max(1e-9) / 1e6
    ));
    let prim_tests = s.trace.triangle_tests + s.trace.sphere_tests;
    report.print(format_args!(
        "[PathTracer] Averaged {:.6} intersection tests per ray ({:.6} BVH node tests + {:.6} primitive tests).\n",
        per_ray(s.trace.node_tests + prim_tests),
        per_ray(s.trace.node_tests),
        per_ray(prim_tests)
    ));
}

pub(super) fn available_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// `dir/scene.dae` -> `scene.png` in the current directory (`scene.part-K-of-N.ptpart` or
/// `scene.ptpart` for a part).
fn default_output(cli: &Cli) -> PathBuf {
    let stem = cli.scene.file_stem().map_or("out".into(), |s| s.to_string_lossy().into_owned());
    match cli.part {
        Some((k, n)) => PathBuf::from(format!("{stem}.part-{k}-of-{n}.ptpart")),
        None if is_part(cli) => PathBuf::from(format!("{stem}.ptpart")),
        None => PathBuf::from(format!("{stem}.png")),
    }
}

/// A part of a render (`--part`, `--samples`, `--crop`, or `-f X.ptpart`): the output is a
/// part file of exact sums for `pathtracer merge`, not an image.
fn is_part(cli: &Cli) -> bool {
    let ptpart = cli.output.as_deref().and_then(|p| p.extension()).is_some_and(|e| e == "ptpart");
    ptpart || cli.part.is_some() || cli.config.samples.is_some() || cli.config.crop.is_some()
}

/// Fail before rendering (not after minutes of work) if the output cannot be written.
fn check_output_path(path: &Path, part: bool) -> Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if part && ext.as_deref() != Some("ptpart") {
        bail!("-f {}: a part (--part, --samples, --crop) is written to a .ptpart file (join parts with pathtracer merge)", path.display());
    }
    if !part && !matches!(ext.as_deref(), Some("png") | Some("exr")) {
        bail!("-f {}: output must end in .png or .exr", path.display());
    }
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !parent.is_dir() {
        bail!("-f {}: directory {} does not exist", path.display(), parent.display());
    }
    Ok(())
}

pub(super) fn parse_args(args: &[String]) -> Result<Cli> {
    let mut cli = Cli {
        scene: PathBuf::new(),
        output: None,
        info: false,
        max_scene_bytes: scene::collada::DEFAULT_MAX_SCENE_BYTES,
        hemisphere: false,
        part: None,
        accel: AccelKind::Bvh,
        bvh_node: None,
        config: RenderConfig {
            threads: 0,
            progress: true,
            integrator: Integrator::Path(DirectLighting::LightSampling),
            ..RenderConfig::default()
        },
    };
    let mut scene = None;
    let mut shading_given = false;
    let mut it = args.iter().map(String::as_str);
    while let Some(arg) = it.next() {
        let mut value =
            |name: &str| it.next().ok_or_else(|| Error::new(format!("{name} needs a value")));
        match arg {
            "-t" => cli.config.threads = parse_in_range("-t", value("-t")?, 1, 1024)? as usize,
            "-s" => cli.config.spp = parse_in_range("-s", value("-s")?, 1, 1 << 20)?,
            "-l" => cli.config.light_samples = parse_in_range("-l", value("-l")?, 1, 1 << 16)?,
            "-m" => cli.config.max_depth = parse_in_range("-m", value("-m")?, 0, 10_000)?,
            "-H" => cli.hemisphere = true,
            "-f" => cli.output = Some(PathBuf::from(value("-f")?)),
            "-r" => {
                let w = parse_in_range("-r width", value("-r")?, 1, MAX_SIDE)?;
                let h = parse_in_range("-r height", value("-r (height)")?, 1, MAX_SIDE)?;
                if w as u64 * h as u64 > MAX_PIXELS {
                    bail!("-r {w} {h}: more than {MAX_PIXELS} pixels");
                }
                (cli.config.width, cli.config.height) = (w, h);
            }
            "-a" => {
                let batch = parse_in_range("-a batch", value("-a")?, 1, 1 << 20)?;
                let tol: f32 = parse_number("-a tolerance", value("-a (tolerance)")?)?;
                if !(tol.is_finite() && tol > 0.0) {
                    bail!("-a tolerance must be a positive number, got {tol}");
                }
                cli.config.adaptive = Some((batch, tol));
            }
            "--seed" => cli.config.seed = parse_number("--seed", value("--seed")?)?,
            "--shading" => {
                cli.config.integrator = parse_integrator(value("--shading")?)?;
                shading_given = true;
            }
            "--bvh-node" => cli.bvh_node = Some(value("--bvh-node")?.to_string()),
            "--sampler" => {
                let name = value("--sampler")?;
                cli.config.sampler = SamplerKind::parse(name).ok_or_else(|| {
                    Error::new(format!(
                        "--sampler: unknown sampler '{name}' (expected sobol or independent)"
                    ))
                })?;
            }
            "--no-bvh" => cli.accel = AccelKind::BruteForce,
            "--part" => cli.part = Some(parse_fraction(value("--part")?)?),
            "--samples" => cli.config.samples = Some(parse_samples(value("--samples")?)?),
            "--crop" => {
                let mut c = [0; 4];
                for (i, v) in c.iter_mut().enumerate() {
                    *v = parse_in_range(
                        "--crop",
                        value(["--crop", "--crop (Y0)", "--crop (X1)", "--crop (Y1)"][i])?,
                        0,
                        MAX_SIDE,
                    )?;
                }
                cli.config.crop = Some(Rect { x0: c[0], y0: c[1], x1: c[2], y1: c[3] });
            }
            "--max-scene-bytes" => {
                cli.max_scene_bytes =
                    parse_byte_count("--max-scene-bytes", value("--max-scene-bytes")?)?
            }
            "--info" => cli.info = true,
            "--quiet" | "-q" => cli.config.progress = false,
            a if a.starts_with('-') && a.len() > 1 => bail!("unknown option '{a}' (see --help)"),
            path => {
                if let Some(first) = scene.replace(PathBuf::from(path)) {
                    bail!("more than one scene file given: '{}' and '{path}'", first.display());
                }
            }
        }
    }
    cli.scene = scene.ok_or_else(|| Error::new("no scene file given (see --help)"))?;
    if cli.hemisphere {
        if cli.config.integrator != Integrator::Path(DirectLighting::LightSampling) {
            bail!("-H conflicts with --shading {}", cli.config.integrator.name());
        }
        cli.config.integrator = Integrator::Path(DirectLighting::Hemisphere);
    }
    if cli.bvh_node.is_some() {
        if cli.config.integrator != Integrator::Normals && (shading_given || cli.hemisphere) {
            bail!(
                "--bvh-node shows normal shading; it conflicts with --shading {}",
                cli.config.integrator.name()
            );
        }
        cli.config.integrator = Integrator::Normals;
    }
    if cli.bvh_node.is_some() && is_part(&cli) {
        bail!("--bvh-node previews a whole image; it cannot render a part (--part, --samples, --crop)");
    }
    resolve_part(&mut cli)?;
    Ok(cli)
}

/// `--part K/N` becomes the plan's crop and samples; explicit ranges are checked.
fn resolve_part(cli: &mut Cli) -> Result<()> {
    let c = &mut cli.config;
    if let Some((k, n)) = cli.part {
        if c.samples.is_some() || c.crop.is_some() {
            bail!("--part {k}/{n} conflicts with --samples and --crop (give a part of the plan or the ranges, not both)");
        }
        let part = pathtracer::farm::plan_part(c.width, c.height, c.spp, k, n)?;
        if c.adaptive.is_some() && part.samples != (0..c.spp) {
            bail!("--part {k}/{n}: the plan of {n} parts splits each pixel's samples, which adaptive sampling (-a) cannot do; use at most {} parts (one per band of 16 rows)", c.height.div_ceil(pathtracer::wavefront::TILE));
        }
        (c.samples, c.crop) = (Some(part.samples), Some(part.crop));
    }
    if let Some(s) = &c.samples {
        if s.end > c.spp {
            bail!("--samples {}..{}: beyond -s {}", s.start, s.end, c.spp);
        }
        if c.adaptive.is_some() && *s != (0..c.spp) {
            bail!("--samples {}..{}: adaptive sampling (-a) decides per pixel how many samples to take, so it cannot render a range of them (split the pixels with --crop instead)", s.start, s.end);
        }
    }
    if let Some(r) = c.crop {
        if r.x0 >= r.x1 || r.y0 >= r.y1 || r.x1 > c.width || r.y1 > c.height {
            bail!(
                "--crop {} {} {} {}: expected X0 < X1 <= {} and Y0 < Y1 <= {} (-r {} {})",
                r.x0,
                r.y0,
                r.x1,
                r.y1,
                c.width,
                c.height,
                c.width,
                c.height
            );
        }
    }
    Ok(())
}

/// `K/N` of `--part`.
fn parse_fraction(text: &str) -> Result<(u32, u32)> {
    let bad = || Error::new(format!("--part: expected K/N with 0 <= K < N, got '{text}'"));
    let (k, n) = text.split_once('/').ok_or_else(bad)?;
    let (k, n): (u32, u32) = (k.parse().map_err(|_| bad())?, n.parse().map_err(|_| bad())?);
    if k >= n {
        return Err(bad());
    }
    Ok((k, n))
}

/// `A..B` of `--samples`.
fn parse_samples(text: &str) -> Result<std::ops::Range<u32>> {
    let bad = || Error::new(format!("--samples: expected A..B with 0 <= A < B, got '{text}'"));
    let (a, b) = text.split_once("..").ok_or_else(bad)?;
    let (a, b): (u32, u32) = (a.parse().map_err(|_| bad())?, b.parse().map_err(|_| bad())?);
    if a >= b {
        return Err(bad());
    }
    Ok(a..b)
}

fn parse_integrator(name: &str) -> Result<Integrator> {
    match name {
        "normals" => Ok(Integrator::Normals),
        "light" => Ok(Integrator::Path(DirectLighting::LightSampling)),
        "hemisphere" => Ok(Integrator::Path(DirectLighting::Hemisphere)),
        "mis" => Ok(Integrator::Path(DirectLighting::Mis)),
        other => bail!(
            "--shading: unknown integrator '{other}' (expected normals, light, hemisphere or mis)"
        ),
    }
}

/// Warnings about lights an estimator cannot reach: never silently render black.
pub(super) fn lighting_warnings(scene: &scene::Scene, integrator: Integrator) -> Vec<String> {
    let count = |kind: &str| scene.lights.iter().filter(|l| l.kind() == kind).count();
    let mut out = Vec::new();
    match integrator {
        Integrator::Path(DirectLighting::Hemisphere) => {
            let delta = count("point") + count("directional");
            if delta > 0 {
                out.push(format!(
                    "uniform hemisphere sampling (-H) cannot find the scene's {delta} point/directional light(s): \
                     a random direction never hits a delta light"
                ));
            }
            let other = count("area") + count("ambient");
            if other > 0 {
                out.push(format!(
                    "uniform hemisphere sampling (-H) sees only emissive geometry; the scene's {other} area/ambient \
                     light(s) are not geometry and are reached only by light sampling"
                ));
            }
            if !scene.has_emissive_geometry() {
                out.push(
                    "the scene has no emissive geometry: with -H the image will be black".into(),
                );
            }
        }
        Integrator::Path(DirectLighting::Mis)
            if !scene.has_emissive_geometry() && scene.lights.is_empty() =>
        {
            out.push(
                "the scene has no emissive geometry and no lights: the image will be black".into(),
            );
        }
        Integrator::Path(DirectLighting::LightSampling) if scene.lights.is_empty() => {
            out.push("the scene has no lights: light sampling will only show emissive geometry seen directly".into());
        }
        _ => {}
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(s: &str) -> Vec<String> {
        s.split_whitespace().map(String::from).collect()
    }

    #[test]
    fn course_flags_parse() {
        let cli =
            parse_args(&args("-t 8 -s 64 -l 32 -m 6 -H -f out.png -r 480 360 scene.dae")).unwrap();
        let c = &cli.config;
        assert_eq!((c.threads, c.spp, c.light_samples, c.max_depth), (8, 64, 32, 6));
        assert_eq!(c.integrator, Integrator::Path(DirectLighting::Hemisphere));
        assert_eq!((c.width, c.height), (480, 360));
        assert_eq!(cli.output.as_deref(), Some(Path::new("out.png")));
        assert_eq!(cli.scene, PathBuf::from("scene.dae"));
    }

    #[test]
    fn bvh_node_renders_normals() {
        let cli = parse_args(&args("--bvh-node LR x.dae")).unwrap();
        assert_eq!(cli.bvh_node.as_deref(), Some("LR"));
        assert_eq!(cli.config.integrator, Integrator::Normals);
        let cli = parse_args(&args("--shading normals --bvh-node root x.dae")).unwrap();
        assert_eq!(cli.bvh_node.as_deref(), Some("root"));
    }

    #[test]
    fn adaptive_flag_takes_two_values() {
        let cli = parse_args(&args("-a 64 0.05 x.dae")).unwrap();
        assert_eq!(cli.config.adaptive, Some((64, 0.05)));
    }

    #[test]
    fn bad_flags_are_one_line_errors() {
        for (a, want) in [
            ("-r 0 600 x.dae", "out of range"),
            ("-r -5 600 x.dae", "out of range"),
            ("-r 800 x.dae", "not a valid number"),
            ("-s abc x.dae", "not a valid number"),
            ("-t 0 x.dae", "out of range"),
            ("-s 99999999999 x.dae", "out of range"),
            ("-r 16384 16384 x.dae", "pixels"),
            ("-a 4 nan x.dae", "positive"),
            ("-a 4 -1 x.dae", "positive"),
            ("--bogus x.dae", "unknown option"),
            ("-s", "needs a value"),
            ("a.dae b.dae", "more than one scene"),
            ("-s 4", "no scene file"),
            ("--shading foo x.dae", "unknown integrator"),
            ("-H --shading mis x.dae", "conflicts"),
            ("--part 2/2 x.dae", "expected K/N"),
            ("--part 1 x.dae", "expected K/N"),
            ("--part 0/4 --crop 0 0 1 1 x.dae", "conflicts"),
            ("-s 8 --samples 3..3 x.dae", "expected A..B"),
            ("-s 8 --samples 3..9 x.dae", "beyond -s 8"),
            ("-s 8 -a 4 0.1 --samples 0..4 x.dae", "adaptive"),
            ("-s 8 -a 4 0.1 -r 64 48 --part 0/4 x.dae", "adaptive"),
            ("-s 2 -r 64 48 --part 0/5 x.dae", "cannot be cut"),
            ("-r 64 48 --crop 0 0 65 1 x.dae", "--crop 0 0 65 1"),
            ("--crop 0 0 1 x.dae", "not a valid number"),
            ("--bvh-node L --part 0/2 -s 2 x.dae", "cannot render a part"),
            ("--bvh-node L --shading light x.dae", "conflicts"),
            ("--bvh-node L -H x.dae", "conflicts"),
            ("x.dae --bvh-node", "needs a value"),
            ("--max-scene-bytes 0 x.dae", "--max-scene-bytes: expected a positive"),
            ("--max-scene-bytes -1 x.dae", "--max-scene-bytes: '-1' is not a valid number"),
        ] {
            let err = parse_args(&args(a)).unwrap_err().to_string();
            assert!(err.contains(want), "{a}: got '{err}', want '{want}'");
            assert!(!err.contains('\n'));
        }
    }

    #[test]
    fn output_must_be_png_or_exr_in_an_existing_directory() {
        assert!(check_output_path(Path::new("a.png"), false).is_ok());
        assert!(check_output_path(Path::new("a.EXR"), false).is_ok());
        assert!(check_output_path(Path::new("a.ptpart"), true).is_ok());
        assert!(check_output_path(Path::new("a.png"), true).is_err());
        assert!(check_output_path(Path::new("a.jpg"), false)
            .unwrap_err()
            .to_string()
            .contains(".png or .exr"));
        let e = check_output_path(Path::new("/no/such/dir/a.png"), false).unwrap_err().to_string();
        assert!(e.contains("does not exist"), "{e}");
    }
}
