//! Monte Carlo convergence: for an unbiased estimator, RMSE against a converged reference falls
//! as spp^-1/2, so log RMSE against log spp has slope -0.5.

mod common;

use common::{coincident_light_box, render_pixels, HEMISPHERE, LIGHT, MIS};
use pathtracer::integrator::Integrator;
use pathtracer::math::Vec3;
use pathtracer::sampler::SamplerKind;

const W: u32 = 24;
const H: u32 = 18;

fn render(
    integrator: Integrator,
    sampler: SamplerKind,
    spp: u32,
    depth: u32,
    seed: u64,
) -> Vec<Vec3> {
    let scene = coincident_light_box();
    render_pixels(&scene, integrator, |c| {
        (c.width, c.height, c.spp, c.max_depth, c.seed, c.sampler) =
            (W, H, spp, depth, seed, sampler)
    })
}

fn rmse(a: &[Vec3], b: &[Vec3]) -> f64 {
    let se: f64 = a.iter().zip(b).map(|(x, y)| (*x - *y).length_squared() as f64).sum();
    (se / (3 * a.len()) as f64).sqrt()
}

/// Least-squares slope of log RMSE against log spp. For independent samples the reference's
/// own noise is removed: MSE(n) = s2 / n + s2 / n_ref, with the per-sample variance
/// s2 ~ 4 MSE(4) (to 0.05%). Sobol points converge faster than that model, and their 8192-spp
/// reference is far below the 64-spp error, so nothing is removed for them.
fn convergence_slope(integrator: Integrator, sampler: SamplerKind, depth: u32) -> f64 {
    slope_against(integrator, sampler, depth, 1.0)
}

/// The slope against a reference scaled by `ref_scale` (1 = the converged image itself).
fn slope_against(integrator: Integrator, sampler: SamplerKind, depth: u32, ref_scale: f32) -> f64 {
    let n_ref = 8192;
    let reference: Vec<Vec3> =
        render(integrator, sampler, n_ref, depth, 1000).iter().map(|p| *p * ref_scale).collect();
    let spps = [4u32, 8, 16, 32, 64];
    let mse: Vec<f64> = spps
        .iter()
        .map(|&n| rmse(&render(integrator, sampler, n, depth, n as u64), &reference).powi(2))
        .collect();
    let ref_var = match sampler {
        SamplerKind::Independent => 4.0 * mse[0] / n_ref as f64,
        SamplerKind::Sobol => 0.0,
    };
    let xs: Vec<f64> = spps.iter().map(|&n| (n as f64).ln()).collect();
    let ys: Vec<f64> = mse.iter().map(|&m| 0.5 * (m - ref_var).max(1e-30).ln()).collect();
    let (mx, my) = (xs.iter().sum::<f64>() / 5.0, ys.iter().sum::<f64>() / 5.0);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    sxy / sxx
}

const ESTIMATORS: [(&str, Integrator, u32); 6] = [
    ("light sampling, direct", LIGHT, 1),
    ("hemisphere sampling, direct", HEMISPHERE, 1),
    ("mis, direct", MIS, 1),
    ("path tracing -m 4", LIGHT, 4),
    ("hemisphere path tracing -m 4", HEMISPHERE, 4),
    ("mis path tracing -m 4", MIS, 4),
];

#[test]
fn every_unbiased_integrator_converges_at_the_monte_carlo_rate() {
    for (name, integrator, depth) in ESTIMATORS {
        let slope = convergence_slope(integrator, SamplerKind::Independent, depth);
        eprintln!("{name}, independent: slope {slope:.3}");
        assert!(
            (slope + 0.5).abs() <= 0.05,
            "{name}: log RMSE vs log spp slope {slope:.3}, want -0.5 +- 0.05"
        );
    }
}

/// Stratified (Sobol) samples of the same estimators converge to the same images at least
/// as fast: slope -0.5 or steeper (the biased-reference test below shows a wrong image
/// flattens it).
#[test]
fn sobol_samples_converge_at_least_at_the_monte_carlo_rate() {
    for (name, integrator, depth) in ESTIMATORS {
        let slope = convergence_slope(integrator, SamplerKind::Sobol, depth);
        eprintln!("{name}, sobol: slope {slope:.3}");
        assert!(slope <= -0.5, "{name}: log RMSE vs log spp slope {slope:.3}, want <= -0.5");
    }
}

/// The test can fail: against a reference 3% too bright (a biased estimator's view of the
/// truth), the error stops falling once noise drops to the bias, and the slope leaves the
/// -0.5 +- 0.05 band.
#[test]
fn a_biased_reference_breaks_the_rate() {
    for sampler in [SamplerKind::Independent, SamplerKind::Sobol] {
        let slope = slope_against(LIGHT, sampler, 1, 1.03);
        eprintln!("light sampling ({sampler:?}) against a 3% biased reference: slope {slope:.3}");
        assert!(slope > -0.45, "slope {slope:.3}: a 3% bias should flatten the curve");
    }
}
