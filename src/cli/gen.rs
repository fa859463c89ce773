//! `pathtracer gen cornell|tori N [--seed S] -o FILE.dae`: write the project's procedural
//! scenes (src/procedural.rs) in the course's COLLADA dialect.

use std::io::Write;
use std::path::PathBuf;

use super::{check_output, parse_number};
use pathtracer::{bail, procedural, Error, Result};

const USAGE: &str = "\
Usage: pathtracer gen cornell -o FILE.dae
       pathtracer gen tori TRIANGLES [--seed S] -o FILE.dae

Writes a deterministic scene in the course's COLLADA dialect:
  cornell         the Cornell box of assets/cornell.dae (area light = emissive quad, two spheres)
  tori N          a grid of tori over a floor with about N triangles (10000 .. 16000000);
                  the benchmark's scaling steps are 10000, 100000, 1000000 and 4000000";

pub fn run(args: &[String]) -> Result<()> {
    if args.iter().any(|a| a == "-h" || a == "--help") {
        return outln!("{USAGE}");
    }
    let (mut kind, mut count, mut seed, mut output) = (None, None, 1u64, None);
    let mut it = args.iter().map(String::as_str);
    while let Some(arg) = it.next() {
        let mut value =
            |name: &str| it.next().ok_or_else(|| Error::new(format!("{name} needs a value")));
        match arg {
            "-o" => output = Some(PathBuf::from(value("-o")?)),
            "--seed" => seed = parse_number("--seed", value("--seed")?)?,
            a if a.starts_with('-') && a.len() > 1 => {
                bail!("gen: unknown option '{a}' (see gen --help)")
            }
            word if kind.is_none() => kind = Some(word.to_string()),
            number if count.is_none() => count = Some(number.to_string()),
            extra => bail!("gen: unexpected argument '{extra}'"),
        }
    }
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
        (None, _) => bail!("gen: which scene? (see gen --help)"),
    };
    pathtracer::staged::write_file(&output, |w| w.write_all(text.as_bytes()))?;
    outln!("wrote {}", output.display())
}
