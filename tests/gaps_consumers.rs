//! Missing outputs in what consumes a record besides the criterion (METHOD.md 21.3): the ARX
//! start, the covariance and the residual tests, each against a direct computation on a small
//! record with gaps; the spectral estimate's segments; the integrating-plant test.

mod common;

use common::*;
use oesweep::estimate::{Loss, Problem, evidence, initial_guess};
use oesweep::oe::{self, Structure};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Uniform numbers in (0, 1) and Gaussians from an LCG (the same on every machine).
/// An OE(2,2) record (delay 1) with output noise of std `noise` and 5 % of its outputs
/// missing (NaN in y).
fn record(n: usize, noise: f64, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<usize>) {
    let (b, f) = oe22();
    let u = binary_input(n, 3, 1.0, seed);
    let mut y = oe::simulate_vec(&b, &f, 1, &u);
    let mut r = Draws(seed ^ 0x5eed);
    for v in y.iter_mut() {
        *v += noise * r.gauss();
    }
    let missing = output_gaps(n, 0.05, &mut r);
    for &t in &missing {
        y[t] = f64::NAN;
    }
    (u, y, missing)
}

/// The ARX start of noise-free data is the system itself, also with 5 % of the outputs
/// missing: a row that needs a missing output is left out, not taken as zero.
#[test]
fn the_arx_start_of_noise_free_data_with_gaps_is_exact() {
    let (u, y, missing) = record(2000, 0.0, 3);
    for seams in [vec![], vec![700]] {
        let prob = Problem {
            u: &u,
            y: &y,
            structure: Structure::siso(2, 2, 1),
            offset: false,
            seams: &seams,
            missing: &missing,
        };
        let theta = initial_guess::arx(&prob).expect("a start");
        let (b, f) = oe22();
        let truth: Vec<f64> = b.iter().chain(&f).copied().collect();
        // Across a seam the ARX rows restart from zero lags, which noise-free data of one
        // simulation does not: only the record of one experiment is exact.
        if seams.is_empty() {
            for (a, t) in theta.iter().zip(&truth) {
                assert!((a - t).abs() < 1e-9, "{theta:?} vs {truth:?}");
            }
        }
        assert!(theta.iter().all(|v| v.is_finite()));
        for start in initial_guess::initial_guesses(&prob) {
            assert!(start.iter().all(|v| v.is_finite()), "{start:?}");
        }
    }
}

/// The ARX start of a noisy record with gaps is the least-squares solution of the regression
/// rows written out: those whose target and output lags are all observed.
#[test]
fn the_arx_start_with_gaps_is_the_regression_of_the_complete_rows() {
    let (u, y, missing) = record(1500, 0.2, 8);
    let prob =
        Problem { u: &u, y: &y, structure: Structure::siso(2, 2, 1), offset: false, seams: &[], missing: &missing };
    let theta = initial_guess::arx(&prob).expect("a start");
    // Rows t with y_t, y_{t-1}, y_{t-2} observed (t - 2 >= 0, or the lag before the start is 0).
    let phi = |t: usize| {
        let at = |x: &[f64], lag: usize| if t >= lag { x[t - lag] } else { 0.0 };
        [at(&u, 1), at(&u, 2), -at(&y, 1), -at(&y, 2)]
    };
    let (mut a, mut rhs) = ([[0.0; 4]; 4], [0.0; 4]);
    let mut rows = 0;
    for t in 0..y.len() {
        if (0..=2).any(|lag| t >= lag && y[t - lag].is_nan()) {
            continue;
        }
        rows += 1;
        let p = phi(t);
        for i in 0..4 {
            rhs[i] += p[i] * y[t];
            for j in 0..4 {
                a[i][j] += p[i] * p[j];
            }
        }
    }
    assert!(rows < y.len() - missing.len(), "rows after a gap are left out");
    let lhs = faer::Mat::<f64>::from_fn(4, 4, |i, j| a[i][j]);
    let sol = oesweep::dense::Lu::new(lhs.as_ref()).solve(faer::Mat::<f64>::from_fn(4, 1, |i, _| rhs[i]).as_ref());
    let direct: Vec<f64> = (0..4).map(|i| sol[(i, 0)]).collect();
    // ARX of OE data is biased but stable here, so no reflection: the same numbers.
    for (x, d) in theta.iter().zip(&direct) {
        assert!((x - d).abs() <= 1e-9 * (1.0 + d.abs()), "{theta:?} vs {direct:?}");
    }
}

/// The covariance and the residual tests of a Huber fit on a record with gaps, against their
/// definitions over the observed samples: the Jacobian by central differences of the
/// simulation, its rows at missing samples left out; the Ljung-Box statistic over the observed
/// pairs; the independence statistic with the observed rows' Gram matrix of the input's lags.
#[test]
fn the_evidence_of_a_record_with_gaps_is_that_of_its_observed_samples() {
    let n = 4000;
    let (u, mut y, missing) = record(n, 0.1, 21);
    let mut r = Draws(77);
    for (t, v) in y.iter_mut().enumerate() {
        if t % 29 == 5 && !v.is_nan() {
            *v += 2.0 * if r.uniform() < 0.5 { 1.0 } else { -1.0 };
        }
    }
    let seams = [2000];
    let prob =
        Problem { u: &u, y: &y, structure: Structure::siso(2, 2, 1), offset: false, seams: &seams, missing: &missing };
    let (b, f) = oe22();
    let theta: Vec<f64> = b.iter().chain(&f).map(|v| v * 1.01).collect();
    let loss = Loss::Huber { gamma: 0.15 };
    let yhat = prob.simulate_vec(&theta);
    let observed: Vec<usize> = (0..n).filter(|t| missing.binary_search(t).is_err()).collect();
    let no = observed.len() as f64;

    // Covariance: kappa (sum_O psi psi^T)^-1.
    let d = theta.len();
    let jac: Vec<Vec<f64>> = (0..d)
        .map(|i| {
            let h = 1e-6;
            let (mut tp, mut tm) = (theta.clone(), theta.clone());
            tp[i] += h;
            tm[i] -= h;
            let (p, m) = (prob.simulate_vec(&tp), prob.simulate_vec(&tm));
            p.iter().zip(&m).map(|(a, b)| (a - b) / (2.0 * h)).collect()
        })
        .collect();
    let psi: Vec<f64> = (0..n).map(|t| loss.psi(y[t] - yhat[t])).collect();
    let inside = observed.iter().filter(|&&t| (y[t] - yhat[t]).abs() <= 0.15).count() as f64 / no;
    let kappa = observed.iter().map(|&t| psi[t] * psi[t]).sum::<f64>() / no / (inside * inside);
    let gram = faer::Mat::<f64>::from_fn(d, d, |i, j| observed.iter().map(|&t| jac[i][t] * jac[j][t]).sum::<f64>());
    let inv = oesweep::dense::Llt::new(gram.as_ref()).expect("positive definite").inverse();
    let cov = evidence::covariance(&prob, &theta, loss, &yhat).expect("a covariance");
    for i in 0..d {
        for j in 0..d {
            let want = kappa * inv[(i, j)];
            let scale = (kappa * inv[(i, i)] * kappa * inv[(j, j)]).sqrt();
            assert!((cov[i * d + j] - want).abs() <= 1e-4 * scale, "({i},{j}): {} vs {want}", cov[i * d + j]);
        }
    }

    // The residual tests through `evidence`, with the solver's Jacobian signals.
    let (mut xu, mut yh, mut xy) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    prob.simulate_filtered(&theta, &mut xu, &mut yh, &mut xy);
    let ev = evidence::evidence(&prob, &theta, loss, &yhat, &xu, &xy, &mut evidence::Scratch::default());
    let mean = observed.iter().map(|&t| psi[t]).sum::<f64>() / no;
    let e: Vec<f64> = (0..n).map(|t| if missing.binary_search(&t).is_ok() { 0.0 } else { psi[t] - mean }).collect();
    let experiment = |t: usize| usize::from(t >= 2000);
    let obs = |t: usize| missing.binary_search(&t).is_err();
    let m = 25;
    let pairs = |k: usize| (0..n - k).filter(move |&s| experiment(s) == experiment(s + k) && obs(s) && obs(s + k));
    let ree = |k: usize| pairs(k).map(|s| e[s] * e[s + k]).sum::<f64>();
    let q = no * (no + 2.0) * (1..=m).map(|k| (ree(k) / ree(0)).powi(2) / pairs(k).count() as f64).sum::<f64>();
    let white = ChiSquared::new(m as f64).unwrap().sf(q);
    let got = ev.resid_white_p.expect("a whiteness p");
    assert!((got - white).abs() <= 1e-9 * white.max(1e-3), "whiteness p {got} vs {white}");

    // Independence: r_k = sum_O e_t u_{t-k}, C = sum_O v_t v_t^T (v_t the lags 0..M within the
    // experiment), zeta = r^T C^-1 r / sigma^2. The engine's C is the input's Toeplitz matrix
    // less the missing rows: equal up to the lags at the experiments' ends (relative M / N).
    let um = u.iter().sum::<f64>() / n as f64;
    let uc: Vec<f64> = u.iter().map(|v| v - um).collect();
    let lagged = |t: usize, k: usize| if t >= k && experiment(t - k) == experiment(t) { uc[t - k] } else { 0.0 };
    let rk = faer::Mat::<f64>::from_fn(m + 1, 1, |k, _| observed.iter().map(|&t| e[t] * lagged(t, k)).sum::<f64>());
    let c = faer::Mat::<f64>::from_fn(m + 1, m + 1, |i, j| {
        observed.iter().map(|&t| lagged(t, i) * lagged(t, j)).sum::<f64>()
    });
    let x = oesweep::dense::Llt::new(c.as_ref()).expect("positive definite").solve(rk.as_ref());
    let sigma2 = ree(0) / no;
    let zeta = (0..=m).map(|k| rk[(k, 0)] * x[(k, 0)]).sum::<f64>() / sigma2;
    let indep = ChiSquared::new((m + 1) as f64).unwrap().sf(zeta);
    let got = ev.resid_indep_p.expect("an independence p");
    assert!((got - indep).abs() <= 0.02 + 0.05 * indep, "independence p {got} vs {indep}");
}

/// A burst of 20 missing outputs in the middle of a record: the spectral estimate is the one of
/// the two stretches as experiments, bit for bit (Welch and robust), and a record whose gaps
/// leave no two segments of 16 is refused with the longest stretch named.
#[test]
fn the_spectral_estimate_uses_the_stretches_between_gaps() {
    use oesweep::spectral::{SpectrumMethod, estimate_inputs};
    let half = 2048;
    let n = 2 * half + 20;
    let (b, f) = oe22();
    let u = binary_input(n, 1, 1.0, 5);
    let mut y = oe::simulate_vec(&b, &f, 1, &u);
    let mut r = Draws(9);
    y.iter_mut().for_each(|v| *v += 0.05 * r.gauss());
    let missing: Vec<usize> = (half..half + 20).collect();
    for &t in &missing {
        y[t] = f64::NAN;
    }
    let keep = |x: &[f64]| x[..half].iter().chain(&x[half + 20..]).copied().collect::<Vec<f64>>();
    for method in [SpectrumMethod::Welch, SpectrumMethod::Robust] {
        let gapped = estimate_inputs(&u, 1, &y, &[], &missing, 1.0, method).expect("two stretches of 2048");
        let cut = estimate_inputs(&keep(&u), 1, &keep(&y), &[half], &[], 1.0, method).expect("two experiments");
        let (g, c) = (&gapped[0], &cut[0]);
        assert_eq!((g.segment, g.segments, g.used), (c.segment, c.segments, c.used));
        assert_eq!(g.used, 2 * half);
        for k in 0..g.re.len() {
            assert_eq!(g.re[k].to_bits(), c.re[k].to_bits(), "{method:?} bin {k}");
            assert_eq!(g.coherence[k].to_bits(), c.coherence[k].to_bits());
        }
    }
    let mut sparse = y.clone();
    let every: Vec<usize> = (0..n).filter(|&t| t % 12 == 11 || missing.contains(&t)).collect();
    every.iter().for_each(|&t| sparse[t] = f64::NAN);
    let e = estimate_inputs(&u, 1, &sparse, &[], &every, 1.0, SpectrumMethod::Welch).unwrap_err().to_string();
    assert!(e.contains("the longest stretch without a missing output has 11 samples"), "{e}");
}

/// The integrating-plant test on a record with 5 % of its outputs missing: an integrator is
/// found, a stable plant is not.
#[test]
fn the_integrating_test_runs_on_the_observed_stretches() {
    use oesweep::estimate::integrating::pole_test;
    let n = 3000;
    let u = binary_input(n, 5, 1.0, 11);
    let mut r = Draws(12);
    let missing = output_gaps(n, 0.05, &mut r);
    for (pole, integrating) in [(1.0, true), (0.9, false)] {
        let mut y = oe::simulate_vec(&[0.1], &[-pole], 1, &u);
        y.iter_mut().for_each(|v| *v += 0.05 * r.gauss());
        let complete = pole_test(&u, &y, &[], 1).expect("the test runs");
        for &t in &missing {
            y[t] = f64::NAN;
        }
        let gapped = pole_test(&u, &y, &[], 1).expect("the test runs on the stretches");
        assert_eq!(gapped.integrating, integrating, "pole {pole}: {gapped:?}");
        assert_eq!(complete.integrating, integrating, "pole {pole}: {complete:?}");
        assert!((gapped.pole.0 - complete.pole.0).abs() < 0.02, "{gapped:?} vs {complete:?}");
    }
}
