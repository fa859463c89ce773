//! The render command's flags (`pathtracer [OPTIONS] SCENE.dae`) as a clap definition, and
//! their check and conversion into a [`Cli`]: the course's flags, ours, and those of a part of a
//! farm render. `converge` reads the same flags.

use std::path::PathBuf;

use clap::{ArgAction, Args};

use super::{parse_byte_count, parse_in_range, parse_number};
use pathtracer::accel::AccelKind;
use pathtracer::integrator::{DirectLighting, Integrator};
use pathtracer::render::{Rect, RenderConfig};
use pathtracer::sampler::SamplerKind;
use pathtracer::{bail, scene, Error, Result};

/// Largest image we accept: 16384 pixels a side and 128 megapixels (1.6 GB of linear RGB).
const MAX_SIDE: u32 = 16_384;
const MAX_PIXELS: u64 = 1 << 27;

/// The flags as given. A flag's value is checked by its value parser (the error names the
/// flag); those of several values (`-r`, `-a`, `--crop`: clap has checked their count) and the
/// flags' combinations by [`RenderArgs::into_cli`].
#[derive(Args, Debug, Clone, Default)]
pub struct RenderArgs {
    /// The COLLADA scene to render
    #[arg(value_name = "SCENE.dae")]
    pub scene: Option<PathBuf>,

    /// Worker threads [default: all cores]
    #[arg(short = 't', value_name = "N", help_heading = "Course options",
          value_parser = |s: &str| parse_in_range("-t", s, 1, 1024))]
    pub threads: Option<u32>,
    /// Samples per pixel (one sample goes through the pixel centre) [default: 1]
    #[arg(short = 's', value_name = "N", help_heading = "Course options",
          value_parser = |s: &str| parse_in_range("-s", s, 1, 1 << 20))]
    pub pixel_samples: Option<u32>,
    /// Samples per area light [default: 1]
    #[arg(short = 'l', value_name = "N", help_heading = "Course options",
          value_parser = |s: &str| parse_in_range("-l", s, 1, 1 << 16))]
    pub light_samples: Option<u32>,
    /// Maximum ray depth: 0 emission only, 1 direct light, N global illumination [default: 1]
    #[arg(short = 'm', value_name = "N", help_heading = "Course options",
          value_parser = |s: &str| parse_in_range("-m", s, 0, 10_000))]
    pub max_depth: Option<u32>,
    /// Uniform hemisphere sampling for direct light (instead of light sampling)
    #[arg(short = 'H', help_heading = "Course options")]
    pub hemisphere: bool,
    /// Output image: .png (course tone map) or .exr (linear) [default: SCENE.png]
    #[arg(short = 'f', value_name = "FILE", help_heading = "Course options")]
    pub output: Option<PathBuf>,
    /// Image size in pixels [default: 800 600]
    #[arg(short = 'r', value_names = ["W", "H"], num_args = 2, action = ArgAction::Set,
          help_heading = "Course options")]
    pub resolution: Option<Vec<String>>,
    /// Adaptive sampling: test convergence every B samples, stop at tolerance TOL
    #[arg(short = 'a', value_names = ["B", "TOL"], num_args = 2, action = ArgAction::Set,
          help_heading = "Course options")]
    pub adaptive: Option<Vec<String>>,

    /// normals: shading normal as colour; light: sample the scene lights (default);
    /// hemisphere: uniform hemisphere sampling (-H); mis: emissive geometry is the light, MIS
    /// with BSDF sampling
    #[arg(long, value_name = "MODE", help_heading = "Our options", value_parser = parse_integrator)]
    pub shading: Option<Integrator>,
    /// Random seed [default: 0]; same seed, same image for any -t
    #[arg(long, value_name = "N", help_heading = "Our options",
          value_parser = |s: &str| parse_number::<u64>("--seed", s))]
    pub seed: Option<u64>,
    /// sobol: Owen-scrambled Sobol points per decision (default); independent: independent
    /// uniform numbers
    #[arg(long, value_name = "KIND", help_heading = "Our options", value_parser = parse_sampler)]
    pub sampler: Option<SamplerKind>,
    /// Extra camera rays per sample on the outlines of visible emitters, sharing the emission
    /// estimate there (less noise at the light's edge, same image); 0: none [default: 8]
    #[arg(long, value_name = "K", help_heading = "Our options",
          value_parser = |s: &str| parse_in_range("--edge-samples", s, 0, 256))]
    pub edge_samples: Option<u32>,
    /// Test every primitive for every ray (slow; for small scenes)
    #[arg(long, help_heading = "Our options")]
    pub no_bvh: bool,
    /// Normal shading with one node of the binary BVH tinted and its box outlined; PATH is L/R
    /// steps from the root (LLR), or root; prints the node's primitive count and SAH cost
    #[arg(long, value_name = "PATH", help_heading = "Our options")]
    pub bvh_node: Option<String>,
    /// Refuse a scene file larger than N bytes [default: 1073741824, 1 GiB]
    #[arg(long, value_name = "N", help_heading = "Our options",
          value_parser = |s: &str| parse_byte_count("--max-scene-bytes", s))]
    pub max_scene_bytes: Option<u64>,
    /// Print what the scene holds and exit
    #[arg(long, help_heading = "Our options")]
    pub info: bool,
    /// No progress line
    #[arg(long, short = 'q', help_heading = "Our options")]
    pub quiet: bool,
    /// After the statistics, the thread time of each stage (camera rays, closest hits,
    /// shading, shadow rays, probes, pixel sums) and each kind of ray's speed in traversal
    #[arg(long, help_heading = "Our options")]
    pub stage_times: bool,

    /// Part K (0-based) of the plan of N parts (bands of pixels, sample ranges); written to a
    /// .ptpart file that pathtracer merge joins
    #[arg(long, value_name = "K/N", help_heading = "Parts of a render for many machines",
          value_parser = parse_fraction)]
    pub part: Option<(u32, u32)>,
    /// Only samples A to B-1 of each pixel (not with -a)
    #[arg(long = "samples", value_name = "A..B",
          help_heading = "Parts of a render for many machines", value_parser = parse_samples)]
    pub sample_range: Option<std::ops::Range<u32>>,
    /// Only the pixels X0..X1-1, Y0..Y1-1 (from the top left)
    #[arg(long, value_names = ["X0", "Y0", "X1", "Y1"], num_args = 4,
          action = ArgAction::Set, help_heading = "Parts of a render for many machines")]
    pub crop: Option<Vec<String>>,
}

/// A checked render command.
#[derive(Debug)]
pub(super) struct Cli {
    pub scene: PathBuf,
    pub output: Option<PathBuf>,
    pub info: bool,
    /// The largest scene file read (`--max-scene-bytes`).
    pub max_scene_bytes: u64,
    /// `--part K/N`.
    pub part: Option<(u32, u32)>,
    pub accel: AccelKind,
    pub config: RenderConfig,
    /// `--bvh-node PATH`: the binary BVH node to preview.
    pub bvh_node: Option<String>,
}

impl RenderArgs {
    /// Checks the flags' values of several parts and their combinations.
    pub(super) fn into_cli(self) -> Result<Cli> {
        let defaults = RenderConfig::default();
        let mut config = RenderConfig {
            threads: self.threads.unwrap_or(0) as usize,
            spp: self.pixel_samples.unwrap_or(defaults.spp),
            light_samples: self.light_samples.unwrap_or(defaults.light_samples),
            edge_samples: self.edge_samples.unwrap_or(defaults.edge_samples),
            max_depth: self.max_depth.unwrap_or(defaults.max_depth),
            seed: self.seed.unwrap_or(defaults.seed),
            sampler: self.sampler.unwrap_or(defaults.sampler),
            progress: !self.quiet,
            stage_times: self.stage_times,
            integrator: Integrator::Path(DirectLighting::LightSampling),
            samples: self.sample_range,
            // `--no-bvh` tests every primitive for every ray (the write-up's comparison), so
            // no ray takes the emitters' own tree either.
            emitters_first: !self.no_bvh,
            ..defaults
        };
        if let Some(r) = &self.resolution {
            let w = parse_in_range("-r width", &r[0], 1, MAX_SIDE)?;
            let h = parse_in_range("-r height", &r[1], 1, MAX_SIDE)?;
            if w as u64 * h as u64 > MAX_PIXELS {
                bail!("-r {w} {h}: more than {MAX_PIXELS} pixels");
            }
            (config.width, config.height) = (w, h);
        }
        if let Some(a) = &self.adaptive {
            let batch = parse_in_range("-a batch", &a[0], 1, 1 << 20)?;
            let tol: f32 = parse_number("-a tolerance", &a[1])?;
            if !(tol.is_finite() && tol > 0.0) {
                bail!("-a tolerance must be a positive number, got {tol}");
            }
            config.adaptive = Some((batch, tol));
        }
        if let Some(v) = &self.crop {
            let mut c = [0; 4];
            for (x, text) in c.iter_mut().zip(v) {
                *x = parse_in_range("--crop", text, 0, MAX_SIDE)?;
            }
            config.crop = Some(Rect { x0: c[0], y0: c[1], x1: c[2], y1: c[3] });
        }
        if let Some(integrator) = self.shading {
            config.integrator = integrator;
        }
        let mut cli = Cli {
            scene: self.scene.ok_or_else(|| Error::new("no scene file given (see --help)"))?,
            output: self.output,
            info: self.info,
            max_scene_bytes: self
                .max_scene_bytes
                .unwrap_or(scene::collada::DEFAULT_MAX_SCENE_BYTES),
            part: self.part,
            accel: if self.no_bvh { AccelKind::BruteForce } else { AccelKind::Bvh },
            config,
            bvh_node: self.bvh_node,
        };
        if self.hemisphere {
            if cli.config.integrator != Integrator::Path(DirectLighting::LightSampling) {
                bail!("-H conflicts with --shading {}", cli.config.integrator.name());
            }
            cli.config.integrator = Integrator::Path(DirectLighting::Hemisphere);
        }
        if cli.bvh_node.is_some() {
            let shading_given = self.shading.is_some() || self.hemisphere;
            if cli.config.integrator != Integrator::Normals && shading_given {
                bail!(
                    "--bvh-node shows normal shading; it conflicts with --shading {}",
                    cli.config.integrator.name()
                );
            }
            cli.config.integrator = Integrator::Normals;
        }
        if cli.bvh_node.is_some() && cli.is_part() {
            bail!("--bvh-node previews a whole image; it cannot render a part (--part, --samples, --crop)");
        }
        resolve_part(&mut cli)?;
        Ok(cli)
    }
}

impl Cli {
    /// A part of a render (`--part`, `--samples`, `--crop`, or `-f X.ptpart`): the output is a
    /// part file of exact sums for `pathtracer merge`, not an image.
    pub fn is_part(&self) -> bool {
        let ptpart =
            self.output.as_deref().and_then(|p| p.extension()).is_some_and(|e| e == "ptpart");
        ptpart || self.part.is_some() || self.config.samples.is_some() || self.config.crop.is_some()
    }
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

fn parse_sampler(name: &str) -> Result<SamplerKind> {
    SamplerKind::parse(name).ok_or_else(|| {
        Error::new(format!("--sampler: unknown sampler '{name}' (expected sobol or independent)"))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn parse(s: &str) -> Result<Cli> {
        let args: Vec<String> = s.split_whitespace().map(String::from).collect();
        super::super::command::parse_render(&args)
    }

    #[test]
    fn course_flags_parse() {
        let cli = parse("-t 8 -s 64 -l 32 -m 6 -H -f out.png -r 480 360 scene.dae").unwrap();
        let c = &cli.config;
        assert_eq!((c.threads, c.spp, c.light_samples, c.max_depth), (8, 64, 32, 6));
        assert_eq!(c.integrator, Integrator::Path(DirectLighting::Hemisphere));
        assert_eq!((c.width, c.height), (480, 360));
        assert_eq!(cli.output.as_deref(), Some(Path::new("out.png")));
        assert_eq!(cli.scene, PathBuf::from("scene.dae"));
    }

    #[test]
    fn defaults_are_the_course_defaults() {
        let cli = parse("scene.dae").unwrap();
        let c = &cli.config;
        assert_eq!((c.threads, c.spp, c.light_samples, c.max_depth), (0, 1, 1, 1));
        assert_eq!((c.width, c.height, c.seed), (800, 600, 0));
        assert_eq!(c.integrator, Integrator::Path(DirectLighting::LightSampling));
        assert!(c.progress && c.adaptive.is_none() && !cli.info && cli.output.is_none());
        assert_eq!(cli.accel, AccelKind::Bvh);
        assert_eq!(cli.max_scene_bytes, scene::collada::DEFAULT_MAX_SCENE_BYTES);
        // The last of a repeated flag counts, as before clap.
        assert_eq!(parse("-s 2 -s 3 x.dae").unwrap().config.spp, 3);
        assert_eq!(parse("-r 8 6 -r 4 2 x.dae").unwrap().config.width, 4);
    }

    #[test]
    fn bvh_node_renders_normals() {
        let cli = parse("--bvh-node LR x.dae").unwrap();
        assert_eq!(cli.bvh_node.as_deref(), Some("LR"));
        assert_eq!(cli.config.integrator, Integrator::Normals);
        let cli = parse("--shading normals --bvh-node root x.dae").unwrap();
        assert_eq!(cli.bvh_node.as_deref(), Some("root"));
    }

    #[test]
    fn adaptive_flag_takes_two_values() {
        let cli = parse("-a 64 0.05 x.dae").unwrap();
        assert_eq!(cli.config.adaptive, Some((64, 0.05)));
    }

    #[test]
    fn bad_flags_are_one_line_errors() {
        for (a, want) in [
            ("-r 0 600 x.dae", "out of range"),
            ("-r -5 600 x.dae", "out of range"),
            ("-r 800 x.dae", "not a valid number"),
            ("-r 800", "-r height needs a value (-r W H)"),
            ("--crop 0 0 1", "--crop Y1 needs a value (--crop X0 Y0 X1 Y1)"),
            ("-s abc x.dae", "not a valid number"),
            ("-t 0 x.dae", "out of range"),
            ("-s 99999999999 x.dae", "out of range"),
            ("-r 16384 16384 x.dae", "pixels"),
            ("-a 4 nan x.dae", "positive"),
            ("-a 4 -1 x.dae", "positive"),
            ("--bogus x.dae", "unknown option '--bogus'"),
            ("-s", "-s needs a value"),
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
            ("x.dae --bvh-node", "--bvh-node needs a value"),
            ("--max-scene-bytes 0 x.dae", "--max-scene-bytes: expected a positive"),
            ("--max-scene-bytes -1 x.dae", "--max-scene-bytes: '-1' is not a valid number"),
        ] {
            let err = parse(a).unwrap_err().to_string();
            assert!(err.contains(want), "{a}: got '{err}', want '{want}'");
            assert!(!err.contains('\n'));
        }
    }
}
