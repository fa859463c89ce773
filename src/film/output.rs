//! Image files: PNG (course tone map), EXR (linear), and the sampling-rate image.

use std::path::{Path, PathBuf};

use image::{ImageFormat, Rgb32FImage, RgbImage};

use crate::error::try_filled_vec;
use crate::math::Vec3;
use crate::staged::Outputs;
use crate::{bail, Result};

/// The course's display transform of one channel: one stop of exposure, gamma 2.2, clamped.
#[inline]
pub(crate) fn tone_map(l: f32) -> u8 {
    let v = (std::f32::consts::SQRT_2 * l).max(0.0).powf(1.0 / 2.2).clamp(0.0, 1.0);
    (v * 255.0 + 0.5) as u8
}

/// Writes `pixels` (row-major, row 0 at the top) as PNG or EXR, chosen by the extension:
/// atomically, so a reader sees the old file or the complete new one.
pub fn write_image(path: &Path, width: u32, height: u32, pixels: &[Vec3]) -> Result<()> {
    let mut outputs = Outputs::new();
    stage_image(&mut outputs, path, width, height, pixels)?;
    outputs.commit()
}

/// [`write_image`] as one file of a set written together (see [`Outputs`]).
pub fn stage_image(
    outputs: &mut Outputs,
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[Vec3],
) -> Result<()> {
    check_size(path, width, height, pixels.len())?;
    match extension(path).as_deref() {
        Some("png") => {
            let mut img = display_image(width, height)?;
            for (p, l) in img.pixels_mut().zip(pixels) {
                *p = image::Rgb([tone_map(l.x), tone_map(l.y), tone_map(l.z)]);
            }
            outputs.stage(path, |w| img.write_to(w, ImageFormat::Png))
        }
        Some("exr") => {
            let buffer = try_filled_vec(3 * pixels.len(), 0.0, &image_name(width, height))?;
            let mut img = Rgb32FImage::from_raw(width, height, buffer).expect("sized to fit");
            for (p, l) in img.pixels_mut().zip(pixels) {
                *p = image::Rgb(l.to_array());
            }
            outputs.stage(path, |w| img.write_to(w, ImageFormat::OpenExr))
        }
        _ => bail!("{}: output must end in .png or .exr", path.display()),
    }
}

/// `dir/name.png` -> `dir/name_rate.png`: where the course writes its sampling-rate image.
pub fn rate_image_path(output: &Path) -> PathBuf {
    let stem = output.file_stem().map_or("out".into(), |s| s.to_string_lossy().into_owned());
    output.with_file_name(format!("{stem}_rate.png"))
}

/// The adaptive-sampling rate image: each pixel's samples / `max_samples` as a colour ramp
/// from blue (few samples: converged early) through green to red (all samples taken).
pub fn stage_rate_image(
    outputs: &mut Outputs,
    path: &Path,
    width: u32,
    height: u32,
    samples: &[u32],
    max_samples: u32,
) -> Result<()> {
    check_size(path, width, height, samples.len())?;
    let mut img = display_image(width, height)?;
    for (p, &n) in img.pixels_mut().zip(samples) {
        *p = image::Rgb(ramp(n as f32 / max_samples.max(1) as f32));
    }
    outputs.stage(path, |w| img.write_to(w, ImageFormat::Png))
}

/// A black 8-bit image; its size is the user's (`-r`), so a failed allocation is an error.
fn display_image(width: u32, height: u32) -> Result<RgbImage> {
    let len = 3 * width as usize * height as usize;
    let buffer = try_filled_vec(len, 0u8, &image_name(width, height))?;
    Ok(RgbImage::from_raw(width, height, buffer).expect("sized to fit"))
}

fn image_name(width: u32, height: u32) -> String {
    format!("the {width}x{height} output image")
}

/// Blue (0) -> green (0.5) -> red (1).
fn ramp(x: f32) -> [u8; 3] {
    let x = x.clamp(0.0, 1.0);
    let byte = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    if x < 0.5 {
        [0, byte(2.0 * x), byte(1.0 - 2.0 * x)]
    } else {
        [byte(2.0 * x - 1.0), byte(2.0 - 2.0 * x), 0]
    }
}

fn extension(path: &Path) -> Option<String> {
    path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase)
}

fn check_size(path: &Path, width: u32, height: u32, len: usize) -> Result<()> {
    if width == 0 || height == 0 || width as usize * height as usize != len {
        bail!("{}: {len} pixels do not make a {width} x {height} image", path.display());
    }
    Ok(())
}

/// Writes `bytes` to `path` through a temporary name, like every output (`staged::Outputs`).
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut outputs = Outputs::new();
    outputs.stage_bytes(path, bytes)?;
    outputs.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("pt-film-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn tone_map_is_the_course_curve() {
        assert_eq!(tone_map(0.0), 0);
        assert_eq!(tone_map(-1.0), 0);
        assert_eq!(tone_map(f32::INFINITY), 255);
        // (sqrt(2) * 0.5)^(1/2.2) = 0.8543 -> 218
        assert_eq!(tone_map(0.5), 218);
        assert_eq!(tone_map(1.0 / std::f32::consts::SQRT_2), 255);
    }

    #[test]
    fn exr_round_trips_linear_radiance() {
        let path = scratch("exr").join("img.exr");
        let pixels = vec![Vec3::new(0.25, 3.5, 1e-3), Vec3::new(100.0, 0.0, 0.5)];
        write_image(&path, 2, 1, &pixels).unwrap();
        let back = image::open(&path).unwrap().into_rgb32f();
        let got: Vec<Vec3> = back.pixels().map(|p| Vec3::from_array(p.0)).collect();
        assert_eq!(got, pixels);
    }

    #[test]
    fn failed_writes_leave_no_file() {
        let dir = scratch("fail");
        let path = dir.join("img.png");
        assert!(write_image(&path, 2, 2, &[Vec3::ZERO; 3]).is_err());
        let missing = dir.join("no-such-dir").join("img.png");
        let err = write_image(&missing, 1, 1, &[Vec3::ZERO]).unwrap_err();
        assert!(err.message().contains("cannot write"), "{err}");
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert!(left.is_empty(), "{left:?}");
    }

    #[test]
    fn rate_ramp_runs_blue_green_red() {
        assert_eq!(ramp(0.0), [0, 0, 255]);
        assert_eq!(ramp(0.5), [0, 255, 0]);
        assert_eq!(ramp(1.0), [255, 0, 0]);
        assert_eq!(rate_image_path(Path::new("a/b.png")), Path::new("a/b_rate.png"));
    }
}
