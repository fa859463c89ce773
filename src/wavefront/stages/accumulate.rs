//! Stage 5: add each finished path's radiance to its pixel.

use super::super::PathState;
use crate::math::Vec3;

/// Paths are summed in the order they were generated (pixel by pixel, sample by sample), so
/// the floating-point sum is the same however the work was scheduled.
pub fn accumulate(paths: &PathState, sum: &mut [Vec3]) {
    for (&pixel, radiance) in paths.pixel.iter().zip(&paths.radiance) {
        sum[pixel as usize] += *radiance;
    }
}
