//! A fitted model and what it is judged by: the least-squares and Huber fit types, their
//! assessment (fit %, pole radius, evidence), the start a fit came from, and the fits of one
//! minimisation (METHOD.md 5-6).

use super::evidence;
use super::fit_percent::fit_percent;
use super::huber::{self, Loss};
use super::initial_state::{self, InitialState};
use super::options::{SolverOptions, Termination};
use super::problem::{Problem, Solution};
use super::problem::{flat_parts, theta_in};
use super::solver;
use super::workspace::Workspace;
use crate::oe::Structure;
use crate::profile::{Phase, Span};
use crate::spectral::SpectralEstimate;

/// What a fitted model is judged against besides its own estimation record.
#[derive(Clone, Copy, Default)]
pub struct Judge<'a> {
    /// Validation record (u, y): used only to judge, never to fit.
    pub validation: Option<(&'a [f64], &'a [f64])>,
    /// The validation record's seams when it is several experiments
    /// ([`crate::data::Record::seams`]; empty: one).
    pub validation_seams: &'a [usize],
    /// The validation record's missing outputs ([`crate::data::Record::missing`]).
    pub validation_missing: &'a [usize],
    /// Spectral estimate of the estimation record, one per input
    /// ([`crate::spectral::estimate_inputs`]), and the bins of the fit band.
    pub band: Option<(&'a [SpectralEstimate], &'a [usize])>,
    /// The initial state `fit` and `fit_val` are computed with.
    pub initial_state: InitialState,
    /// Fits only for their criterion: a pair's walk (its cells are judged once the walk is
    /// done, [`judged`]), a long record's walk on its head, whose every cell is fitted again on
    /// the whole record (METHOD.md 5.5) and judged there, and a nested check's refit until it
    /// replaces its cell. Such a fit carries no assessment, L1C or robust criteria (NaN and
    /// None) and never becomes a row as it is; judging the head's fits was 6 % of a long-record
    /// run (the evidence, fit % and criteria).
    pub criterion_only: bool,
}

impl Judge<'_> {
    /// The output the model is judged by on a record (u, y), in place: `yhat` holds its
    /// simulation from zero initial conditions (offset included), to which the fitted free
    /// response is added with [`InitialState::Estimate`] (`s`: its buffers).
    pub fn judge_output(
        &self,
        prob: &Problem,
        theta: &[f64],
        y: &[f64],
        yhat: &mut [f64],
        s: &mut initial_state::Scratch,
    ) {
        if self.initial_state != InitialState::Estimate {
            return;
        }
        // One initial state per experiment.
        if prob.m() == 1 {
            let (b, f, _) = prob.split(theta);
            for e in prob.experiments() {
                initial_state::add_free_response_in(f, b.len(), prob.one().delay, &y[e.clone()], &mut yhat[e], s);
            }
        } else {
            let (f, past) = initial_state::common_denominator(&prob.structure, theta);
            for e in prob.experiments() {
                initial_state::add_free_response_in(&f, past + 1, 0, &y[e.clone()], &mut yhat[e], s);
            }
        }
    }
}

/// The fit % of each experiment of a record of several (`prob.seams` not empty; None for one
/// experiment, whose fit is the pooled one).
fn fit_per_experiment(prob: &Problem, y: &[f64], yhat: &[f64]) -> Option<Vec<f64>> {
    (!prob.seams.is_empty()).then(|| prob.experiments().map(|e| fit_percent(&y[e.clone()], &yhat[e])).collect())
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
    /// A cell refitted from its sub-model's solution at the same k (`sweep::nested`, METHOD.md 5.6).
    Nested,
    /// A cell of the walk from a pair's boundary probe ([`super::ChainWalk`], METHOD.md 5.5):
    /// an interior fit that replaced a boundary one (or a lower one).
    Probe,
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
            StartKind::Nested => "nested",
            StartKind::Probe => "probe",
        }
    }
}

/// What every Huber fit of one order pair shares: the problem, the least-squares scale sigma
/// (gamma = k sigma), what the fits are judged against, and the solver settings.
#[derive(Clone, Copy)]
pub struct PairProblem<'a> {
    pub prob: &'a Problem<'a>,
    pub sigma: f64,
    pub judge: &'a Judge<'a>,
    pub opts: &'a SolverOptions,
}

/// Quantities every fitted model reports.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Assessment {
    /// Fit % on the estimation record.
    pub fit: f64,
    /// Fit % on the validation record (None without one).
    pub fit_val: Option<f64>,
    /// Fit % of the frequency response against the spectral estimate in the band (several
    /// inputs: the mean of `fit_band_inputs`, [`crate::spectral::combined_band_fit`]).
    pub fit_band: Option<f64>,
    /// Several inputs: each input's band fit (None for one input, and when an input's is not
    /// finite, as `fit_band` then).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit_band_inputs: Option<Vec<f64>>,
    /// Fit % of each estimation experiment when the record is several (METHOD.md 16); `fit`
    /// is then the pooled one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit_exp: Option<Vec<f64>>,
    /// Fit % of each validation experiment when the validation record is several.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit_val_exp: Option<Vec<f64>>,
    pub max_pole_radius: f64,
    /// Parameter standard deviations and residual tests (METHOD.md 10).
    #[serde(flatten)]
    pub evidence: evidence::Evidence,
}

impl Assessment {
    /// The assessment of a fit that is not judged ([`Judge::criterion_only`]).
    fn unjudged(max_pole_radius: f64) -> Self {
        Assessment {
            fit: f64::NAN,
            fit_val: None,
            fit_band: None,
            fit_band_inputs: None,
            fit_exp: None,
            fit_val_exp: None,
            max_pole_radius,
            evidence: evidence::Evidence::default(),
        }
    }
}

/// The assessment of the solution `theta` whose output and Jacobian signals the workspace
/// holds (the solver's last, or [`Workspace::resimulate`]).
fn assess(prob: &Problem, theta: &[f64], loss: Loss, ws: &mut Workspace, judge: &Judge) -> Assessment {
    let profile = ws.profile.clone();
    let judging = Span::start(profile.as_deref(), Phase::Judge);
    let mut fit_val_exp = None;
    let fit_val = judge.validation.map(|(u, y)| {
        let val = Problem { u, y, seams: judge.validation_seams, missing: judge.validation_missing, ..*prob };
        let judged = &mut ws.judged_val;
        judged.resize(y.len(), 0.0);
        val.simulate(theta, judged);
        judge.judge_output(&val, theta, y, judged, &mut ws.free_response);
        fit_val_exp = fit_per_experiment(&val, y, judged);
        ws.spread_val.fit_percent(y, judged)
    });
    ws.judged.clear();
    ws.judged.extend_from_slice(&ws.yhat);
    judge.judge_output(prob, theta, prob.y, &mut ws.judged, &mut ws.free_response);
    let fit = ws.spread.fit_percent(prob.y, &ws.judged);
    let fit_exp = fit_per_experiment(prob, prob.y, &ws.judged);
    let (fit_band, fit_band_inputs) = band_fits(prob, theta, judge);
    drop(judging);
    let _evidence = Span::start(profile.as_deref(), Phase::Evidence);
    Assessment {
        fit,
        fit_val: fit_val.filter(|v| v.is_finite()),
        fit_band: fit_band.filter(|v| v.is_finite()),
        fit_band_inputs,
        fit_exp,
        fit_val_exp,
        max_pole_radius: prob.max_pole_radius(theta),
        evidence: evidence::evidence(prob, theta, loss, &ws.yhat, &ws.xu, &ws.xy, &mut ws.evidence),
    }
}

/// The band fit of `theta` (METHOD.md 11) and, for several inputs, each input's: input i's
/// `B_i/F_i` against its estimate `H_i`.
fn band_fits(prob: &Problem, theta: &[f64], judge: &Judge) -> (Option<f64>, Option<Vec<f64>>) {
    let Some((ests, bins)) = judge.band else { return (None, None) };
    assert_eq!(ests.len(), prob.m(), "one spectral estimate per input");
    if prob.m() == 1 {
        let (b, f, _) = prob.split(theta);
        return (crate::spectral::band_fit(&ests[0], bins, b, f, prob.one().delay), None);
    }
    let per_input: Vec<Option<f64>> = (0..prob.m())
        .map(|i| {
            let (b, f) = prob.input_parts(theta, i);
            crate::spectral::band_fit(&ests[i], bins, b, f, prob.structure.inputs()[i].delay)
        })
        .collect();
    // Every input's or none (a row's list never holds a gap): the combined fit needs them all.
    let finite: Option<Vec<f64>> = per_input.iter().map(|v| v.filter(|v| v.is_finite())).collect();
    (crate::spectral::combined_band_fit(&per_input), finite)
}

/// The least-squares (L2) fit of an order pair and the scale sigma it provides.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LsFit {
    /// One input's orders (several inputs: input 1's; `structure` has them all).
    pub nb: usize,
    pub nf: usize,
    pub delay: usize,
    #[serde(skip)]
    pub structure: Structure,
    /// `(1/N) sum e^2 / 2`.
    pub criterion: f64,
    /// Standard deviation of the residuals (ddof = 0).
    pub sigma: f64,
    #[serde(flatten)]
    pub assessment: Assessment,
    pub iterations: usize,
    pub termination: Termination,
    pub reflections: usize,
    /// B's coefficients and F's ([`Parameters`]: with several inputs, every input's one after
    /// the other).
    pub b: Vec<f64>,
    pub f: Vec<f64>,
    /// The estimated output offset c (None when the model has none, [`Problem::offset`]).
    pub offset: Option<f64>,
    /// AIC, AICc, BIC and FPE of this fit ([`super::criteria`]).
    #[serde(flatten)]
    pub criteria: super::criteria::Criteria,
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
    let big = prob.one();
    assert!(nb <= big.nb && nf <= big.nf, "OE({nb},{nf}) is no sub-model of OE({},{})", big.nb, big.nf);
    assert_eq!(theta.len(), nb + nf + usize::from(prob.offset));
    let mut out = vec![0.0; prob.dim()];
    out[..nb].copy_from_slice(&theta[..nb]);
    out[big.nb..big.nb + nf].copy_from_slice(&theta[nb..nb + nf]);
    if prob.offset {
        out[big.nb + big.nf] = theta[nb + nf];
    }
    out
}

/// `[b, f]`, or `[b, f, c]` with an offset: the solver's parameter vector.
pub fn theta_of(b: &[f64], f: &[f64], offset: Option<f64>) -> Vec<f64> {
    b.iter().chain(f).chain(offset.as_ref()).copied().collect()
}

impl LsFit {
    pub fn theta(&self) -> Vec<f64> {
        theta_in(&self.structure, &self.b, &self.f, self.offset)
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
    /// Robust AIC and BIC of this fit ([`super::criteria::robust`]).
    #[serde(flatten)]
    pub criteria: super::criteria::Robust,
    #[serde(skip)]
    pub structure: Structure,
}

impl HuberFit {
    pub fn theta(&self) -> Vec<f64> {
        theta_in(&self.structure, &self.b, &self.f, self.offset)
    }
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
    let (b, f) = flat_parts(&prob.structure, &sol.theta);
    let c = prob.offset_of(&sol.theta);
    let (l1c, assessment, criteria) = if judge.criterion_only {
        let radius = prob.max_pole_radius(&sol.theta);
        (f64::NAN, Assessment::unjudged(radius), super::criteria::Robust { raic: f64::NAN, rbic: f64::NAN })
    } else {
        if resimulate {
            ws.resimulate(prob, &sol.theta);
        }
        huber_judgement(prob, &sol.theta, gamma, judge, ws)
    };
    HuberFit {
        k,
        gamma,
        criterion: sol.criterion,
        l1c,
        assessment,
        iterations: sol.iterations,
        termination: sol.termination,
        reflections: sol.reflections,
        b,
        f,
        offset: prob.offset.then_some(c),
        criteria,
        structure: prob.structure,
    }
}

/// The L1C, assessment and robust criteria of the Huber solution `theta` whose output and
/// Jacobian signals the workspace holds.
fn huber_judgement(
    prob: &Problem,
    theta: &[f64],
    gamma: f64,
    judge: &Judge,
    ws: &mut Workspace,
) -> (f64, Assessment, super::criteria::Robust) {
    (
        huber::l1_contribution(prob.y, ws.yhat(), gamma, prob.n_obs()),
        assess(prob, theta, Loss::Huber { gamma }, ws, judge),
        super::criteria::robust(prob.y, ws.yhat(), gamma, prob.dim()),
    )
}

/// A fit made for its criterion only ([`Judge::criterion_only`]) judged by `judge`, from the
/// solver's own simulation of its solution ([`Workspace::solver_state`]): what
/// [`huber_from_solution`] gives a fit judged straight after its minimisation, bit for bit.
///
/// Why later: a walk replaces cells (the backward pass, the top cell, the boundary probe, the
/// nested check) after they were fitted, and judging each fit as it came (the evidence, fit %,
/// the band fit; about 1 ms a cell at the paper grid's orders) judged 5 164 fits for 3 936
/// rows on the paper grid. A walk now fits for the criterion and judges each cell's final fit
/// once (METHOD.md 5.5).
pub(crate) fn judged(prob: &Problem, fit: HuberFit, judge: &Judge, ws: &mut Workspace) -> HuberFit {
    let theta = fit.theta();
    ws.solver_state(prob, &theta);
    let (l1c, assessment, criteria) = huber_judgement(prob, &theta, fit.gamma, judge, ws);
    HuberFit { l1c, assessment, criteria, ..fit }
}

pub(super) fn ls_from_solution(
    prob: &Problem,
    sol: Solution,
    judge: &Judge,
    _opts: &SolverOptions,
    ws: &mut Workspace,
) -> LsFit {
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
    // Over the observed outputs (a missing one is NaN in y).
    let n = prob.n_obs() as f64;
    let seen = || prob.y.iter().zip(yhat).filter(|(a, _)| !a.is_nan());
    let mean_e = seen().map(|(a, b)| a - b).sum::<f64>() / n;
    let var = seen().map(|(a, b)| (a - b - mean_e).powi(2)).sum::<f64>() / n;
    let (b, f) = flat_parts(&prob.structure, &sol.theta);
    let c = prob.offset_of(&sol.theta);
    let first = prob.structure.inputs()[0];
    LsFit {
        nb: first.nb,
        nf: first.nf,
        delay: first.delay,
        structure: prob.structure,
        criterion: sol.criterion,
        sigma: var.sqrt(),
        assessment: assess(prob, &sol.theta, Loss::LeastSquares, ws, judge),
        iterations: sol.iterations,
        termination: sol.termination,
        reflections: sol.reflections,
        b: b.to_vec(),
        f: f.to_vec(),
        offset: prob.offset.then_some(c),
        // V = (1/N) sum e^2 = 2 criterion, over every estimated parameter.
        criteria: super::criteria::least_squares(2.0 * sol.criterion, prob.n_obs(), prob.dim()),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::Structure;

    /// A fit judged later ([`judged`], after other minimisations ran in the workspace) is the
    /// fit judged straight after its own minimisation, bit for bit: the same evidence, fit %,
    /// L1C and robust criteria, with an offset and across a seam, for a well- and an
    /// ill-conditioned (over-parameterised) model.
    #[test]
    fn a_fit_judged_later_is_the_fit_judged_at_once() {
        let n = 3000;
        let mut s = 11u64;
        let mut draw = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let u: Vec<f64> = (0..n).map(|_| draw()).collect();
        let clean = crate::oe::simulate_vec(&[0.4, 0.25], &[-1.5, 0.7], 1, &u);
        // Spikes on every 17th sample: some residuals beyond gamma.
        let y: Vec<f64> = clean
            .iter()
            .enumerate()
            .map(|(t, v)| v + 0.3 + 0.02 * draw() + if t % 17 == 0 { 2.0 } else { 0.0 })
            .collect();
        let seams = [1200];
        let val_u: Vec<f64> = (0..800).map(|_| draw()).collect();
        let val_y = crate::oe::simulate_vec(&[0.4, 0.25], &[-1.5, 0.7], 1, &val_u);
        let judge = Judge { validation: Some((&val_u, &val_y)), ..Judge::default() };
        let later = Judge { criterion_only: true, ..Judge::default() };
        let opts = SolverOptions::default();
        for (nb, nf) in [(2, 2), (5, 6)] {
            let prob = Problem {
                u: &u,
                y: &y,
                structure: Structure::siso(nb, nf, 1),
                offset: true,
                seams: &seams,
                missing: &[],
            };
            let mut ws = Workspace::default();
            let ls = super::super::least_squares::fit_ls(&prob, &judge, &opts, &mut ws);
            let start = ls.theta();
            let at_once = fit_huber(&prob, ls.sigma, 0.5, &start, &judge, &opts, &mut ws);
            let unjudged = fit_huber(&prob, ls.sigma, 0.5, &start, &later, &opts, &mut ws);
            assert!(unjudged.l1c.is_nan() && unjudged.assessment.evidence.max_rel_std.is_none());
            // Another minimisation in between leaves other signals in the workspace.
            fit_huber(&prob, ls.sigma, 1.5, &start, &later, &opts, &mut ws);
            let judged = judged(&prob, unjudged, &judge, &mut ws);
            let bits = |f: &HuberFit| serde_json::to_string(f).unwrap();
            assert_eq!(bits(&judged), bits(&at_once), "OE({nb},{nf})");
            assert!(at_once.assessment.evidence.max_rel_std.is_some() && at_once.assessment.fit_val.is_some());
        }
    }
}
