//! Monte Carlo checks of the evidence a fit reports (METHOD.md 10): the standard deviations of
//! the parameters match their spread over noise realisations, and the residual tests pass the
//! true orders and reject an under-parameterised model.

mod common;

use common::*;
use oesweep::estimate::{self, Judge, Problem, SolverOptions, Workspace};
use oesweep::oe;
use oesweep::oe::Structure;

/// One realisation of our OE(2,2) system: Gaussian noise, and with `spikes` that share of
/// samples hit by a spike of 1..3 of either sign.
fn realisation(seed: u64, spikes: f64) -> (Vec<f64>, Vec<f64>) {
    let (b, f) = oe22();
    let n = 2000;
    let u = binary_input(n, 3, 1.0, 1000 + seed);
    let mut rng = Lcg(seed);
    let y = oe::simulate_vec(&b, &f, 1, &u)
        .iter()
        .map(|v| {
            let mut e = 0.1 * rng.normal();
            if rng.next() < spikes {
                e += (1.0 + 2.0 * rng.next()) * if rng.next() < 0.5 { -1.0 } else { 1.0 };
            }
            v + e
        })
        .collect();
    (u, y)
}

/// Per parameter: (mean reported std, standard deviation of the estimates).
fn calibration(estimates: &[Vec<f64>], stds: &[Vec<f64>]) -> Vec<(f64, f64)> {
    let m = estimates.len() as f64;
    (0..estimates[0].len())
        .map(|i| {
            let mean = estimates.iter().map(|t| t[i]).sum::<f64>() / m;
            let spread = (estimates.iter().map(|t| (t[i] - mean).powi(2)).sum::<f64>() / (m - 1.0)).sqrt();
            (stds.iter().map(|s| s[i]).sum::<f64>() / m, spread)
        })
        .collect()
}

fn assert_calibrated(what: &str, cal: &[(f64, f64)]) {
    eprintln!(
        "{what}: reported / spread = {:?}",
        cal.iter().map(|(r, s)| (r / s * 100.0).round() / 100.0).collect::<Vec<_>>()
    );
    for (i, (reported, spread)) in cal.iter().enumerate() {
        assert!(
            (reported / spread - 1.0).abs() <= 0.25,
            "{what}: parameter {i}: mean reported std {reported:.3e}, spread {spread:.3e}"
        );
    }
}

/// Enough that the spread itself is known to ~5 % (its relative error is about 1/sqrt(2 m)).
const REALISATIONS: u64 = 200;

#[test]
fn huber_std_matches_the_spread_with_spikes_and_least_squares_std_without() {
    let (opts, judge) = (SolverOptions::default(), Judge::default());
    let mut ws = Workspace::new();
    let (mut h_est, mut h_std, mut l_est, mut l_std) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for seed in 0..REALISATIONS {
        let (u, y) = realisation(seed, 0.05);
        let prob =
            Problem { u: &u, y: &y, structure: Structure::siso(2, 2, 1), offset: false, seams: &[], missing: &[] };
        let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
        let h = estimate::fit_huber(&prob, ls.sigma, 0.3, &ls.theta(), &judge, &opts, &mut ws);
        assert!(h.termination.converged(), "{:?}", h.termination);
        h_est.push(h.theta());
        let e = &h.assessment.evidence;
        h_std.push([&e.b_std[..], &e.f_std[..]].concat());

        let (u, y) = realisation(seed + 500, 0.0);
        let prob =
            Problem { u: &u, y: &y, structure: Structure::siso(2, 2, 1), offset: true, seams: &[], missing: &[] };
        let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
        l_est.push(ls.theta());
        let e = &ls.assessment.evidence;
        l_std.push([&e.b_std[..], &e.f_std[..], &[e.offset_std.unwrap()]].concat());
    }
    assert_calibrated("Huber, 5 % spikes", &calibration(&h_est, &h_std));
    assert_calibrated("least squares with an offset, Gaussian noise", &calibration(&l_est, &l_std));
}

#[test]
fn residual_tests_pass_the_true_orders_and_reject_too_few() {
    let (opts, judge) = (SolverOptions::default(), Judge::default());
    let mut ws = Workspace::new();
    let (mut white, mut indep, mut small_indep) = (0, 0, 0);
    for seed in 0..20 {
        let (u, y) = realisation(seed + 100, 0.05);
        let prob =
            Problem { u: &u, y: &y, structure: Structure::siso(2, 2, 1), offset: false, seams: &[], missing: &[] };
        let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
        let h = estimate::fit_huber(&prob, ls.sigma, 0.3, &ls.theta(), &judge, &opts, &mut ws);
        let e = &h.assessment.evidence;
        white += usize::from(e.resid_white_p.is_some_and(|p| p >= 0.01));
        indep += usize::from(e.resid_indep_p.is_some_and(|p| p >= 0.01));
        let under = Problem { structure: Structure::siso(1, 1, 1), ..prob };
        let ls = estimate::fit_ls(&under, &judge, &opts, &mut ws);
        let h = estimate::fit_huber(&under, ls.sigma, 0.3, &ls.theta(), &judge, &opts, &mut ws);
        small_indep += usize::from(h.assessment.evidence.resid_indep_p.is_some_and(|p| p < 0.01));
    }
    eprintln!("true orders: white {white}/20, independent {indep}/20; OE(1,1) rejected {small_indep}/20");
    assert!(white >= 16, "whiteness passed in {white} of 20 realisations at the true orders");
    assert!(indep >= 16, "independence passed in {indep} of 20 realisations at the true orders");
    assert!(small_indep >= 18, "OE(1,1) failed independence in only {small_indep} of 20");
}

/// A model with a parameter the data cannot determine (a pole-zero cancellation) says so.
#[test]
fn an_over_parameterised_model_has_a_large_relative_std() {
    let (u, y) = realisation(7, 0.0);
    let prob = Problem { u: &u, y: &y, structure: Structure::siso(6, 6, 1), offset: false, seams: &[], missing: &[] };
    let (opts, judge) = (SolverOptions::default(), Judge::default());
    let ls = estimate::fit_ls(&prob, &judge, &opts, &mut Workspace::new());
    assert!(ls.assessment.evidence.max_rel_std.is_some_and(|v| v > 1.0), "{:?}", ls.assessment.evidence);
    let right = Problem { structure: Structure::siso(2, 2, 1), ..prob };
    let ls = estimate::fit_ls(&right, &judge, &opts, &mut Workspace::new());
    assert!(ls.assessment.evidence.max_rel_std.is_some_and(|v| v < 0.2), "{:?}", ls.assessment.evidence);
}
