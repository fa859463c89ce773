//! The plan of N parts: it depends only on the image size, `-s` and N.
//!
//! The image is cut into `b` horizontal bands of whole tile rows (`wavefront::TILE` pixels
//! high) and each pixel's samples into `s` ranges, with `b x s = N`; `b` is the largest
//! divisor of N that is at most the number of tile rows and leaves `s = N / b` at most `-s`.
//! So a plan of up to one part per tile row splits only pixels (which adaptive sampling
//! allows), and larger plans split samples too. Part K is band `K / s`, sample range `K % s`.

use std::ops::Range;

use crate::render::Rect;
use crate::wavefront::TILE;
use crate::{bail, Result};

/// One part of a render: these pixels, these samples of each.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Part {
    /// The part's pixels.
    pub crop: Rect,
    /// The samples of each pixel (end excluded).
    pub samples: Range<u32>,
}

/// All N parts of the plan for a `width` x `height` image at `spp` samples per pixel.
pub fn plan(width: u32, height: u32, spp: u32, n: u32) -> Result<Vec<Part>> {
    (0..n).map(|k| plan_part(width, height, spp, k, n)).collect()
}

/// Part `k` (0-based) of the plan of `n`.
pub fn plan_part(width: u32, height: u32, spp: u32, k: u32, n: u32) -> Result<Part> {
    if n == 0 || k >= n {
        bail!("--part {k}/{n}: expected K/N with 0 <= K < N");
    }
    let rows = height.div_ceil(TILE);
    let Some(bands) = (1..=n.min(rows)).rev().find(|&b| n.is_multiple_of(b) && n / b <= spp) else {
        bail!(
            "--part {k}/{n}: a {width}x{height} image at -s {spp} cannot be cut into {n} parts \
             ({rows} bands of {TILE}-pixel rows times at most {spp} sample ranges, with N = bands x ranges)"
        );
    };
    let ranges = n / bands;
    let (band, range) = (k / ranges, k % ranges);
    let y0 = (band * rows / bands * TILE).min(height);
    let y1 = ((band + 1) * rows / bands * TILE).min(height);
    let samples = range * spp / ranges..(range + 1) * spp / ranges;
    Ok(Part { crop: Rect { x0: 0, y0, x1: width, y1 }, samples })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plans_cover_every_pixel_sample_once() {
        for (w, h, spp) in [(64, 48, 8), (17, 100, 3), (1, 1, 1), (64, 48, 1)] {
            for n in 1..=12 {
                let Ok(parts) = plan(w, h, spp, n) else { continue };
                let mut cover = vec![0u32; (w * h * spp) as usize];
                for p in &parts {
                    for y in p.crop.y0..p.crop.y1 {
                        for x in p.crop.x0..p.crop.x1 {
                            for s in p.samples.clone() {
                                cover[((y * w + x) * spp + s) as usize] += 1;
                            }
                        }
                    }
                }
                assert!(cover.iter().all(|&c| c == 1), "{w}x{h} s{spp} n{n}");
            }
        }
    }

    #[test]
    fn small_plans_split_pixels_and_large_ones_samples() {
        // 48 rows = 3 tile rows.
        assert_eq!(plan(64, 48, 8, 3).unwrap()[1].samples, 0..8);
        assert_eq!(plan(64, 48, 8, 3).unwrap()[1].crop, Rect { x0: 0, y0: 16, x1: 64, y1: 32 });
        let p4 = plan(64, 48, 8, 4).unwrap();
        assert_eq!(p4[1], Part { crop: Rect { x0: 0, y0: 0, x1: 64, y1: 16 }, samples: 4..8 });
        assert_eq!(plan(64, 48, 8, 5).unwrap()[4].samples, 6..8);
        let err = plan(64, 48, 2, 5).unwrap_err().to_string();
        assert!(err.contains("cannot be cut into 5 parts"), "{err}");
        assert!(plan_part(64, 48, 8, 4, 4).is_err());
        assert!(plan_part(64, 48, 8, 0, 0).is_err());
    }
}
