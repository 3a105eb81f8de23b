//! Levenberg-Marquardt prediction-error minimisation of an OE criterion (METHOD.md 3, 5).
//!
//! At `theta` with residuals `e_t`, row weights `w_t` and influence `r_t = psi_g(e_t)`:
//!
//! ```text
//! H = (1/N) sum_t w_t psi_t psi_t^T        g = (1/N) sum_t psi_t r_t   (= -grad criterion)
//! (H + lambda D) delta = g,   D = diag(H) (Marquardt scaling, floored)
//! ```
//!
//! Least squares: `w = 1`, `r = e`. Huber: `r = clamp(e, -g, g)` and either the exact
//! Gauss-Newton weights (1 on the L2 set, 0 on the L1 set; METHOD.md 3) or IRLS weights
//! `min(1, g/|e|)`. The exact weights make `H` near singular at small k; the damping
//! `lambda D` is what keeps the step defined, and the gain ratio drives lambda (Nielsen's rule).
//!
//! Invariants: a trial step is accepted only when the criterion strictly decreases, and only
//! with a stable F. An unstable trial F is first reflected into the unit circle (as the scipy
//! peer does) and accepted if that point lowers the criterion; otherwise the step is
//! rejected and lambda raised, i.e. the step shortened (METHOD.md 8).
//!
//! All buffers live in [`Workspace`]; after the first call of a given size the iteration loop
//! allocates nothing, pole reflections included (stack buffers up to nF = 64; tested in
//! `tests/no_allocation.rs`).

use super::huber::Loss;
use super::normal::{Layout, NormalEquations};
use super::separable;
use crate::oe;

/// How the Huber Hessian weights the L1 rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HuberHessian {
    /// Exact Gauss-Newton Hessian of W: L1 rows get weight 0 (METHOD.md 3).
    GaussNewton,
    /// Iteratively reweighted least squares: L1 rows get weight g/|e|.
    Irls,
}

/// How the parameters are searched.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Levenberg-Marquardt over all of theta = [b, f, c].
    #[default]
    Lm,
    /// Variable projection: Levenberg-Marquardt over F, with [b, c] solved for each F
    /// ([`super::separable`], METHOD.md 12).
    Separable,
}

/// Solver settings, also the job file's `solver` object (same names; absent fields take the
/// defaults, unknown ones are refused; the ranges are checked by [`crate::job`]). Defaults are
/// tight enough to match a scipy trust-region fit to ~1e-8.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverOptions {
    /// Iteration cap (accepted + rejected steps count as one iteration each outer pass).
    pub max_iterations: usize,
    /// Stop when both actual and predicted relative decrease of the criterion are below this.
    pub ftol: f64,
    /// Stop when the step is below `xtol (||theta|| + xtol)`.
    pub xtol: f64,
    /// Stop when the scaled gradient `max_i |g_i|/sqrt(H_ii)` is below `gtol sqrt(2 criterion)`.
    pub gtol: f64,
    /// Initial damping (relative to diag(H)).
    pub lambda0: f64,
    /// Initial damping of a warm-started Huber fit: a cell of a continuation chain, started
    /// from the minimum at the neighbouring k. That start is within ~1e-6 (relative W) of the
    /// new minimum, and `lambda0` there costs 10-20 iterations of creeping along the
    /// ill-conditioned directions of OE models while lambda decays; near Gauss-Newton steps
    /// converge in 2-5 (measured on the paper grid: 89 k to 41 k warm iterations).
    pub warm_lambda0: f64,
    /// Huber Hessian weighting.
    pub huber_hessian: HuberHessian,
    /// `ftol` and `xtol` of the Huber fits (the least-squares fits use `ftol`, `xtol`). Looser
    /// than those, as scipy's default: a warm-started cell of a k chain spends its last
    /// iterations creeping below 1e-8, far under the 1e-4 at which local minima differ.
    pub huber_tol: f64,
    /// Extra starts of each Huber fit besides theta_LS: the runner-up least-squares minima
    /// (and a contracted theta_LS when it sits on the stability boundary). 0 = the paper's
    /// single start.
    pub huber_extra_starts: usize,
    /// Full Levenberg-Marquardt or variable projection.
    pub method: Method,
    /// Records longer than this explore the least-squares starts on their first
    /// `explore_rows` samples and minimise only the best few on the whole record
    /// ([`super::fit_ls`]); 0 = explore on the whole record.
    pub explore_rows: usize,
    /// The sweep's least-squares phase also starts each pair from its sub-models' solutions,
    /// (nB - 1, nF) and (nB, nF - 1) (METHOD.md 5.2, step 2): pairs are then fitted in waves
    /// of nB + nF, and a shard also fits the sub-models of its pairs. false = independent
    /// pairs.
    pub nested_starts: bool,
}

impl Default for SolverOptions {
    fn default() -> Self {
        SolverOptions {
            max_iterations: 300,
            ftol: 1e-10,
            xtol: 1e-10,
            gtol: 1e-9,
            lambda0: 1e-3,
            warm_lambda0: 1e-8,
            huber_hessian: HuberHessian::GaussNewton,
            huber_tol: 1e-8,
            huber_extra_starts: 2,
            method: Method::Lm,
            explore_rows: 16384,
            nested_starts: true,
        }
    }
}

impl SolverOptions {
    /// The settings of a Huber fit: `huber_tol` as its `ftol` and `xtol`.
    pub fn huber(&self) -> SolverOptions {
        SolverOptions { ftol: self.huber_tol, xtol: self.huber_tol, ..self.clone() }
    }

    /// The settings of a warm-started Huber fit: [`Self::huber`] with `warm_lambda0`.
    pub fn huber_warm(&self) -> SolverOptions {
        SolverOptions { lambda0: self.warm_lambda0, ..self.huber() }
    }
}

/// Why a minimisation stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Termination {
    /// Relative decrease of the criterion (actual and predicted) below `ftol`.
    CriterionTolerance,
    /// Step below `xtol`.
    StepTolerance,
    /// Scaled gradient below `gtol`.
    GradientTolerance,
    /// The residuals are zero to rounding (noise-free data at the true model).
    ExactFit,
    /// `max_iterations` reached before a tolerance was met.
    MaxIterations,
    /// No decreasing step could be found although no tolerance was met (damping exhausted).
    Stalled,
    /// The criterion or the normal equations became non-finite (at the start point, or at an
    /// accepted point whose normal equations overflowed).
    NonFinite,
}

impl Termination {
    /// The one rule for a usable fit: it did not break down and `value` (its criterion, or a
    /// quantity computed from its residuals such as sigma) is finite.
    pub fn usable(self, value: f64) -> bool {
        self != Termination::NonFinite && value.is_finite()
    }

    pub fn converged(self) -> bool {
        matches!(
            self,
            Termination::CriterionTolerance
                | Termination::StepTolerance
                | Termination::GradientTolerance
                | Termination::ExactFit
        )
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Termination::CriterionTolerance => "criterion_tolerance",
            Termination::StepTolerance => "step_tolerance",
            Termination::GradientTolerance => "gradient_tolerance",
            Termination::ExactFit => "exact_fit",
            Termination::MaxIterations => "max_iterations",
            Termination::Stalled => "stalled",
            Termination::NonFinite => "non_finite",
        }
    }
}

impl std::fmt::Display for Termination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One SISO estimation problem: data and model structure.
#[derive(Clone, Copy, Debug)]
pub struct Problem<'a> {
    pub u: &'a [f64],
    pub y: &'a [f64],
    pub nb: usize,
    pub nf: usize,
    pub delay: usize,
    /// Estimate a constant output offset c jointly with B and F (METHOD.md 9.1): theta is
    /// `[b, f, c]` and `yhat = q^-d B/F u + c`.
    pub offset: bool,
}

impl Problem<'_> {
    /// Number of parameters: nB + nF (+ 1 with an offset).
    pub fn dim(&self) -> usize {
        self.nb + self.nf + usize::from(self.offset)
    }

    /// `theta` as (b, f, c); c = 0 without an offset.
    pub fn split<'t>(&self, theta: &'t [f64]) -> (&'t [f64], &'t [f64], f64) {
        let (b, rest) = theta.split_at(self.nb);
        let (f, c) = rest.split_at(self.nf);
        (b, f, c.first().copied().unwrap_or(0.0))
    }

    /// The F part of `theta`, mutable (for pole reflection).
    pub fn f_mut<'t>(&self, theta: &'t mut [f64]) -> &'t mut [f64] {
        &mut theta[self.nb..self.nb + self.nf]
    }

    /// [`Self::simulate`] into a new vector.
    pub fn simulate_vec(&self, theta: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.u.len()];
        self.simulate(theta, &mut y);
        y
    }

    /// The model's output at `theta` from zero initial conditions, offset included.
    pub fn simulate(&self, theta: &[f64], yhat: &mut [f64]) {
        let (b, f, c) = self.split(theta);
        oe::simulate(b, f, self.delay, self.u, yhat);
        add_offset(yhat, c);
    }
    pub fn layout(&self) -> Layout {
        Layout { nb: self.nb, nf: self.nf, delay: self.delay }
    }
    pub fn n(&self) -> usize {
        self.u.len()
    }
}

/// Result of one minimisation.
#[derive(Clone, Debug)]
pub struct Solution {
    pub theta: Vec<f64>,
    pub criterion: f64,
    /// Outer iterations (each builds the normal equations once).
    pub iterations: usize,
    pub termination: Termination,
    /// Accepted steps that needed a pole reflection.
    pub reflections: usize,
    /// Damping at the end.
    pub lambda: f64,
}

impl Solution {
    /// See [`Termination::usable`].
    pub fn usable(&self) -> bool {
        self.termination.usable(self.criterion)
    }
}

/// Per-worker buffers, reused across fits of any size.
///
/// Memory is O(N) with a fixed count of record-length buffers (issue 19; checked by
/// `tests/memory.rs` against a budget of 24 at N = 16 384 and 131 072, the record itself
/// shared by all workers and not counted):
/// - the solver: `yhat`, `xu`, `xy` and their trial copies, `r`, `w` (8);
/// - the normal equations, of the solver and of the separable inner problem: each a row list
///   (u32) and its weights (3 together); the packed rows of a weighted sum are blocks of a
///   fixed 512 rows, not N;
/// - the evidence ([`super::evidence::Scratch`]): the robust residuals, their centred copy,
///   the centred input and the input it was computed from (4);
/// - while a fit is judged, its outputs with the fitted free response on the estimation and
///   validation records (3-4, freed after the fit);
/// - the initial guesses stream the regressions in 256-row blocks and simulate one instrument
///   vector.
///
/// Measured peak: 16.5 vectors with `method = lm`, 18.1 with `separable`.
#[derive(Default, Debug)]
pub struct Workspace {
    pub(crate) yhat: Vec<f64>,
    trial_yhat: Vec<f64>,
    pub(crate) xu: Vec<f64>,
    trial_xu: Vec<f64>,
    pub(crate) xy: Vec<f64>,
    trial_xy: Vec<f64>,
    r: Vec<f64>,
    w: Vec<f64>,
    h: Vec<f64>,
    g: Vec<f64>,
    a: Vec<f64>,
    delta: Vec<f64>,
    theta: Vec<f64>,
    trial: Vec<f64>,
    ne: NormalEquations,
    inner: super::separable::Inner,
    pub(crate) evidence: super::evidence::Scratch,
    /// Criterion after each accepted step (first entry: the start), when `record_trace`.
    pub trace: Vec<f64>,
    pub record_trace: bool,
}

impl Workspace {
    pub fn new() -> Self {
        Self::default()
    }

    fn prepare(&mut self, n: usize, d: usize) {
        for v in [
            &mut self.yhat,
            &mut self.trial_yhat,
            &mut self.xu,
            &mut self.trial_xu,
            &mut self.xy,
            &mut self.trial_xy,
            &mut self.r,
            &mut self.w,
        ] {
            v.resize(n, 0.0);
        }
        for v in [&mut self.h, &mut self.a] {
            v.resize(d * d, 0.0);
        }
        for v in [&mut self.g, &mut self.delta, &mut self.theta, &mut self.trial] {
            v.resize(d, 0.0);
        }
        self.trace.clear();
    }

    /// The simulated output at the last solution returned by [`minimise`].
    pub fn yhat(&self) -> &[f64] {
        &self.yhat
    }

    /// Makes `theta` the workspace's solution: its output ([`Problem::simulate`]) and the
    /// Jacobian signals `xu`, `xy` (for another solution than the last minimisation's).
    pub(crate) fn resimulate(&mut self, prob: &Problem, theta: &[f64]) {
        let n = prob.n();
        for v in [&mut self.yhat, &mut self.xu, &mut self.xy] {
            v.resize(n, 0.0);
        }
        prob.simulate(theta, &mut self.yhat);
        self.xu.copy_from_slice(prob.u);
        oe::inv_f_in_place(prob.split(theta).1, &mut self.xu);
        output_filtered(prob, theta, &self.yhat, &mut self.xy);
    }
}

/// In-place Cholesky of the d x d row-major SPD matrix `a` (lower factor); false if not SPD.
pub(crate) fn cholesky(a: &mut [f64], d: usize) -> bool {
    for j in 0..d {
        let mut s = a[j * d + j];
        for k in 0..j {
            s -= a[j * d + k] * a[j * d + k];
        }
        if s.is_nan() || s <= 0.0 || s.is_infinite() {
            return false;
        }
        let l = s.sqrt();
        a[j * d + j] = l;
        for i in j + 1..d {
            let mut s = a[i * d + j];
            for k in 0..j {
                s -= a[i * d + k] * a[j * d + k];
            }
            a[i * d + j] = s / l;
        }
    }
    true
}

/// Solves `L L^T x = b` in place (`x` holds b) with the factor of [`cholesky`].
pub(crate) fn cholesky_solve(l: &[f64], d: usize, x: &mut [f64]) {
    for i in 0..d {
        let mut s = x[i];
        for k in 0..i {
            s -= l[i * d + k] * x[k];
        }
        x[i] = s / l[i * d + i];
    }
    for i in (0..d).rev() {
        let mut s = x[i];
        for k in i + 1..d {
            s -= l[k * d + i] * x[k];
        }
        x[i] = s / l[i * d + i];
    }
}

/// The damping after a failed step. From lambda = 0 (allowed as `lambda0`: a pure
/// Gauss-Newton first step) it starts at a level that can grow.
fn raised(lambda: f64, nu: f64) -> f64 {
    (lambda * nu).max(MIN_RAISED_LAMBDA)
}

/// Smallest damping after a failed step (relative to the Marquardt scaling diag(H)).
const MIN_RAISED_LAMBDA: f64 = 1e-12;

fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// `yhat += c`: the offset sits outside the dynamics, so the Jacobian signals `xu` and
/// `xy = (1/F) (yhat - c)` of [`oe::simulate_filtered`] stay as they are.
fn add_offset(yhat: &mut [f64], c: f64) {
    if c != 0.0 {
        yhat.iter_mut().for_each(|v| *v += c);
    }
}

/// `xy = (1/F) (yhat - c)`: the F columns' signal of the Jacobian from a given output (a
/// separable evaluation's, or a re-simulated one), when no fused pass computed it.
fn output_filtered(prob: &Problem, theta: &[f64], yhat: &[f64], xy: &mut [f64]) {
    let (_, f, c) = prob.split(theta);
    for (x, &v) in xy.iter_mut().zip(yhat) {
        *x = v - c;
    }
    oe::inv_f_in_place(f, xy);
}

/// Minimise `loss` over theta = [b, f] (or [b, f, c], see [`Problem::offset`]) from `theta0`.
/// The returned F is stable.
pub fn minimise(prob: &Problem, loss: Loss, theta0: &[f64], opts: &SolverOptions, ws: &mut Workspace) -> Solution {
    let n = prob.n();
    let d = prob.dim();
    assert_eq!(theta0.len(), d);
    assert_eq!(prob.y.len(), n);
    ws.prepare(n, d);
    ws.theta.copy_from_slice(theta0);
    let mut reflections = 0;
    let mut lambda = opts.lambda0;
    if oe::reflect_unstable(prob.f_mut(&mut ws.theta)) {
        reflections += 1;
    }
    let lay = prob.layout();
    let y_scale = prob.y.iter().map(|v| v * v).sum::<f64>() / n as f64;
    // Residuals at this level are rounding noise of the simulation.
    let exact_level = 1e-26 * y_scale.max(f64::MIN_POSITIVE);

    // yhat = q^-d B (1/F) u = B applied to xu = (1/F) u (LTI operators commute, zero initial
    // conditions): one pass gives the simulation and both Jacobian signals (xu and
    // xy = (1/F) yhat), so an accepted trial point needs no further filtering.
    let separable = opts.method == Method::Separable;
    let mut crit = if separable {
        let ws = &mut *ws;
        let c = separable::project(
            prob,
            loss,
            &mut ws.theta,
            &mut ws.xu,
            &mut ws.yhat,
            &mut ws.r,
            &mut ws.w,
            &mut ws.inner,
        );
        output_filtered(prob, &ws.theta, &ws.yhat, &mut ws.xy);
        c
    } else {
        let (b0, f0, c0) = prob.split(&ws.theta);
        oe::simulate_filtered(b0, f0, prob.delay, prob.u, &mut ws.xu, &mut ws.yhat, &mut ws.xy);
        add_offset(&mut ws.yhat, c0);
        loss.criterion(prob.y, &ws.yhat)
    };
    let finish = |ws: &mut Workspace, crit, iterations, termination, reflections, lambda| Solution {
        theta: ws.theta.clone(),
        criterion: crit,
        iterations,
        termination,
        reflections,
        lambda,
    };
    if !crit.is_finite() {
        return finish(ws, crit, 0, Termination::NonFinite, reflections, lambda);
    }
    if ws.record_trace {
        ws.trace.push(crit);
    }
    let mut nu = 2.0;
    let use_weights = !matches!(loss, Loss::LeastSquares);

    for it in 0..opts.max_iterations {
        if crit <= exact_level {
            return finish(ws, crit, it, Termination::ExactFit, reflections, lambda);
        }
        // Residual influence and row weights at the current point.
        match loss {
            Loss::LeastSquares => {
                for ((r, &y), &yh) in ws.r.iter_mut().zip(prob.y).zip(&ws.yhat) {
                    *r = y - yh;
                }
            }
            Loss::Huber { gamma } => {
                // Branch-free and over zipped slices, so it vectorises (the L1/L2 split of
                // consecutive residuals is unpredictable).
                let rows = ws.r.iter_mut().zip(ws.w.iter_mut()).zip(prob.y.iter().zip(&ws.yhat));
                match opts.huber_hessian {
                    HuberHessian::GaussNewton => {
                        for ((r, w), (&y, &yh)) in rows {
                            let e = y - yh;
                            *r = e.clamp(-gamma, gamma);
                            *w = if e.abs() <= gamma { 1.0 } else { 0.0 };
                        }
                    }
                    HuberHessian::Irls => {
                        for ((r, w), (&y, &yh)) in rows {
                            let e = y - yh;
                            *r = e.clamp(-gamma, gamma);
                            *w = if e.abs() <= gamma { 1.0 } else { gamma / e.abs() };
                        }
                    }
                }
            }
        }
        let w = if use_weights { Some(&ws.w[..]) } else { None };
        ws.ne.build(&lay, &ws.xu, &ws.xy, w, &ws.r, &mut ws.h, &mut ws.g);
        if prob.offset {
            ws.ne.add_offset(&lay, &ws.xu, &ws.xy, w, &ws.r, &mut ws.h, &mut ws.g);
        }
        if ws.h.iter().any(|v| !v.is_finite()) || ws.g.iter().any(|v| !v.is_finite()) {
            return finish(ws, crit, it, Termination::NonFinite, reflections, lambda);
        }
        let hmax = (0..d).map(|i| ws.h[i * d + i]).fold(0.0, f64::max);
        let floor = 1e-12 * hmax.max(f64::MIN_POSITIVE);
        let scaled_grad = (0..d).map(|i| ws.g[i].abs() / ws.h[i * d + i].max(floor).sqrt()).fold(0.0, f64::max);
        if scaled_grad <= opts.gtol * (2.0 * crit).sqrt() {
            return finish(ws, crit, it, Termination::GradientTolerance, reflections, lambda);
        }

        // Inner loop: raise damping until a step decreases the criterion.
        loop {
            ws.a.copy_from_slice(&ws.h);
            for i in 0..d {
                // Variable projection damps F only: b and c are solved for, not stepped.
                let damped = !separable || (prob.nb..prob.nb + prob.nf).contains(&i);
                ws.a[i * d + i] += if damped { lambda * ws.h[i * d + i].max(floor) } else { floor };
            }
            if !cholesky(&mut ws.a, d) {
                lambda = raised(lambda, nu);
                nu *= 2.0;
                if lambda > 1e20 {
                    return finish(ws, crit, it + 1, Termination::Stalled, reflections, lambda);
                }
                continue;
            }
            ws.delta.copy_from_slice(&ws.g);
            cholesky_solve(&ws.a, d, &mut ws.delta);
            // Predicted decrease of the quadratic model: g.delta - delta^T H delta / 2.
            let mut quad = 0.0;
            for i in 0..d {
                let mut hi = 0.0;
                for j in 0..d {
                    hi += ws.h[i * d + j] * ws.delta[j];
                }
                quad += ws.delta[i] * hi;
            }
            let pred = ws.g.iter().zip(&ws.delta).map(|(a, b)| a * b).sum::<f64>() - 0.5 * quad;
            for i in 0..d {
                ws.trial[i] = ws.theta[i] + ws.delta[i];
            }
            let mut reflected = false;
            if ws.trial.iter().any(|v| !v.is_finite()) {
                // A degenerate system (e.g. gamma ~ 0 on noise-free data): more damping.
                lambda = raised(lambda, nu);
                nu *= 2.0;
                if lambda > 1e20 {
                    return finish(ws, crit, it + 1, Termination::Stalled, reflections, lambda);
                }
                continue;
            }
            if !oe::is_stable(prob.f_mut(&mut ws.trial)) {
                oe::reflect_unstable(prob.f_mut(&mut ws.trial));
                reflected = true;
            }
            let new_crit = if separable {
                // r and w were used up by this iteration's normal equations: scratch now.
                let ws = &mut *ws;
                separable::project(
                    prob,
                    loss,
                    &mut ws.trial,
                    &mut ws.trial_xu,
                    &mut ws.trial_yhat,
                    &mut ws.r,
                    &mut ws.w,
                    &mut ws.inner,
                )
            } else {
                let (tb, tf, tc) = prob.split(&ws.trial);
                oe::simulate_filtered(
                    tb,
                    tf,
                    prob.delay,
                    prob.u,
                    &mut ws.trial_xu,
                    &mut ws.trial_yhat,
                    &mut ws.trial_xy,
                );
                add_offset(&mut ws.trial_yhat, tc);
                loss.criterion(prob.y, &ws.trial_yhat)
            };
            if new_crit.is_finite() && new_crit < crit {
                let rho = if pred > 0.0 { (crit - new_crit) / pred } else { 0.0 };
                lambda *= f64::max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0).powi(3));
                nu = 2.0;
                // The separable step moved b and c to their inner optimum, not by delta.
                let step = if separable {
                    ws.trial.iter().zip(&ws.theta).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt()
                } else {
                    norm2(&ws.delta)
                };
                let rel_actual = (crit - new_crit) / crit;
                let rel_pred = pred.abs() / crit;
                let small_step = step <= opts.xtol * (norm2(&ws.theta) + opts.xtol);
                if separable {
                    output_filtered(prob, &ws.trial, &ws.trial_yhat, &mut ws.trial_xy);
                }
                std::mem::swap(&mut ws.theta, &mut ws.trial);
                std::mem::swap(&mut ws.yhat, &mut ws.trial_yhat);
                std::mem::swap(&mut ws.xu, &mut ws.trial_xu);
                std::mem::swap(&mut ws.xy, &mut ws.trial_xy);
                crit = new_crit;
                if reflected {
                    reflections += 1;
                }
                if ws.record_trace {
                    ws.trace.push(crit);
                }
                if !reflected && rel_actual <= opts.ftol && rel_pred <= opts.ftol {
                    return finish(ws, crit, it + 1, Termination::CriterionTolerance, reflections, lambda);
                }
                if !reflected && small_step {
                    return finish(ws, crit, it + 1, Termination::StepTolerance, reflections, lambda);
                }
                break;
            }
            // Rejected. A predicted decrease below rounding of the criterion means the point is
            // a minimum to machine precision: more damping cannot help.
            if !reflected && pred.abs() <= 1e-15 * crit {
                return finish(ws, crit, it + 1, Termination::CriterionTolerance, reflections, lambda);
            }
            lambda = raised(lambda, nu);
            nu *= 2.0;
            if lambda > 1e20 {
                return finish(ws, crit, it + 1, Termination::Stalled, reflections, lambda);
            }
        }
    }
    finish(ws, crit, opts.max_iterations, Termination::MaxIterations, reflections, lambda)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_spd_system() {
        let a0 = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let mut a = a0;
        assert!(cholesky(&mut a, 3));
        let mut x = [1.0, 2.0, 3.0];
        cholesky_solve(&a, 3, &mut x);
        for i in 0..3 {
            let r: f64 = (0..3).map(|j| a0[i * 3 + j] * x[j]).sum();
            assert!((r - [1.0, 2.0, 3.0][i]).abs() < 1e-12);
        }
        let mut b = [1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky(&mut b, 2));
    }
}
