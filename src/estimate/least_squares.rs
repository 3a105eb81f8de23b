//! Steps 1-2 of a cell (METHOD.md 5.2): the least-squares fit of an order pair from its initial
//! guesses, robust detours and nested starts, and the scale sigma it gives the Huber fits.

use super::fit::{Judge, LsFit, ls_from_solution};
use super::huber::Loss;
use super::initial_guess;
use super::options::SolverOptions;
use super::problem::{Problem, Solution};
use super::solver;
use super::workspace::Workspace;

/// Steps 1-2: least-squares prediction-error fit from each initial guess (ARX, IV); the
/// lowest criterion wins (ties: the first).
///
/// On a record at least [`HEAD_SHARE`] times `opts.explore_rows` long the starts are explored
/// on its first `explore_rows` samples (every start and detour of [`ls_minima`]), and only the
/// best of those minima is then minimised on the whole record, from where it ended, with the
/// nested starts; the runners-up become Huber starts as they are: the exploration is most of
/// the least-squares phase, and its cost then stops growing with N (METHOD.md 5.2, step 5).
pub fn fit_ls(prob: &Problem, judge: &Judge, opts: &SolverOptions, ws: &mut Workspace) -> LsFit {
    fit_ls_nested(prob, judge, opts, &[], ws)
}

/// [`fit_ls`] with `nested` as further starts: the least-squares solutions of the pair's
/// sub-models (nB - 1, nF) and (nB, nF - 1), embedded with [`embed`] (METHOD.md 5.2, step 2).
/// A start at a sub-model's minimum is that same model, so the fit of the larger model is never
/// worse than its sub-models' fits: the least-squares criterion cannot rise with the orders.
pub fn fit_ls_nested(
    prob: &Problem,
    judge: &Judge,
    opts: &SolverOptions,
    nested: &[Vec<f64>],
    ws: &mut Workspace,
) -> LsFit {
    let own = own_minima(prob, opts, nested.is_empty(), ws);
    finish_ls(prob, judge, opts, own, nested, ws)
}

/// What a pair's least-squares phase finds from its own starts ([`own_minima`]), before the
/// nested starts: it needs no other pair's fit, so the sweep runs it while the sub-models are
/// still being fitted, and [`finish_ls`] adds the nested starts. Together they are
/// [`fit_ls_nested`], bit for bit.
#[derive(Clone, Debug)]
pub struct OwnMinima {
    sols: Vec<Solution>,
    /// On a long record, the head's runners-up (Huber starts as the head left them).
    head_others: Option<Vec<Vec<f64>>>,
    /// Found for a pair without nested starts (`ls_minima`'s `alone`).
    pub alone: bool,
}

/// The pair's own least-squares minima (guesses, detours; on a long record explored on the head
/// and the best minimised on the whole record), `alone` when there will be no nested starts.
pub fn own_minima(prob: &Problem, opts: &SolverOptions, alone: bool, ws: &mut Workspace) -> OwnMinima {
    // On a long record the starts of the pair itself (guesses, detours) are explored on the
    // head, and only the head's best minimum is minimised again on the whole record; the
    // runners-up are Huber starts as the head left them (the chains walk on the head anyway).
    // Minimising them too on the whole record never changed theta_LS or a cell (two
    // 131 072-sample records: all 704 criteria the same to 1e-6) and cost 11-14 % of the run.
    // Warm, as the cells' whole-record fits from the head's minima: the head's best is near the
    // whole record's minimum (64 such fits on a 131 072-sample record: 897 -> 491 iterations,
    // every criterion within a relative 5e-10).
    match exploration_head(prob, opts) {
        Some(head) => {
            let found = ls_minima(&head, opts, alone, ws);
            let (best, others) = ranked(&found);
            let others: Vec<Vec<f64>> = others.iter().map(|s| s.theta.clone()).collect();
            let sols = vec![solver::minimise(prob, Loss::LeastSquares, &best.theta, &warm(opts), ws)];
            OwnMinima { sols, head_others: Some(others), alone }
        }
        None => OwnMinima { sols: ls_minima(prob, opts, alone, ws), head_others: None, alone },
    }
}

fn warm(opts: &SolverOptions) -> SolverOptions {
    SolverOptions { lambda0: opts.warm_lambda0, ..opts.clone() }
}

/// The pair's least-squares fit from its own minima `own` and the `nested` starts (see
/// [`fit_ls_nested`]); `own` must have been found with `alone = nested.is_empty()`.
pub fn finish_ls(
    prob: &Problem,
    judge: &Judge,
    opts: &SolverOptions,
    own: OwnMinima,
    nested: &[Vec<f64>],
    ws: &mut Workspace,
) -> LsFit {
    assert_eq!(own.alone, nested.is_empty(), "own minima found for another set of nested starts");
    let OwnMinima { mut sols, head_others, .. } = own;
    // The nested starts are minimised on the whole record itself, warm: they are the
    // sub-models' whole-record minima, so the pair's fit stays no worse than its sub-models'.
    // Explored on the head with the rest, they lost that: on a 65 536-sample record with
    // spikes (paper grid, 16 384-row head) 75 of 96 least-squares fits and 758 of 768 Huber
    // cells were no worse than the scipy peer's; minimised on the whole record 94 and 768
    // (cold) and 96 and 768 (warm). Warm because a nested start is at a minimum of the
    // sub-model.
    let warm = warm(opts);
    let nested_opts = if head_others.is_some() { &warm } else { opts };
    // The sub-models' minima, last, so that the detours start where they did without them. At
    // high orders the per-pair starts often end in a local minimum worse than a sub-model's (on
    // the paper grid, in 46 of 172 neighbouring pairs the larger model's criterion was higher,
    // by up to 0.5 %; the scipy peer's fits show the same, 44 of 172).
    sols.extend(nested.iter().map(|start| solver::minimise(prob, Loss::LeastSquares, start, nested_opts, ws)));
    let (best, others) = ranked(&sols);
    let others = head_others.unwrap_or_else(|| others.iter().map(|s| s.theta.clone()).collect());
    let mut alternatives: Vec<Vec<f64>> = others.into_iter().take(opts.huber_extra_starts).collect();
    // On the stability boundary the Huber fit cannot move the near-unit pole (1/F has an
    // almost infinite memory there), while a start just inside often reaches a much lower W.
    let theta = &best.theta;
    let radius = prob.max_pole_radius(theta);
    if opts.huber_extra_starts > 0 && radius > BOUNDARY && radius.is_finite() {
        alternatives.push(contracted(prob, theta));
    }
    let mut fit = ls_from_solution(prob, best.clone(), judge, opts, ws);
    fit.alternatives = alternatives;
    fit
}

/// The first `solver.explore_rows` samples of a record at least [`HEAD_SHARE`] times longer,
/// where the starts are explored (METHOD.md 5.2 step 5, 5.5); None when the whole record is
/// explored.
pub fn exploration_head<'a>(prob: &Problem<'a>, opts: &SolverOptions) -> Option<Problem<'a>> {
    let rows = opts.explore_rows;
    // Several inputs sit input after input: a head would copy them (not done yet).
    (rows > 0 && prob.m() == 1 && prob.n() >= HEAD_SHARE * rows).then(|| prob.head(rows))
}

/// A record explores on a head only when it is at least this many heads long. Exploring on
/// the head trades quality for time: its minima rank the starts as the head's data do, not as
/// the whole record's. Against the scipy peer on the paper grid (96 pairs x 8 k, 5 % spikes
/// of 20-60; `examples/compare_peer_grid.rs`), heads of two thirds of the record fell short
/// of the project's bars (98 % of the least-squares fits, 99 % of the Huber cells no worse)
/// for a third less exploration: 24 576 samples on a 16 384-row head 90/96 and 759/768
/// (explored whole 96 and 768), 12 288 on an 8 192-row head 96 and 759 (whole 96 and 762);
/// 65 536 samples on a 16 384-row head, a quarter, 96 and 768 (METHOD.md 5.2 step 5).
pub const HEAD_SHARE: usize = 4;

/// The lowest usable solution (ties: the first) and the others that are usable and distinct
/// from it (relative [`DISTINCT`] in the criterion), in increasing criterion: the runner-up
/// least-squares minima, further Huber starts (`solver.huber_extra_starts`).
fn ranked(sols: &[Solution]) -> (&Solution, Vec<&Solution>) {
    let mut best = 0;
    for (i, sol) in sols.iter().enumerate() {
        if better(sol, &sols[best]) {
            best = i;
        }
    }
    let top = &sols[best];
    let mut others: Vec<&Solution> = sols
        .iter()
        .enumerate()
        .filter(|&(i, sol)| {
            let distinct = (sol.criterion - top.criterion).abs() > DISTINCT * top.criterion.abs();
            i != best && sol.usable() && distinct
        })
        .map(|(_, sol)| sol)
        .collect();
    others.sort_by(|a, b| a.criterion.total_cmp(&b.criterion));
    (top, others)
}

/// The least-squares minimisations of the pair's own starts: from each initial guess (ARX, IV)
/// and from the robust detours (the nested starts are the caller's).
///
/// A pair without sub-models (`alone`) also runs each guess with heavy initial damping. With
/// them that run no longer pays (issue 19, commit 1b1b605): on the paper grid it was never the
/// only run to reach a pair's minimum, and dropping it kept the quality against the scipy peer
/// (L2 96/96 on both records; Huber 760 and 763 of 768 against 761 and 762) for 2 fewer
/// minimisations per pair. (Dropping the first detour too saved as much again but left 8 of the
/// paper grid's 96 least-squares fits higher than before, by up to 0.22 %, against 21 lower.) A
/// pair without sub-models (`oesweep fit`, a grid's smallest pair) keeps it: with these starts
/// the OE(6,6) fit of noise-free OE(2,2) data reaches the exact fit
/// (`tests/estimation.rs::an_over_parameterised_fit_of_noise_free_data_is_exact`).
fn ls_minima(prob: &Problem, opts: &SolverOptions, alone: bool, ws: &mut Workspace) -> Vec<Solution> {
    let guesses = initial_guess::initial_guesses(prob);
    // Each guess also with heavy initial damping (gradient-like first steps, as a trust-region
    // solver takes), which often ends in another, lower minimum.
    let damped = SolverOptions { lambda0: DAMPED_LAMBDA0, ..opts.clone() };
    let settings: &[&SolverOptions] = if alone { &[opts, &damped] } else { &[opts] };
    let mut sols = Vec::new();
    for g in &guesses {
        for o in settings {
            sols.push(solver::minimise(prob, Loss::LeastSquares, g, o, ws));
        }
    }
    // Robust detours: spikes pull the least-squares fit into poor local minima, and a Huber
    // fit (gamma = k sigma) followed by least squares from its solution often lands in a
    // lower least-squares minimum (measured on piezo-like data).
    let first = ranked(&sols).0.clone();
    if first.criterion.is_finite() && first.criterion > 0.0 {
        let sigma = (2.0 * first.criterion).sqrt();
        for k in ROBUST_START_K {
            let robust = solver::minimise(prob, Loss::Huber { gamma: k * sigma }, &first.theta, opts, ws);
            if robust.criterion.is_finite() {
                sols.push(solver::minimise(prob, Loss::LeastSquares, &robust.theta, opts, ws));
            }
        }
    }
    sols
}

/// Initial damping of the second least-squares run from each initial guess, for a pair
/// without nested starts (see [`ls_minima`]). Damping 1 relative to diag(H) makes the first
/// steps gradient-like, as a trust-region solver's are, and such a run often ends in a lower
/// minimum than the undamped one; with nested starts it never was the only run to reach a
/// pair's minimum on the paper grid (issue 19, commit 1b1b605), so only lone pairs pay for it.
const DAMPED_LAMBDA0: f64 = 1.0;
/// k of the robust detours of the least-squares phase (see [`ls_minima`]): a Huber fit at
/// gamma = k sigma from the best start, then least squares from there, escapes the poor minima
/// spikes pull a least-squares fit into. Two detours are what hold the least-squares fits at
/// 96 of 96 against the scipy peer on the paper grid: dropping one left 6 to 8 of the 96 fits
/// higher (up to 0.22 %; without the k = 0.5 one, 6 fits higher and 363 Huber cells moved,
/// issue 19, commit 63cbb84; docs/PERFORMANCE.md).
const ROBUST_START_K: [f64; 2] = [0.5, 0.1];
/// Pole radius above which a least-squares fit counts as on the stability boundary: there the
/// Huber fit cannot move the near-unit pole (1/F has an almost infinite memory), so the fit
/// gets a contracted extra start (METHOD.md 5.2, step 4). 0.999 is well above the poles of the
/// lightly damped piezo models (0.98-0.99) and below where the memory makes the fit creep.
pub const BOUNDARY: f64 = 0.999;
/// Radius the poles of a boundary fit are scaled to for that extra start: inside enough that
/// the Huber fit moves freely, close enough to stay in the basin of theta_LS. Dropping the
/// start saved only 6-10 % of the Huber phase (issue 19); no other radius was measured.
pub const CONTRACTED: f64 = 0.99;

/// `theta` with every pole scaled to radius at most [`CONTRACTED`], `f_j <- f_j rho^j` with
/// `rho = CONTRACTED / r` (r the largest pole radius): the start just inside the stability
/// boundary of a fit that ended on it.
pub fn contracted(prob: &Problem, theta: &[f64]) -> Vec<f64> {
    let mut c = theta.to_vec();
    let radius = prob.max_pole_radius(theta);
    if radius > CONTRACTED && radius.is_finite() {
        let rho = CONTRACTED / radius;
        for i in 0..prob.m() {
            for (j, v) in c[prob.structure.f_range(i)].iter_mut().enumerate() {
                *v *= rho.powi(j as i32 + 1);
            }
        }
    }
    c
}

/// Least-squares minima whose criteria differ by less than this (relative) are one minimum:
/// well above the solver's `ftol` (1e-10), so two runs that converged to the same minimum
/// count once, and well below [`crate::estimate::Chains::MERGE`] (1e-6), because a runner-up
/// least-squares minimum is a start of its own for the Huber chains (which decide themselves,
/// at 1e-6 on W, when two of them met).
const DISTINCT: f64 = 1e-9;

/// True when `a` is a usable solution with a lower criterion than `b`.
fn better(a: &Solution, b: &Solution) -> bool {
    a.usable() && (!b.usable() || a.criterion < b.criterion)
}
