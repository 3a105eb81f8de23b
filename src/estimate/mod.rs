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
    let mut best: Option<Solution> = None;
    for theta0 in init::initial_guesses(prob) {
        let sol = solver::minimise(prob, Loss::LeastSquares, &theta0, opts, ws);
        if best.as_ref().is_none_or(|b| better(&sol, b)) {
            best = Some(sol);
        }
    }
    let best = best.expect("at least one start");
    ls_from_solution(prob, best, judge, opts, ws)
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
    let gamma = k * sigma;
    let loss = Loss::Huber { gamma };
    let sol = solver::minimise(prob, loss, start, opts, ws);
    let yhat = ws.yhat();
    let (b, f) = sol.theta.split_at(prob.nb);
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
