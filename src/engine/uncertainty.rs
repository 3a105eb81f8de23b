//! The uncertainty of the watched picks (the lead rule's and the paper's, those
//! `reduce::doubts` watches): the doubt about their standard deviations (METHOD.md 17.2), a
//! warning when a pick's criterion is far from quadratic over its confidence region
//! ([`estimate::quadratic`]), where the sandwich covariance does not describe the uncertainty
//! (`reduce::doubts` says it of a pick on the stability boundary); the record's
//! integrating-plant test judged against them ([`integrating_doubts`], METHOD.md 7.3); and, when
//! the job asks (`"uncertainty": "bootstrap"`), the bootstrap of their whole estimation
//! (METHOD.md 17.3).

use crate::estimate::least_squares::BOUNDARY;
use crate::estimate::{self, Problem};
use crate::job::{Inputs, Uncertainty};
use crate::reduce::{PickBootstrap, Rule, Selection};
use crate::table::{CellRow, PerInput};
use rayon::prelude::*;
use std::collections::BTreeMap;

/// What the warnings advise instead of the local standard deviations.
pub const REMEDY: &str = "a bootstrap that includes the search: `\"uncertainty\": \"bootstrap\"` in the job, or `oesweep fit` of this model with `--bootstrap 200`";

/// The same advice when the job's bootstrap ran.
const REMEDY_DONE: &str = "the bootstrap's intervals of this model (selection.json `bootstrap`)";

/// A picked cell: (delay, nB, nF, k index) of the first input, then the other inputs' orders
/// (the order of one input's cells as before).
type Cell = (u32, u32, u32, Option<u32>, crate::table::More);

/// The models picked by a watched rule, each with the rules that picked it, in a fixed order.
fn watched_models(sel: &Selection) -> Vec<(Vec<Rule>, &CellRow)> {
    let mut models: BTreeMap<Cell, (Vec<Rule>, &CellRow)> = BTreeMap::new();
    let watched = |r: &Rule| *r == sel.rule || matches!(r, Rule::PaperM1 | Rule::PaperM2);
    for (rule, pick) in sel.picks.iter().filter(|(r, _)| watched(r)) {
        if let Some(m) = &pick.model {
            let key = cell(&m.row);
            models.entry(key).or_insert((Vec::new(), &m.row)).0.push(*rule);
        }
    }
    models.into_values().collect()
}

/// What the picks' uncertainty needs of each model it looks at (the watched models, M1 and
/// M2), computed once per model: its covariance (for the quadratic check, the pick's
/// `covariance` and the bootstrap's sandwich std alike) and, for a watched model inside the
/// stability boundary, the check of METHOD.md 17.2.
pub struct PickModels {
    models: BTreeMap<Cell, (Option<Vec<f64>>, Option<estimate::quadratic::QuadraticCheck>)>,
}

impl PickModels {
    /// The models of `sel` on the job's estimation record, side by side on the current rayon
    /// pool (each model's numbers do not depend on it).
    pub fn of(sel: &Selection, inputs: &Inputs) -> PickModels {
        let mut rows: BTreeMap<Cell, (&CellRow, bool)> = BTreeMap::new();
        for (_, row) in watched_models(sel) {
            rows.insert(cell(row), (row, true));
        }
        for pick in [sel.m1.as_ref(), sel.m2.as_ref()].into_iter().flatten() {
            rows.entry(cell(&pick.model)).or_insert((&pick.model.row, false));
        }
        let rows: Vec<(Cell, &CellRow, bool)> = rows.into_iter().map(|(c, (row, watched))| (c, row, watched)).collect();
        let models = rows
            .into_par_iter()
            .map(|(c, row, watched)| {
                let cov = covariance_of(row, inputs);
                let inside = row.fit.max_pole_radius.unwrap_or(0.0) < BOUNDARY;
                let check = cov.as_ref().filter(|_| watched && inside).map(|cov| {
                    let prob = problem(row, inputs);
                    let theta = theta(row, inputs);
                    estimate::quadratic::check(&prob, &theta, loss(row), cov)
                });
                (c, (cov, check))
            })
            .collect();
        PickModels { models }
    }

    /// The covariance of a model of [`PickModels::of`]'s selection (computed if it was not).
    pub fn covariance(&self, row: &CellRow, inputs: &Inputs) -> Option<Vec<f64>> {
        match self.models.get(&cell(row)) {
            Some((cov, _)) => cov.clone(),
            None => covariance_of(row, inputs),
        }
    }

    fn check(&self, row: &CellRow, inputs: &Inputs) -> Option<estimate::quadratic::QuadraticCheck> {
        match self.models.get(&cell(row)) {
            Some((_, check)) => check.clone(),
            None => quadratic_check(row, inputs),
        }
    }
}

fn cell(row: &CellRow) -> Cell {
    (row.key.delay, row.key.nb, row.key.nf, row.key.k_index, row.key.more)
}

/// The row's parameters as the solver takes them (any number of inputs).
fn theta(row: &CellRow, inputs: &Inputs) -> Vec<f64> {
    estimate::theta_in(&row.key.structure(), &row.fit.b, &row.fit.f, inputs.levels.estimated_c(row.fit.offset))
}

/// The warnings, one per watched model; `bootstrapped`: the job's bootstrap ran (the remedy
/// then points to its intervals).
pub fn pick_doubts(sel: &Selection, models: &PickModels, inputs: &Inputs, bootstrapped: bool) -> Vec<String> {
    watched_models(sel)
        .into_iter()
        .filter_map(|(rules, row)| {
            let names = rules.iter().map(|r| r.as_str()).collect::<Vec<_>>().join(", ");
            let k = row.k.map_or("least squares".to_string(), |k| format!("k = {}", crate::text::k(k)));
            let model = format!("{} {k} (picked by {names})", row.key.label());
            let radius = row.fit.max_pole_radius.unwrap_or(0.0);
            // A boundary pick has its warning, with this doubt, from `reduce::doubts`.
            if radius >= BOUNDARY {
                return None;
            }
            let check = models.check(row, inputs);
            estimate::quadratic::doubt(&model, radius, check.as_ref(), if bootstrapped { REMEDY_DONE } else { REMEDY })
        })
        .collect()
}

/// The integrating-plant test of the estimation record, each input's, judged against the
/// watched picks (METHOD.md 7.3, 19): its warning, or the drift of the picks' residuals, or
/// nothing when the stable picks explain the record. Their residuals are looked at only when a
/// test fired (once per model).
pub fn integrating_doubts(sel: &Selection, inputs: &Inputs) -> Vec<String> {
    use estimate::integrating::{self, Judged};
    if !inputs.pole_tests.iter().flatten().any(|t| t.integrating) {
        return Vec::new();
    }
    let models = watched_models(sel);
    let drifts: Vec<std::cell::OnceCell<f64>> = models.iter().map(|_| std::cell::OnceCell::new()).collect();
    let record = inputs.est.path.display().to_string();
    integrating::doubts(&inputs.pole_tests, &inputs.est.u_names, &record, |i| {
        models
            .iter()
            .zip(&drifts)
            .map(|((rules, row), drift)| {
                let names = rules.iter().map(|r| r.as_str()).collect::<Vec<_>>().join(", ");
                let name = format!("{} (picked by {names})", row.key.label());
                let theta = theta(row, inputs);
                let radius = match row.key.m() {
                    1 => row.fit.max_pole_radius.unwrap_or(0.0),
                    _ => integrating::input_radius(&row.key.structure(), &theta, i),
                };
                let drift = integrating::judged_by_residuals(radius)
                    .then(|| *drift.get_or_init(|| integrating::residual_drift(&problem(row, inputs), &theta)));
                Judged { name, radius, drift }
            })
            .collect()
    })
}

/// The bootstrap of every watched model's whole estimation on the job's estimation record
/// (METHOD.md 17.3), replicates in parallel on the current rayon pool: the parameters'
/// intervals (theta's order, every input's b_i, f_i) and each input's response intervals.
pub fn bootstrap_picks(
    sel: &Selection,
    models: &PickModels,
    inputs: &Inputs,
    settings: &Uncertainty,
    solver: &estimate::SolverOptions,
    ts: f64,
) -> Vec<PickBootstrap> {
    let boot =
        estimate::bootstrap::Settings { replicates: settings.replicates, seed: settings.seed, ..Default::default() };
    watched_models(sel)
        .into_iter()
        .map(|(rules, row)| {
            let prob = problem(row, inputs);
            let theta = theta(row, inputs);
            let sandwich = models.covariance(row, inputs);
            let dim = theta.len();
            let sandwich_std =
                (0..dim).map(|i| sandwich.as_ref().map(|cov| cov[i * dim + i].max(0.0).sqrt())).collect();
            PickBootstrap {
                rules,
                nb: PerInput::of(&row.key, |o| o.nb),
                nf: PerInput::of(&row.key, |o| o.nf),
                delay: PerInput::of(&row.key, |o| o.delay),
                k: row.k,
                parameters: crate::export::model::structure_parameter_names(&prob.structure, prob.offset),
                values: theta.clone(),
                sandwich_std,
                ts,
                intervals: estimate::bootstrap::run(&prob, &theta, row.k, &boot, solver),
            }
        })
        .collect()
}

/// The check of METHOD.md 17.2 of a row on the job's estimation record (None: no covariance).
pub fn quadratic_check(row: &CellRow, inputs: &Inputs) -> Option<estimate::quadratic::QuadraticCheck> {
    let cov = covariance_of(row, inputs)?;
    let prob = problem(row, inputs);
    let theta = theta(row, inputs);
    Some(estimate::quadratic::check(&prob, &theta, loss(row), &cov))
}

/// The row's model structure on the job's estimation record, as the run fitted it.
pub(super) fn problem<'a>(row: &CellRow, inputs: &'a Inputs) -> Problem<'a> {
    Problem {
        u: &inputs.est.u,
        y: &inputs.est.y,
        structure: row.key.structure(),
        offset: inputs.levels.mode.estimated(),
        seams: &inputs.est.seams,
        missing: &inputs.est.missing,
    }
}

/// The loss the row was fitted with.
pub(super) fn loss(row: &CellRow) -> estimate::Loss {
    row.fit.gamma.map_or(estimate::Loss::LeastSquares, |gamma| estimate::Loss::Huber { gamma })
}

/// The covariance of a row's parameters `[b, f(, c)]` on the estimation record (None when its
/// Gram matrix is singular): the model as the run fitted it, levels taken out and the offset a
/// parameter when the job estimated it; robust for a Huber row (METHOD.md 10).
pub(super) fn covariance_of(c: &CellRow, inputs: &Inputs) -> Option<Vec<f64>> {
    let prob = problem(c, inputs);
    let theta = theta(c, inputs);
    let yhat = prob.simulate_vec(&theta);
    estimate::evidence::covariance(&prob, &theta, loss(c), &yhat)
}
