//! Convergence runs: render a scene at a list of sample counts, time each render, and measure
//! its error against a reference. Shared by `pathtracer converge` and the speed-versus-accuracy
//! chart (`examples/accuracy_chart.rs`).

use crate::accel::Accel;
use crate::metrics::{self, Comparison, Image};
use crate::render::{render, RenderConfig};
use crate::scene::Scene;
use crate::Result;

/// One render of a sweep.
#[derive(Debug, Clone, Copy)]
pub struct Point {
    /// Samples per pixel asked for.
    pub spp: u32,
    /// Rendering time (the render loop only: not loading or BVH building, which every point
    /// of a sweep shares); the best of repeated renders for renders under 0.1 s, whose time
    /// is otherwise dominated by start-up jitter (thread pool, first touch of memory).
    pub seconds: f64,
    /// Rays traced, all kinds together.
    pub rays: u64,
    /// Mean samples per pixel actually taken (below `spp` under adaptive sampling).
    pub mean_spp: f64,
    /// The image's error against the reference.
    pub error: Comparison,
}

/// Renders `scene` as `base` says but with each of `spps` samples per pixel, and compares each
/// image with `reference`. Each render gets its own seed (`base.seed + spp`), so the points'
/// errors are independent rather than sharing their first samples.
pub fn sweep(
    scene: &Scene,
    accel: &Accel,
    base: &RenderConfig,
    reference: &Image,
    mask: Option<&[bool]>,
    spps: &[u32],
) -> Result<Vec<Point>> {
    let mut out = Vec::with_capacity(spps.len());
    for &spp in spps {
        let config = RenderConfig { spp, seed: base.seed.wrapping_add(spp as u64), ..base.clone() };
        let (image, r) = render_image(scene, accel, &config)?;
        // The same seed renders the same image, so repeats only refine the time.
        let (mut seconds, mut spent, mut reps) = (r.time.as_secs_f64(), r.time.as_secs_f64(), 1);
        while spent < 0.3 && reps < 5 {
            let t = render(scene, accel, &config)?.time.as_secs_f64();
            (seconds, spent, reps) = (seconds.min(t), spent + t, reps + 1);
        }
        let mean_spp = r.samples.iter().map(|&s| s as f64).sum::<f64>() / r.samples.len() as f64;
        out.push(Point {
            spp,
            seconds,
            rays: r.stats.total_rays(),
            mean_spp,
            error: metrics::compare(&image, reference, mask)?,
        });
    }
    Ok(out)
}

/// Renders and returns the image with the render's output (times, statistics, sample counts).
pub fn render_image(
    scene: &Scene,
    accel: &Accel,
    config: &RenderConfig,
) -> Result<(Image, crate::render::RenderOutput)> {
    let mut r = render(scene, accel, config)?;
    let image = Image { width: r.width, height: r.height, pixels: std::mem::take(&mut r.pixels) };
    Ok((image, r))
}

/// The least-squares slope of ln y against ln x (points with a non-positive coordinate are
/// left out). An unbiased Monte Carlo estimator's RMSE against a converged reference has slope
/// -0.5 against spp.
pub fn log_log_slope(points: &[(f64, f64)]) -> Option<f64> {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if logs.len() < 2 {
        return None;
    }
    let n = logs.len() as f64;
    let mx = logs.iter().map(|p| p.0).sum::<f64>() / n;
    let my = logs.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = logs.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = logs.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_a_power_law() {
        let pts: Vec<(f64, f64)> =
            [1.0, 2.0, 4.0, 8.0].iter().map(|&x| (x, 3.0 / f64::sqrt(x))).collect();
        assert!((log_log_slope(&pts).unwrap() + 0.5).abs() < 1e-12);
        assert_eq!(log_log_slope(&pts[..1]), None);
        assert_eq!(log_log_slope(&[(1.0, 1.0), (1.0, 2.0)]), None);
    }
}
