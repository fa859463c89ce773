//! `pathtracer chart accuracy|scaling ...`: the charts of PERF.md, drawn by the project itself
//! (plotters, SVG).

mod accuracy;
mod peer;
mod scaling;

use pathtracer::{bail, Result};

const USAGE: &str = "\
Usage: pathtracer chart accuracy SCENE.dae OUT_DIR [-r W H] [--ref-spp N] [--spp LIST] [-t N] [--depths LIST]
                                  [--peer FILE.jsonl] [--max-scene-bytes N]
       pathtracer chart scaling BENCH.jsonl OUT.svg

  accuracy   relative RMSE against render time for every integrator, one SVG (and CSV) per depth;
             --peer FILE.jsonl adds another renderer's runs as dashed series: the lines (one
             flat JSON object each, with scene, size, m, spp, renderer, seconds, rel_noise)
             whose scene is SCENE's file name, at each chart's depth m, one series per
             renderer and size; the file is checked before anything renders
  scaling    Mrays/s, build time and bytes per triangle against triangle count, from
             `pathtracer bench --json` lines";

pub fn run(args: &[String]) -> Result<()> {
    match args.first().map(String::as_str) {
        Some("accuracy") => accuracy::run(&args[1..]),
        Some("scaling") => scaling::run(&args[1..]),
        Some("-h" | "--help") | None => outln!("{USAGE}"),
        Some(other) => bail!("chart: unknown chart '{other}' (expected accuracy or scaling)"),
    }
}
