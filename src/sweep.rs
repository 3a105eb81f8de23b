//! Running a plan: rayon workers estimate the cells; the module that knows about the worker pool.
//!
//! Two stages. (1) The least-squares phase (initial guess, L2 fit, sigma) of every order pair,
//! in parallel over pairs. (2) The Huber cells: with the `ls` start every cell is independent
//! and runs in parallel over cells; with `neighbour`/`best` the k values of a pair form a
//! continuation chain (largest k first) and run in parallel over pairs. Each task is
//! sequential and deterministic, so the table does not depend on the thread count. One
//! [`Workspace`] per worker (`map_init`). A panic inside a fit is caught and becomes a failed
//! row; the sweep goes on.
//!
//! Resuming ([`Control`]): rows finished by an earlier run of the same job are not computed
//! again. A finished `ls` row *is* the pair's least-squares fit for the Huber phase: sigma and
//! theta_LS = b ++ f are read from the row, and a pair fitted in this run goes through the same
//! row-based path, so a resumed cell starts from the same bits as in an uninterrupted run. A
//! continuation chain walks over its finished cells taking each one's (b, f) as the next start,
//! exactly as the run that computed them did, and continues from the last one. Every row
//! finished in this run is handed to [`Control::on_row`] (the checkpoint writer) at once, and
//! the workers look at [`Control::stop`] before each cell, so an interrupt stops handing out
//! work while running cells finish.

use crate::data::Record;
use crate::estimate::{self, Judge, Problem, SolverOptions, Workspace};
use crate::job::StartStrategy;
use crate::plan::{Cell, Plan};
use crate::progress::Progress;
use crate::spectral::SpectralEstimate;
use crate::table::{CellRow, Method};
use rayon::prelude::*;
use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Everything a cell needs besides its orders and k.
pub struct Context<'a> {
    pub est: &'a Record,
    pub val: Option<&'a Record>,
    pub band: Option<(&'a SpectralEstimate, &'a [usize])>,
    pub solver: SolverOptions,
}

impl Context<'_> {
    fn judge(&self) -> Judge<'_> {
        Judge { validation: self.val.map(|v| (&v.u[..], &v.y[..])), band: self.band }
    }
}

fn panic_message(e: Box<dyn std::any::Any + Send>) -> String {
    if let Some(s) = e.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = e.downcast_ref::<String>() {
        s.clone()
    } else {
        "unknown panic".to_string()
    }
}

/// Identity of a row in a table: (is a Huber row, nb, nf, k_index). A complete table has
/// exactly one row per key of its plan.
pub type RowKey = (bool, u32, u32, Option<u32>);

pub fn row_key(r: &CellRow) -> RowKey {
    (r.method == Method::Huber, r.nb, r.nf, r.k_index)
}

/// Sort rows as in `cells.parquet`: `ls` rows first, then by nb, nf, k_index.
pub fn sort_rows(rows: &mut [CellRow]) {
    rows.sort_by_key(row_key);
}

/// How a sweep continues an earlier run and reports to a checkpoint.
pub struct Control<'a> {
    /// Rows finished by an earlier run of the same job (one per key; rows of keys seen before
    /// are ignored). Their cells are not computed again and they are part of the outcome.
    pub done: Vec<CellRow>,
    /// Called from the worker threads with every row finished in this run, as soon as it is.
    pub on_row: &'a (dyn Fn(&CellRow) + Sync),
    /// Once true, no further cell is started; running cells finish.
    pub stop: &'a AtomicBool,
}

static NEVER: AtomicBool = AtomicBool::new(false);

fn ignore(_: &CellRow) {}

impl Control<'static> {
    /// A run from scratch that is never stopped and reports nowhere.
    pub fn none() -> Self {
        Control { done: Vec::new(), on_row: &ignore, stop: &NEVER }
    }
}

/// Result of a sweep: rows sorted by (method, nb, nf, k_index), `ls` rows first.
pub struct Outcome {
    /// Rows of earlier runs and of this one.
    pub rows: Vec<CellRow>,
    /// Wall time of this run.
    pub seconds: f64,
    /// Huber cells taken from earlier runs.
    pub resumed: usize,
    /// Huber cells computed in this run.
    pub computed: usize,
    /// True when the sweep stopped before every cell had a row.
    pub interrupted: bool,
}

impl Outcome {
    pub fn failed_cells(&self) -> usize {
        self.rows.iter().filter(|r| r.method == Method::Huber && !r.ok()).count()
    }
}

/// Run the cells of `plan` that `control.done` does not hold, on `threads` workers
/// (0 = all cores).
pub fn run(plan: &Plan, ctx: &Context, threads: usize, progress: &Progress, control: Control) -> Outcome {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    let t0 = Instant::now();
    let mut done: HashMap<RowKey, CellRow> = HashMap::with_capacity(control.done.len());
    for row in control.done {
        done.entry(row_key(&row)).or_insert(row);
    }
    let resumed = done.values().filter(|r| r.method == Method::Huber).count();
    let new_rows = pool.install(|| run_in_pool(plan, ctx, progress, &done, control.on_row, control.stop));
    let computed = new_rows.iter().filter(|r| r.method == Method::Huber).count();
    let mut rows: Vec<CellRow> = done.into_values().chain(new_rows).collect();
    sort_rows(&mut rows);
    let interrupted = rows.len() < plan.pairs.len() + plan.n_cells();
    Outcome { rows, seconds: t0.elapsed().as_secs_f64(), resumed, computed, interrupted }
}

/// What the Huber cells of a pair take from its least-squares phase: the `ls` row, and sigma
/// and theta_LS read from it when the fit is usable.
struct PairLs {
    row: CellRow,
    start: Option<(f64, Vec<f64>)>,
    /// Further Huber starts ([`estimate::LsFit::alternatives`]).
    alternatives: Vec<Vec<f64>>,
}

impl PairLs {
    fn from_row(row: CellRow, alternatives: Vec<Vec<f64>>) -> Self {
        // `CellRow::from_ls` marks a fit ok exactly when `LsFit::ok` holds (finite sigma, not
        // non_finite), so this is the fresh run's condition too.
        let start = match (row.ok(), row.sigma) {
            (true, Some(sigma)) => Some((sigma, [&row.b[..], &row.f[..]].concat())),
            _ => None,
        };
        PairLs { row, start, alternatives }
    }
}

/// Parameters a finished Huber row hands to the next cell of its chain (none if it failed).
fn chain_theta(row: &CellRow) -> Option<Vec<f64>> {
    row.ok().then(|| [&row.b[..], &row.f[..]].concat())
}

fn run_in_pool(
    plan: &Plan,
    ctx: &Context,
    progress: &Progress,
    done: &HashMap<RowKey, CellRow>,
    on_row: &(dyn Fn(&CellRow) + Sync),
    stop: &AtomicBool,
) -> Vec<CellRow> {
    let judge = ctx.judge();
    let delay = plan.delay;
    let stopped = || stop.load(Ordering::Relaxed);
    let huber_key = |cell: Cell| {
        let pair = plan.pairs[cell.pair];
        (true, pair.nb as u32, pair.nf as u32, Some(cell.k_index as u32))
    };
    progress.message("least-squares phase");
    // The least-squares phase of one pair: (the pair's fit, whether it was computed in this
    // run); None: stopped before it.
    let pair_ls = |pair: &crate::plan::Pair, p: usize, ws: &mut Workspace| -> Option<(PairLs, bool)> {
        let resumed = done.get(&(false, pair.nb as u32, pair.nf as u32, None));
        let all_done = (0..plan.ks.len()).all(|k| done.contains_key(&huber_key(Cell { pair: p, k_index: k })));
        if let (Some(row), true) = (resumed, all_done) {
            return Some((PairLs::from_row(row.clone(), Vec::new()), false));
        }
        if stopped() {
            return None;
        }
        let prob = Problem { u: &ctx.est.u, y: &ctx.est.y, nb: pair.nb, nf: pair.nf, delay };
        let t = Instant::now();
        // A resumed pair with cells left is fitted again for its extra Huber starts: the
        // least-squares phase is deterministic, so this reproduces the interrupted run.
        let (row, alternatives) =
            match catch_unwind(AssertUnwindSafe(|| estimate::fit_ls(&prob, &judge, &ctx.solver, ws))) {
                Ok(fit) => (CellRow::from_ls(&fit, t.elapsed().as_secs_f64()), fit.alternatives),
                Err(e) => {
                    let reason = format!("least-squares phase panicked: {}", panic_message(e));
                    (CellRow::failed(Method::Ls, pair.nb, pair.nf, delay, None, reason), Vec::new())
                }
            };
        if let Some(row) = resumed {
            return Some((PairLs::from_row(row.clone(), alternatives), false));
        }
        on_row(&row);
        Some((PairLs::from_row(row, alternatives), true))
    };
    // Largest pairs first, one task each, so a phase ends on small pairs rather than on one
    // large pair while the other workers idle; the results go back into plan order.
    let by_cost = plan.pairs_by_cost();
    let mut ls: Vec<(usize, Option<(PairLs, bool)>)> = by_cost
        .par_iter()
        .with_max_len(1)
        .map_init(Workspace::new, |ws, &p| {
            let pair = &plan.pairs[p];
            (p, pair_ls(pair, p, ws))
        })
        .collect();
    ls.sort_by_key(|(p, _)| *p);
    let ls: Vec<Option<(PairLs, bool)>> = ls.into_iter().map(|(_, v)| v).collect();
    progress.message("Huber phase");

    let huber_rows: Vec<CellRow> = match plan.start {
        StartStrategy::Ls => plan
            .cells()
            .par_iter()
            .map_init(Workspace::new, |ws, &cell| {
                if done.contains_key(&huber_key(cell)) || stopped() {
                    return None;
                }
                // A pair without a fit here was skipped because of a stop.
                let (pair_ls, _) = ls[cell.pair].as_ref()?;
                let row = huber_cell(plan, ctx, &judge, pair_ls, cell, None, ws);
                on_row(&row);
                progress.inc(1);
                Some(row)
            })
            .flatten()
            .collect(),
        StartStrategy::Chains => {
            let order = plan.k_ascending();
            by_cost
                .par_iter()
                .with_max_len(1)
                .map_init(Workspace::new, |ws, &p| {
                    let Some((pair_ls, _)) = &ls[p] else { return Vec::new() };
                    let keys: Vec<bool> =
                        order.iter().map(|&ki| done.contains_key(&huber_key(Cell { pair: p, k_index: ki }))).collect();
                    if keys.iter().all(|&d| d) {
                        return Vec::new();
                    }
                    chain_cells(plan, ctx, &judge, pair_ls, p, &order, &keys, ws, &stopped, on_row, progress)
                })
                .flatten()
                .collect()
        }
        StartStrategy::Neighbour | StartStrategy::Best => {
            let chain = plan.k_chain();
            (0..plan.pairs.len())
                .into_par_iter()
                .map_init(Workspace::new, |ws, p| {
                    let mut out = Vec::new();
                    let Some((pair_ls, _)) = &ls[p] else { return out };
                    let mut prev: Option<Vec<f64>> = None;
                    for &ki in &chain {
                        let cell = Cell { pair: p, k_index: ki };
                        let row = match done.get(&huber_key(cell)) {
                            Some(row) => {
                                prev = chain_theta(row).or(prev);
                                continue;
                            }
                            None if stopped() => break,
                            None => huber_cell(plan, ctx, &judge, pair_ls, cell, prev.as_deref(), ws),
                        };
                        // From the row, like a resumed chain: one path, the same bits.
                        prev = chain_theta(&row).or(prev);
                        on_row(&row);
                        progress.inc(1);
                        out.push(row);
                    }
                    out
                })
                .flatten()
                .collect()
        }
    };
    let mut rows: Vec<CellRow> = ls.into_iter().flatten().filter(|(_, fresh)| *fresh).map(|(p, _)| p.row).collect();
    rows.extend(huber_rows);
    rows
}

/// The Huber cells of pair `p` under the `chains` strategy, in increasing k (`order`). The
/// chains carry state from cell to cell that the rows do not hold, so a pair with unfinished
/// cells is walked again from its first cell: the walk is deterministic, so the cells an
/// earlier run finished (`done[i]` for `order[i]`) come out bit for bit the same and are not
/// reported again. Each cell is guarded on its own: a panic becomes that cell's failed row
/// and the chains go on from their last points.
#[allow(clippy::too_many_arguments)]
fn chain_cells(
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
    let delay = plan.delay;
    let mut out = Vec::new();
    let failed = |ki: usize, reason: String| {
        CellRow::failed(Method::Huber, pair.nb, pair.nf, delay, Some((ki, plan.ks[ki])), reason)
    };
    let Some((sigma, theta_ls)) = &ls.start else {
        for (&ki, _) in order.iter().zip(done).filter(|(_, d)| !**d) {
            let reason = ls.row.reason.as_deref().unwrap_or("it failed");
            let row = failed(ki, format!("no least-squares fit for this order pair: {reason}"));
            on_row(&row);
            progress.inc(1);
            out.push(row);
        }
        return out;
    };
    let prob = Problem { u: &ctx.est.u, y: &ctx.est.y, nb: pair.nb, nf: pair.nf, delay };
    let mut chains = estimate::Chains::new(theta_ls, &ls.alternatives);
    // The up walk, then the backward pass over the whole pair (`ChainWalk`), which may still
    // change any cell: a pair's rows are final, and handed out, only when both are done. A
    // stop in between drops the pair's new rows (at most one pair per worker is redone).
    let mut walk = estimate::ChainWalk::default();
    let mut seconds = Vec::with_capacity(order.len());
    let mut panics: Vec<Option<String>> = Vec::with_capacity(order.len());
    for (&ki, &was_done) in order.iter().zip(done) {
        if !was_done && stopped() {
            return out;
        }
        let k = plan.ks[ki];
        let t = Instant::now();
        let run = catch_unwind(AssertUnwindSafe(|| {
            crate::failpoint::before_cell(pair.nb, pair.nf, ki);
            chains.step(&prob, *sigma, k, judge, &ctx.solver, ws)
        }));
        seconds.push(t.elapsed().as_secs_f64());
        match run {
            Ok(cell) => {
                walk.cells.push(Some(cell));
                panics.push(None);
            }
            Err(e) => {
                walk.cells.push(None);
                panics.push(Some(format!("Huber fit panicked: {}", panic_message(e))));
            }
        }
    }
    let ks: Vec<f64> = order.iter().map(|&ki| plan.ks[ki]).collect();
    // The pass replaces a cell only by a complete, lower fit, so after a panic in it every cell
    // is still a valid fit (of the up walk or of the pass).
    let extra = catch_unwind(AssertUnwindSafe(|| walk.walk_back(&prob, *sigma, &ks, judge, &ctx.solver, ws)))
        .unwrap_or_else(|_| vec![0.0; order.len()]);
    for (i, (&ki, &was_done)) in order.iter().zip(done).enumerate() {
        if was_done {
            continue;
        }
        let row = match (&walk.cells[i], &panics[i]) {
            (Some((fit, which)), _) => CellRow::from_huber_of_pair(
                fit,
                (pair.nb, pair.nf, delay),
                *sigma,
                ki,
                match *which {
                    0 => "chain_ls",
                    estimate::ChainWalk::BACK => "chain_back",
                    _ => "chain_alt",
                },
                seconds[i] + extra[i],
            ),
            (None, reason) => failed(ki, reason.clone().unwrap_or_else(|| "Huber fit panicked".into())),
        };
        on_row(&row);
        progress.inc(1);
        out.push(row);
    }
    out
}

/// One Huber cell of the pair whose least-squares phase is `ls`, started from theta_LS and/or
/// `neighbour` as the plan's start strategy says.
fn huber_cell(
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
    let failed =
        |reason: String| CellRow::failed(Method::Huber, pair.nb, pair.nf, plan.delay, Some((cell.k_index, k)), reason);
    let Some((sigma, theta_ls)) = &ls.start else {
        return failed(format!(
            "no least-squares fit for this order pair: {}",
            ls.row.reason.as_deref().unwrap_or("it failed")
        ));
    };
    let prob = Problem { u: &ctx.est.u, y: &ctx.est.y, nb: pair.nb, nf: pair.nf, delay: plan.delay };
    let t = Instant::now();
    let run = catch_unwind(AssertUnwindSafe(|| {
        crate::failpoint::before_cell(pair.nb, pair.nf, cell.k_index);
        // theta_LS, then the pair's extra starts; the lowest criterion wins, ties the earlier.
        let from_ls = |ws: &mut Workspace| {
            let (fit, which) =
                estimate::fit_huber_starts(&prob, *sigma, k, theta_ls, &ls.alternatives, judge, &ctx.solver, ws);
            (fit, if which == 0 { "ls" } else { "ls_alt" })
        };
        // The neighbour's solution is a warm start (the minimum at the next k).
        let warm = SolverOptions { lambda0: ctx.solver.warm_lambda0, ..ctx.solver.clone() };
        let fit_from =
            |start: &[f64], ws: &mut Workspace| estimate::fit_huber(&prob, *sigma, k, start, judge, &warm, ws);
        match (plan.start, neighbour) {
            (StartStrategy::Ls | StartStrategy::Chains, _) | (_, None) => from_ls(ws),
            (StartStrategy::Neighbour, Some(nb)) => (fit_from(nb, ws), "neighbour"),
            (StartStrategy::Best, Some(nb)) => {
                let a = from_ls(ws);
                let b = fit_from(nb, ws);
                // Ties keep the least-squares start.
                if b.criterion < a.0.criterion { (b, "neighbour") } else { a }
            }
        }
    }));
    match run {
        Ok((fit, start)) => CellRow::from_huber_of_pair(
            &fit,
            (pair.nb, pair.nf, plan.delay),
            *sigma,
            cell.k_index,
            start,
            t.elapsed().as_secs_f64(),
        ),
        Err(e) => failed(format!("Huber fit panicked: {}", panic_message(e))),
    }
}
