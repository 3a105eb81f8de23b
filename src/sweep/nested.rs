//! The nested check (METHOD.md 5.6): no Huber cell is left above a sub-model's cell at the
//! same k.
//!
//! OE(nB - 1, nF) and OE(nB, nF - 1) are OE(nB, nF) with one coefficient zero, so the
//! sub-model's solution embedded ([`crate::plan::embed`]) is a point of the larger model with the
//! same criterion W at the same gamma... when both share sigma, which they do not: gamma = k
//! sigma of each pair's own least-squares fit. The embedded point is therefore only a start:
//! where a sub-model's cell has the lower W, the cell is refitted warm from it and keeps the
//! refit when that is lower (start `nested`). A cell is checked after its sub-models' cells at
//! the same k, so that a refitted sub-model hands its new solution on: in a whole run as a task
//! of the sweep's graph per cell ([`check_cell`], after the pair's Huber walk and the
//! sub-models' checks), in a merge of shards by [`nested_pass`] in waves of increasing nB + nF.
//! A check reads only the walks' rows and the sub-models' final rows, so its result does not
//! depend on the thread count, the order, the shard split or a resume.
//!
//! Why: the chains of each pair walk on their own, and on over-parameterised pairs they settle
//! in basins that a smaller model's walk beats: on the paper grid 289 of 3840 cells were above
//! a sub-model's W at the same k by more than a relative 1e-6 (74 by more than 1e-4), 59 of the
//! demo job's 540. With the pass none are above by more than the solver's tolerance; against the
//! scipy peer's whole grid (`benches/compare_table.py`) the bundled record's cells no worse at a
//! relative 1e-6 went from 3672 to 3745 of 3840, for 353 warm fits (+3 % iterations).

use super::{Context, Workspaces};
use crate::error::Result;
use crate::estimate::{self, Judge, StartKind};
use crate::plan::Plan;
use crate::profile::Role;
use crate::table::{CellRow, RowKey};
use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

/// A sub-model's cell counts as lower when its W is below the cell's by more than this
/// (relative): below, the two are the same minimum to the solver's precision
/// ([`estimate::Chains::MERGE`]).
const LOWER: f64 = estimate::Chains::MERGE;

/// The check of one Huber cell (METHOD.md 5.6), the rule both the sweep's task
/// ([`super::graph::Task::Nested`]) and the waves of [`nested_pass`] run: when a sub-model's
/// cell at the same k (`sub` gives a key's final row, when the table has it) has a lower W, the
/// cell is refitted warm from that sub-model's solution (on a workspace of `workspaces`).
/// Returns the refit when it came out lower. It reads only the cell's row and its sub-models'
/// final rows, so the result does not depend on when it runs.
pub(super) fn check_cell<'r>(
    plan: &Plan,
    ctx: &Context,
    judge: &Judge,
    workspaces: &Workspaces,
    row: &CellRow,
    sub: &dyn Fn(RowKey) -> Option<&'r CellRow>,
) -> Option<CellRow> {
    let w = row.fit.criterion.filter(|w| row.ok() && w.is_finite())?;
    let sigma = row.fit.sigma?;
    let key = row.key;
    let pair = key.structure();
    let sub = crate::plan::sub_structures(&pair)
        .iter()
        .map(|s| RowKey::new(key.kind, s, key.k_index))
        .filter_map(sub)
        // Rows read back from a checkpoint fit their orders: the reader refuses others
        // (`CellRow::shape_error`).
        .filter(|s| s.ok())
        .filter_map(|s| s.fit.criterion.filter(|v| *v < w * (1.0 - LOWER)).map(|v| (v, s)))
        // The lowest (ties: the first listed, input by input, nB before nF).
        .fold(None, |best: Option<(f64, &CellRow)>, (v, s)| match best {
            Some((b, _)) if b <= v => best,
            _ => Some((v, s)),
        })?
        .1;
    let k_index = key.k_index? as usize;
    let prob = ctx.problem(&pair);
    let warm = ctx.solver.huber_warm();
    let t = Instant::now();
    // A panic (in the numerics, or an edited row's parameters that do not embed) keeps the cell
    // as the walk left it.
    // Fitted for its criterion, judged only when it replaces the cell (most refits do not).
    let fit = catch_unwind(AssertUnwindSafe(|| {
        let start = crate::plan::embed(&ctx.theta(sub), &sub.key.structure(), &pair, prob.offset);
        workspaces.with(|ws| {
            ws.role = Role::Back;
            let criterion_only = Judge { criterion_only: true, ..Judge::default() };
            let fit = estimate::fit_huber(&prob, sigma, plan.ks[k_index], &start, &criterion_only, &warm, ws);
            (fit.criterion < w).then(|| estimate::judged(&prob, fit, judge, ws))
        })
    }))
    .ok()??;
    let seconds = row.fit.seconds + t.elapsed().as_secs_f64();
    Some(ctx.with_offset(CellRow::from_huber(&fit, &pair, sigma, k_index, StartKind::Nested, seconds)))
}

/// Refit every Huber cell of `rows` whose sub-model's cell at the same k has a lower W, warm from
/// that sub-model's solution ([`check_cell`]), in waves of nB + nF, the cells of a wave in
/// parallel on `threads` workers (0: all cores): the pass of a merge, whose rows come from
/// shards that each lacked sub-models (a whole run checks its cells as tasks of its graph).
/// Returns how many cells came out lower; an error, with `rows` untouched, when the system
/// refused the workers ([`crate::pool::local`]).
pub fn nested_pass(plan: &Plan, ctx: &Context, rows: &mut [CellRow], threads: usize) -> Result<usize> {
    let index: HashMap<RowKey, usize> = rows.iter().enumerate().map(|(i, r)| (r.key, i)).collect();
    let mut waves: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
    for (i, row) in rows.iter().enumerate().filter(|(_, r)| r.is_huber()) {
        waves.entry(row.parameters()).or_default().push(i);
    }
    let pool = crate::pool::local(threads, "for the nested check")?;
    let t0 = Instant::now();
    let judge = ctx.judge();
    let workspaces = Workspaces::new(ctx);
    let mut lowered = 0;
    for wave in waves.values() {
        let table = &*rows;
        let sub = |key: RowKey| index.get(&key).map(|&j| &table[j]);
        let refits: Vec<(usize, CellRow)> = pool.install(|| {
            wave.par_iter()
                .filter_map(|&i| check_cell(plan, ctx, &judge, &workspaces, &table[i], &sub).map(|row| (i, row)))
                .collect()
        });
        lowered += refits.len();
        for (i, row) in refits {
            rows[i] = row;
        }
    }
    // For `benches/replay.py` a serial part (its wall time on this run's threads): its waves
    // are not tasks of a graph, and a part counted as serial only lowers the bound.
    if let Some(p) = &ctx.profile {
        p.serial("nested", t0.elapsed().as_secs_f64());
    }
    Ok(lowered)
}

/// [`nested_pass`] of rows computed by the `kernels` flavour (a merge's, on all cores): run
/// only when this machine runs the same kernels, since refits on other kernels would mix two
/// flavours in one table (README's promise for shards across CPUs). Returns the warning that
/// says why it was not run, or the error of [`nested_pass`].
pub fn nested_pass_of_rows_from(
    kernels: &str,
    plan: &Plan,
    ctx: &Context,
    rows: &mut [CellRow],
) -> Result<Option<String>> {
    let here = crate::kernels::flavour().name();
    if kernels != here {
        return Ok(Some(format!(
            "the nested pass (METHOD.md 5.6) was not run: the rows were computed with the {kernels} kernels and \
             this machine runs the {here} kernels; merge on a machine of the rows' kind for the table a whole \
             run gives"
        )));
    }
    nested_pass(plan, ctx, rows, 0)?;
    Ok(None)
}
