//! Missing outputs (METHOD.md 21.2): the fit of a record with gaps in its output is the
//! minimiser of the criterion over the observed residuals only, checked against a direct
//! computation of that criterion (its value, its gradient by central differences, and its rise
//! in every direction around the estimate).

mod common;

use common::*;
use oesweep::estimate::{self, Judge, Loss, Problem, SolverOptions, Workspace};
use oesweep::oe::{self, Structure};

/// An OE(2,2) record of N samples with Gaussian noise and 5 % spikes, and the indices of 5 % of
/// its outputs: half of them at random, half in bursts of 20.
fn record_with_gaps(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<usize>) {
    let (u, _, y, missing) = records(n, seed);
    (u, y, missing)
}

/// [`record_with_gaps`] with the full record's output beside it: (u, full y, y with gaps, gaps).
fn records(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<usize>) {
    let (b, f) = oe22();
    let u = binary_input(n, 3, 1.0, seed);
    let mut y = oe::simulate_vec(&b, &f, 1, &u);
    let mut r = Draws(seed ^ 0x9e37);
    for v in y.iter_mut() {
        *v += 0.05 * r.gauss();
        if r.uniform() < 0.05 {
            *v += if r.uniform() < 0.5 { 1.0 } else { -1.0 };
        }
    }
    let missing = output_gaps(n, 0.05, &mut r);
    let full = y.clone();
    for &t in &missing {
        y[t] = f64::NAN;
    }
    (u, full, y, missing)
}

/// The criterion over the observed residuals, computed directly from its definition.
fn direct(u: &[f64], y: &[f64], missing: &[usize], theta: &[f64], loss: Loss) -> f64 {
    let yhat = oe::simulate_vec(&theta[..2], &theta[2..4], 1, u);
    let c = theta[4];
    let observed: Vec<usize> = (0..y.len()).filter(|t| missing.binary_search(t).is_err()).collect();
    observed.iter().map(|&t| loss.rho(y[t] - yhat[t] - c)).sum::<f64>() / observed.len() as f64
}

/// The fit is where the direct criterion is smallest: same value, zero gradient (central
/// differences, relative to the gradient's size a small step away), and no lower point within
/// a few standard deviations' worth of steps in the coordinate directions.
fn assert_minimiser(u: &[f64], y: &[f64], missing: &[usize], theta: &[f64], reported: f64, loss: Loss) {
    let at = direct(u, y, missing, theta, loss);
    assert!((at - reported).abs() <= 1e-12 * at, "criterion {reported} vs direct {at}");
    let grad = |p: &[f64]| -> Vec<f64> {
        (0..p.len())
            .map(|i| {
                let h = 1e-6 * p[i].abs().max(1e-3);
                let (mut a, mut b) = (p.to_vec(), p.to_vec());
                a[i] += h;
                b[i] -= h;
                (direct(u, y, missing, &a, loss) - direct(u, y, missing, &b, loss)) / (2.0 * h)
            })
            .collect()
    };
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let away: Vec<f64> = theta.iter().map(|v| v + 1e-3 * v.abs().max(1e-2)).collect();
    let (g0, g1) = (norm(&grad(theta)), norm(&grad(&away)));
    assert!(g0 < 1e-3 * g1, "gradient at the estimate {g0} vs {g1} a step away");
    for i in 0..theta.len() {
        for s in [-1.0, 1.0] {
            let mut p = theta.to_vec();
            p[i] += s * 1e-4 * theta[i].abs().max(1e-2);
            assert!(direct(u, y, missing, &p, loss) >= at, "theta[{i}] {s:+}: lower than the estimate");
        }
    }
}

#[test]
fn the_fit_minimises_the_criterion_over_the_observed_outputs() {
    let n = 3000;
    let (u, y, missing) = record_with_gaps(n, 11);
    assert_eq!(missing.len(), n / 20);
    let prob =
        Problem { u: &u, y: &y, structure: Structure::siso(2, 2, 1), offset: true, seams: &[], missing: &missing };
    let opts = SolverOptions::default();
    let mut ws = Workspace::new();
    let judge = Judge::default();
    let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
    assert!(ls.termination.converged(), "{:?}", ls.termination);
    assert_minimiser(&u, &y, &missing, &ls.theta(), ls.criterion, Loss::LeastSquares);

    // sigma, fit %, L1C and the criteria's N are over the observed outputs.
    let theta = ls.theta();
    let yhat: Vec<f64> = oe::simulate_vec(&theta[..2], &theta[2..4], 1, &u).iter().map(|v| v + theta[4]).collect();
    let e: Vec<f64> = (0..n).filter(|t| missing.binary_search(t).is_err()).map(|t| y[t] - yhat[t]).collect();
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    let sigma = (e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / e.len() as f64).sqrt();
    assert!((ls.sigma - sigma).abs() <= 1e-12 * sigma, "sigma {} vs {sigma}", ls.sigma);
    let v = e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64;
    let aic = e.len() as f64 * (v.ln() + (2.0 * std::f64::consts::PI).ln() + 1.0) + 2.0 * 5.0;
    assert!((ls.criteria.aic - aic).abs() <= 1e-9 * aic.abs(), "aic {} vs {aic}", ls.criteria.aic);
    assert!(ls.assessment.fit.is_finite() && ls.assessment.fit > 50.0, "fit {}", ls.assessment.fit);

    for k in [0.1, 1.0] {
        let h = estimate::fit_huber(&prob, ls.sigma, k, &theta, &judge, &opts, &mut ws);
        assert!(h.termination.converged(), "{:?}", h.termination);
        let loss = Loss::Huber { gamma: h.gamma };
        assert_minimiser(&u, &y, &missing, &h.theta(), h.criterion, loss);
        let th = h.theta();
        let yh: Vec<f64> = oe::simulate_vec(&th[..2], &th[2..4], 1, &u).iter().map(|v| v + th[4]).collect();
        let beyond = (0..n).filter(|t| missing.binary_search(t).is_err() && (y[*t] - yh[*t]).abs() > h.gamma).count();
        let l1c = beyond as f64 / (n - missing.len()) as f64;
        assert!((h.l1c - l1c).abs() < 1e-15, "L1C {} vs {l1c}", h.l1c);
    }
}

#[test]
fn five_percent_missing_stays_within_the_reported_std_of_the_full_record() {
    let n = 3000;
    let (u, y_full, y_gaps, missing) = records(n, 23);
    let opts = SolverOptions::default();
    let judge = Judge::default();
    let mut ws = Workspace::new();
    let fit = |y: &[f64], missing: &[usize], ws: &mut Workspace| {
        let prob = Problem { u: &u, y, structure: Structure::siso(2, 2, 1), offset: true, seams: &[], missing };
        estimate::fit_one(&prob, 1.0, &judge, &opts, ws).huber
    };
    let full = fit(&y_full, &[], &mut ws);
    let gaps = fit(&y_gaps, &missing, &mut ws);
    let std: Vec<f64> = gaps.assessment.evidence.b_std.iter().chain(&gaps.assessment.evidence.f_std).copied().collect();
    assert_eq!(std.len(), 4);
    for (i, ((a, g), s)) in full.theta().iter().zip(gaps.theta()).zip(&std).enumerate() {
        assert!(s.is_finite() && *s > 0.0, "std[{i}] = {s}");
        assert!((a - g).abs() <= *s, "theta[{i}]: full {a}, with gaps {g}, reported std {s}");
    }
}
