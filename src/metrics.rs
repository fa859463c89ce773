//! Image error metrics against a reference: RMSE, relative RMSE and mean bias per channel,
//! over the whole image and over a mask. Used by `pathtracer compare`, `pathtracer converge`,
//! the convergence tests and the speed-versus-accuracy chart.
//!
//! Definitions, per channel c over the N pixels of a region (image = test, reference = ref):
//!
//! - `rmse = sqrt(sum (image - ref)^2 / N)`
//! - `rel_rmse = rmse / mean(ref)`: RMSE in units of the reference's mean brightness. We divide
//!   by the mean rather than per pixel (as relMSE does) because per-pixel division is dominated
//!   by near-black pixels, which a Cornell box has many of, and needs an arbitrary epsilon.
//! - `bias = sum (image - ref) / N`: the mean signed error. For an unbiased estimator it shrinks
//!   like rmse / sqrt(N); a bias that stays put while rmse falls is a systematic error.

use std::path::Path;

use crate::math::Vec3;
use crate::{bail, Error, Result};

/// A linear RGB image, row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` linear RGB values.
    pub pixels: Vec<Vec3>,
}

/// The error of one region of an image, per channel (R, G, B) and over all three together.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionError {
    /// Pixels in the region.
    pub pixels: usize,
    /// Root-mean-square error per channel.
    pub rmse: [f64; 3],
    /// `rmse` divided by the reference's mean, per channel.
    pub rel_rmse: [f64; 3],
    /// Mean signed error (image - reference) per channel.
    pub bias: [f64; 3],
    /// Mean of the reference per channel (the denominator of `rel_rmse`).
    pub reference_mean: [f64; 3],
    /// The three channels pooled: RMSE over all 3N values, relative to the mean of all 3N
    /// reference values, and the mean of all 3N signed errors.
    pub rmse_all: f64,
    /// `rmse_all` relative to the mean of all 3N reference values.
    pub rel_rmse_all: f64,
    /// The mean of all 3N signed errors.
    pub bias_all: f64,
}

/// Errors of an image against a reference: over the whole image and, if a mask was given, over
/// its nonzero pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Comparison {
    /// The error over the whole image.
    pub image: RegionError,
    /// The error over the mask's pixels, if a mask was given.
    pub masked: Option<RegionError>,
}

/// Compares `image` with `reference` (and over `mask`'s true pixels, if given). Sizes must match.
pub fn compare(image: &Image, reference: &Image, mask: Option<&[bool]>) -> Result<Comparison> {
    if (image.width, image.height) != (reference.width, reference.height) {
        bail!(
            "image sizes differ: {}x{} vs reference {}x{}",
            image.width,
            image.height,
            reference.width,
            reference.height
        );
    }
    if image.pixels.len() != reference.pixels.len() {
        bail!("pixel counts differ: {} vs {}", image.pixels.len(), reference.pixels.len());
    }
    let masked = match mask {
        Some(m) if m.len() != image.pixels.len() => {
            bail!("mask has {} pixels, images have {}", m.len(), image.pixels.len())
        }
        Some(m) => Some(region_error(&image.pixels, &reference.pixels, |i| m[i])),
        None => None,
    };
    Ok(Comparison { image: region_error(&image.pixels, &reference.pixels, |_| true), masked })
}

/// RMSE of `a` against `b` over every channel of every pixel (the pooled `rmse_all`).
pub fn rmse(a: &[Vec3], b: &[Vec3]) -> f64 {
    region_error(a, b, |_| true).rmse_all
}

fn region_error(a: &[Vec3], b: &[Vec3], inside: impl Fn(usize) -> bool) -> RegionError {
    // f64 sums: a megapixel image's squared errors lose digits in f32.
    let (mut n, mut se, mut sd, mut sr) = (0usize, [0f64; 3], [0f64; 3], [0f64; 3]);
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        if !inside(i) {
            continue;
        }
        n += 1;
        for c in 0..3 {
            let d = x[c] as f64 - y[c] as f64;
            se[c] += d * d;
            sd[c] += d;
            sr[c] += y[c] as f64;
        }
    }
    let nf = n.max(1) as f64;
    let rmse = se.map(|s| (s / nf).sqrt());
    let reference_mean = sr.map(|s| s / nf);
    // A black reference channel has no meaningful relative error: report NaN, not infinity.
    let rel = |e: f64, m: f64| if m > 0.0 { e / m } else { f64::NAN };
    let rmse_all = (se.iter().sum::<f64>() / (3.0 * nf)).sqrt();
    let mean_all = sr.iter().sum::<f64>() / (3.0 * nf);
    RegionError {
        pixels: n,
        rmse,
        rel_rmse: std::array::from_fn(|c| rel(rmse[c], reference_mean[c])),
        bias: sd.map(|s| s / nf),
        reference_mean,
        rmse_all,
        rel_rmse_all: rel(rmse_all, mean_all),
        bias_all: sd.iter().sum::<f64>() / (3.0 * nf),
    }
}

/// Reads an image for comparison: EXR as linear radiance; PNG (and other 8/16-bit formats) as
/// their stored values scaled to [0, 1] (display values, not radiance: compare PNG with PNG).
pub fn read_image(path: &Path) -> Result<Image> {
    let img = decode(path)?;
    let (width, height) = (img.width(), img.height());
    let rgb = img.into_rgb32f();
    let pixels = rgb.pixels().map(|p| Vec3::new(p[0], p[1], p[2])).collect();
    Ok(Image { width, height, pixels })
}

/// Reads a mask: a pixel is inside when any of its colour channels is nonzero and it is not
/// fully transparent (an opaque image has alpha 1 everywhere, so alpha alone cannot decide).
pub fn read_mask(path: &Path) -> Result<(u32, u32, Vec<bool>)> {
    let img = decode(path)?;
    let (w, h) = (img.width(), img.height());
    let rgba = img.into_rgba32f();
    Ok((w, h, rgba.pixels().map(|p| p.0[3] != 0.0 && p.0[..3].iter().any(|&v| v != 0.0)).collect()))
}

fn decode(path: &Path) -> Result<image::DynamicImage> {
    let reader = image::ImageReader::open(path)
        .map_err(|e| Error::new(format!("{}: cannot read: {e}", path.display())))?
        .with_guessed_format()
        .map_err(|e| Error::new(format!("{}: cannot read: {e}", path.display())))?;
    if reader.format().is_none() {
        bail!("{}: not an image format we can read (expected EXR or PNG)", path.display());
    }
    reader.decode().map_err(|e| Error::new(format!("{}: cannot decode: {e}", path.display())))
}

/// Writes a linear RGB image as 32-bit float OpenEXR (atomically, through the film module).
pub fn write_exr(path: &Path, image: &Image) -> Result<()> {
    let mut outputs = crate::staged::Outputs::new();
    stage_exr(&mut outputs, path, image)?;
    outputs.commit()
}

/// [`write_exr`] as one file of a set written together.
pub fn stage_exr(outputs: &mut crate::staged::Outputs, path: &Path, image: &Image) -> Result<()> {
    if !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        bail!("{}: a reference must be written as .exr", path.display());
    }
    crate::film::stage_image(outputs, path, image.width, image.height, &image.pixels)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(pixels: Vec<Vec3>) -> Image {
        Image { width: pixels.len() as u32, height: 1, pixels }
    }

    #[test]
    fn identical_images_have_zero_error() {
        let a = img(vec![Vec3::new(0.1, 0.2, 0.3), Vec3::new(4.0, 5.0, 6.0)]);
        let c = compare(&a, &a, None).unwrap();
        assert_eq!(c.image.rmse, [0.0; 3]);
        assert_eq!(c.image.bias, [0.0; 3]);
        assert_eq!(c.image.rel_rmse_all, 0.0);
        assert!(c.masked.is_none());
    }

    #[test]
    fn known_answers_per_channel() {
        // Reference R = (1, 3): mean 2. Image R = (2, 3): errors (1, 0) -> RMSE sqrt(1/2),
        // bias 1/2, relative RMSE sqrt(1/2)/2. G: errors (-2, 2) -> RMSE 2, bias 0, mean 2.
        // B: constant offset 0.5 on reference (4, 4) -> RMSE 0.5, bias 0.5, relative 1/8.
        let reference = img(vec![Vec3::new(1.0, 1.0, 4.0), Vec3::new(3.0, 3.0, 4.0)]);
        let image = img(vec![Vec3::new(2.0, -1.0, 4.5), Vec3::new(3.0, 5.0, 4.5)]);
        let e = compare(&image, &reference, None).unwrap().image;
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert_eq!(e.pixels, 2);
        assert!(close(e.rmse[0], 0.5f64.sqrt()), "{:?}", e.rmse);
        assert!(close(e.rmse[1], 2.0));
        assert!(close(e.rmse[2], 0.5));
        assert!(close(e.bias[0], 0.5) && close(e.bias[1], 0.0) && close(e.bias[2], 0.5));
        assert!(close(e.rel_rmse[0], 0.5f64.sqrt() / 2.0));
        assert!(close(e.rel_rmse[1], 1.0));
        assert!(close(e.rel_rmse[2], 0.125));
        // Pooled: squared errors 1 + 0 + 4 + 4 + 0.25 + 0.25 = 9.5 over 6 values; reference
        // mean 16/6; signed errors sum 1 + 0 + 1 = 2 over 6.
        assert!(close(e.rmse_all, (9.5f64 / 6.0).sqrt()));
        assert!(close(e.rel_rmse_all, (9.5f64 / 6.0).sqrt() / (16.0 / 6.0)));
        assert!(close(e.bias_all, 2.0 / 6.0));
        assert!(close(rmse(&image.pixels, &reference.pixels), e.rmse_all));
    }

    #[test]
    fn mask_selects_nonzero_pixels_only() {
        let reference = img(vec![Vec3::ONE, Vec3::ONE, Vec3::ONE]);
        let image = img(vec![Vec3::splat(2.0), Vec3::ONE, Vec3::splat(10.0)]);
        let c = compare(&image, &reference, Some(&[false, true, true])).unwrap();
        let m = c.masked.unwrap();
        assert_eq!(m.pixels, 2);
        // Errors 0 and 9 over the two masked pixels: RMSE sqrt(81/2), bias 4.5.
        assert!((m.rmse[1] - (40.5f64).sqrt()).abs() < 1e-12);
        assert!((m.bias[2] - 4.5).abs() < 1e-12);
        // The whole image: errors 1, 0, 9.
        assert!((c.image.bias[0] - 10.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn black_reference_gives_nan_relative_error_not_infinity() {
        let e = compare(&img(vec![Vec3::ONE]), &img(vec![Vec3::ZERO]), None).unwrap().image;
        assert!(e.rel_rmse.iter().all(|v| v.is_nan()));
        assert_eq!(e.rmse, [1.0; 3]);
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let a = img(vec![Vec3::ONE; 2]);
        let b = Image { width: 1, height: 2, pixels: vec![Vec3::ONE; 2] };
        let e = compare(&a, &b, None).unwrap_err().to_string();
        assert!(e.contains("sizes differ"), "{e}");
        let e = compare(&a, &a, Some(&[true])).unwrap_err().to_string();
        assert!(e.contains("mask"), "{e}");
    }

    #[test]
    fn rmse_of_independent_noise_falls_as_one_over_sqrt_n() {
        // The metric itself, on synthetic Monte Carlo estimates: means of n uniform samples
        // have variance 1/(12 n), so RMSE(n) = 1/sqrt(12 n).
        let mut rng = crate::sampler::Pcg32::new(7, 0);
        let reference = img(vec![Vec3::splat(0.5); 4096]);
        for n in [1u32, 16, 256] {
            let pixels = (0..4096)
                .map(|_| {
                    let s: f32 = (0..n).map(|_| rng.next_f32()).sum();
                    Vec3::splat(s / n as f32)
                })
                .collect();
            let e = compare(&img(pixels), &reference, None).unwrap().image;
            let want = 1.0 / (12.0 * n as f64).sqrt();
            assert!((e.rmse_all / want - 1.0).abs() < 0.05, "n {n}: {} vs {want}", e.rmse_all);
        }
    }

    #[test]
    fn exr_round_trip_is_exact() {
        let dir = std::env::temp_dir().join(format!("pt-metrics-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.exr");
        let image = Image {
            width: 3,
            height: 2,
            pixels: (0..6).map(|i| Vec3::new(i as f32 * 0.37, 1e-4 * i as f32, 123.5)).collect(),
        };
        write_exr(&path, &image).unwrap();
        assert_eq!(read_image(&path).unwrap(), image);
        assert!(write_exr(&dir.join("a.png"), &image).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn masks_are_nonzero_colour_where_not_transparent() {
        let dir = std::env::temp_dir().join(format!("pt-metrics-mask-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.png");
        let mut m = image::RgbaImage::new(3, 1);
        m.put_pixel(0, 0, image::Rgba([255, 255, 255, 255]));
        m.put_pixel(1, 0, image::Rgba([0, 0, 0, 255]));
        m.put_pixel(2, 0, image::Rgba([0, 9, 0, 0]));
        m.save(&path).unwrap();
        assert_eq!(read_mask(&path).unwrap(), (3, 1, vec![true, false, false]));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn unreadable_files_are_one_line_errors() {
        let dir = std::env::temp_dir().join(format!("pt-metrics-bad-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let junk = dir.join("junk.exr");
        std::fs::write(&junk, b"not an image\nat all").unwrap();
        for p in [dir.join("missing.exr"), junk] {
            let e = read_image(&p).unwrap_err().to_string();
            assert!(!e.is_empty() && !e.contains('\n'), "{e}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
