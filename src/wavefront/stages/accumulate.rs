//! Stage 5: add each finished path's radiance to its pixel.

use super::super::{PathState, PixelStats};
use crate::integrator::lights::luminance;

/// Radiance sums are exact (`ExactRgb`), so they do not depend on the order or on how the
/// samples were split; the f64 moments of adaptive sampling are summed in the order the
/// paths were generated (pixel by pixel, sample by sample), the same however the work was
/// scheduled.
pub fn accumulate(paths: &PathState, pixels: &mut PixelStats) {
    for (&pixel, radiance) in paths.pixel.iter().zip(&paths.radiance) {
        let i = pixel as usize;
        let lum = luminance(*radiance) as f64;
        pixels.sum[i].add(radiance.to_array());
        pixels.lum_sum[i] += lum;
        pixels.lum_sq_sum[i] += lum * lum;
        pixels.count[i] += 1;
    }
}
