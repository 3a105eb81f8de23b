//! The solver's settings (the job file's `solver` object), the search method, and why a
//! minimisation stopped ([`Termination`], a table column).

/// How the Huber Hessian weights the L1 rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HuberHessian {
    /// Exact Gauss-Newton Hessian of W: L1 rows get weight 0 (METHOD.md 3).
    GaussNewton,
    /// Iteratively reweighted least squares: L1 rows get weight g/|e|.
    Irls,
}

crate::names::names!(HuberHessian { GaussNewton = "gauss_newton", Irls = "irls" });

/// How the parameters are searched.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SolverMethod {
    /// Levenberg-Marquardt over all of theta = [b, f, c].
    #[default]
    Lm,
    /// Variable projection: Levenberg-Marquardt over F, with [b, c] solved for each F
    /// ([`super::separable`], METHOD.md 12).
    Separable,
}

crate::names::names!(SolverMethod { Lm = "lm", Separable = "separable" });

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
    /// converge in 2-5 (measured on the paper grid: 89 k to 41 k warm iterations). A long
    /// record's whole-record fits from its head's minima start as near and take it too
    /// (METHOD.md 5.5).
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
    pub method: SolverMethod,
    /// Records at least [`super::least_squares::HEAD_SHARE`] times longer explore the
    /// least-squares starts on their first `explore_rows` samples and minimise only the best on
    /// the whole record ([`super::fit_ls`]); 0 = explore on the whole record.
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
            method: SolverMethod::Lm,
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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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

crate::names::names!(Termination { CriterionTolerance = "criterion_tolerance", StepTolerance = "step_tolerance", GradientTolerance = "gradient_tolerance", ExactFit = "exact_fit", MaxIterations = "max_iterations", Stalled = "stalled", NonFinite = "non_finite" });

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
}

impl std::fmt::Display for Termination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}
