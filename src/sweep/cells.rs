//! The Huber cells of one pair or one cell, as the sweep's tasks run them: the `chains` walk of
//! a pair ([`chain_cells`]) and a cell from theta_LS and/or a neighbour ([`huber_cell`]).

use super::{Context, PairLs};
use crate::estimate::chains::{CellOutcome, PairProblem, panic_message, walk_pair};
use crate::estimate::{self, Judge, StartKind, Workspace};
use crate::job::StartStrategy;
use crate::plan::{Cell, Plan};
use crate::profile::{Phase, Role, Span};
use crate::progress::Progress;
use crate::table::{CellRow, RowKey};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

/// The Huber cells of pair `p` under the `chains` strategy, in increasing k (`order`), those
/// an earlier run finished (`done[i]` for `order[i]`) left out; empty when stopped mid-walk
/// (see [`walk_pair`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn chain_cells(
    plan: &Plan,
    ctx: &Context,
    judge: &Judge,
    ls: &PairLs,
    p: usize,
    order: &[usize],
    done: &[bool],
    ws: &mut Workspace,
    stopped: &dyn Fn() -> bool,
    on_row: &(dyn Fn(&CellRow) + Sync),
    progress: &Progress,
) -> Vec<CellRow> {
    let pair = plan.pairs[p];
    let failed = |ki: usize, reason: String| CellRow::failed(RowKey::huber(&pair, ki), Some(plan.ks[ki]), reason);
    let span = Span::start(ctx.profile.as_deref(), Phase::Huber);
    let rows: Vec<CellRow> = match &ls.start {
        None => {
            let reason = ls.row.reason.as_deref().unwrap_or("it failed");
            order
                .iter()
                .zip(done)
                .filter(|(_, d)| !**d)
                .map(|(&ki, _)| failed(ki, format!("no least-squares fit for this order pair: {reason}")))
                .collect()
        }
        Some((sigma, theta_ls)) => {
            let prob = ctx.problem(&pair);
            let problem = PairProblem { prob: &prob, sigma: *sigma, judge, opts: &ctx.solver };
            let ks: Vec<(usize, f64)> = order.iter().map(|&ki| (ki, plan.ks[ki])).collect();
            let Some(cells) = walk_pair(&problem, theta_ls, &ls.alternatives, &ks, done, stopped, ws) else {
                return Vec::new();
            };
            cells
                .into_iter()
                .map(|(ki, cell)| match cell {
                    CellOutcome::Fit { fit, start, seconds } => {
                        ctx.with_offset(CellRow::from_huber(&fit, &pair, *sigma, ki, start, seconds))
                    }
                    CellOutcome::Panicked(reason) => failed(ki, reason),
                })
                .collect()
        }
    };
    drop(span);
    for row in &rows {
        on_row(row);
        progress.inc(1);
    }
    rows
}

/// One Huber cell of the pair whose least-squares phase is `ls`, started from theta_LS and/or
/// `neighbour` as the plan's start strategy says.
pub(super) fn huber_cell(
    plan: &Plan,
    ctx: &Context,
    judge: &Judge,
    ls: &PairLs,
    cell: Cell,
    neighbour: Option<&[f64]>,
    ws: &mut Workspace,
) -> CellRow {
    let pair = plan.pairs[cell.pair];
    let k = plan.ks[cell.k_index];
    let failed = |reason: String| CellRow::failed(RowKey::huber(&pair, cell.k_index), Some(k), reason);
    let Some((sigma, theta_ls)) = &ls.start else {
        return failed(format!(
            "no least-squares fit for this order pair: {}",
            ls.row.reason.as_deref().unwrap_or("it failed")
        ));
    };
    let prob = ctx.problem(&pair);
    let t = Instant::now();
    let _span = Span::start(ctx.profile.as_deref(), Phase::Huber);
    ws.role = Role::Other;
    let run = catch_unwind(AssertUnwindSafe(|| {
        crate::failpoint::before_cell(pair.inputs()[0].nb, pair.inputs()[0].nf, cell.k_index);
        // theta_LS, then the pair's extra starts; the lowest criterion wins, ties the earlier.
        let from_ls = |ws: &mut Workspace| {
            let (fit, which) =
                estimate::fit_huber_starts(&prob, *sigma, k, theta_ls, &ls.alternatives, judge, &ctx.solver, ws);
            (fit, StartKind::Ls { start: which })
        };
        // The neighbour's solution is a warm start (the minimum at the next k).
        let warm = ctx.solver.huber_warm();
        let fit_from =
            |start: &[f64], ws: &mut Workspace| estimate::fit_huber(&prob, *sigma, k, start, judge, &warm, ws);
        // `neighbour` is None for `ls` and for the first cell of a `neighbour`/`best` chain.
        match neighbour {
            None => from_ls(ws),
            Some(nb) if plan.start == StartStrategy::Best => {
                let a = from_ls(ws);
                let b = fit_from(nb, ws);
                // Ties keep the least-squares start.
                if b.criterion < a.0.criterion { (b, StartKind::Neighbour) } else { a }
            }
            Some(nb) => (fit_from(nb, ws), StartKind::Neighbour),
        }
    }));
    match run {
        Ok((fit, start)) => {
            ctx.with_offset(CellRow::from_huber(&fit, &pair, *sigma, cell.k_index, start, t.elapsed().as_secs_f64()))
        }
        Err(e) => failed(format!("Huber fit panicked: {}", panic_message(e))),
    }
}
