//! Estimation of one model ("cell") and the quantities it is judged by (METHOD.md 5-6).
//!
//! ```text
//! 1. theta_0  = initial_guess (ARX + IV, F stable)                       [init]
//! 2. theta_LS = argmin (1/N) sum e^2/2 from theta_0, sigma = std(e_LS)   [fit_ls]
//! 3. theta_H  = argmin W_{N, k sigma} from theta_LS                      [fit_huber]
//! ```
//! Steps 1-2 depend only on (nB, nF, delay), so a sweep runs them once per order pair and
//! shares the [`LsFit`] across all k.

pub mod chains;
pub mod evidence;
pub mod huber;
pub mod init;
pub mod initial;
pub mod normal;
pub mod separable;
pub mod solver;

pub use chains::{ChainWalk, Chains, PairProblem};
pub use huber::Loss;
pub use initial::InitialState;
pub use solver::{HuberHessian, Method, Problem, Solution, SolverOptions, Termination, Workspace};

use crate::oe;
use crate::spectral::SpectralEstimate;

/// What a fitted model is judged against besides its own estimation record.
#[derive(Clone, Copy, Default)]
pub struct Judge<'a> {
    /// Validation record (u, y): used only to judge, never to fit.
    pub validation: Option<(&'a [f64], &'a [f64])>,
    /// Spectral estimate of the estimation record and the bins of the fit band.
    pub band: Option<(&'a SpectralEstimate, &'a [usize])>,
    /// The initial state `fit` and `fit_val` are computed with.
    pub initial_state: InitialState,
}

impl Judge<'_> {
    /// The output the model is judged by on a record (u, y): its simulation from zero initial
    /// conditions (`yhat0`, offset included), plus the fitted free response with
    /// [`InitialState::Estimate`].
    pub fn judged_output(&self, prob: &Problem, theta: &[f64], y: &[f64], yhat0: Vec<f64>) -> Vec<f64> {
        let mut yhat = yhat0;
        if self.initial_state == InitialState::Estimate {
            let (b, f, _) = prob.split(theta);
            initial::add_free_response(f, b.len(), prob.delay, y, &mut yhat);
        }
        yhat
    }
}

/// Fit percentage `100 (1 - ||y - yhat|| / ||y - mean(y)||)`.
pub fn fit_percent(y: &[f64], yhat: &[f64]) -> f64 {
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let num: f64 = y.iter().zip(yhat).map(|(a, b)| (a - b) * (a - b)).sum();
    let den: f64 = y.iter().map(|a| (a - mean) * (a - mean)).sum();
    100.0 * (1.0 - (num / den).sqrt())
}

/// Where a fit started: the table's `start` column ([`StartKind::as_str`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StartKind {
    /// A least-squares fit from the ARX/IV initial guesses.
    Init,
    /// A Huber fit from the pair's least-squares starts: 0 = theta_LS, else an extra start.
    Ls { start: usize },
    /// A Huber fit from the solution at the neighbouring k.
    Neighbour,
    /// A cell of the `chains` walk, won by the chain begun at start `start` (0 = theta_LS).
    Chain { start: usize },
    /// A cell improved by the backward pass of the `chains` walk ([`ChainWalk`]).
    ChainBack,
}

impl StartKind {
    pub fn as_str(self) -> &'static str {
        match self {
            StartKind::Init => "init",
            StartKind::Ls { start: 0 } => "ls",
            StartKind::Ls { .. } => "ls_alt",
            StartKind::Neighbour => "neighbour",
            StartKind::Chain { start: 0 } => "chain_ls",
            StartKind::Chain { .. } => "chain_alt",
            StartKind::ChainBack => "chain_back",
        }
    }
}

/// Quantities every fitted model reports.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Assessment {
    /// Fit % on the estimation record.
    pub fit: f64,
    /// Fit % on the validation record (None without one).
    pub fit_val: Option<f64>,
    /// Fit % of the frequency response against the spectral estimate in the band.
    pub fit_band: Option<f64>,
    pub max_pole_radius: f64,
    /// Parameter standard deviations and residual tests (METHOD.md 10).
    #[serde(flatten)]
    pub evidence: evidence::Evidence,
}

/// The assessment of the solution `theta` whose output and Jacobian signals the workspace
/// holds (the solver's last, or [`Workspace::resimulate`]).
fn assess(prob: &Problem, theta: &[f64], loss: Loss, ws: &mut Workspace, judge: &Judge) -> Assessment {
    let yhat = &ws.yhat[..];
    let (b, f, _) = prob.split(theta);
    let fit_val = judge.validation.map(|(u, y)| {
        let val = Problem { u, y, ..*prob };
        fit_percent(y, &judge.judged_output(&val, theta, y, val.simulate_vec(theta)))
    });
    let fit = fit_percent(prob.y, &judge.judged_output(prob, theta, prob.y, yhat.to_vec()));
    let fit_band = judge.band.and_then(|(est, bins)| crate::spectral::band_fit(est, bins, b, f, prob.delay));
    Assessment {
        fit,
        fit_val: fit_val.filter(|v| v.is_finite()),
        fit_band: fit_band.filter(|v| v.is_finite()),
        max_pole_radius: oe::max_pole_radius(f),
        evidence: evidence::evidence(prob, theta, loss, &ws.yhat, &ws.xu, &ws.xy, &mut ws.evidence),
    }
}

/// The least-squares (L2) fit of an order pair and the scale sigma it provides.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LsFit {
    pub nb: usize,
    pub nf: usize,
    pub delay: usize,
    /// `(1/N) sum e^2 / 2`.
    pub criterion: f64,
    /// Standard deviation of the residuals (ddof = 0).
    pub sigma: f64,
    #[serde(flatten)]
    pub assessment: Assessment,
    pub iterations: usize,
    pub termination: Termination,
    pub reflections: usize,
    pub b: Vec<f64>,
    pub f: Vec<f64>,
    /// The estimated output offset c (None when the model has none, [`Problem::offset`]).
    pub offset: Option<f64>,
    /// Further starts for the Huber phase (see [`fit_huber_multi`]): the least-squares
    /// solutions reached from the other initial guesses, and theta_LS with its poles pulled
    /// to radius 0.99 when it ended on the stability boundary. Deterministic, so a resumed
    /// sweep recomputes them identically; not part of the result table.
    #[serde(skip)]
    pub alternatives: Vec<Vec<f64>>,
}

/// `theta` of the sub-model (`nb`, `nf`) of `prob`'s structure (same delay and offset mode) as
/// `prob`'s parameters: the same model, with zero trailing coefficients in B and F.
pub fn embed(theta: &[f64], nb: usize, nf: usize, prob: &Problem) -> Vec<f64> {
    assert!(nb <= prob.nb && nf <= prob.nf, "OE({nb},{nf}) is no sub-model of OE({},{})", prob.nb, prob.nf);
    assert_eq!(theta.len(), nb + nf + usize::from(prob.offset));
    let mut out = vec![0.0; prob.dim()];
    out[..nb].copy_from_slice(&theta[..nb]);
    out[prob.nb..prob.nb + nf].copy_from_slice(&theta[nb..nb + nf]);
    if prob.offset {
        out[prob.nb + prob.nf] = theta[nb + nf];
    }
    out
}

/// `[b, f]`, or `[b, f, c]` with an offset: the solver's parameter vector.
pub fn theta_of(b: &[f64], f: &[f64], offset: Option<f64>) -> Vec<f64> {
    b.iter().chain(f).chain(offset.as_ref()).copied().collect()
}

impl LsFit {
    pub fn theta(&self) -> Vec<f64> {
        theta_of(&self.b, &self.f, self.offset)
    }
    /// True when the numbers are usable (finite criterion and parameters).
    pub fn ok(&self) -> bool {
        self.termination.usable(self.sigma)
    }
}

/// A Huber fit at one tuning constant k.
#[derive(Clone, Debug, serde::Serialize)]
pub struct HuberFit {
    pub k: f64,
    pub gamma: f64,
    /// `W_{N,gamma}` at the solution.
    pub criterion: f64,
    /// Share of residuals beyond gamma.
    pub l1c: f64,
    #[serde(flatten)]
    pub assessment: Assessment,
    pub iterations: usize,
    pub termination: Termination,
    pub reflections: usize,
    pub b: Vec<f64>,
    pub f: Vec<f64>,
    /// The estimated output offset c (None when the model has none).
    pub offset: Option<f64>,
}

impl HuberFit {
    pub fn theta(&self) -> Vec<f64> {
        theta_of(&self.b, &self.f, self.offset)
    }
}

/// Steps 1-2: least-squares prediction-error fit from each initial guess (ARX, IV); the
/// lowest criterion wins (ties: the first).
///
/// On a record longer than `opts.explore_rows` the starts are explored on its first
/// `explore_rows` samples (every start and detour of [`ls_minima`]), and only the best of those
/// minima is then minimised on the whole record, from where it ended; the runners-up become
/// Huber starts as they are: the exploration is most of the least-squares phase, and its cost
/// then stops growing with N (METHOD.md 5.2, step 5).
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
    // On a long record only the head's best minimum is minimised again on the whole record; the
    // runners-up are Huber starts as the head left them (the chains walk on the head anyway).
    // Minimising them too on the whole record never changed theta_LS or a cell (two
    // 131 072-sample records: all 704 criteria the same to 1e-6) and cost 11-14 % of the run.
    let (sols, head_others) = match exploration_head(prob, opts) {
        Some(head) => {
            let found = ls_minima(&head, opts, nested, ws);
            let (best, others) = ranked(&found);
            let others: Vec<Vec<f64>> = others.iter().map(|s| s.theta.clone()).collect();
            (vec![solver::minimise(prob, Loss::LeastSquares, &best.theta, opts, ws)], Some(others))
        }
        None => (ls_minima(prob, opts, nested, ws), None),
    };
    let (best, others) = ranked(&sols);
    let others = head_others.unwrap_or_else(|| others.iter().map(|s| s.theta.clone()).collect());
    let mut alternatives: Vec<Vec<f64>> = others.into_iter().take(opts.huber_extra_starts).collect();
    // On the stability boundary the Huber fit cannot move the near-unit pole (1/F has an
    // almost infinite memory there), while a start just inside often reaches a much lower W.
    let theta = &best.theta;
    let radius = crate::oe::max_pole_radius(prob.split(theta).1);
    if opts.huber_extra_starts > 0 && radius > BOUNDARY && radius.is_finite() {
        let mut c = theta.clone();
        let rho = CONTRACTED / radius;
        for (j, v) in prob.f_mut(&mut c).iter_mut().enumerate() {
            *v *= rho.powi(j as i32 + 1);
        }
        alternatives.push(c);
    }
    let mut fit = ls_from_solution(prob, best.clone(), judge, opts, ws);
    fit.alternatives = alternatives;
    fit
}

/// The first `solver.explore_rows` samples of a record longer than that, where the starts are
/// explored (METHOD.md 5.2 step 5, 5.5); None when the whole record is explored.
pub fn exploration_head<'a>(prob: &Problem<'a>, opts: &SolverOptions) -> Option<Problem<'a>> {
    let rows = opts.explore_rows;
    (rows > 0 && prob.n() > rows).then(|| Problem { u: &prob.u[..rows], y: &prob.y[..rows], ..*prob })
}

/// The lowest usable solution (ties: the first) and the others that are usable and distinct
/// from it (relative 1e-9 in the criterion), in increasing criterion: the runner-up
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
            let distinct = (sol.criterion - top.criterion).abs() > 1e-9 * top.criterion.abs();
            i != best && sol.usable() && distinct
        })
        .map(|(_, sol)| sol)
        .collect();
    others.sort_by(|a, b| a.criterion.total_cmp(&b.criterion));
    (top, others)
}

/// Every least-squares minimisation of the phase: from each initial guess (ARX, IV), from the
/// robust detours, and from each `nested` start.
///
/// Without nested starts each guess also runs with heavy initial damping. With them that run
/// no longer pays (issue 19, third session): on the paper grid it was never the only run to
/// reach a pair's minimum, and dropping it kept the quality against the scipy peer (L2 96/96
/// on both records; Huber 760 and 763 of 768 against 761 and 762) for 2 fewer minimisations
/// per pair. (Dropping the first detour too saved as much again but left 8 of the paper
/// grid's 96 least-squares fits higher than before, by up to 0.22 %, against 21 lower.) A
/// pair without sub-models (`oesweep fit`, a grid's smallest pair) keeps it: on noise-free
/// OE(2,2) data the OE(6,6) fit needs these starts to reach the exact fit.
fn ls_minima(prob: &Problem, opts: &SolverOptions, nested: &[Vec<f64>], ws: &mut Workspace) -> Vec<Solution> {
    let alone = nested.is_empty();
    let guesses = init::initial_guesses(prob);
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
    // The sub-models' minima, last, so that the detours start where they did without them.
    // At high orders the per-pair starts above often end in a local minimum worse than a
    // sub-model's (on the paper grid, in 46 of 172 neighbouring pairs the larger model's
    // criterion was higher, by up to 0.5 %; the scipy peer's fits show the same, 44 of 172).
    for start in nested {
        sols.push(solver::minimise(prob, Loss::LeastSquares, start, opts, ws));
    }
    sols
}

/// Initial damping of the second least-squares run from each initial guess (without nested
/// starts, see [`ls_minima`]).
const DAMPED_LAMBDA0: f64 = 1.0;
/// k of the robust detours of the least-squares phase (see [`ls_minima`]).
const ROBUST_START_K: [f64; 2] = [0.5, 0.1];
/// Pole radius above which a least-squares fit counts as on the stability boundary.
const BOUNDARY: f64 = 0.999;
/// Radius the poles of a boundary fit are scaled to for the extra Huber start.
const CONTRACTED: f64 = 0.99;

/// Step 3 from theta_LS and from each of `ls.alternatives`, keeping the lowest criterion (ties:
/// the earlier start). Returns the fit and the index of the winning start (0 = theta_LS).
/// Least-squares OE fits have several minima (METHOD.md 8) and the Huber fit inherits its
/// start's basin; this multi-start is what keeps oesweep no worse than an independent solver.
pub fn fit_huber_multi(
    prob: &Problem,
    ls: &LsFit,
    k: f64,
    judge: &Judge,
    opts: &SolverOptions,
    ws: &mut Workspace,
) -> (HuberFit, usize) {
    fit_huber_starts(prob, ls.sigma, k, &ls.theta(), &ls.alternatives, judge, opts, ws)
}

/// [`fit_huber_multi`] from its parts: `theta_ls` first, then `alternatives`.
#[allow(clippy::too_many_arguments)]
pub fn fit_huber_starts(
    prob: &Problem,
    sigma: f64,
    k: f64,
    theta_ls: &[f64],
    alternatives: &[Vec<f64>],
    judge: &Judge,
    opts: &SolverOptions,
    ws: &mut Workspace,
) -> (HuberFit, usize) {
    // One step of fresh chains is exactly this: every start once, the lowest W wins.
    Chains::new(theta_ls, alternatives).step(&PairProblem { prob, sigma, judge, opts }, k, ws)
}

/// A [`HuberFit`] from a finished minimisation. `resimulate`: the workspace does not hold this
/// solution's simulation (another fit ran after it).
pub(crate) fn huber_from_solution(
    prob: &Problem,
    sigma: f64,
    k: f64,
    sol: &Solution,
    judge: &Judge,
    ws: &mut Workspace,
    resimulate: bool,
) -> HuberFit {
    let gamma = k * sigma;
    if resimulate {
        ws.resimulate(prob, &sol.theta);
    }
    let (b, f, _) = prob.split(&sol.theta);
    HuberFit {
        k,
        gamma,
        criterion: sol.criterion,
        l1c: huber::l1_contribution(prob.y, ws.yhat(), gamma),
        assessment: assess(prob, &sol.theta, Loss::Huber { gamma }, ws, judge),
        iterations: sol.iterations,
        termination: sol.termination,
        reflections: sol.reflections,
        b: b.to_vec(),
        f: f.to_vec(),
        offset: prob.offset.then(|| prob.split(&sol.theta).2),
    }
}

/// True when `a` is a usable solution with a lower criterion than `b`.
fn better(a: &Solution, b: &Solution) -> bool {
    a.usable() && (!b.usable() || a.criterion < b.criterion)
}

fn ls_from_solution(prob: &Problem, sol: Solution, judge: &Judge, _opts: &SolverOptions, ws: &mut Workspace) -> LsFit {
    // The workspace holds the simulation of the last minimisation, not necessarily this one.
    ws.resimulate(prob, &sol.theta);
    ls_fit(prob, sol, judge, ws)
}

/// Step 2 from a given start.
pub fn fit_ls_from(prob: &Problem, theta0: &[f64], judge: &Judge, opts: &SolverOptions, ws: &mut Workspace) -> LsFit {
    let sol = solver::minimise(prob, Loss::LeastSquares, theta0, opts, ws);
    ls_fit(prob, sol, judge, ws)
}

fn ls_fit(prob: &Problem, sol: Solution, judge: &Judge, ws: &mut Workspace) -> LsFit {
    let yhat = ws.yhat();
    let n = prob.n() as f64;
    let mean_e = prob.y.iter().zip(yhat).map(|(a, b)| a - b).sum::<f64>() / n;
    let var = prob.y.iter().zip(yhat).map(|(a, b)| (a - b - mean_e).powi(2)).sum::<f64>() / n;
    let (b, f, c) = prob.split(&sol.theta);
    LsFit {
        nb: prob.nb,
        nf: prob.nf,
        delay: prob.delay,
        criterion: sol.criterion,
        sigma: var.sqrt(),
        assessment: assess(prob, &sol.theta, Loss::LeastSquares, ws, judge),
        iterations: sol.iterations,
        termination: sol.termination,
        reflections: sol.reflections,
        b: b.to_vec(),
        f: f.to_vec(),
        offset: prob.offset.then_some(c),
        alternatives: Vec::new(),
    }
}

/// Step 3: Huber fit with gamma = k sigma from `start` (normally theta_LS).
pub fn fit_huber(
    prob: &Problem,
    sigma: f64,
    k: f64,
    start: &[f64],
    judge: &Judge,
    opts: &SolverOptions,
    ws: &mut Workspace,
) -> HuberFit {
    let sol = solver::minimise(prob, Loss::Huber { gamma: k * sigma }, start, &opts.huber(), ws);
    huber_from_solution(prob, sigma, k, &sol, judge, ws, false)
}
