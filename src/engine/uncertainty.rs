//! The doubt about the picks' standard deviations (METHOD.md 17.2): for the lead rule's and
//! the paper's picks (those `reduce::doubts` watches, which also says it of a pick on the
//! stability boundary), a warning when the pick's criterion is far from quadratic over its confidence region
//! ([`estimate::quadratic`]), where the sandwich covariance does not describe the uncertainty.

use super::covariance_of;
use crate::estimate::least_squares::BOUNDARY;
use crate::estimate::{self, Problem};
use crate::job::Inputs;
use crate::reduce::{Rule, Selection};
use crate::table::CellRow;
use std::collections::BTreeMap;

/// What the warnings advise instead of the local standard deviations.
pub const REMEDY: &str = "a bootstrap that includes the search: `oesweep fit` of this model with `--bootstrap 200`";

/// A picked cell: (delay, nB, nF, k index).
type Cell = (u32, u32, u32, Option<u32>);

/// The warnings, one per model (a cell: orders, delay and k) picked by a watched rule.
pub fn pick_doubts(sel: &Selection, inputs: &Inputs) -> Vec<String> {
    let mut models: BTreeMap<Cell, (Vec<Rule>, &CellRow)> = BTreeMap::new();
    let watched = |r: &Rule| *r == sel.rule || matches!(r, Rule::PaperM1 | Rule::PaperM2);
    for (rule, pick) in sel.picks.iter().filter(|(r, _)| watched(r)) {
        if let Some(m) = &pick.model {
            let key = (m.key.delay, m.key.nb, m.key.nf, m.key.k_index);
            models.entry(key).or_insert((Vec::new(), &m.row)).0.push(*rule);
        }
    }
    models
        .into_values()
        .filter_map(|(rules, row)| {
            let names = rules.iter().map(|r| r.as_str()).collect::<Vec<_>>().join(", ");
            let k =
                row.k.map_or("least squares".to_string(), |k| format!("k = {}", crate::report::plot::trimmed(k, 4)));
            let model = format!("OE({},{}) delay {} {k} (picked by {names})", row.key.nb, row.key.nf, row.key.delay);
            let radius = row.fit.max_pole_radius.unwrap_or(0.0);
            // A boundary pick has its warning, with this doubt, from `reduce::doubts`.
            if radius >= BOUNDARY {
                return None;
            }
            let check = quadratic_check(row, inputs);
            estimate::quadratic::doubt(&model, radius, check.as_ref(), REMEDY)
        })
        .collect()
}

/// The check of METHOD.md 17.2 of a row on the job's estimation record (None: no covariance).
pub fn quadratic_check(row: &CellRow, inputs: &Inputs) -> Option<estimate::quadratic::QuadraticCheck> {
    let cov = covariance_of(row, inputs)?;
    let prob = problem(row, inputs);
    let theta = estimate::theta_of(&row.fit.b, &row.fit.f, inputs.levels.estimated_c(row.fit.offset));
    Some(estimate::quadratic::check(&prob, &theta, loss(row), &cov))
}

/// The row's model structure on the job's estimation record, as the run fitted it.
pub(super) fn problem<'a>(row: &CellRow, inputs: &'a Inputs) -> Problem<'a> {
    Problem {
        u: &inputs.est.u,
        y: &inputs.est.y,
        nb: row.key.nb as usize,
        nf: row.key.nf as usize,
        delay: row.key.delay as usize,
        offset: inputs.levels.mode.estimated(),
        seams: &inputs.est.seams,
    }
}

/// The loss the row was fitted with.
pub(super) fn loss(row: &CellRow) -> estimate::Loss {
    row.fit.gamma.map_or(estimate::Loss::LeastSquares, |gamma| estimate::Loss::Huber { gamma })
}
