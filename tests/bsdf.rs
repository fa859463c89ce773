//! Properties of the BSDFs (`pathtracer::integrator::bsdf`) that any correct implementation
//! has, whatever random numbers it draws: these pin the shading across a rewrite.
//!
//! - Smooth lobes (Diffuse, Microfacet): sampled directions follow the pdf that `pdf()`
//!   reports, by a chi-square goodness-of-fit test as in Mitsuba 3's `chi2` and pbrt-v4's
//!   `bsdfs_test.cpp` (the sphere binned 20 x 40 in cos theta x phi, 10^6 samples, expected
//!   counts integrated from `pdf()` by adaptive Gauss-Legendre cubature, cells with expected
//!   count < 5 pooled, and one more cell for "no sample"; p-value from the chi-square
//!   distribution against 1e-2 Bonferroni-corrected over every chi-square test here).
//!   Deliberately wrong pdfs are rejected by the same routine.
//! - Sample weights equal f cos / pdf; the pdf integrates to at most 1; f is reciprocal.
//! - White furnace: the mean sample weight is at most 1 (for dielectrics, once the radiance
//!   scaling of transmission is taken out, reflection and transmission probabilities sum to 1).
//! - Delta lobes (Mirror, Glass, Refraction): `eval` and `pdf` are 0, samples are the mirror
//!   direction or obey Snell's law, with the course's Schlick reflection probability, and
//!   total internal reflection past the critical angle.
//!
//! One `#[ignore]`d test asserts physics that the glass does not have: Schlick's R from inside
//! at the outside angle (the renderer keeps the course's Schlick of |wo.z| on both sides; the
//! physical choice was tried and measured 3% darker on the glass ball against Mitsuba 3's
//! exact-Fresnel reference, not yet understood: PERF.md "Whole renders: bias"). Run it with
//! `-- --ignored`. A second test found the transmission's eta^2 radiance scaling inverted;
//! that bug is fixed.
//!
//! Every test uses a fixed-seed PCG32, so it is deterministic.
//! `cargo test --release --test bsdf -- --nocapture` prints the chi-square p-values.

use std::f64::consts::{PI, TAU};

use pathtracer::integrator::bsdf::{eval, has_smooth_lobe, pdf, sample, BsdfSample};
use pathtracer::math::Vec3;
use pathtracer::sampler::Pcg32;
use pathtracer::scene::Material;

// ------------------------------------------------------------------------------------------
// The materials and directions under test.

/// Aluminium and silver as the course's `CBspheres_microfacet_al_ag.dae` has them, and a
/// near-perfect conductor (Fresnel reflectance ~1).
const CONDUCTORS: [(&str, [f32; 3], [f32; 3]); 3] = [
    ("al", [1.3352, 1.0109, 0.68955], [7.3398, 6.6157, 5.6471]),
    ("ag", [0.059193, 0.059881, 0.047366], [4.1283, 3.5892, 2.8132]),
    ("perfect", [1.0, 1.0, 1.0], [1e3, 1e3, 1e3]),
];
const ALPHAS: [f32; 3] = [0.05, 0.2, 0.5];

/// (theta, phi) in degrees of the outgoing directions above the surface: the normal, 45
/// degrees, grazing, and one off the x axis (so that a lobe mirrored about the wrong axis
/// shows).
const WO_ANGLES: [(f32, f32); 4] = [(0.0, 0.0), (45.0, 0.0), (85.0, 0.0), (60.0, 130.0)];

fn dir(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

fn microfacet(alpha: f32, eta: [f32; 3], k: [f32; 3]) -> Material {
    Material::Microfacet { alpha, eta: Vec3::from_array(eta), k: Vec3::from_array(k) }
}

/// Every smooth material of the course with a name.
fn smooth_materials() -> Vec<(String, Material)> {
    let mut out =
        vec![("diffuse".to_string(), Material::Diffuse { albedo: Vec3::new(0.2, 0.5, 0.8) })];
    for alpha in ALPHAS {
        for (name, eta, k) in CONDUCTORS {
            out.push((format!("microfacet {name} alpha {alpha}"), microfacet(alpha, eta, k)));
        }
    }
    out
}

/// Chi-square tests run in this file (the smooth materials x the directions), for Bonferroni.
const CHI2_TESTS: usize = (1 + ALPHAS.len() * CONDUCTORS.len()) * WO_ANGLES.len();
const SIGNIFICANCE: f64 = 1e-2 / CHI2_TESTS as f64;

fn u3(rng: &mut Pcg32) -> [f32; 3] {
    [rng.next_f32(), rng.next_f32(), rng.next_f32()]
}

fn rel_close(a: Vec3, b: Vec3, rel: f32) -> bool {
    (a - b).abs().max_element() <= rel * a.abs().max(b.abs()).max_element()
}

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
// Weights, pdf normalisation, reciprocity, white furnace.

/// Every sample's weight is f cos / pdf and its pdf is `pdf()`, to 1e-3 relative.
#[test]
fn sample_weight_is_f_cos_over_pdf() {
    let mut rng = Pcg32::new(21, 3);
    for (name, m) in smooth_materials() {
        for (t, p) in WO_ANGLES {
            let wo = dir(t, p);
            let mut taken = 0;
            for _ in 0..100_000 {
                let Some(s) = sample(&m, wo, u3(&mut rng)) else { continue };
                taken += 1;
                let q = pdf(&m, wo, s.wi);
                let f = eval(&m, wo, s.wi);
                assert!(s.pdf > 0.0 && s.pdf != 0.0, "{name}: {s:?}");
                assert!((s.pdf - q).abs() <= 1e-3 * q, "{name} wo {wo}: pdf {} vs {q}", s.pdf);
                let want = f * s.wi.z / q;
                assert!(s.weight.is_finite() && s.weight.min_element() >= 0.0, "{name}: {s:?}");
                assert!(
                    rel_close(s.weight, want, 1e-3),
                    "{name} wo {wo} wi {}: weight {} vs f cos / pdf {want}",
                    s.wi,
                    s.weight
                );
            }
            assert!(taken > 10_000, "{name} wo ({t}, {p}): only {taken} samples");
        }
    }
}

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

/// f(wo, wi) = f(wi, wo) for random direction pairs: uniform over the sphere (above and across
/// the surface; a sharp lobe is 0 for most of them) and pairs where wi is sampled from wo (so
/// that the lobes' peaks are covered).
#[test]
fn smooth_lobes_are_reciprocal() {
    let mut rng = Pcg32::new(5, 8);
    let random_dir = |rng: &mut Pcg32| {
        let z = 2.0 * rng.next_f32() - 1.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * rng.next_f32();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    };
    for (name, m) in smooth_materials() {
        let mut nonzero = 0;
        for i in 0..20_000 {
            let a = random_dir(&mut rng);
            let b = match i % 2 {
                0 => random_dir(&mut rng),
                _ => sample(&m, a, u3(&mut rng)).map_or_else(|| random_dir(&mut rng), |s| s.wi),
            };
            let (ab, ba) = (eval(&m, a, b), eval(&m, b, a));
            assert!(ab.is_finite() && ab.min_element() >= 0.0, "{name}: f({a}, {b}) = {ab}");
            assert!(rel_close(ab, ba, 1e-4), "{name}: f({a}, {b}) = {ab} but f({b}, {a}) = {ba}");
            if a.z <= 0.0 || b.z <= 0.0 {
                assert_eq!(ab, Vec3::ZERO, "{name}: f across the surface");
            }
            nonzero += (ab.max_element() > 0.0) as u32;
        }
        assert!(nonzero > 5_000, "{name}: only {nonzero} nonzero pairs");
    }
}

/// Mean and standard error of `x` over `n` draws.
fn mean_se(n: usize, mut x: impl FnMut() -> f64) -> (f64, f64) {
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..n {
        let v = x();
        s += v;
        s2 += v * v;
    }
    let mean = s / n as f64;
    let var = (s2 / n as f64 - mean * mean).max(0.0) * n as f64 / (n as f64 - 1.0);
    (mean, (var / n as f64).sqrt())
}

/// White furnace of the smooth lobes: albedo 1, and a conductor whose Fresnel reflectance is
/// ~1 (k = 1e3). The mean sample weight (directional albedo) is at most 1 for every wo, exactly
/// 1 for the Diffuse lobe, and close to 1 for a Beckmann lobe that stays above the horizon.
#[test]
fn white_furnace_smooth_lobes_reflect_at_most_everything() {
    let mut materials = vec![("diffuse".to_string(), Material::Diffuse { albedo: Vec3::ONE })];
    for alpha in ALPHAS {
        materials
            .push((format!("microfacet alpha {alpha}"), microfacet(alpha, [1.0; 3], [1e3; 3])));
    }
    let mut rng = Pcg32::new(9, 9);
    for (name, m) in materials {
        for (t, p) in WO_ANGLES {
            let wo = dir(t, p);
            let (mean, se) = mean_se(400_000, || {
                sample(&m, wo, u3(&mut rng)).map_or(0.0, |s| s.weight.max_element() as f64)
            });
            eprintln!("furnace {name} wo ({t}, {p}): {mean:.5} +- {se:.5}");
            // Walter et al.'s rational Smith G1 is within ~0.4% of the exact one.
            assert!(mean <= 1.0 + 4.0 * se + 5e-3, "{name} wo ({t}, {p}): albedo {mean} > 1");
            match m {
                Material::Diffuse { .. } => assert!((mean - 1.0).abs() < 1e-6, "{name}: {mean}"),
                Material::Microfacet { alpha, .. } if alpha <= 0.2 && t <= 45.0 => {
                    assert!(mean > 0.95, "{name} wo ({t}, {p}): albedo {mean}")
                }
                _ => {}
            }
        }
    }
}

// ------------------------------------------------------------------------------------------
// Delta lobes: Mirror, Glass, Refraction.

const IORS: [f32; 2] = [1.5, 1.33];

/// The course's Schlick approximation R0 + (1 - R0) (1 - cos)^5, R0 = ((1 - ior) / (1 + ior))^2.
fn schlick(cos: f32, ior: f32) -> f32 {
    let r0 = ((1.0 - ior) / (1.0 + ior)).powi(2);
    r0 + (1.0 - r0) * (1.0 - cos).powi(5)
}

fn glass(ior: f32) -> Material {
    Material::Glass { reflectance: Vec3::ONE, transmittance: Vec3::ONE, roughness: 0.0, ior }
}

fn refraction(ior: f32) -> Material {
    Material::Refraction { transmittance: Vec3::ONE, roughness: 0.0, ior }
}

/// Outgoing directions for dielectrics: the WO_ANGLES and 30 degrees (inside, below the critical
/// angle of both IORS) outside, and the same mirrored inside.
fn dielectric_wos() -> Vec<Vec3> {
    let outside: Vec<Vec3> =
        WO_ANGLES.iter().chain(&[(30.0, 200.0)]).map(|&(t, p)| dir(t, p)).collect();
    outside.iter().copied().chain(outside.iter().map(|w| Vec3::new(w.x, w.y, -w.z))).collect()
}

/// The transmitted direction by Snell's law, or None past the critical angle.
fn snell(wo: Vec3, ior: f32) -> Option<Vec3> {
    let ratio = if wo.z > 0.0 { 1.0 / ior } else { ior }; // n_wo / n_wi
    let sin2_t = ratio * ratio * (1.0 - wo.z * wo.z);
    (sin2_t < 1.0)
        .then(|| Vec3::new(-ratio * wo.x, -ratio * wo.y, -wo.z.signum() * (1.0 - sin2_t).sqrt()))
}

fn mirror_dir(wo: Vec3) -> Vec3 {
    Vec3::new(-wo.x, -wo.y, wo.z)
}

#[test]
fn delta_lobes_have_zero_eval_and_pdf_and_no_smooth_lobe() {
    let deltas = [
        Material::Mirror { reflectance: Vec3::ONE },
        glass(1.5),
        glass(1.33),
        refraction(1.5),
        refraction(1.33),
    ];
    let mut rng = Pcg32::new(4, 4);
    for m in deltas {
        assert!(!has_smooth_lobe(&m), "{m:?}");
        for wo in dielectric_wos() {
            // Random directions and the lobes' own specular directions alike.
            let mut wis: Vec<Vec3> = (0..200)
                .map(|_| {
                    let z = 2.0 * rng.next_f32() - 1.0;
                    let r = (1.0 - z * z).sqrt();
                    let phi = std::f32::consts::TAU * rng.next_f32();
                    Vec3::new(r * phi.cos(), r * phi.sin(), z)
                })
                .collect();
            wis.push(mirror_dir(wo));
            wis.extend(IORS.iter().filter_map(|&ior| snell(wo, ior)));
            for wi in wis {
                assert_eq!(eval(&m, wo, wi), Vec3::ZERO, "{m:?} f({wo}, {wi})");
                assert_eq!(pdf(&m, wo, wi), 0.0, "{m:?} pdf({wo}, {wi})");
            }
            for _ in 0..100 {
                if let Some(s) = sample(&m, wo, u3(&mut rng)) {
                    assert!(s.pdf == 0.0, "{m:?}: {s:?}");
                }
            }
        }
    }
    for m in [Material::Diffuse { albedo: Vec3::ONE }, microfacet(0.2, [1.0; 3], [1e3; 3])] {
        assert!(has_smooth_lobe(&m), "{m:?}");
    }
    let emitter = Material::Emission { radiance: Vec3::ONE };
    assert!(!has_smooth_lobe(&emitter));
    assert!(sample(&emitter, Vec3::Z, [0.5; 3]).is_none(), "emitters reflect nothing");
}

#[test]
fn mirror_reflects_about_the_normal_with_its_reflectance() {
    let m = Material::Mirror { reflectance: Vec3::new(0.9, 0.8, 0.7) };
    let mut rng = Pcg32::new(6, 6);
    for (t, p) in WO_ANGLES {
        let wo = dir(t, p);
        for _ in 0..100 {
            let s = sample(&m, wo, u3(&mut rng)).expect("a mirror always reflects from above");
            assert!((s.wi - mirror_dir(wo)).length() < 1e-6, "{wo}: {}", s.wi);
            assert_eq!(s.weight, Vec3::new(0.9, 0.8, 0.7));
        }
    }
}

/// Sampled glass: reflection is the mirror direction with weight `reflectance`, transmission
/// obeys Snell's law, and the reflection probability from outside is Schlick's R at that angle
/// (within 4 binomial standard errors). White glass then keeps all energy: with the radiance
/// scaling of transmission taken out, every sample carries 1, so E = R + (1 - R) = 1.
#[test]
fn glass_reflects_with_schlick_probability_and_refracts_by_snell() {
    let n = 200_000;
    let mut rng = Pcg32::new(12, 12);
    for ior in IORS {
        let m = glass(ior);
        for wo in dielectric_wos() {
            let mut reflected = 0usize;
            let mut scale = None;
            for _ in 0..n {
                let s = sample(&m, wo, u3(&mut rng)).expect("glass always scatters");
                assert!(s.pdf == 0.0);
                if s.wi.z * wo.z > 0.0 {
                    reflected += 1;
                    assert!((s.wi - mirror_dir(wo)).length() < 1e-6, "{wo}: {}", s.wi);
                    assert_eq!(s.weight, Vec3::ONE, "reflection carries the reflectance alone");
                } else {
                    let want = snell(wo, ior).expect("no transmission past the critical angle");
                    assert!((s.wi - want).length() < 1e-5, "ior {ior} {wo}: {} vs {want}", s.wi);
                    assert!((s.wi.length() - 1.0).abs() < 1e-5);
                    // Transmission carries the transmittance times a radiance scaling that is
                    // the same for every sample at this wo (see the tests below).
                    assert!(s.weight.x == s.weight.y && s.weight.y == s.weight.z);
                    let w = s.weight.x;
                    assert!(*scale.get_or_insert(w) == w);
                }
            }
            let p = reflected as f64 / n as f64;
            match snell(wo, ior) {
                None => assert_eq!(reflected, n, "total internal reflection"),
                Some(_) if wo.z > 0.0 => {
                    let r = schlick(wo.z, ior) as f64;
                    let sigma = (r * (1.0 - r) / n as f64).sqrt();
                    eprintln!("glass {ior} wo {wo}: P(reflect) {p:.5} vs Schlick {r:.5}");
                    assert!(
                        (p - r).abs() < 4.0 * sigma + 1e-6,
                        "ior {ior} wo {wo}: P(reflect) {p} vs Schlick {r} (sigma {sigma})"
                    );
                }
                // From inside below the critical angle: `glass_reflects_from_inside_...` below.
                Some(_) => assert!(p < 1.0),
            }
        }
    }
}

/// Total internal reflection: from inside, past the critical angle asin(1 / ior), glass reflects
/// every sample back inside and the transmission-only material returns no sample.
#[test]
fn total_internal_reflection_from_inside_at_grazing_angles() {
    let mut rng = Pcg32::new(13, 13);
    for ior in IORS {
        let critical = (1.0 / ior).asin().to_degrees();
        for theta in [critical + 0.5, 60.0, 75.0, 85.0, 89.0] {
            for phi in [0.0, 130.0] {
                let w = dir(theta, phi);
                let wo = Vec3::new(w.x, w.y, -w.z);
                for _ in 0..1000 {
                    let s = sample(&glass(ior), wo, u3(&mut rng)).unwrap();
                    assert!(s.wi.z < 0.0, "ior {ior} theta {theta}: TIR stays inside");
                    assert!((s.wi - mirror_dir(wo)).length() < 1e-6);
                    assert_eq!(s.weight, Vec3::ONE);
                    assert!(sample(&refraction(ior), wo, u3(&mut rng)).is_none());
                }
            }
        }
        // Just inside the critical angle both still transmit.
        let w = dir(critical - 1.0, 0.0);
        let wo = Vec3::new(w.x, w.y, -w.z);
        assert!(sample(&refraction(ior), wo, [0.5; 3]).is_some_and(|s| s.wi.z > 0.0));
        assert!(sample(&glass(ior), wo, [0.0, 0.0, 0.9999]).is_some_and(|s| s.wi.z > 0.0));
    }
}

/// The transmission-only material: always transmits by Snell's law (no Fresnel reflection).
#[test]
fn refraction_always_transmits_by_snell() {
    let mut rng = Pcg32::new(14, 14);
    for ior in IORS {
        let t = Vec3::new(0.9, 0.7, 0.5);
        let m = Material::Refraction { transmittance: t, roughness: 0.0, ior };
        for wo in dielectric_wos() {
            let Some(want) = snell(wo, ior) else { continue };
            for _ in 0..100 {
                let s = sample(&m, wo, u3(&mut rng)).expect("below the critical angle");
                assert!(s.pdf == 0.0);
                assert!((s.wi - want).length() < 1e-5, "ior {ior} {wo}: {} vs {want}", s.wi);
                let scale = s.weight / t;
                assert!(rel_close(scale, Vec3::splat(scale.x), 1e-6), "{}", s.weight);
            }
        }
    }
}

/// Radiance scaling of transmission, as the renderer has it: the weight is the transmittance
/// times (n_a / n_b)^2 for the two media, and the scalings of entering and of leaving are
/// reciprocal, so a path through a closed dielectric comes out unscaled. With the scaling
/// taken out, white glass and white Refraction carry exactly 1 per sample (R + T = 1, and
/// T = 1 for Refraction): nothing is created.
#[test]
fn transmission_scaling_is_a_ratio_of_indices_squared_and_reciprocal() {
    let mut rng = Pcg32::new(15, 15);
    for ior in IORS {
        for m in [glass(ior), refraction(ior)] {
            for (t, p) in WO_ANGLES {
                let wo = dir(t, p);
                let transmitted = |wo: Vec3, rng: &mut Pcg32| loop {
                    let s = sample(&m, wo, u3(rng)).unwrap();
                    if s.wi.z * wo.z < 0.0 {
                        return s;
                    }
                };
                let enter = transmitted(wo, &mut rng);
                // The reversed path: seen from inside along the transmitted direction, the
                // light comes in from outside along wo.
                let leave = transmitted(enter.wi, &mut rng);
                assert!((leave.wi - wo).length() < 1e-4, "{m:?}: {} vs {wo}", leave.wi);
                let (a, b) = (enter.weight.x, leave.weight.x);
                let ior2 = ior * ior;
                assert!(
                    (a - ior2).abs() < 1e-5 * ior2 || (a - 1.0 / ior2).abs() < 1e-5 / ior2,
                    "{m:?} wo {wo}: scaling {a} is neither ior^2 nor 1 / ior^2"
                );
                assert!((a * b - 1.0).abs() < 1e-5, "{m:?}: entering {a} x leaving {b} != 1");
                // White furnace with the scaling taken out: exactly 1 per sample.
                let energy = (0..10_000)
                    .map(|_| {
                        let s = sample(&m, wo, u3(&mut rng)).unwrap();
                        let scaling = if s.wi.z * wo.z < 0.0 { a } else { 1.0 };
                        (s.weight.max_element() / scaling) as f64
                    })
                    .sum::<f64>()
                    / 10_000.0;
                assert!((energy - 1.0).abs() < 1e-6, "{m:?} wo {wo}: energy {energy}");
            }
        }
    }
}

/// The physical direction of the scaling: radiance over n^2 is invariant across a smooth
/// interface, so radiance seen from outside (n = 1) through glass (n = ior) is the radiance
/// inside times (1 - F) / ior^2 (pbrt's `ft *= Sqr(etaI / etaT)` in radiance mode, etaI on the
/// side of wo). The BSDF's own doc comment defines eta = n_incident / n_transmitted along the
/// light path (ior / 1 for a camera ray entering), and weights by 1 / eta^2.
// BUG: `refract` returns eta = 1 / ior for a ray entering from outside (contradicting its doc
// comment), so the weight is T * ior^2 = 2.25 T at ior 1.5 instead of T / ior^2 = 0.444 T,
// and the inverse when leaving. A path through a closed object cancels it; paths that end
// inside (depth limit, Russian roulette) or see light inside do not.
#[test]
fn transmission_scales_radiance_by_n_wo_over_n_wi_squared() {
    for ior in IORS {
        for m in [glass(ior), refraction(ior)] {
            for wo in dielectric_wos() {
                let Some(want_wi) = snell(wo, ior) else { continue };
                let (n_wo, n_wi) = if wo.z > 0.0 { (1.0, ior) } else { (ior, 1.0) };
                let want = (n_wo / n_wi) * (n_wo / n_wi);
                // u[2] = 0.9999 picks transmission for glass below grazing angles.
                let s = sample(&m, wo, [0.5, 0.5, 0.9999]).unwrap();
                assert!((s.wi - want_wi).length() < 1e-5);
                assert!(
                    (s.weight.x - want).abs() < 1e-5 * want,
                    "ior {ior} wo {wo}: transmission weight {} vs (n_wo / n_wi)^2 = {want}",
                    s.weight.x
                );
            }
        }
    }
}

/// Fresnel reflectance is the same from both sides of an interface (Stokes): from inside at
/// theta_i below the critical angle, glass must reflect with Schlick's R of the angle outside,
/// theta_t (Schlick's formula holds for the cosine on the side of the lower index), so that R
/// rises continuously to 1 at the critical angle.
#[test]
#[ignore = "course convention kept: from inside, the reflection probability is Schlick of the \
            inside angle (0.041 at 40 deg, ior 1.5) instead of the outside angle (0.246)"]
fn glass_reflects_from_inside_with_schlick_of_the_outside_angle() {
    let n = 200_000;
    let mut rng = Pcg32::new(16, 16);
    for ior in IORS {
        let m = glass(ior);
        for wo in dielectric_wos().into_iter().filter(|w| w.z < 0.0) {
            let Some(wt) = snell(wo, ior) else { continue };
            let reflected =
                (0..n).filter(|_| sample(&m, wo, u3(&mut rng)).unwrap().wi.z < 0.0).count();
            let p = reflected as f64 / n as f64;
            let r = schlick(wt.z.abs(), ior) as f64;
            let sigma = (r * (1.0 - r) / n as f64).sqrt();
            assert!(
                (p - r).abs() < 4.0 * sigma + 1e-6,
                "ior {ior} inside wo {wo}: P(reflect) {p:.4} vs Schlick(theta_t) {r:.4}"
            );
        }
        // The critical angle: R must be continuous there.
        let critical = (1.0 / ior).asin().to_degrees();
        let w = dir(critical - 0.2, 0.0);
        let wo = Vec3::new(w.x, w.y, -w.z);
        let reflected = (0..n).filter(|_| sample(&m, wo, u3(&mut rng)).unwrap().wi.z < 0.0).count();
        let p = reflected as f64 / n as f64;
        assert!(p > 0.5, "ior {ior}: 0.2 deg inside the critical angle P(reflect) = {p:.4}");
    }
}
