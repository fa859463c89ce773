//! The BSDFs' sampling against the pdf they report, by a chi-square goodness-of-fit test as in
//! Mitsuba 3's `chi2` and pbrt-v4's `bsdfs_test.cpp` (the sphere binned 20 x 40 in cos theta x
//! phi, 10^6 samples, expected counts integrated from `pdf()` by adaptive Gauss-Legendre
//! cubature, cells with expected count < 5 pooled, and one more cell for "no sample"; p-value
//! from the chi-square distribution against 1e-2 Bonferroni-corrected over every chi-square
//! test here). Deliberately wrong pdfs are rejected by the same routine. The other BSDF
//! properties are in `tests/bsdf.rs`.
//!
//! Every test uses a fixed-seed PCG32, so it is deterministic.
//! `cargo test --release --test bsdf_chi2 -- --nocapture` prints the p-values.

use std::f64::consts::{PI, TAU};

use pathtracer::integrator::bsdf::{pdf, sample, BsdfSample};
use pathtracer::math::Vec3;
use pathtracer::sampler::Pcg32;
use pathtracer::scene::Material;

mod common;

use common::bsdf::*;

// ------------------------------------------------------------------------------------------
// The chi-square distribution: Q(a, x), the regularised upper incomplete gamma function.

/// ln Gamma(a) for a = k / 2, k a positive integer: exact by the recursion from Gamma(1) = 1
/// or Gamma(1/2) = sqrt(pi).
fn ln_gamma_half_integer(a: f64) -> f64 {
    let twice = (2.0 * a).round() as i64;
    assert!(twice >= 1 && (2.0 * a - twice as f64).abs() < 1e-12, "a = {a}");
    let (mut x, mut sum) = if twice % 2 == 0 { (1.0, 0.0) } else { (0.5, 0.5 * PI.ln()) };
    while x < a - 0.25 {
        sum += x.ln();
        x += 1.0;
    }
    sum
}

/// Q(a, x) = Gamma(a, x) / Gamma(a) for a = k / 2 (series below a + 1, Lentz's continued
/// fraction above, as Numerical Recipes' `gammq`).
fn gamma_q(a: f64, x: f64) -> f64 {
    assert!(x >= 0.0 && a > 0.0);
    if x == 0.0 {
        return 1.0;
    }
    let ln_prefix = -x + a * x.ln() - ln_gamma_half_integer(a);
    if x < a + 1.0 {
        // P(a, x) = e^-x x^a / Gamma(a + 1) * sum_n x^n / ((a + 1) ... (a + n))
        let (mut ap, mut term) = (a, 1.0 / a);
        let mut sum = term;
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        (1.0 - sum * ln_prefix.exp()).max(0.0)
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-15 {
                break;
            }
        }
        ln_prefix.exp() * h
    }
}

/// P(X >= x) for X chi-square distributed with `dof` degrees of freedom.
fn chi2_survival(x: f64, dof: usize) -> f64 {
    gamma_q(dof as f64 / 2.0, x / 2.0)
}

#[test]
fn chi_square_survival_matches_tables() {
    // Critical values from the standard tables: (x, dof, upper-tail probability).
    for (x, dof, p) in [
        (3.841, 1, 0.05),
        (6.635, 1, 0.01),
        (5.991, 2, 0.05),
        (11.345, 3, 0.01),
        (18.307, 10, 0.05),
        (124.342, 100, 0.05),
        (135.807, 100, 0.01),
        (63.691, 40, 0.01),
    ] {
        let q = chi2_survival(x, dof);
        assert!((q - p).abs() < 2e-3 * p, "chi2({x}, {dof}) = {q}, want {p}");
    }
    // Two degrees of freedom have Q = exp(-x / 2) exactly, on both branches of gamma_q.
    for x in [0.1, 1.0, 3.0, 4.0, 30.0, 300.0] {
        let q = chi2_survival(x, 2);
        assert!((q - (-x / 2.0f64).exp()).abs() <= 1e-12 * q.max(1e-300), "{x}: {q}");
    }
    assert_eq!(chi2_survival(0.0, 7), 1.0);
}

// ------------------------------------------------------------------------------------------
// The chi-square test of sampling against pdf().

const COS_BINS: usize = 20;
const PHI_BINS: usize = 40;
const CHI2_SAMPLES: usize = 1_000_000;
const MIN_EXPECTED: f64 = 5.0;

/// Cell of a direction on the sphere: cos theta over [-1, 1] x phi over [0, 2 pi).
fn cell(w: Vec3) -> usize {
    let c = (w.z as f64).clamp(-1.0, 1.0);
    let i = (((c + 1.0) / 2.0 * COS_BINS as f64) as usize).min(COS_BINS - 1);
    let mut phi = (w.y as f64).atan2(w.x as f64);
    if phi < 0.0 {
        phi += TAU;
    }
    let j = ((phi / TAU * PHI_BINS as f64) as usize).min(PHI_BINS - 1);
    i * PHI_BINS + j
}

/// Tolerance of each cell's probability: absolute, and relative to the cell's probability.
/// At CHI2_SAMPLES samples 1e-8 is 0.01 of a count, and a cell of E counts off by 1e-5 E
/// adds 1e-10 E to the statistic. (Much tighter would chase the f32 rounding of `pdf()`.)
const QUAD_TOL: (f64, f64) = (1e-8, 1e-5);

/// The 5-point Gauss-Legendre rule on [-1, 1]: (node, weight).
fn gauss_legendre_5() -> [(f64, f64); 5] {
    let s = (10.0f64 / 7.0).sqrt();
    let (a, b) = ((5.0 - 2.0 * s).sqrt() / 3.0, (5.0 + 2.0 * s).sqrt() / 3.0);
    let (wa, wb) = ((322.0 + 13.0 * 70f64.sqrt()) / 900.0, (322.0 - 13.0 * 70f64.sqrt()) / 900.0);
    [(-b, wb), (-a, wa), (0.0, 128.0 / 225.0), (a, wa), (b, wb)]
}

/// A solid-angle density integrated over theta in [t0, t1], phi in [p0, p1] by a 5 x 5
/// Gauss-Legendre product rule (d omega = sin theta d theta d phi: over theta the integrand is
/// smooth up to the pole, over cos theta it has a square-root cusp there).
fn gauss_rect(density: &dyn Fn(Vec3) -> f64, (t0, t1): (f64, f64), (p0, p1): (f64, f64)) -> f64 {
    let gl = gauss_legendre_5();
    let (tm, ht, pm, hp) = (0.5 * (t0 + t1), 0.5 * (t1 - t0), 0.5 * (p0 + p1), 0.5 * (p1 - p0));
    let mut sum = 0.0;
    for &(xt, wt) in &gl {
        let (st, ct) = (tm + ht * xt).sin_cos();
        let mut row = 0.0;
        for &(xp, wp) in &gl {
            let (sp, cp) = (pm + hp * xp).sin_cos();
            row += wp * density(Vec3::new((st * cp) as f32, (st * sp) as f32, ct as f32));
        }
        sum += wt * st * row;
    }
    sum * ht * hp
}

/// Adaptive cubature: a rectangle whose four quarters disagree with the whole by more than
/// `tol` is split, each quarter refined to tol / 2.
fn refine(
    density: &dyn Fn(Vec3) -> f64,
    (t0, t1): (f64, f64),
    (p0, p1): (f64, f64),
    whole: f64,
    tol: f64,
    depth: u32,
) -> f64 {
    let (tm, pm) = (0.5 * (t0 + t1), 0.5 * (p0 + p1));
    let quarters =
        [((t0, tm), (p0, pm)), ((t0, tm), (pm, p1)), ((tm, t1), (p0, pm)), ((tm, t1), (pm, p1))];
    let parts = quarters.map(|(t, p)| gauss_rect(density, t, p));
    let sum: f64 = parts.iter().sum();
    if depth == 0 || (sum - whole).abs() <= tol {
        return sum;
    }
    quarters
        .iter()
        .zip(parts)
        .map(|(&(t, p), part)| refine(density, t, p, part, 0.5 * tol, depth - 1))
        .sum()
}

/// Probability of the region cos theta in [c0, c1], phi in [p0, p1] under `density`, to
/// `(abs, rel)` tolerance. The region is first cut 4 x 4, so that no narrow peak (a Beckmann
/// lobe at grazing incidence is ~0.01 rad wide in phi) can hide between the first nodes.
fn integrate(
    density: &dyn Fn(Vec3) -> f64,
    (c0, c1): (f64, f64),
    (p0, p1): (f64, f64),
    (abs, rel): (f64, f64),
) -> f64 {
    const CUTS: usize = 4;
    let (t0, t1) = (c1.clamp(-1.0, 1.0).acos(), c0.clamp(-1.0, 1.0).acos());
    let (ht, hp) = ((t1 - t0) / CUTS as f64, (p1 - p0) / CUTS as f64);
    let pieces: Vec<((f64, f64), (f64, f64))> = (0..CUTS * CUTS)
        .map(|k| {
            let (i, j) = ((k / CUTS) as f64, (k % CUTS) as f64);
            ((t0 + i * ht, t0 + (i + 1.0) * ht), (p0 + j * hp, p0 + (j + 1.0) * hp))
        })
        .collect();
    let first: Vec<f64> = pieces.iter().map(|&(t, p)| gauss_rect(density, t, p)).collect();
    let total: f64 = first.iter().sum();
    let tol = abs.max(rel * total.abs()) / CUTS as f64;
    pieces.iter().zip(first).map(|(&(t, p), whole)| refine(density, t, p, whole, tol, 8)).sum()
}

/// Probability of each cell under `density`.
fn cell_probabilities(density: &dyn Fn(Vec3) -> f64) -> Vec<f64> {
    cell_probabilities_with(density, QUAD_TOL)
}

fn cell_probabilities_with(density: &dyn Fn(Vec3) -> f64, tol: (f64, f64)) -> Vec<f64> {
    let mut out = Vec::with_capacity(COS_BINS * PHI_BINS);
    for i in 0..COS_BINS {
        let c0 = -1.0 + 2.0 * i as f64 / COS_BINS as f64;
        let c1 = -1.0 + 2.0 * (i + 1) as f64 / COS_BINS as f64;
        for j in 0..PHI_BINS {
            let p0 = TAU * j as f64 / PHI_BINS as f64;
            let p1 = TAU * (j + 1) as f64 / PHI_BINS as f64;
            out.push(integrate(density, (c0, c1), (p0, p1), tol));
        }
    }
    out
}

struct Chi2 {
    statistic: f64,
    dof: usize,
    p: f64,
    /// Total probability of the density over the sphere (the numerical integral of `pdf()`).
    total: f64,
    /// Fraction of `sample` calls that returned a direction.
    accepted: f64,
}

/// Pearson's test of the directions `sample` draws against the cell probabilities of
/// `density`. Samples that return `None` form one more cell, of probability 1 - total.
fn chi2_test(
    density: &dyn Fn(Vec3) -> f64,
    sampler: &dyn Fn([f32; 3]) -> Option<BsdfSample>,
    seed: u64,
) -> Chi2 {
    let probs = cell_probabilities(density);
    let total: f64 = probs.iter().sum();
    let n = CHI2_SAMPLES as f64;
    let mut observed = vec![0u64; probs.len() + 1];
    let mut rng = Pcg32::new(seed, 11);
    for _ in 0..CHI2_SAMPLES {
        match sampler(u3(&mut rng)) {
            Some(s) => {
                assert!(s.wi.is_finite() && (s.wi.length() - 1.0).abs() < 1e-4, "{s:?}");
                observed[cell(s.wi)] += 1;
            }
            None => observed[probs.len()] += 1,
        }
    }
    let mut expected: Vec<f64> = probs.iter().map(|p| p * n).collect();
    expected.push(((1.0 - total) * n).max(0.0));
    let accepted = 1.0 - observed[probs.len()] as f64 / n;

    // Pool cells as pbrt-v4 does: sorted by expected count, cells below MIN_EXPECTED (and then
    // further cells until the pool reaches it) go into one cell.
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut pooled_obs, mut pooled_exp) = (0.0, 0.0);
    let (mut statistic, mut cells) = (0.0, 0usize);
    for &i in &order {
        let (o, e) = (observed[i] as f64, expected[i]);
        if e == 0.0 {
            // Samples where the pdf says none can be: beyond a few rounding strays, reject.
            if o > n * 1e-5 {
                return Chi2 { statistic: f64::INFINITY, dof: 1, p: 0.0, total, accepted };
            }
            pooled_obs += o;
        } else if e < MIN_EXPECTED || (pooled_exp > 0.0 && pooled_exp < MIN_EXPECTED) {
            pooled_obs += o;
            pooled_exp += e;
        } else {
            statistic += (o - e) * (o - e) / e;
            cells += 1;
        }
    }
    if pooled_exp > 0.0 {
        statistic += (pooled_obs - pooled_exp).powi(2) / pooled_exp;
        cells += 1;
    }
    assert!(cells >= 2, "too few cells for a chi-square test");
    let dof = cells - 1;
    Chi2 { statistic, dof, p: chi2_survival(statistic, dof), total, accepted }
}

fn material_chi2(m: &Material, wo: Vec3, seed: u64) -> Chi2 {
    chi2_test(&|wi| pdf(m, wo, wi) as f64, &|u| sample(m, wo, u), seed)
}

/// The expected counts are exact enough for the test: a 10 times tighter quadrature moves no
/// cell by as much as one count at CHI2_SAMPLES samples and adds under 0.01 to the statistic
/// (whose standard deviation is ~sqrt(2 dof), 4 to 28 here), for the sharpest lobes; the
/// Diffuse cells sum to 1.
#[test]
fn chi_square_quadrature_is_accurate() {
    let n = CHI2_SAMPLES as f64;
    let sharpest = smooth_materials()
        .into_iter()
        .filter(|(name, _)| name == "diffuse" || name == "microfacet al alpha 0.05");
    for (name, m) in sharpest {
        for (t, p) in WO_ANGLES {
            let wo = dir(t, p);
            let density = |wi: Vec3| pdf(&m, wo, wi) as f64;
            let coarse = cell_probabilities_with(&density, QUAD_TOL);
            let fine = cell_probabilities_with(&density, (QUAD_TOL.0 / 10.0, QUAD_TOL.1 / 10.0));
            let pairs = || coarse.iter().zip(&fine).filter(|(_, &b)| b > 0.0);
            let worst = pairs().map(|(a, b)| (a - b).abs() * n).fold(0.0, f64::max);
            let x2: f64 = pairs().map(|(a, b)| (a - b).powi(2) * n / b).sum();
            assert!(worst < 1.0, "{name} wo ({t}, {p}): a cell moves by {worst} counts");
            assert!(x2 < 0.01, "{name} wo ({t}, {p}): quadrature error adds {x2} to X2");
            if name == "diffuse" {
                let total: f64 = coarse.iter().sum();
                assert!((total - 1.0).abs() < 1e-7, "diffuse pdf integrates to {total}");
            }
        }
    }
}

/// Sampled directions follow `pdf()` for every smooth material and outgoing direction.
#[test]
fn smooth_lobes_sample_the_pdf_they_report_chi_square() {
    let mut failures = Vec::new();
    let mut ps = Vec::new();
    let mut count = 0;
    for (name, m) in smooth_materials() {
        for (t, p) in WO_ANGLES {
            count += 1;
            let r = material_chi2(&m, dir(t, p), count as u64);
            eprintln!(
                "chi2 {name}, wo theta {t} phi {p}: X2 {:.1}, dof {}, p {:.4} \
                 (pdf integral {:.5}, sampled {:.5})",
                r.statistic, r.dof, r.p, r.total, r.accepted
            );
            ps.push(r.p);
            if !(r.p > SIGNIFICANCE) {
                failures.push(format!("{name} wo ({t}, {p}): p = {:.3e}", r.p));
            }
        }
    }
    assert_eq!(count, CHI2_TESTS, "the Bonferroni correction counts every test");
    let (lo, hi) = ps.iter().fold((1.0f64, 0.0f64), |(l, h), &p| (l.min(p), h.max(p)));
    eprintln!("chi2 p-values in [{lo:.4}, {hi:.4}], significance {SIGNIFICANCE:.2e}");
    assert!(failures.is_empty(), "sampling does not follow pdf():\n{}", failures.join("\n"));
}

/// The same test rejects a lobe sampled from one distribution and judged against another: the
/// cosine-weighted Diffuse lobe against the uniform-hemisphere pdf, and Beckmann lobes against
/// the pdf of an alpha 20% off.
#[test]
fn chi_square_rejects_a_wrong_pdf() {
    let diffuse = Material::Diffuse { albedo: Vec3::ONE };
    let wo = dir(45.0, 0.0);
    let uniform = |wi: Vec3| if wi.z > 0.0 { 1.0 / TAU } else { 0.0 };
    let r = chi2_test(&uniform, &|u| sample(&diffuse, wo, u), 1);
    eprintln!("diffuse vs uniform pdf: X2 {:.1}, dof {}, p {:.3e}", r.statistic, r.dof, r.p);
    assert!(r.p < SIGNIFICANCE, "uniform pdf accepted for cosine sampling: p = {}", r.p);

    let (_, eta, k) = CONDUCTORS[0];
    for (alpha, wrong, t) in [(0.2, 0.24, 0.0), (0.2, 0.16, 45.0), (0.5, 0.6, 60.0)] {
        let right = microfacet(alpha, eta, k);
        let off = microfacet(wrong, eta, k);
        let wo = dir(t, 30.0);
        let r = chi2_test(&|wi| pdf(&off, wo, wi) as f64, &|u| sample(&right, wo, u), 2);
        eprintln!(
            "alpha {alpha} sampled, alpha {wrong} pdf, theta {t}: X2 {:.1}, dof {}, p {:.3e}",
            r.statistic, r.dof, r.p
        );
        assert!(r.p < SIGNIFICANCE, "alpha {wrong} pdf accepted for alpha {alpha}: p = {}", r.p);
    }
}

// ------------------------------------------------------------------------------------------
// The pdf's normalisation, by the same cubature.

/// The pdf integrates to at most 1 over the sphere, to exactly 1 for the Diffuse lobe, and
/// close to 1 where a Beckmann lobe stays above the horizon.
#[test]
fn pdf_integrates_to_at_most_one() {
    for (name, m) in smooth_materials() {
        for (t, p) in WO_ANGLES {
            let wo = dir(t, p);
            let cells = cell_probabilities(&|wi| pdf(&m, wo, wi) as f64);
            // The lower hemisphere (the first half of the cells) holds nothing.
            let (below, above) = cells.split_at(cells.len() / 2);
            let below: f64 = below.iter().sum();
            let above: f64 = above.iter().sum();
            eprintln!("{name} wo ({t}, {p}): integral of pdf {above:.6}");
            assert_eq!(below, 0.0, "{name}");
            assert!(above <= 1.0 + 1e-4, "{name} wo ({t}, {p}): pdf integrates to {above}");
            let lossless = match m {
                Material::Diffuse { .. } => true,
                Material::Microfacet { alpha, .. } => alpha <= 0.2 && t <= 45.0,
                _ => false,
            };
            if lossless {
                assert!(above > 0.995, "{name} wo ({t}, {p}): pdf integrates to {above}");
            }
        }
    }
}
