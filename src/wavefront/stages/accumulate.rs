//! Stage 5: add each finished path's radiance to its pixel.

use super::super::{PathState, PixelStats};
use crate::integrator::lights::luminance;

/// Radiance sums are exact (`ExactRgb`), so they do not depend on the order or on how the
/// samples were split, and a pixel's run of samples is added in one call (`add_all`); the f64
/// moments of adaptive sampling are summed in the order the
/// paths were generated (pixel by pixel, sample by sample), the same however the work was
/// scheduled.
pub fn accumulate(paths: &PathState, pixels: &mut PixelStats) {
    for (&pixel, radiance) in paths.pixel.iter().zip(&paths.radiance) {
        let i = pixel as usize;
        let lum = luminance(*radiance) as f64;
        pixels.lum_sum[i] += lum;
        pixels.lum_sq_sum[i] += lum * lum;
        pixels.count[i] += 1;
    }
    // A pixel's samples are consecutive paths (`generate_camera_rays`): one exact sum per run.
    let mut start = 0;
    while start < paths.len() {
        let pixel = paths.pixel[start];
        let len = paths.pixel[start..].iter().take_while(|&&p| p == pixel).count();
        pixels.sum[pixel as usize].add_all(&paths.radiance[start..start + len]);
        start += len;
    }
}
