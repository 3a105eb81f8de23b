//! A look just beyond the grid's edge (METHOD.md 7.2): when RBIC's pick has the largest nB or
//! nF of the grid, the next larger model in that direction is fitted once, and its RBIC says
//! whether the data want more than the grid offered.
//!
//! The larger model starts from the pick itself, embedded with a zero trailing coefficient
//! ([`estimate::embed`]): the same transfer function, so both fits can only go down from the
//! pick's criteria. The least-squares fit (from the pair's least-squares row) gives sigma and
//! gamma = k sigma as the sweep would for that pair; the Huber fit at the pick's k gives RBIC.
//! A larger model whose RBIC is above the pick's is the RBIC minimum's neighbour: widening the
//! grid in that direction would not change RBIC's answer.

use crate::estimate::{self, Judge, Problem, Workspace};
use crate::job::{Inputs, ValidJob};
use crate::oe::Structure;
use crate::reduce::doubts::{Beyond, GridBounds};
use crate::table::{CellRow, FitKind};
use rayon::prelude::*;

/// The models one step beyond the grid's nB and nF edges that `pick` sits on, fitted warm from
/// it, with their RBIC (none when the pick is inside, or a fit fails), in the order nB, nF.
pub fn beyond_edges(
    pick: &CellRow,
    rows: &[CellRow],
    grid: &GridBounds,
    inputs: &Inputs,
    job: &ValidJob,
) -> Vec<Beyond> {
    let (nb, nf, delay) = (pick.key.nb as usize, pick.key.nf as usize, pick.key.delay as usize);
    let (Some(k), Some(ls)) = (
        pick.k,
        rows.iter().find(|r| r.key.kind == FitKind::Ls && r.key.structure() == pick.key.structure() && r.ok()),
    ) else {
        return Vec::new();
    };
    let mut larger = Vec::new();
    if pick.key.nb == grid.nb.1 && grid.nb.0 < grid.nb.1 {
        larger.push((nb + 1, nf));
    }
    if pick.key.nf == grid.nf.1 && grid.nf.0 < grid.nf.1 {
        larger.push((nb, nf + 1));
    }
    let judge = Judge { initial_state: job.job.initial_state, ..Judge::default() };
    let offset = inputs.levels.mode.estimated();
    let theta = |r: &CellRow| estimate::theta_of(&r.fit.b, &r.fit.f, inputs.levels.estimated_c(r.fit.offset));
    // The larger models side by side on the current rayon pool, each with its own workspace
    // (a fit does not depend on what a workspace held before).
    larger
        .into_par_iter()
        .filter_map(|(b, f)| {
            let mut ws = Workspace::new();
            let prob = Problem {
                u: &inputs.est.u,
                y: &inputs.est.y,
                structure: Structure::siso(b, f, delay),
                offset,
                seams: &inputs.est.seams,
            };
            if inputs.est.u.len() < crate::data::min_samples(b, f, delay) {
                return None;
            }
            let ls = estimate::fit_ls_from(
                &prob,
                &estimate::embed(&theta(ls), nb, nf, &prob),
                &judge,
                &job.job.solver,
                &mut ws,
            );
            if !ls.ok() {
                return None;
            }
            let start = estimate::embed(&theta(pick), nb, nf, &prob);
            let huber = estimate::fit_huber(&prob, ls.sigma, k, &start, &judge, &job.job.solver, &mut ws);
            let rbic = huber.criteria.rbic;
            rbic.is_finite().then_some(Beyond { nb: b as u32, nf: f as u32, delay: delay as u32, rbic })
        })
        .collect()
}
