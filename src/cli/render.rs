//! `pathtracer [OPTIONS] SCENE.dae`: render a scene to an image (the flags: `render_args.rs`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::render_args::{Cli, RenderArgs};
use super::{check_output, Report};
use pathtracer::accel::{binary_node, Accel, AccelKind, BinaryNode, BuildParams};
use pathtracer::film;
use pathtracer::integrator::{DirectLighting, Integrator};
use pathtracer::render::{render, RenderConfig};
use pathtracer::staged::Outputs;
use pathtracer::{bail, bvh_preview, scene, Result};

pub fn run(args: RenderArgs) -> Result<()> {
    let cli = args.into_cli()?;
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
    check_output_path(&output, cli.is_part())?;
    let what = if cli.output.is_some() { "-f" } else { "output (the scene's name with .png)" };
    check_output(what, &output, &[&cli.scene])?;
    if cli.config.adaptive.is_some() && !cli.is_part() {
        let rate = pathtracer::film::rate_image_path(&output);
        check_output("rate image", &rate, &[&cli.scene])?;
    }
    let config = &RenderConfig { keep_sums: cli.is_part(), ..cli.config.clone() };
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
    // Finite but absurd scene numbers (a colour of 3.4e38) overflow f32 on the way: said, not
    // hidden (PERF.md, "Loader fuzzing").
    let non_finite = out.pixels.iter().filter(|p| !p.is_finite()).count();
    if non_finite > 0 {
        errln!(
            "warning: {}: {non_finite} pixels are NaN or infinite: the scene's numbers overflow \
             32-bit floats (e.g. a colour or radiance near 3.4e38)",
            cli.scene.display()
        );
    }
    if let Some(n) = &node {
        let camera = bvh_preview::camera_for(&scene, config);
        bvh_preview::mark_node(&mut out.pixels, &camera, &accel, n);
    }
    if let Some((prims, secs)) = out.emitter_tree {
        // Built by the render (before its clock starts), so reported once it returns.
        report.print(format_args!(
            "[PathTracer] Building the emitters' BVH from {prims} primitives... Done! ({:.4} sec)\n",
            secs.as_secs_f64()
        ));
    }
    print_render_stats(&mut report, &out.stats, out.time);
    if config.stage_times {
        print_stage_times(&mut report, &out.stats, &out.stage_times);
    }
    if cli.is_part() {
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
        "[PathTracer] BVH traced {rays} rays ({} camera, {} bounce, {} shadow, {} probe).\n",
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

/// The `--stage-times` line: each stage's thread time, the speed of each kind of ray in its
/// traversal stage, and traversal's share of the stages' time.
fn print_stage_times(
    report: &mut Report,
    s: &pathtracer::wavefront::RenderStats,
    t: &pathtracer::wavefront::StageTimes,
) {
    let secs = |d: std::time::Duration| d.as_secs_f64();
    let rate = |rays: u64, d: std::time::Duration| rays as f64 / secs(d).max(1e-9) / 1e6;
    let total = secs(t.total());
    report.print(format_args!(
        "[PathTracer] Stage times (thread seconds): camera rays {:.4}, camera hits {:.4} ({:.2} Mrays/s), \
         shading {:.4}, bounce hits {:.4} ({:.2} Mrays/s), shadow rays {:.4} ({:.2} Mrays/s), \
         probes {:.4}, pixel sums {:.4}; traversal {:.1}% of {:.4}.\n",
        secs(t.generate),
        secs(t.camera_hits),
        rate(s.camera_rays, t.camera_hits),
        secs(t.shade),
        secs(t.bounce_hits),
        rate(s.bounce_rays, t.bounce_hits),
        secs(t.shadow_rays),
        rate(s.shadow_rays, t.shadow_rays),
        secs(t.probes),
        secs(t.accumulate),
        100.0 * secs(t.traversal()) / total.max(1e-12),
        total
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
        None if cli.is_part() => PathBuf::from(format!("{stem}.ptpart")),
        None => PathBuf::from(format!("{stem}.png")),
    }
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
