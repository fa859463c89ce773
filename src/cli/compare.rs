//! `pathtracer compare IMAGE REFERENCE [--mask MASK]`: error metrics of an image against a
//! reference (see `pathtracer::metrics` for the definitions).

use std::path::{Path, PathBuf};

use clap::Args;

use pathtracer::metrics::{self, Comparison, Image, RegionError};
use pathtracer::{bail, Error, Result};

/// `pathtracer compare`.
#[derive(Args, Debug, Clone)]
#[command(
    about = "Error metrics of an image against a reference",
    override_usage = "pathtracer compare IMAGE REFERENCE [--mask MASK.png]",
    long_about = "Prints RMSE, relative RMSE (RMSE / mean of the reference) and mean bias (image - \
reference) per channel and over all channels, for the whole image and for the mask's nonzero \
pixels.\n\nEXR files are read as linear radiance; PNG as display values in [0, 1]: both images \
must be of the same kind (EXR with EXR, PNG with PNG). A NaN or infinite pixel is an error. Both \
images (and the mask) must have the same size."
)]
pub struct CompareArgs {
    /// The image and the reference
    #[arg(value_names = ["IMAGE", "REFERENCE"])]
    files: Vec<PathBuf>,
    /// Also report errors over the mask's nonzero pixels
    #[arg(long, value_name = "MASK.png")]
    mask: Vec<PathBuf>,
}

pub fn run(args: CompareArgs) -> Result<()> {
    let (image_path, reference_path, mask_path) = check(args)?;
    let image = metrics::read_image(&image_path)?;
    let reference = metrics::read_image(&reference_path)?;
    let (a_linear, b_linear) = (is_linear(&image_path)?, is_linear(&reference_path)?);
    if a_linear != b_linear {
        let kind = |linear| if linear { "EXR (linear radiance)" } else { "display values" };
        bail!(
            "compare: {} holds {} but {} holds {}: compare like with like (EXR with EXR, PNG with PNG)",
            image_path.display(),
            kind(a_linear),
            reference_path.display(),
            kind(b_linear)
        );
    }
    check_finite(&image_path, &image)?;
    check_finite(&reference_path, &reference)?;
    let mask = match &mask_path {
        Some(p) => {
            let (w, h, m) = metrics::read_mask(p)?;
            if (w, h) != (image.width, image.height) {
                bail!(
                    "compare: mask {} is {w}x{h} but the images are {}x{}",
                    p.display(),
                    image.width,
                    image.height
                );
            }
            if !m.iter().any(|&b| b) {
                bail!("compare: mask {} has no nonzero pixel", p.display());
            }
            Some(m)
        }
        None => None,
    };
    let c = metrics::compare(&image, &reference, mask.as_deref()).map_err(|e| {
        e.context(format!("compare {} {}", image_path.display(), reference_path.display()))
    })?;
    out!("{}", format_comparison(&c))
}

/// Whether `path` holds linear values (EXR) rather than display values (PNG), by its contents.
fn is_linear(path: &Path) -> Result<bool> {
    let format = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| Error::new(format!("{}: cannot read: {e}", path.display())))?
        .format();
    Ok(matches!(format, Some(image::ImageFormat::OpenExr | image::ImageFormat::Hdr)))
}

/// A NaN or infinite pixel makes every metric NaN or infinite: name the first one instead.
pub(super) fn check_finite(path: &Path, image: &Image) -> Result<()> {
    if let Some(i) = image.pixels.iter().position(|p| !p.is_finite()) {
        let (x, y) = (i % image.width as usize, i / image.width as usize);
        let p = image.pixels[i];
        bail!(
            "{}: pixel ({x}, {y}) (x, y from the top left) is not finite: ({}, {}, {})",
            path.display(),
            p.x,
            p.y,
            p.z
        );
    }
    Ok(())
}

/// Two images and at most one mask.
fn check(args: CompareArgs) -> Result<(PathBuf, PathBuf, Option<PathBuf>)> {
    if args.mask.len() > 1 {
        bail!("compare: --mask given twice");
    }
    let mask = args.mask.into_iter().next();
    match <[PathBuf; 2]>::try_from(args.files) {
        Ok([a, b]) => Ok((a, b, mask)),
        Err(f) => bail!("compare: expected two images (IMAGE REFERENCE), got {}", f.len()),
    }
}

/// The table `compare` prints: one row per region and channel.
pub fn format_comparison(c: &Comparison) -> String {
    let mut s = format!(
        "{:<7} {:>9} {:<4} {:>12} {:>10} {:>13} {:>12}\n",
        "region", "pixels", "chan", "rmse", "rel_rmse", "bias", "ref_mean"
    );
    let mut region = |name: &str, e: &RegionError| {
        let ref_all = e.reference_mean.iter().sum::<f64>() / 3.0;
        let rows = [
            ("R", e.rmse[0], e.rel_rmse[0], e.bias[0], e.reference_mean[0]),
            ("G", e.rmse[1], e.rel_rmse[1], e.bias[1], e.reference_mean[1]),
            ("B", e.rmse[2], e.rel_rmse[2], e.bias[2], e.reference_mean[2]),
            ("all", e.rmse_all, e.rel_rmse_all, e.bias_all, ref_all),
        ];
        for (ch, rmse, rel, bias, mean) in rows {
            s += &format!(
                "{name:<7} {:>9} {ch:<4} {rmse:>12.6e} {rel:>10.6} {bias:>+13.6e} {mean:>12.6e}\n",
                e.pixels
            );
        }
    };
    region("image", &c.image);
    if let Some(m) = &c.masked {
        region("mask", m);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<(PathBuf, PathBuf, Option<PathBuf>)> {
        let args: Vec<String> =
            ["compare"].into_iter().chain(s.split_whitespace()).map(String::from).collect();
        match crate::cli::command::parse(&args)? {
            crate::cli::command::Command::Compare(a) => check(a),
            _ => unreachable!(),
        }
    }

    #[test]
    fn arguments() {
        let (a, b, m) = parse("a.exr b.exr --mask m.png").unwrap();
        assert_eq!((a, b, m), ("a.exr".into(), "b.exr".into(), Some("m.png".into())));
        for (bad, want) in [
            ("a.exr", "expected two images"),
            ("a.exr b.exr c.exr", "expected two images"),
            ("a.exr b.exr --mask", "needs a value"),
            ("a.exr b.exr --mask m --mask n", "twice"),
            ("a.exr b.exr --bogus", "unknown option"),
        ] {
            let e = parse(bad).unwrap_err().to_string();
            assert!(e.contains(want), "{bad}: {e}");
        }
    }
}
