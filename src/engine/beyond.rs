//! A look just beyond the grid's edge (METHOD.md 7.2): when RBIC's pick has the largest nB or
//! nF of the grid (several inputs: of an input's grid), the next larger model in that
//! direction (that input's order one up, the other inputs' as picked) is fitted once, and its
//! RBIC says whether the data want more than the grid offered.
//!
//! The larger model starts from the pick itself, embedded with a zero trailing coefficient
//! ([`crate::plan::embed`]): the same transfer function, so both fits can only go down from the
//! pick's criteria. The least-squares fit (from the pair's least-squares row) gives sigma and
//! gamma = k sigma as the sweep would for that pair; the Huber fit at the pick's k gives RBIC.
//! A larger model whose RBIC is above the pick's is the RBIC minimum's neighbour: widening the
//! grid in that direction would not change RBIC's answer.

use crate::estimate::{self, Judge, Problem, Workspace};
use crate::job::{Inputs, ValidJob};
use crate::oe::{Orders, Structure};
use crate::reduce::doubts::{Beyond, GridBounds};
use crate::table::{CellRow, FitKind};
use rayon::prelude::*;

/// The models one step beyond the grid's nB and nF edges that `pick` sits on, fitted warm from
/// it, with their RBIC (none when the pick is inside, or a fit fails), input by input in the
/// order nB, nF. `grids`: one input's bounds for every input, or each input's own; several
/// inputs grow the orders of the input on the edge, the others' held.
pub fn beyond_edges(
    pick: &CellRow,
    rows: &[CellRow],
    grids: &[GridBounds],
    inputs: &Inputs,
    job: &ValidJob,
) -> Vec<Beyond> {
    let s = pick.key.structure();
    let (Some(k), Some(ls)) =
        (pick.k, rows.iter().find(|r| r.key.kind == FitKind::Ls && r.key.structure() == s && r.ok()))
    else {
        return Vec::new();
    };
    let mut larger = Vec::new();
    for (i, &o) in s.inputs().iter().enumerate() {
        let g = if grids.len() == 1 { grids.first() } else { grids.get(i) };
        let Some(g) = g else { continue };
        if o.nb as u32 == g.nb.1 && g.nb.0 < g.nb.1 {
            larger.push(s.with(i, Orders { nb: o.nb + 1, ..o }));
        }
        if o.nf as u32 == g.nf.1 && g.nf.0 < g.nf.1 {
            larger.push(s.with(i, Orders { nf: o.nf + 1, ..o }));
        }
    }
    let judge = Judge { initial_state: job.job.initial_state, ..Judge::default() };
    let offset = inputs.levels.mode.estimated();
    let theta = |r: &CellRow| estimate::theta_in(&s, &r.fit.b, &r.fit.f, inputs.levels.estimated_c(r.fit.offset));
    // The larger models side by side on the current rayon pool, each with its own workspace
    // (a fit does not depend on what a workspace held before).
    larger
        .into_par_iter()
        .filter_map(|big: Structure| {
            let mut ws = Workspace::new();
            let prob = Problem {
                u: &inputs.est.u,
                y: &inputs.est.y,
                structure: big,
                offset,
                seams: &inputs.est.seams,
                missing: &inputs.est.missing,
            };
            if inputs.est.len() < crate::data::min_samples_of(&big) {
                return None;
            }
            let ls = estimate::fit_ls_from(
                &prob,
                &crate::plan::embed(&theta(ls), &s, &big, offset),
                &judge,
                &job.job.solver,
                &mut ws,
            );
            if !ls.ok() {
                return None;
            }
            let start = crate::plan::embed(&theta(pick), &s, &big, offset);
            let huber = estimate::fit_huber(&prob, ls.sigma, k, &start, &judge, &job.job.solver, &mut ws);
            let rbic = huber.criteria.rbic;
            rbic.is_finite().then_some(Beyond { structure: big, rbic })
        })
        .collect()
}
