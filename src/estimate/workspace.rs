//! The per-worker buffers of the solver, the evidence and the separable inner problem.

use super::normal::NormalEquations;
use super::problem::{Problem, output_filtered};

/// Per-worker buffers, reused across fits of any size.
///
/// Memory is O(N) with a fixed count of record-length buffers (issue 19; checked by
/// `tests/memory.rs` against a budget of [`Workspace::RECORD_VECTORS`] at N = 16 384 and 131 072, the record itself
/// shared by all workers and not counted):
/// - the solver: `yhat`, `xu`, `xy` and their trial copies, `r`, `w` (8);
/// - the normal equations, of the solver and of the separable inner problem: each a row list
///   (u32) and its weights (3 together); the packed rows of a weighted sum are blocks of a
///   fixed 512 rows, not N;
/// - the evidence ([`super::evidence::Scratch`]): the robust residuals, their centred copy,
///   the centred input and the input it was computed from (4);
/// - a fit's judged outputs on the estimation and validation records, and those records'
///   outputs as the fit %'s sums of them were taken from ([`super::fit_percent::OutputSpread`]) (4; the fitted free
///   response's impulse response and residual are as long as the response takes to decay);
/// - the initial guesses stream the regressions in 256-row blocks and simulate one instrument
///   vector.
///
/// Measured peak (`tests/memory.rs`, N = 16 384): 16.7 vectors with `method = lm`, 18.5 with
/// `separable` (16.5 and 18.1 before the fit %'s kept outputs).
#[derive(Default, Debug)]
pub struct Workspace {
    pub(crate) yhat: Vec<f64>,
    pub(super) trial_yhat: Vec<f64>,
    pub(crate) xu: Vec<f64>,
    pub(super) trial_xu: Vec<f64>,
    pub(crate) xy: Vec<f64>,
    pub(super) trial_xy: Vec<f64>,
    pub(super) r: Vec<f64>,
    pub(super) w: Vec<f64>,
    pub(super) h: Vec<f64>,
    pub(super) g: Vec<f64>,
    pub(super) a: Vec<f64>,
    pub(super) delta: Vec<f64>,
    pub(super) theta: Vec<f64>,
    pub(super) trial: Vec<f64>,
    pub(super) ne: NormalEquations,
    pub(super) inner: super::separable::Inner,
    pub(crate) evidence: super::evidence::Scratch,
    /// A fit's judged outputs on the estimation and validation records, and the buffers of
    /// their fitted free response ([`super::initial_state::Scratch`]).
    pub(super) judged: Vec<f64>,
    pub(super) judged_val: Vec<f64>,
    /// The fit %'s sums of the estimation and validation outputs.
    pub(super) spread: super::fit_percent::OutputSpread,
    pub(super) spread_val: super::fit_percent::OutputSpread,
    pub(super) free_response: super::initial_state::Scratch,
    /// Criterion after each accepted step (first entry: the start), when `record_trace`.
    pub trace: Vec<f64>,
    pub record_trace: bool,
    /// The run's counters, when it is profiled ([`crate::profile`]).
    pub profile: Option<std::sync::Arc<crate::profile::Profile>>,
    /// Who the next minimisations are for (counted by role in `profile`).
    pub role: crate::profile::Role,
}

impl Workspace {
    /// Record-length f64 vectors a workspace may hold at its peak (the list above; checked by
    /// `tests/memory.rs`): the budget of one worker, [`Workspace::bytes`].
    pub const RECORD_VECTORS: usize = 24;

    /// The bytes a workspace is budgeted for on a record of `rows` samples (the sweep's cap on
    /// live workspaces, `sweep::live_workspaces`).
    pub const fn bytes(rows: usize) -> usize {
        Self::RECORD_VECTORS * std::mem::size_of::<f64>() * rows
    }

    pub fn new() -> Self {
        Self::default()
    }

    /// A workspace whose fits count into `profile`.
    pub fn profiled(profile: Option<std::sync::Arc<crate::profile::Profile>>) -> Self {
        Workspace { profile, ..Self::default() }
    }

    /// The run's profile, if any.
    pub fn profile(&self) -> Option<&crate::profile::Profile> {
        self.profile.as_deref()
    }

    /// Sizes the solver's buffers for `m` inputs of `n` samples and `d` parameters: `xu`,
    /// `xy` and their trial copies hold every input's signal (m x N).
    pub(super) fn prepare(&mut self, n: usize, m: usize, d: usize) {
        for v in [&mut self.yhat, &mut self.trial_yhat, &mut self.r, &mut self.w] {
            v.resize(n, 0.0);
        }
        for v in [&mut self.xu, &mut self.trial_xu, &mut self.xy, &mut self.trial_xy] {
            v.resize(m * n, 0.0);
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

    /// Makes `theta` the workspace's solution as the solver's own fused pass leaves it
    /// ([`Problem::simulate_filtered`], offset added): the same bits as the buffers of a
    /// minimisation (Levenberg-Marquardt) that ended at `theta`, so a fit judged after other
    /// fits ran is judged exactly as one judged straight away ([`super::fit::judged`]).
    pub(crate) fn solver_state(&mut self, prob: &Problem, theta: &[f64]) {
        let n = prob.n();
        self.yhat.resize(n, 0.0);
        for v in [&mut self.xu, &mut self.xy] {
            v.resize(prob.m() * n, 0.0);
        }
        prob.simulate_filtered(theta, &mut self.xu, &mut self.yhat, &mut self.xy);
        super::problem::add_offset(&mut self.yhat, prob.offset_of(theta));
    }

    /// Makes `theta` the workspace's solution: its output ([`Problem::simulate`]) and the
    /// Jacobian signals `xu`, `xy` (for another solution than the last minimisation's).
    pub(crate) fn resimulate(&mut self, prob: &Problem, theta: &[f64]) {
        let n = prob.n();
        self.yhat.resize(n, 0.0);
        for v in [&mut self.xu, &mut self.xy] {
            v.resize(prob.m() * n, 0.0);
        }
        if prob.m() > 1 {
            self.solver_state(prob, theta);
            return;
        }
        prob.simulate(theta, &mut self.yhat);
        self.xu.copy_from_slice(prob.u);
        prob.inv_f(prob.split(theta).1, &mut self.xu);
        output_filtered(prob, theta, &self.yhat, &mut self.xy);
    }
}
