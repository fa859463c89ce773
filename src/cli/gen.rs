//! `pathtracer gen cornell|tori N [--seed S] -o FILE.dae`: write the project's procedural
//! scenes (src/procedural.rs) in the course's COLLADA dialect.

use std::io::Write;
use std::path::PathBuf;

use clap::Args;

use super::{check_output, parse_number};
use pathtracer::{bail, procedural, Error, Result};

/// `pathtracer gen`.
#[derive(Args, Debug, Clone)]
#[command(
    about = "Write a procedural scene in the course's COLLADA dialect",
    override_usage = "pathtracer gen cornell -o FILE.dae\n       \
pathtracer gen tori TRIANGLES [--seed S] -o FILE.dae",
    after_help = "Scenes:\n  \
cornell   the Cornell box of assets/cornell.dae (area light = emissive quad, two spheres)\n  \
tori N    a grid of tori over a floor with about N triangles (10000 .. 16000000); the \
benchmark's scaling steps are 10000, 100000, 1000000 and 4000000"
)]
pub struct GenArgs {
    /// cornell or tori
    #[arg(value_name = "SCENE")]
    kind: Option<String>,
    /// The number of triangles (tori)
    #[arg(value_name = "TRIANGLES")]
    count: Option<String>,
    /// Random seed of the tori
    #[arg(long, value_name = "S", default_value = "1",
          value_parser = |s: &str| parse_number::<u64>("--seed", s))]
    seed: u64,
    /// The scene file to write
    #[arg(short = 'o', value_name = "FILE.dae")]
    output: Option<PathBuf>,
}

pub fn run(args: GenArgs) -> Result<()> {
    let GenArgs { kind, count, seed, output } = args;
    let output = output.ok_or_else(|| Error::new("gen: no output file given (-o FILE.dae)"))?;
    check_output("gen: -o", &output, &[])?;
    let count = match (kind.as_deref(), count) {
        (Some("cornell"), Some(n)) => {
            bail!("gen cornell takes no count, got '{n}' (usage: gen cornell -o FILE.dae)")
        }
        (Some("tori"), Some(n)) => Some(parse_number::<usize>("gen tori", &n)?),
        (_, n) => n.map(|_| 0), // An unknown scene: reported below.
    };
    let text = match (kind.as_deref(), count) {
        (Some("cornell"), None) => procedural::cornell_box(),
        (Some("tori"), Some(n)) if (10_000..=16_000_000).contains(&n) => procedural::tori(n, seed),
        (Some("tori"), Some(n)) => {
            bail!("gen tori: {n} triangles is out of range (10000 to 16000000)")
        }
        (Some("tori"), None) => {
            bail!("gen tori: how many triangles? (e.g. gen tori 1000000 -o tori1m.dae)")
        }
        (Some(other), _) => bail!("gen: unknown scene '{other}' (expected cornell or tori)"),
        (None, _) => bail!("gen: which scene? (see pathtracer gen --help)"),
    };
    pathtracer::staged::write_file(&output, |w| w.write_all(text.as_bytes()))?;
    outln!("wrote {}", output.display())
}
