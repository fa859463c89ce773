//! Stage 5: add each finished path's radiance to its pixel.

use super::super::{PathState, PixelStats};
use crate::integrator::lights::luminance;

/// Paths are summed in the order they were generated (pixel by pixel, sample by sample), so
/// the floating-point sums are the same however the work was scheduled.
pub fn accumulate(paths: &PathState, pixels: &mut PixelStats) {
    for (&pixel, radiance) in paths.pixel.iter().zip(&paths.radiance) {
        let i = pixel as usize;
        let lum = luminance(*radiance) as f64;
        pixels.sum[i] += *radiance;
        pixels.lum_sum[i] += lum;
        pixels.lum_sq_sum[i] += lum * lum;
        pixels.count[i] += 1;
    }
}
