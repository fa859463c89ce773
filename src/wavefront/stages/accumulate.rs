//! Stage 5: add each finished path's radiance to its pixel.

use super::super::{PathState, PixelStats};
use crate::integrator::lights::luminance;

/// Radiance sums are exact (`ExactRgb`), so they do not depend on the order or on how the
/// samples were split, and a pixel's run of samples is added in one call (`add_all`); the f64
/// moments of adaptive sampling are summed in the order the
/// paths were generated (pixel by pixel, sample by sample), the same however the work was
/// scheduled. Only adaptive sampling (`moments`) reads those moments: without it they are not
/// summed.
pub fn accumulate(paths: &PathState, pixels: &mut PixelStats, moments: bool) {
    // A pixel's samples are consecutive paths (`generate_camera_rays`): one run per pixel, its
    // moments summed in registers (in the same order, so to the same bits) rather than through
    // memory, where each add waited on the previous one's store.
    let mut start = 0;
    while start < paths.len() {
        let pixel = paths.pixel[start];
        let len = paths.pixel[start..].iter().take_while(|&&p| p == pixel).count();
        let run = &paths.radiance[start..start + len];
        let i = pixel as usize;
        if moments {
            let (mut sum, mut sq) = (pixels.lum_sum[i], pixels.lum_sq_sum[i]);
            for radiance in run {
                let lum = luminance(*radiance) as f64;
                sum += lum;
                sq += lum * lum;
            }
            (pixels.lum_sum[i], pixels.lum_sq_sum[i]) = (sum, sq);
        }
        pixels.count[i] += len as u32;
        pixels.sum[i].add_all(run);
        start += len;
    }
}
