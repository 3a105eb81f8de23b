//! Estimation of one model ("cell") and the quantities it is judged by (METHOD.md 5-6).
//!
//! ```text
//! 1. theta_0  = initial_guess (ARX + IV, F stable)                       [init]
//! 2. theta_LS = argmin (1/N) sum e^2/2 from theta_0, sigma = std(e_LS)   [fit_ls]
//! 3. theta_H  = argmin W_{N, k sigma} from theta_LS                      [fit_huber]
//! ```
//! Steps 1-2 depend only on (nB, nF, delay), so a sweep runs them once per order pair and
//! shares the [`LsFit`] across all k.

pub mod huber;
pub mod init;
pub mod normal;
pub mod solver;

pub use huber::Loss;
pub use solver::{HuberHessian, Problem, Solution, SolverOptions, Termination, Workspace};

use crate::oe;
use crate::spectral::SpectralEstimate;

/// What a fitted model is judged against besides its own estimation record.
#[derive(Clone, Copy, Default)]
pub struct Judge<'a> {
    /// Validation record (u, y): used only to judge, never to fit.
    pub validation: Option<(&'a [f64], &'a [f64])>,
    /// Spectral estimate of the estimation record and the bins of the fit band.
    pub band: Option<(&'a SpectralEstimate, &'a [usize])>,
}

/// Fit percentage `100 (1 - ||y - yhat|| / ||y - mean(y)||)`.
pub fn fit_percent(y: &[f64], yhat: &[f64]) -> f64 {
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let num: f64 = y.iter().zip(yhat).map(|(a, b)| (a - b) * (a - b)).sum();
    let den: f64 = y.iter().map(|a| (a - mean) * (a - mean)).sum();
    100.0 * (1.0 - (num / den).sqrt())
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
}

fn assess(prob: &Problem, b: &[f64], f: &[f64], yhat: &[f64], judge: &Judge) -> Assessment {
    let fit_val = judge.validation.map(|(u, y)| fit_percent(y, &oe::simulate_vec(b, f, prob.delay, u)));
    let fit_band = judge.band.and_then(|(est, bins)| crate::spectral::band_fit(est, bins, b, f, prob.delay));
    Assessment {
        fit: fit_percent(prob.y, yhat),
        fit_val: fit_val.filter(|v| v.is_finite()),
        fit_band: fit_band.filter(|v| v.is_finite()),
        max_pole_radius: oe::max_pole_radius(f),
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
    /// Further starts for the Huber phase (see [`fit_huber_multi`]): the least-squares
    /// solutions reached from the other initial guesses, and theta_LS with its poles pulled
    /// to radius 0.99 when it ended on the stability boundary. Deterministic, so a resumed
    /// sweep recomputes them identically; not part of the result table.
    #[serde(skip)]
    pub alternatives: Vec<Vec<f64>>,
}

impl LsFit {
    pub fn theta(&self) -> Vec<f64> {
        [&self.b[..], &self.f[..]].concat()
    }
    /// True when the numbers are usable (finite criterion and parameters).
    pub fn ok(&self) -> bool {
        self.termination != Termination::NonFinite && self.sigma.is_finite()
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
}

/// Steps 1-2: least-squares prediction-error fit from each initial guess (ARX, IV); the
/// lowest criterion wins (ties: the first).
pub fn fit_ls(prob: &Problem, judge: &Judge, opts: &SolverOptions, ws: &mut Workspace) -> LsFit {
    let guesses = init::initial_guesses(prob);
    // Each guess twice: with the usual damping and with heavy initial damping (gradient-like
    // first steps, as a trust-region solver takes), which often ends in another, lower minimum.
    let damped = SolverOptions { lambda0: DAMPED_LAMBDA0, ..opts.clone() };
    let mut sols: Vec<Solution> = guesses
        .iter()
        .flat_map(|g| [opts, &damped].map(|o| solver::minimise(prob, Loss::LeastSquares, g, o, ws)))
        .collect();
    let best_of = |sols: &[Solution]| {
        let mut best = 0;
        for (i, sol) in sols.iter().enumerate() {
            if better(sol, &sols[best]) {
                best = i;
            }
        }
        best
    };
    // One more start from a robust detour: spikes pull the least-squares fit into poor local
    // minima, and a Huber fit (gamma = sigma/2) followed by least squares from its solution
    // often lands in a lower least-squares minimum (measured on piezo-like data).
    let first = best_of(&sols);
    if sols[first].criterion.is_finite() && sols[first].criterion > 0.0 {
        let sigma = (2.0 * sols[first].criterion).sqrt();
        for k in ROBUST_START_K {
            let robust = solver::minimise(prob, Loss::Huber { gamma: k * sigma }, &sols[first].theta, opts, ws);
            if robust.criterion.is_finite() {
                sols.push(solver::minimise(prob, Loss::LeastSquares, &robust.theta, opts, ws));
            }
        }
    }
    let best = best_of(&sols);
    // The runner-up least-squares minima are further Huber starts (solver.huber_extra_starts).
    let mut others: Vec<&Solution> = sols
        .iter()
        .enumerate()
        .filter(|&(i, sol)| {
            let distinct = (sol.criterion - sols[best].criterion).abs() > 1e-9 * sols[best].criterion.abs();
            i != best && sol.termination != Termination::NonFinite && sol.criterion.is_finite() && distinct
        })
        .map(|(_, sol)| sol)
        .collect();
    others.sort_by(|a, b| a.criterion.total_cmp(&b.criterion));
    let mut alternatives: Vec<Vec<f64>> =
        others.iter().take(opts.huber_extra_starts).map(|s| s.theta.clone()).collect();
    // On the stability boundary the Huber fit cannot move the near-unit pole (1/F has an
    // almost infinite memory there), while a start just inside often reaches a much lower W.
    let theta = &sols[best].theta;
    let radius = crate::oe::max_pole_radius(&theta[prob.nb..]);
    if opts.huber_extra_starts > 0 && radius > BOUNDARY && radius.is_finite() {
        let mut c = theta.clone();
        let rho = CONTRACTED / radius;
        for (j, v) in c[prob.nb..].iter_mut().enumerate() {
            *v *= rho.powi(j as i32 + 1);
        }
        alternatives.push(c);
    }
    let best_sol = sols.into_iter().nth(best).expect("at least one start");
    let mut fit = ls_from_solution(prob, best_sol, judge, opts, ws);
    fit.alternatives = alternatives;
    fit
}

/// Initial damping of the second least-squares run from each initial guess.
const DAMPED_LAMBDA0: f64 = 1.0;
/// k of the robust detour start of the least-squares phase (see [`fit_ls`]).
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
    Chains::new(theta_ls, alternatives).step(prob, sigma, k, judge, opts, ws)
}

/// Continuation chains along k for one order pair (start strategy `chains`, METHOD.md 5).
///
/// One chain per start (theta_LS, then the pair's alternative starts). The cells are fitted in
/// increasing k: each chain starts the next cell from its own solution at the previous k. Small
/// k comes first because there the Huber minima are farthest from theta_LS and the starts most
/// often end in different basins; moving up in k then tracks each basin (measured against the
/// scipy peer: no worse in 96 % of cells, against 91 % going down from theta_LS). Chains
/// that reach the same criterion (relative [`Chains::MERGE`]) have found the same minimum and
/// merge into the earlier one, so most pairs soon run a single chain. A losing chain that ran
/// out of iterations (creeping along the stability boundary) continues on a small iteration
/// budget until it converges again ([`Chains::CREEP_ITERATIONS`]).
#[derive(Clone, Debug)]
pub struct Chains {
    /// Current point of each chain (None: merged into an earlier chain).
    points: Vec<Option<Vec<f64>>>,
    /// The points are minima at the previous k (after the first step), not cold starts.
    warm: bool,
    /// Per chain: its last fit lost and ran out of iterations (see [`Chains::step`]).
    creeping: Vec<bool>,
}

impl Chains {
    /// Relative criterion difference below which two chains count as one minimum.
    pub const MERGE: f64 = 1e-6;
    /// Iteration budget of a chain creeping along the stability boundary.
    pub const CREEP_ITERATIONS: usize = 10;

    /// Chains from `theta_ls` (chain 0) and each of `alternatives`.
    pub fn new(theta_ls: &[f64], alternatives: &[Vec<f64>]) -> Self {
        let points: Vec<_> = std::iter::once(theta_ls.to_vec()).chain(alternatives.iter().cloned()).map(Some).collect();
        let creeping = vec![false; points.len()];
        Chains { points, warm: false, creeping }
    }

    /// Chains still running.
    pub fn live(&self) -> usize {
        self.points.iter().flatten().count()
    }

    /// Chains running on the creeping budget [`Chains::CREEP_ITERATIONS`].
    pub fn creeping(&self) -> usize {
        self.points.iter().zip(&self.creeping).filter(|(p, c)| p.is_some() && **c).count()
    }

    /// The cell at tuning constant `k` (larger than at the previous call): one fit per live
    /// chain, the lowest criterion wins (ties: the earlier chain). Returns the fit and the
    /// index of the chain's start (0 = theta_LS).
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        prob: &Problem,
        sigma: f64,
        k: f64,
        judge: &Judge,
        opts: &SolverOptions,
        ws: &mut Workspace,
    ) -> (HuberFit, usize) {
        let loss = Loss::Huber { gamma: k * sigma };
        let opts = &if self.warm { opts.huber_warm() } else { opts.huber() };
        self.warm = true;
        let mut sols: Vec<Option<Solution>> = Vec::with_capacity(self.points.len());
        let budget = SolverOptions { max_iterations: Self::CREEP_ITERATIONS.min(opts.max_iterations), ..opts.clone() };
        for (point, &creeping) in self.points.iter().zip(&self.creeping) {
            let opts = if creeping { &budget } else { opts };
            sols.push(point.as_ref().map(|p| solver::minimise(prob, loss, p, opts, ws)));
        }
        let last = sols.iter().rposition(Option::is_some);
        // Criteria this small are rounding noise of an exact fit, equal whatever their ratio.
        let floor = 1e-20 * prob.y.iter().map(|v| v * v).sum::<f64>() / prob.n() as f64;
        let mut best: Option<usize> = None;
        for (i, sol) in sols.iter().enumerate() {
            let Some(sol) = sol else { continue };
            let usable = sol.termination != Termination::NonFinite && sol.criterion.is_finite();
            if !usable {
                // A chain that broke down keeps its last point (the next k may recover).
                continue;
            }
            let merged = sols[..i].iter().enumerate().any(|(j, other)| {
                self.points[j].is_some()
                    && other.as_ref().is_some_and(|o| {
                        o.criterion.is_finite()
                            && (o.criterion - sol.criterion).abs() <= Self::MERGE * sol.criterion.abs() + floor
                    })
            });
            self.points[i] = if merged { None } else { Some(sol.theta.clone()) };
            if best.is_none_or(|b| sol.criterion < sols[b].as_ref().expect("live").criterion) {
                best = Some(i);
            }
        }
        // No usable chain: report chain 0's (non-finite) attempt as the cell's failure.
        let which = best.unwrap_or(0);
        // A losing chain whose fit ran out of iterations is creeping along the stability
        // boundary: nearly every step leaves the unit circle and is reflected back for a
        // decrease of ~1e-5, the minimum of its basin lying outside. Walked on, it repeats
        // that at every k (on the paper grid such steps never won a cell, yet took a quarter
        // of the Huber iterations), so it runs on a budget of CREEP_ITERATIONS per cell until
        // a fit of it converges again: enough for a warm start whose basin has turned
        // interior (2-5 iterations), and the chain stays in the race.
        for (i, sol) in sols.iter().enumerate() {
            self.creeping[i] = best.is_some()
                && i != which
                && sol.as_ref().is_some_and(|s| s.termination == Termination::MaxIterations);
        }
        let sol = sols[which].as_ref().or(sols.iter().flatten().next()).expect("at least one chain");
        let fit = huber_from_solution(prob, sigma, k, sol, judge, ws, Some(which) != last);
        (fit, which)
    }
}

/// The cells of one order pair along its k grid (increasing k), as [`Chains`] left them, and
/// the backward pass over them ([`ChainWalk::walk_back`]).
///
/// Walking up in k, a chain follows its minimum until that minimum ceases to exist (a fold:
/// the basin merges into another one as gamma grows); the chain then falls into the other
/// basin, which may have been the lower one at the smaller k too, unseen because every start
/// was elsewhere. On the paper grid this happened in 62 of 3840 cells (up to 12 % lower W,
/// e.g. OE(8,4) at k = 0.0875: 1.795 against the 1.586 that the scipy peer found, and that is
/// the continuation of the k = 0.1 minimum downwards). So where the up walk jumped (the
/// winning chain changed, or its warm fit needed [`ChainWalk::JUMP_ITERATIONS`] or more) the
/// pass walks down from that cell, warm start by warm start, as long as each fit lowers the
/// criterion of the cell below; a cell keeps the better of the two. Never worse than the up
/// walk; on the paper grid it added ~9 % to the Huber iterations and 2-3 % to the wall time.
#[derive(Clone, Debug, Default)]
pub struct ChainWalk {
    /// Per k: the cell's fit and where it came from (the winning chain's start index, or
    /// [`ChainWalk::BACK`]); None for a cell that failed outright (a panic), which a walk
    /// does not cross.
    pub cells: Vec<Option<(HuberFit, usize)>>,
}

impl ChainWalk {
    /// Start index of a cell improved by the backward pass.
    pub const BACK: usize = usize::MAX;
    /// A warm fit this long has likely left its basin (warm fits converge in 2-5 iterations).
    pub const JUMP_ITERATIONS: usize = 15;

    /// The backward pass; `ks[i]` is the tuning constant of `cells[i]`. Returns the time spent
    /// per cell (seconds), to be added to its own. Deterministic, like the up walk.
    #[allow(clippy::too_many_arguments)]
    pub fn walk_back(
        &mut self,
        prob: &Problem,
        sigma: f64,
        ks: &[f64],
        judge: &Judge,
        opts: &SolverOptions,
        ws: &mut Workspace,
    ) -> Vec<f64> {
        let n = self.cells.len();
        assert_eq!(ks.len(), n);
        let mut seconds = vec![0.0; n];
        // The triggers are those of the up walk, fixed before any cell changes.
        let jumped: Vec<bool> = (0..n)
            .map(|i| {
                i > 0
                    && match (&self.cells[i], &self.cells[i - 1]) {
                        (Some((fit, which)), Some((_, below))) => {
                            which != below || fit.iterations >= Self::JUMP_ITERATIONS
                        }
                        _ => false,
                    }
            })
            .collect();
        let opts = opts.huber_warm();
        for i in (1..n).rev().filter(|&i| jumped[i]) {
            let mut j = i;
            while j > 0 {
                let (Some((from, _)), Some((below, _))) = (&self.cells[j], &self.cells[j - 1]) else { break };
                let start = [&from.b[..], &from.f[..]].concat();
                let incumbent = below.criterion;
                let t = std::time::Instant::now();
                let loss = Loss::Huber { gamma: ks[j - 1] * sigma };
                let sol = solver::minimise(prob, loss, &start, &opts, ws);
                let lower = sol.termination != Termination::NonFinite
                    && sol.criterion.is_finite()
                    && (!incumbent.is_finite() || sol.criterion < incumbent * (1.0 - Chains::MERGE));
                if lower {
                    let fit = huber_from_solution(prob, sigma, ks[j - 1], &sol, judge, ws, false);
                    self.cells[j - 1] = Some((fit, Self::BACK));
                }
                seconds[j - 1] += t.elapsed().as_secs_f64();
                if !lower {
                    break;
                }
                j -= 1;
            }
        }
        seconds
    }
}

/// A [`HuberFit`] from a finished minimisation. `resimulate`: the workspace does not hold this
/// solution's simulation (another fit ran after it).
fn huber_from_solution(
    prob: &Problem,
    sigma: f64,
    k: f64,
    sol: &Solution,
    judge: &Judge,
    ws: &mut Workspace,
    resimulate: bool,
) -> HuberFit {
    let gamma = k * sigma;
    let (b, f) = sol.theta.split_at(prob.nb);
    if resimulate {
        crate::oe::simulate(b, f, prob.delay, prob.u, &mut ws.yhat);
    }
    let yhat = ws.yhat();
    HuberFit {
        k,
        gamma,
        criterion: sol.criterion,
        l1c: huber::l1_contribution(prob.y, yhat, gamma),
        assessment: assess(prob, b, f, yhat, judge),
        iterations: sol.iterations,
        termination: sol.termination,
        reflections: sol.reflections,
        b: b.to_vec(),
        f: f.to_vec(),
    }
}

/// True when `a` is a usable solution with a lower criterion than `b`.
fn better(a: &Solution, b: &Solution) -> bool {
    a.termination != Termination::NonFinite
        && a.criterion.is_finite()
        && (b.termination == Termination::NonFinite || !b.criterion.is_finite() || a.criterion < b.criterion)
}

fn ls_from_solution(prob: &Problem, sol: Solution, judge: &Judge, _opts: &SolverOptions, ws: &mut Workspace) -> LsFit {
    // The workspace holds the simulation of the last minimisation, not necessarily this one.
    let (b, f) = sol.theta.split_at(prob.nb);
    crate::oe::simulate(b, f, prob.delay, prob.u, &mut ws.yhat);
    ls_fit(prob, sol, judge, ws)
}

/// Step 2 from a given start.
pub fn fit_ls_from(prob: &Problem, theta0: &[f64], judge: &Judge, opts: &SolverOptions, ws: &mut Workspace) -> LsFit {
    let sol = solver::minimise(prob, Loss::LeastSquares, theta0, opts, ws);
    ls_fit(prob, sol, judge, ws)
}

fn ls_fit(prob: &Problem, sol: Solution, judge: &Judge, ws: &Workspace) -> LsFit {
    let yhat = ws.yhat();
    let n = prob.n() as f64;
    let mean_e = prob.y.iter().zip(yhat).map(|(a, b)| a - b).sum::<f64>() / n;
    let var = prob.y.iter().zip(yhat).map(|(a, b)| (a - b - mean_e).powi(2)).sum::<f64>() / n;
    let (b, f) = sol.theta.split_at(prob.nb);
    LsFit {
        nb: prob.nb,
        nf: prob.nf,
        delay: prob.delay,
        criterion: sol.criterion,
        sigma: var.sqrt(),
        assessment: assess(prob, b, f, yhat, judge),
        iterations: sol.iterations,
        termination: sol.termination,
        reflections: sol.reflections,
        b: b.to_vec(),
        f: f.to_vec(),
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
