//! Estimation core against known solutions, finite differences and invariants (METHOD.md 2-6).

mod common;

use common::*;
use oesweep::estimate::normal::{Layout, NormalEquations};
use oesweep::estimate::{self, Judge, Loss, Problem, SolverOptions, Workspace, solver};
use oesweep::oe;
use oesweep::oe::Structure;

fn assert_params(got: &[f64], truth: &[f64], tol: f64, what: &str) {
    let scale = truth.iter().map(|v| v.abs()).fold(0.0, f64::max);
    for (i, (g, t)) in got.iter().zip(truth).enumerate() {
        assert!((g - t).abs() <= tol * scale.max(t.abs()), "{what}: theta[{i}] = {g}, true {t}");
    }
}

fn recover(b: &[f64], f: &[f64], n: usize) {
    let u = binary_input(n, 3, 10.0, 7);
    let y = oe::simulate_vec(b, f, 1, &u);
    let truth = [b, f].concat();
    let prob = Problem {
        u: &u,
        y: &y,
        structure: Structure::siso(b.len(), f.len(), 1),
        offset: false,
        seams: &[],
        missing: &[],
    };
    let opts = SolverOptions::default();
    let mut ws = Workspace::new();
    let judge = Judge::default();
    let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
    assert!(ls.termination.converged(), "{:?}", ls.termination);
    assert_params(&ls.theta(), &truth, 1e-6, "L2");
    for k in [0.1, 1.5] {
        let h = estimate::fit_huber(&prob, ls.sigma, k, &ls.theta(), &judge, &opts, &mut ws);
        assert!(h.termination.converged(), "{:?}", h.termination);
        assert_params(&[&h.b[..], &h.f[..]].concat(), &truth, 1e-6, &format!("Huber k={k}"));
    }
    // The solver itself (not only the ARX/IV start) must find the truth from a poor start:
    // scale B by 1/2 and shrink the poles towards the origin.
    let start = shrunk(&truth, b.len(), 0.5, 0.97);
    let ls2 = estimate::fit_ls_from(&prob, &start, &judge, &opts, &mut ws);
    assert!(ls2.termination.converged(), "{:?}", ls2.termination);
    assert_params(&ls2.theta(), &truth, 1e-6, "L2 from a perturbed start");
    let g = 0.05 * (y.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
    let sol = solver::minimise(&prob, Loss::Huber { gamma: g }, &start, &opts, &mut ws);
    assert!(sol.termination.converged(), "{:?}", sol.termination);
    assert_params(&sol.theta, &truth, 1e-6, "Huber from a perturbed start");
}

#[test]
fn noise_free_oe22_recovers_true_parameters() {
    let (b, f) = oe22();
    recover(&b, &f, 2000);
}

#[test]
fn noise_free_oe1010_recovers_true_parameters() {
    let (b, f) = oe1010();
    recover(&b, &f, 5000);
}

/// Predictor Jacobian rows (two 1/F passes, METHOD.md 2) against central differences.
/// An over-parameterised model on noise-free data reaches the exact fit from the least-squares
/// phase of a pair without sub-models (the ARX/IV guesses, plain and damped): OE(6,6) on OE(2,2)
/// data, a criterion at rounding level and the data reproduced (METHOD.md 5.2).
#[test]
fn an_over_parameterised_fit_of_noise_free_data_is_exact() {
    let (b, f) = oe22();
    let u = binary_input(2000, 3, 1.0, 11);
    let y = oe::simulate_vec(&b, &f, 1, &u);
    let prob = Problem { u: &u, y: &y, structure: Structure::siso(6, 6, 1), offset: false, seams: &[], missing: &[] };
    let ls = estimate::fit_ls(&prob, &Judge::default(), &SolverOptions::default(), &mut Workspace::new());
    let scale = y.iter().map(|v| v * v).sum::<f64>() / y.len() as f64;
    assert!(ls.criterion < 1e-12 * scale, "criterion {} against a mean square of {scale}", ls.criterion);
    assert!(ls.assessment.fit > 99.999, "fit {} %", ls.assessment.fit);
}

#[test]
fn jacobian_matches_finite_differences() {
    let (b, f) = oe1010();
    let n = 400;
    let u = binary_input(n, 2, 1.0, 3);
    let lay = Layout::siso(b.len(), f.len(), 1);
    let theta: Vec<f64> = [&b[..], &f[..]].concat().iter().map(|v| v * 0.99).collect();
    let (tb, tf) = theta.split_at(b.len());
    let yhat = oe::simulate_vec(tb, tf, 1, &u);
    let mut xu = u.clone();
    oe::inv_f_in_place(tf, &mut xu);
    let mut xy = yhat.clone();
    oe::inv_f_in_place(tf, &mut xy);
    let d = theta.len();
    let mut row = vec![0.0; d];
    let h = 1e-6;
    for c in 0..d {
        let mut tp = theta.clone();
        let mut tm = theta.clone();
        tp[c] += h;
        tm[c] -= h;
        let yp = oe::simulate_vec(&tp[..b.len()], &tp[b.len()..], 1, &u);
        let ym = oe::simulate_vec(&tm[..b.len()], &tm[b.len()..], 1, &u);
        let mut worst: f64 = 0.0;
        let mut scale: f64 = 0.0;
        for t in 0..n {
            lay.row(&xu, &xy, t, &mut row);
            let fd = (yp[t] - ym[t]) / (2.0 * h);
            worst = worst.max((fd - row[c]).abs());
            scale = scale.max(fd.abs());
        }
        assert!(worst <= 1e-6 * scale.max(1e-12), "column {c}: max error {worst} (scale {scale})");
    }
}

/// Gradient of W assembled from the normal equations against central differences of W.
#[test]
fn huber_gradient_matches_finite_differences() {
    let (b, f) = oe22();
    let n = 1500;
    let u = binary_input(n, 2, 1.0, 5);
    let mut rng = Lcg(11);
    let y: Vec<f64> = oe::simulate_vec(&b, &f, 1, &u).iter().map(|v| v + 0.3 * rng.normal()).collect();
    let theta = vec![0.45, 0.33, f[0] * 0.98, f[1] * 1.01];
    let gamma = 0.2;
    let loss = Loss::Huber { gamma };
    let crit = |th: &[f64]| loss.criterion(&y, &oe::simulate_vec(&th[..2], &th[2..], 1, &u));
    let yhat = oe::simulate_vec(&theta[..2], &theta[2..], 1, &u);
    let r: Vec<f64> = y.iter().zip(&yhat).map(|(a, b)| loss.psi(a - b)).collect();
    let mut xu = u.clone();
    oe::inv_f_in_place(&theta[2..], &mut xu);
    let mut xy = yhat.clone();
    oe::inv_f_in_place(&theta[2..], &mut xy);
    let (mut h, mut g) = (vec![0.0; 16], vec![0.0; 4]);
    NormalEquations::default().build(&Layout::siso(2, 2, 1), &xu, &xy, None, &r, &mut h, &mut g);
    for c in 0..4 {
        let step = 1e-6;
        let mut tp = theta.clone();
        let mut tm = theta.clone();
        tp[c] += step;
        tm[c] -= step;
        let fd = (crit(&tp) - crit(&tm)) / (2.0 * step);
        // g is the negative gradient
        assert!((fd + g[c]).abs() <= 1e-5 * fd.abs().max(1e-8), "param {c}: fd {fd}, analytic {}", -g[c]);
    }
}

struct Outlier {
    u: Vec<f64>,
    y: Vec<f64>,
    uv: Vec<f64>,
    yv0: Vec<f64>,
}

/// Our OE(10,10) system with Gaussian noise and 10% large spikes; noise-free validation.
fn outlier_data(frac: f64) -> Outlier {
    let (b, f) = oe1010();
    let n = 4000;
    let u = binary_input(n, 3, 10.0, 21);
    let uv = binary_input(n, 3, 10.0, 22);
    let y0 = oe::simulate_vec(&b, &f, 1, &u);
    let scale = (y0.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
    let mut rng = Lcg(99);
    let y = y0
        .iter()
        .map(|v| {
            let mut e = 0.01 * scale * rng.normal();
            if rng.next() < frac {
                let m = scale * (1.0 + 2.0 * rng.next());
                e += if rng.next() < 0.5 { -m } else { m };
            }
            v + e
        })
        .collect();
    let yv0 = oe::simulate_vec(&b, &f, 1, &uv);
    Outlier { u, y, uv, yv0 }
}

#[test]
fn huber_beats_least_squares_with_outliers_and_invariants_hold() {
    let d = outlier_data(0.10);
    let prob =
        Problem { u: &d.u, y: &d.y, structure: Structure::siso(10, 10, 1), offset: false, seams: &[], missing: &[] };
    let judge = Judge {
        validation: Some((&d.uv, &d.yv0)),
        initial_state: oesweep::estimate::InitialState::Zero,
        ..Judge::default()
    };
    let opts = SolverOptions::default();
    let mut ws = Workspace::new();
    ws.record_trace = true;
    let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
    let ls_val = ls.assessment.fit_val.unwrap();
    let mut last_l1c = -1.0;
    for &k in &[2.0, 1.0, 0.5, 0.2, 0.1, 0.05] {
        let h = estimate::fit_huber(&prob, ls.sigma, k, &ls.theta(), &judge, &opts, &mut ws);
        // W never increases over accepted steps.
        for w in ws.trace.windows(2) {
            assert!(w[1] < w[0], "k={k}: criterion rose from {} to {}", w[0], w[1]);
        }
        assert!(oe::is_stable(&h.f) && h.assessment.max_pole_radius < 1.0, "k={k}: unstable F");
        assert!(h.l1c >= last_l1c, "k={k}: L1C {} fell below {}", h.l1c, last_l1c);
        last_l1c = h.l1c;
        if k <= 0.1 {
            let hv = h.assessment.fit_val.unwrap();
            assert!(hv >= ls_val + 5.0, "k={k}: Huber validation fit {hv:.2} vs L2 {ls_val:.2}");
        }
    }
}

/// Continuation chains (start strategy `chains`): on noise-free data every cell recovers the
/// truth; chains that reach the same minimum merge; a cell reports the best of its chains.
#[test]
fn chains_recover_the_truth_merge_duplicates_and_keep_the_best() {
    let (b, f) = oe22();
    let u = binary_input(2000, 3, 10.0, 7);
    let y = oe::simulate_vec(&b, &f, 1, &u);
    let truth = [&b[..], &f[..]].concat();
    let prob = Problem { u: &u, y: &y, structure: Structure::siso(2, 2, 1), offset: false, seams: &[], missing: &[] };
    let (opts, judge, mut ws) = (SolverOptions::default(), Judge::default(), Workspace::new());
    let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
    // The same start twice plus a poor one: all three reach the single (true) minimum.
    let mut poor = truth.clone();
    poor[0] *= 0.5;
    poor[2] *= 0.9;
    let mut chains = estimate::Chains::new(&ls.theta(), &[ls.theta(), poor]);
    // sigma of a noise-free fit is ~0; a scale of the signal keeps gamma meaningful.
    let scale = (y.iter().map(|v| v * v).sum::<f64>() / y.len() as f64).sqrt();
    assert_eq!(chains.live(), 3);
    for k in [0.05, 0.1, 0.5, 2.0] {
        let (h, which) =
            chains.step(&estimate::PairProblem { prob: &prob, sigma: scale, judge: &judge, opts: &opts }, k, &mut ws);
        assert!(h.termination.converged(), "{:?}", h.termination);
        assert!(which < 3);
        assert_params(&[&h.b[..], &h.f[..]].concat(), &truth, 1e-6, &format!("chains k={k}"));
        assert_eq!(chains.live(), 1, "chains at one minimum merge");
    }

    // Noisy data with spikes: each cell is the best of its chains, so never worse than the
    // chain from theta_LS alone walked over the same k.
    let mut rng = Lcg(11);
    let y: Vec<f64> = y.iter().map(|v| v + 0.05 * rng.normal() + if rng.next() < 0.05 { 3.0 } else { 0.0 }).collect();
    let prob = Problem { y: &y, ..prob };
    let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
    let mut start = ls.theta();
    start[2] *= 0.5;
    let mut both = estimate::Chains::new(&ls.theta(), &[start]);
    let mut alone = estimate::Chains::new(&ls.theta(), &[]);
    for k in [0.05, 0.2, 1.0] {
        let (h2, _) =
            both.step(&estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &opts }, k, &mut ws);
        let (h1, _) =
            alone.step(&estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &opts }, k, &mut ws);
        assert!(h2.criterion <= h1.criterion * (1.0 + 1e-12), "k={k}: {} > {}", h2.criterion, h1.criterion);
    }
}

/// A warm-started cell (`warm_lambda0`) ends at a minimum (polishing it with tight tolerances
/// lowers W by less than 1e-6, against the 1e-4 at which local minima differ) in fewer iterations than with the cold damping `lambda0`;
/// `lambda0 = 0` (a pure Gauss-Newton first step) is allowed, and a rejected step from it still
/// raises the damping (it used to stay 0 and loop forever).
#[test]
fn warm_damping_converges_to_a_minimum_in_fewer_iterations() {
    let (b, f) = oe1010();
    let u = binary_input(4000, 3, 10.0, 7);
    let mut rng = Lcg(5);
    let y: Vec<f64> = oe::simulate_vec(&b, &f, 1, &u)
        .iter()
        .map(|v| v + rng.normal() + if rng.next() < 0.05 { 6.0 } else { 0.0 })
        .collect();
    let prob = Problem {
        u: &u,
        y: &y,
        structure: Structure::siso(b.len(), f.len(), 1),
        offset: false,
        seams: &[],
        missing: &[],
    };
    let (judge, mut ws) = (Judge::default(), Workspace::new());
    let opts = SolverOptions::default();
    let cold = SolverOptions { warm_lambda0: opts.lambda0, ..opts.clone() };
    let tight = SolverOptions { ftol: 1e-14, xtol: 1e-14, gtol: 1e-14, huber_tol: 1e-14, ..opts.clone() };
    let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
    let ks: Vec<f64> = (0..12).map(|i| 0.1 * 1.1f64.powi(i)).collect();
    let mut warm_chain = estimate::Chains::new(&ls.theta(), &[]);
    let mut cold_chain = estimate::Chains::new(&ls.theta(), &[]);
    let (mut warm_its, mut cold_its) = (0, 0);
    for (i, &k) in ks.iter().enumerate() {
        let (w, _) = warm_chain.step(
            &estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &opts },
            k,
            &mut ws,
        );
        let (c, _) = cold_chain.step(
            &estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &cold },
            k,
            &mut ws,
        );
        assert!(w.termination.converged(), "{:?}", w.termination);
        let polished = estimate::fit_huber(&prob, ls.sigma, k, &[&w.b[..], &w.f[..]].concat(), &judge, &tight, &mut ws);
        assert!(
            polished.criterion >= w.criterion * (1.0 - 1e-6),
            "k={k}: {} polishes to {}",
            w.criterion,
            polished.criterion
        );
        if i == 0 {
            assert_eq!(w.iterations, c.iterations, "the first cell is a cold start in both");
        } else {
            warm_its += w.iterations;
            cold_its += c.iterations;
        }
    }
    assert!(warm_its < cold_its, "warm {warm_its} iterations, cold {cold_its}");

    let gn = SolverOptions { lambda0: 0.0, ..opts.clone() };
    let sol =
        solver::minimise(&prob, Loss::LeastSquares, &estimate::initial_guess::initial_guesses(&prob)[0], &gn, &mut ws);
    assert!(sol.termination.converged(), "{:?}", sol.termination);
}

/// The creeping-budget tests' case: noisy data of the OE(10,10) system on a binary input.
struct Oe1010 {
    u: Vec<f64>,
    y: Vec<f64>,
    nb: usize,
    nf: usize,
}

impl Oe1010 {
    fn new() -> Self {
        let (b, f) = oe1010();
        let u = binary_input(3000, 3, 10.0, 7);
        let mut rng = Lcg(9);
        let y: Vec<f64> = oe::simulate_vec(&b, &f, 1, &u).iter().map(|v| v + 0.1 * rng.normal()).collect();
        Oe1010 { u, y, nb: b.len(), nf: f.len() }
    }

    fn prob(&self) -> Problem<'_> {
        Problem {
            u: &self.u,
            y: &self.y,
            structure: Structure::siso(self.nb, self.nf, 1),
            offset: false,
            seams: &[],
            missing: &[],
        }
    }

    /// The least-squares fit (default settings) and a start far from it (see [`shrunk`]).
    fn ls_and_far(&self, b_scale: f64, pole_scale: f64, ws: &mut Workspace) -> (estimate::LsFit, Vec<f64>) {
        let ls = estimate::fit_ls(&self.prob(), &Judge::default(), &SolverOptions::default(), ws);
        let far = shrunk(&ls.theta(), self.nb, b_scale, pole_scale);
        (ls, far)
    }
}

/// `theta` moved away: B scaled by `b_scale`, every pole's radius by `pole_scale` (towards the
/// origin for a scale below 1).
fn shrunk(theta: &[f64], nb: usize, b_scale: f64, pole_scale: f64) -> Vec<f64> {
    let mut out = theta.to_vec();
    for v in &mut out[..nb] {
        *v *= b_scale;
    }
    for (j, v) in out[nb..].iter_mut().enumerate() {
        *v *= pole_scale.powi(j as i32 + 1);
    }
    out
}

/// The bundled piezo estimation record.
fn piezo_estimation_record() -> oesweep::data::Record {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/data/piezo_est.csv");
    oesweep::data::read_record(&path, "u", "y").unwrap()
}

/// The paper grid's 40 log-spaced k over [0.05, 2].
fn paper_ks() -> Vec<f64> {
    (0..40).map(|i| 0.05 * (2.0f64 / 0.05).powf(i as f64 / 39.0)).collect()
}

/// The up walk of the `chains` strategy over `ks` from `ls` and its extra starts.
fn walk_up(pair: &estimate::PairProblem, ls: &estimate::LsFit, ks: &[f64], ws: &mut Workspace) -> estimate::ChainWalk {
    let mut chains = estimate::Chains::new(&ls.theta(), &ls.alternatives);
    let mut walk = estimate::ChainWalk::default();
    for &k in ks {
        let (fit, which) = chains.step(pair, k, ws);
        walk.cells.push(Some((fit, estimate::StartKind::Chain { start: which })));
    }
    walk
}

/// A losing chain that runs out of iterations stays in the race on a budget of
/// `Chains::CREEP_ITERATIONS` per cell, and keeps that budget while it loses, also after a
/// fit of it converged within the budget (which, on the boundary, is often a tiny step that
/// meets the tolerance before the next cell creeps for hundreds of iterations).
#[test]
fn a_losing_chain_out_of_iterations_runs_on_the_creeping_budget() {
    let case = Oe1010::new();
    let prob = case.prob();
    let (judge, opts, mut ws) = (Judge::default(), SolverOptions::default(), Workspace::new());
    let (ls, far) = case.ls_and_far(0.2, 0.6, &mut ws);
    let short = SolverOptions { max_iterations: 2 * estimate::Chains::CREEP_ITERATIONS, ..opts.clone() };
    let mut chains = estimate::Chains::new(&ls.theta(), &[far]);
    ws.record_trace = true;
    // At k = 3 W is nearly the least-squares criterion: theta_LS converges at once.
    let (h, which) =
        chains.step(&estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &short }, 3.0, &mut ws);
    assert!(h.termination.converged() && which == 0, "{:?} {which}", h.termination);
    assert_eq!((chains.live(), chains.creeping()), (2, 1), "the far chain lost without converging");
    let (_, which) =
        chains.step(&estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &short }, 3.1, &mut ws);
    assert_eq!(which, 0);
    // The far chain ran last: its accepted steps are in the trace.
    assert!(ws.trace.len() - 1 <= estimate::Chains::CREEP_ITERATIONS, "{} steps", ws.trace.len() - 1);
    // With the full settings from here on, it still gets ten iterations per cell while it
    // loses (see also the next test).
    for step in 1..=40 {
        let pair = estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &opts };
        let (_, which) = chains.step(&pair, 3.1 + 0.01 * step as f64, &mut ws);
        assert_eq!(which, 0, "cell {step}");
        assert_eq!((chains.live(), chains.creeping()), (2, 1), "cell {step}: the losing chain left the budget");
        assert!(ws.trace.len() - 1 <= estimate::Chains::CREEP_ITERATIONS, "cell {step}: {} steps", ws.trace.len() - 1);
    }
}

/// A creeping chain keeps its budget while it loses, also after a fit of it converged within
/// the budget: on the boundary such a fit is often a tiny step that meets the tolerance, and
/// the next cell, on the full settings, creeps for hundreds of iterations again (paper grid,
/// OE(12,13): 2 iterations at one k, 226 at the next, over and over). And it is fitted only
/// every `Chains::CREEP_PERIOD`-th cell, holding its point in between.
#[test]
fn a_creeping_chain_keeps_its_budget_while_it_loses() {
    let case = Oe1010::new();
    let prob = case.prob();
    let (judge, opts, mut ws) = (Judge::default(), SolverOptions::default(), Workspace::new());
    let (ls, far) = case.ls_and_far(0.1, 0.3, &mut ws);
    let pair = estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &opts };
    let mut chains = estimate::Chains::new(&ls.theta(), std::slice::from_ref(&far));
    let period = estimate::Chains::CREEP_PERIOD;
    // The far chain's own fits, as the steps run them, to see when one converged on the budget.
    let (mut point, mut budgeted, mut converged_on_budget) = (far, false, 0);
    for step in 0..30 * period {
        let k = 1.0 + 0.02 * step as f64 / period as f64;
        let settings = if step == 0 { opts.huber() } else { opts.huber_warm() };
        let budget = SolverOptions { max_iterations: estimate::Chains::CREEP_ITERATIONS, ..settings.clone() };
        let runs = !budgeted || step % period == 0;
        if runs {
            let gamma = k * ls.sigma;
            let own = solver::minimise(
                &prob,
                Loss::Huber { gamma },
                &point,
                if budgeted { &budget } else { &settings },
                &mut ws,
            );
            converged_on_budget += usize::from(budgeted && own.termination.converged());
            (point, budgeted) = (own.theta, true);
        }
        let (_, which) = chains.step(&pair, k, &mut ws);
        assert_eq!((which, chains.live()), (0, 2), "cell {step}: the case needs the far chain to lose and stay");
        assert_eq!(chains.creeping(), 1, "cell {step}: the losing chain is not on the budget");
        // Bit for bit its own fits: it ran exactly at the period's cells and held its point
        // at the others.
        assert_eq!(chains.point(1), Some(&point[..]), "cell {step} (ran: {runs})");
    }
    assert!(converged_on_budget >= 10, "the case needs fits that converge on the budget: {converged_on_budget}");
}

/// Walking up in k, a chain can miss a lower branch that exists only below a fold (on the
/// bundled piezo data, OE(8,4) for k up to ~0.1: the scipy peer found W = 1.586 at k = 0.0875
/// where the chains end at 1.795). The backward pass from the cell where the chain jumped finds
/// it, and never leaves a cell worse than the up walk did.
#[test]
fn the_backward_walk_finds_the_branch_below_a_fold_and_is_never_worse() {
    let rec = piezo_estimation_record();
    let prob =
        Problem { u: &rec.u, y: &rec.y, structure: Structure::siso(8, 4, 1), offset: false, seams: &[], missing: &[] };
    let (judge, mut ws) = (Judge::default(), Workspace::new());
    let opts = SolverOptions::default();
    let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
    // The paper grid's k up to 0.2.
    let ks: Vec<f64> = paper_ks()[..16].to_vec();
    let pair = estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &opts };
    let mut walk = walk_up(&pair, &ls, &ks, &mut ws);
    let up: Vec<f64> = walk.cells.iter().map(|c| c.as_ref().unwrap().0.criterion).collect();
    let seconds = walk.walk_back(&pair, &ks, &ls.theta(), &mut ws);
    assert_eq!(seconds.len(), ks.len());
    let mut best_gain: f64 = 0.0;
    for (i, cell) in walk.cells.iter().enumerate() {
        let (fit, which) = cell.as_ref().unwrap();
        assert!(fit.criterion <= up[i], "k = {}: {} after the walk, {} before", ks[i], fit.criterion, up[i]);
        let gain = (up[i] - fit.criterion) / up[i];
        if gain > 0.0 {
            // The top cell may also have been won by the fit from theta_LS.
            let top = i + 1 == ks.len() && *which == estimate::StartKind::Ls { start: 0 };
            assert!(*which == estimate::StartKind::ChainBack || top, "{which:?}");
            // A replaced cell is a full fit: its W is that of its own parameters.
            let yhat = oe::simulate_vec(&fit.b, &fit.f, 1, &rec.u);
            let w = Loss::Huber { gamma: fit.gamma }.criterion(&rec.y, &yhat);
            assert!((w - fit.criterion).abs() <= 1e-9 * w, "{w} vs {}", fit.criterion);
        }
        best_gain = best_gain.max(gain);
    }
    assert!(best_gain > 0.05, "the backward walk gained only {best_gain:.2e}");
}

/// The chains reach the largest k from below and may sit in another basin than the Huber
/// minimum next to theta_LS, which an independent solver (the scipy peer starts every cell
/// from theta_LS) finds: on the bundled piezo data OE(14,11) at k = 2 (W 24.943 against the
/// peer's 24.929). The backward pass also fits the top cell from theta_LS, with the warm and
/// with the cold settings, keeps the lowest fit and walks it down. OE(12,8) is a case where
/// the cold settings reach the lower minimum (5e-5 below the warm fit's).
#[test]
fn the_top_cell_is_no_worse_than_its_fits_from_theta_ls() {
    let rec = piezo_estimation_record();
    for (nb, nf, cold_lower) in [(14, 11, false), (12, 8, true)] {
        let prob = Problem {
            u: &rec.u,
            y: &rec.y,
            structure: Structure::siso(nb, nf, 1),
            offset: false,
            seams: &[],
            missing: &[],
        };
        let (judge, mut ws) = (Judge::default(), Workspace::new());
        let opts = SolverOptions::default();
        let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
        let ks = paper_ks();
        let pair = estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &opts };
        let mut walk = walk_up(&pair, &ls, &ks, &mut ws);
        let up: Vec<f64> = walk.cells.iter().map(|c| c.as_ref().unwrap().0.criterion).collect();
        let loss = Loss::Huber { gamma: ks[39] * ls.sigma };
        let warm = estimate::solver::minimise(&prob, loss, &ls.theta(), &opts.huber_warm(), &mut ws);
        let cold = estimate::solver::minimise(&prob, loss, &ls.theta(), &opts.huber(), &mut ws);
        let from_ls = warm.criterion.min(cold.criterion);
        assert_eq!(
            cold.criterion < warm.criterion,
            cold_lower,
            "OE({nb},{nf}): cold {} warm {}",
            cold.criterion,
            warm.criterion
        );
        // The case exercises the start: the up walk alone ends higher.
        assert!(up[39] > from_ls * (1.0 + 1e-5), "OE({nb},{nf}): up walk {} against {from_ls}", up[39]);
        walk.walk_back(&pair, &ks, &ls.theta(), &mut ws);
        let (top, which) = walk.cells[39].as_ref().unwrap();
        assert_eq!(*which, estimate::StartKind::Ls { start: 0 });
        assert!(top.criterion <= from_ls * (1.0 + 1e-12), "OE({nb},{nf}): {} against {from_ls}", top.criterion);
        // Walked down: the cells below are no worse than the up walk's, and some are lower.
        let mut lower = 0;
        for (i, cell) in walk.cells.iter().enumerate() {
            let fit = &cell.as_ref().unwrap().0;
            assert!(fit.criterion <= up[i], "OE({nb},{nf}) k = {}: {} after, {} before", ks[i], fit.criterion, up[i]);
            lower += usize::from(i < 39 && fit.criterion < up[i] * (1.0 - 1e-6));
        }
        assert!(lower > 0, "OE({nb},{nf}): the fit from theta_LS was not walked down");
    }
}

/// A losing chain that converged, but only after `Chains::SLOW_ITERATIONS` or more, is put on
/// the creeping budget too: a chain that creeps along the boundary and stops on the criterion
/// tolerance just under the cap would otherwise pay that at every cell.
#[test]
fn a_slow_losing_chain_runs_on_the_creeping_budget_too() {
    let case = Oe1010::new();
    let prob = case.prob();
    let (judge, opts, mut ws) = (Judge::default(), SolverOptions::default(), Workspace::new());
    let (ls, far) = case.ls_and_far(0.2, 0.6, &mut ws);
    let pair = estimate::PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &opts };
    // The far chain's own first fit, as the step runs it (cold settings).
    let alone = solver::minimise(&prob, Loss::Huber { gamma: 3.0 * ls.sigma }, &far, &opts.huber(), &mut ws);
    let mut chains = estimate::Chains::new(&ls.theta(), &[far]);
    let (_, which) = chains.step(&pair, 3.0, &mut ws);
    assert_eq!(which, 0);
    assert!(alone.termination.converged(), "the case needs a fit that converges: {:?}", alone.termination);
    assert!(alone.iterations >= estimate::Chains::SLOW_ITERATIONS, "{} iterations", alone.iterations);
    assert_eq!((chains.live(), chains.creeping()), (2, 1), "the slow losing chain is not on the budget");
}
