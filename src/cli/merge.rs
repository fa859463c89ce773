//! `pathtracer merge PART... -f OUT`: join the parts of a farm render into its image, exactly;
//! `pathtracer part-info PART...`: check parts and print what each holds (one JSON line each);
//! and the part file a `--part` render writes.

use std::path::{Path, PathBuf};

use clap::Args;

use super::{check_output, Report};
use pathtracer::accel::AccelKind;
use pathtracer::farm::{self, PartFile, PartHeader};
use pathtracer::render::{RenderConfig, RenderOutput};
use pathtracer::{bail, Error, Result};

/// `pathtracer merge`.
#[derive(Args, Debug, Clone)]
#[command(
    about = "Join the parts of a farm render into its image, exactly",
    long_about = "Joins the parts of one render (pathtracer --part K/N, --samples, --crop) into \
the image the whole render gives, byte for byte. It refuses parts of different scenes, flags or \
renderer versions, and any pixel sample missing or held by two parts. With -a it also writes \
NAME_rate.png. It prints the render statistics summed over the parts.",
    arg_required_else_help = true
)]
pub struct MergeArgs {
    /// The parts (written by pathtracer --part K/N, --samples, --crop)
    #[arg(value_name = "PART.ptpart")]
    parts: Vec<PathBuf>,
    /// The image: OUT.png or OUT.exr
    #[arg(short = 'f', value_name = "OUT")]
    output: Vec<PathBuf>,
    /// Accepted for symmetry with rendering (merge shows no progress line)
    #[arg(long, short = 'q')]
    quiet: bool,
}

/// `pathtracer part-info`.
#[derive(Args, Debug, Clone)]
#[command(
    about = "Check parts and print what each holds (one JSON line each)",
    long_about = "Checks each part (a damaged or truncated file is an error) and prints one JSON \
line per part: file, renderer, scene, scene hash, flags, crop, samples.",
    arg_required_else_help = true
)]
pub struct PartInfoArgs {
    /// The parts to check
    #[arg(value_name = "PART.ptpart")]
    parts: Vec<String>,
}

pub fn run(args: MergeArgs) -> Result<()> {
    let (parts, output) = check(args)?;
    let output = output.ok_or_else(|| Error::new("merge: no output given (-f OUT.png|OUT.exr)"))?;
    let ext = output.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("png") | Some("exr")) {
        bail!("-f {}: output must end in .png or .exr", output.display());
    }
    let inputs: Vec<&Path> = parts.iter().map(PathBuf::as_path).collect();
    check_output("-f", &output, &inputs)?;
    let read: Vec<(PathBuf, PartFile)> =
        parts.iter().map(|p| Ok((p.clone(), farm::read_part(p)?))).collect::<Result<_>>()?;
    let merged = farm::merge(&read)?;
    if merged.adaptive {
        check_output("rate image", &pathtracer::film::rate_image_path(&output), &inputs)?;
    }
    let mut report = Report::default();
    let time = std::time::Duration::from_secs_f64(merged.seconds);
    report.print(format_args!(
        "[PathTracer] Merged {} parts (rendering times summed):\n",
        read.len()
    ));
    super::render::print_render_stats(&mut report, &merged.stats, time);
    // The image and, with -a, its rate image: both or neither.
    let (w, h) = (merged.width, merged.height);
    let mut outputs = pathtracer::staged::Outputs::new();
    pathtracer::film::stage_image(&mut outputs, &output, w, h, &merged.pixels)?;
    let rate = pathtracer::film::rate_image_path(&output);
    if merged.adaptive {
        pathtracer::film::stage_rate_image(&mut outputs, &rate, w, h, &merged.samples, merged.spp)?;
    }
    outputs.commit()?;
    report.print(format_args!("[PathTracer] Saved {}\n", output.display()));
    if merged.adaptive {
        report.print(format_args!("[PathTracer] Sampling rate image: {}\n", rate.display()));
    }
    report.finish()
}

fn check(args: MergeArgs) -> Result<(Vec<PathBuf>, Option<PathBuf>)> {
    if args.output.len() > 1 {
        bail!("merge: -f given twice");
    }
    if args.parts.is_empty() {
        bail!("merge: no part files given");
    }
    Ok((args.parts, args.output.into_iter().next()))
}

pub fn run_info(args: PartInfoArgs) -> Result<()> {
    let infos: Vec<String> = args
        .parts
        .iter()
        .map(|p| Ok(info_json(p, &farm::read_part(Path::new(p))?.header)))
        .collect::<Result<_>>()?;
    infos.iter().try_for_each(|line| outln!("{line}"))
}

fn info_json(file: &str, h: &PartHeader) -> String {
    let c = &h.crop;
    format!(
        "{{\"file\": {}, \"renderer\": {}, \"scene\": {}, \"scene_fnv1a64\": \"{:016x}\", \"flags\": {}, \
         \"crop\": [{}, {}, {}, {}], \"samples\": [{}, {}], \"seconds\": {}}}",
        json_string(file),
        json_string(&h.renderer),
        json_string(&h.scene),
        h.scene_hash,
        json_string(&h.flags),
        c.x0,
        c.y0,
        c.x1,
        c.y1,
        h.samples.start,
        h.samples.end,
        h.seconds
    )
}

fn json_string(s: &str) -> String {
    let mut out = String::from("\"");
    for ch in s.chars() {
        match ch {
            '"' => out += "\\\"",
            '\\' => out += "\\\\",
            c if (c as u32) < 0x20 => out += &format!("\\u{:04x}", c as u32),
            c => out.push(c),
        }
    }
    out + "\""
}

/// Writes the part a render made (`--part`, `--samples`, `--crop`, `-f X.ptpart`).
pub(super) fn write_part_file(
    scene: &Path,
    output: &Path,
    config: &RenderConfig,
    accel: AccelKind,
    out: &RenderOutput,
) -> Result<()> {
    let bytes = std::fs::read(scene)
        .map_err(|e| Error::new(format!("{}: cannot read: {e}", scene.display())))?;
    let name = scene.file_name().map_or("scene".into(), |n| n.to_string_lossy().into_owned());
    let header = PartHeader {
        renderer: env!("CARGO_PKG_VERSION").to_string(),
        scene: name,
        scene_hash: farm::fnv1a64(&bytes),
        flags: farm::image_flags(config, accel),
        crop: out.window,
        samples: config.samples.clone().unwrap_or(0..config.spp),
        stats: out.stats,
        seconds: out.time.as_secs_f64(),
    };
    let counts = copy_window(&out.samples, out.width, &out.window);
    farm::write_part(output, &PartFile { header, counts, sums: out.sums.clone() })
}

fn copy_window(image: &[u32], width: u32, w: &pathtracer::render::Rect) -> Vec<u32> {
    (w.y0..w.y1)
        .flat_map(|y| {
            image[(y * width + w.x0) as usize..(y * width + w.x1) as usize].iter().copied()
        })
        .collect()
}
