//! Running a plan: rayon workers estimate the cells; the module that knows about the worker pool.
//!
//! Two stages ([`run_in_pool`]). (1) The least-squares phase (initial guesses, L2 fits, sigma)
//! of every order pair, in parallel over pairs, largest first (`Sweep::least_squares_phase`).
//! (2) The Huber cells, as the plan's start strategy says: `chains` (the default) walks each
//! pair's k values in increasing order ([`estimate::chains::walk_pair`]) and runs in parallel
//! over pairs (`Sweep::k_chains`); `ls` makes every cell independent and runs in parallel over
//! cells (`Sweep::independent_cells`); `neighbour`/`best` walk each pair from the largest k
//! down, in parallel over pairs (`Sweep::neighbour_chains`). Each task is sequential and deterministic, so the
//! table does not depend on the thread count. One [`Workspace`] per worker ([`Workspaces`]). A
//! panic inside a fit is caught and becomes a failed row; the sweep goes on.
//!
//! Resuming ([`Control`]): rows finished by an earlier run of the same job are not computed
//! again. A finished `ls` row *is* the pair's least-squares fit for the Huber phase: sigma and
//! theta_LS = b ++ f are read from the row, and a pair fitted in this run goes through the same
//! row-based path, so a resumed cell starts from the same bits as in an uninterrupted run. A
//! `neighbour` chain walks over its finished cells taking each one's (b, f) as the next start,
//! exactly as the run that computed them did, and continues from the last one; a `chains` pair
//! with unfinished cells is walked again whole (its chains hold state the rows do not). Every
//! row finished in this run is handed to [`Control::on_row`] (the checkpoint writer) at once,
//! and the workers look at [`Control::stop`] before each cell, so an interrupt stops handing
//! out work while running cells finish.

use crate::data::{Levels, Record};
use crate::estimate::chains::{CellOutcome, PairProblem, panic_message, walk_pair};
use crate::estimate::{self, InitialState, Judge, Problem, SolverOptions, StartKind, Workspace};
use crate::job::StartStrategy;
use crate::plan::{Cell, Plan, Structure};
use crate::profile::{Phase, Profile, Role, Span};
use crate::progress::Progress;
use crate::spectral::SpectralEstimate;
use crate::table::{CellRow, RowKey, sort_rows};
use rayon::prelude::*;
use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Everything a cell needs besides its orders and k.
pub struct Context<'a> {
    /// The records with their levels taken out ([`Levels::apply`]).
    pub est: &'a Record,
    pub val: Option<&'a Record>,
    pub band: Option<(&'a SpectralEstimate, &'a [usize])>,
    pub solver: SolverOptions,
    /// The levels taken out of the records; `levels.mode` says whether the fits estimate an
    /// output offset.
    pub levels: Levels,
    pub initial_state: InitialState,
    /// The run's counters when it is profiled ([`crate::profile`]).
    pub profile: Option<Arc<Profile>>,
}

impl Context<'_> {
    fn judge(&self) -> Judge<'_> {
        Judge {
            validation: self.val.map(|v| (&v.u[..], &v.y[..])),
            validation_seams: self.val.map_or(&[][..], |v| &v.seams[..]),
            band: self.band,
            initial_state: self.initial_state,
            criterion_only: false,
        }
    }

    fn problem(&self, pair: &Structure) -> Problem<'_> {
        Problem {
            u: &self.est.u,
            y: &self.est.y,
            nb: pair.nb,
            nf: pair.nf,
            delay: pair.delay,
            offset: self.levels.mode.estimated(),
            seams: &self.est.seams,
        }
    }

    /// The parameters a row holds, as the solver takes them.
    fn theta(&self, row: &CellRow) -> Vec<f64> {
        estimate::theta_of(&row.fit.b, &row.fit.f, self.levels.estimated_c(row.fit.offset))
    }

    /// `row` with its `offset` in the data's units.
    fn with_offset(&self, mut row: CellRow) -> CellRow {
        row.fit.offset = self.levels.offset(row.fit.offset);
        row
    }
}

/// The workers' [`Workspace`]s, kept across tasks: a task takes one (made the first time, counting
/// into the run's profile) and gives it back, so there are as many as tasks ever ran at once.
/// rayon's `map_init` makes one per split, and with a task per pair that was a fresh workspace
/// per pair: its record-length buffers touched and zeroed anew each time (on a 131 072-sample
/// record, page faults and zeroing were 8 % of the run). A workspace's contents never reach a
/// result (every buffer is written before it is read), so which one a task gets does not matter.
struct Workspaces {
    profile: Option<Arc<Profile>>,
    free: Mutex<Vec<Workspace>>,
}

impl Workspaces {
    fn new(ctx: &Context) -> Self {
        Workspaces { profile: ctx.profile.clone(), free: Mutex::new(Vec::new()) }
    }

    /// `task` with a workspace of its own for its duration (one lost when the task panics).
    fn with<R>(&self, task: impl FnOnce(&mut Workspace) -> R) -> R {
        let taken = self.free.lock().unwrap_or_else(|e| e.into_inner()).pop();
        let mut ws = taken.unwrap_or_else(|| Workspace::profiled(self.profile.clone()));
        let out = task(&mut ws);
        self.free.lock().unwrap_or_else(|e| e.into_inner()).push(ws);
        out
    }
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
        crate::table::failed_cells(&self.rows)
    }
}

/// Most worker threads a run may ask for (`--threads`): more than any machine oesweep runs on
/// has cores, and each worker holds a workspace; `--threads 100000` made the process spend
/// minutes creating threads or abort when the system refused them.
pub const MAX_THREADS: usize = 1024;

/// Run the cells of `plan` that `control.done` does not hold, on `threads` workers
/// (0 = all cores; at most [`MAX_THREADS`], checked by the caller).
pub fn run(plan: &Plan, ctx: &Context, threads: usize, progress: &Progress, control: Control) -> Outcome {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    let t0 = Instant::now();
    let mut done: HashMap<RowKey, CellRow> = HashMap::with_capacity(control.done.len());
    for row in control.done {
        done.entry(row.key).or_insert(row);
    }
    let resumed = done.values().filter(|r| r.is_huber()).count();
    let new_rows = pool.install(|| run_in_pool(plan, ctx, progress, &done, control.on_row, control.stop));
    let computed = crate::table::huber_rows(&new_rows);
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
    fn from_row(ctx: &Context, row: CellRow, alternatives: Vec<Vec<f64>>) -> Self {
        // `CellRow::from_ls` marks a fit ok exactly when `LsFit::ok` holds (finite sigma, not
        // non_finite), so this is the fresh run's condition too.
        let start = match (row.ok(), row.fit.sigma) {
            (true, Some(sigma)) => Some((sigma, ctx.theta(&row))),
            _ => None,
        };
        PairLs { row, start, alternatives }
    }
}

/// Parameters a finished Huber row hands to the next cell of its chain (none if it failed).
fn chain_theta(ctx: &Context, row: &CellRow) -> Option<Vec<f64>> {
    row.ok().then(|| ctx.theta(row))
}

/// Per plan pair, what its least-squares phase gave (None: stopped before it) and whether its
/// `ls` row was computed in this run (else an earlier run's row was taken).
type LsPhase = Vec<Option<(PairLs, bool)>>;

/// One sweep's plan, context and bookkeeping, shared by its steps.
struct Sweep<'s> {
    plan: &'s Plan,
    ctx: &'s Context<'s>,
    judge: Judge<'s>,
    workspaces: Workspaces,
    progress: &'s Progress,
    /// Rows of earlier runs.
    done: &'s HashMap<RowKey, CellRow>,
    on_row: &'s (dyn Fn(&CellRow) + Sync),
    stop: &'s AtomicBool,
}

/// The sweep in the pool: the least-squares phase of every pair, then the Huber cells as the
/// start strategy says. Returns the rows computed in this run.
fn run_in_pool<'s>(
    plan: &'s Plan,
    ctx: &'s Context<'s>,
    progress: &'s Progress,
    done: &'s HashMap<RowKey, CellRow>,
    on_row: &'s (dyn Fn(&CellRow) + Sync),
    stop: &'s AtomicBool,
) -> Vec<CellRow> {
    let sweep = Sweep { plan, ctx, judge: ctx.judge(), workspaces: Workspaces::new(ctx), progress, done, on_row, stop };
    progress.message("least-squares phase");
    let ls = sweep.least_squares_phase();
    progress.message("Huber phase");
    let huber_rows = match plan.start {
        StartStrategy::Ls => sweep.independent_cells(&ls),
        StartStrategy::Chains => sweep.k_chains(&ls),
        StartStrategy::Neighbour | StartStrategy::Best => sweep.neighbour_chains(&ls),
    };
    let mut rows: Vec<CellRow> = ls.into_iter().flatten().filter(|(_, fresh)| *fresh).map(|(p, _)| p.row).collect();
    rows.extend(huber_rows);
    rows
}

impl Sweep<'_> {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    fn huber_key(&self, cell: Cell) -> RowKey {
        RowKey::huber(&self.plan.pairs[cell.pair], cell.k_index)
    }

    /// The least-squares phase of every pair, in waves of equal nB + nF, so that a pair's
    /// sub-models are fitted before it (nested starts, METHOD.md 5.2, step 2); the pairs of a
    /// wave in parallel, one task each. The nested starts are read from the sub-models' rows,
    /// as a resumed run reads them, so both give the same bits.
    fn least_squares_phase(&self) -> LsPhase {
        let ls_pairs = self.plan.ls_pairs();
        let subs = self.plan.ls_sub_models();
        let mut ls: LsPhase = (0..ls_pairs.len()).map(|_| None).collect();
        for wave in self.plan.ls_waves() {
            let fitted: Vec<(usize, Option<(PairLs, bool)>)> = wave
                .par_iter()
                .with_max_len(1)
                .map(|&p| {
                    self.workspaces.with(|ws| {
                        let pair = &ls_pairs[p];
                        let prob = self.ctx.problem(pair);
                        let subs: &[usize] = if self.ctx.solver.nested_starts { &subs[p] } else { &[] };
                        let nested: Vec<Vec<f64>> = subs
                            .iter()
                            .filter_map(|&s| {
                                let (sub, _) = ls[s].as_ref()?;
                                let (_, theta) = sub.start.as_ref()?;
                                Some(estimate::embed(theta, ls_pairs[s].nb, ls_pairs[s].nf, &prob))
                            })
                            .collect();
                        (p, self.pair_ls(pair, p, &nested, ws))
                    })
                })
                .collect();
            for (p, fit) in fitted {
                ls[p] = fit;
            }
        }
        ls.truncate(self.plan.pairs.len());
        ls
    }

    /// The least-squares phase of one pair of `plan.ls_pairs()` (index `p`; beyond the plan's
    /// own pairs, a sub-model kept for its nested start only, which gives no row) from the
    /// `nested` starts: (the pair's fit, whether it is a row computed in this run); None:
    /// stopped before it.
    fn pair_ls(&self, pair: &Structure, p: usize, nested: &[Vec<f64>], ws: &mut Workspace) -> Option<(PairLs, bool)> {
        let (plan, ctx) = (self.plan, self.ctx);
        let own = plan.pairs.len();
        // Without nested starts no pair needs another's fit.
        if p >= own && !ctx.solver.nested_starts {
            return None;
        }
        let resumed = if p < own { self.done.get(&RowKey::ls(pair)) } else { None };
        let all_done = p < own
            && (0..plan.ks.len()).all(|k| self.done.contains_key(&self.huber_key(Cell { pair: p, k_index: k })));
        if let (Some(row), true) = (resumed, all_done) {
            return Some((PairLs::from_row(ctx, row.clone(), Vec::new()), false));
        }
        if self.stopped() {
            return None;
        }
        let prob = ctx.problem(pair);
        let t = Instant::now();
        let _span = Span::start(ctx.profile.as_deref(), Phase::LeastSquares);
        ws.role = Role::LeastSquares;
        // A resumed pair with cells left is fitted again for its extra Huber starts: the
        // least-squares phase is deterministic, so this reproduces the interrupted run.
        let fit =
            catch_unwind(AssertUnwindSafe(|| estimate::fit_ls_nested(&prob, &self.judge, &ctx.solver, nested, ws)));
        let (row, alternatives) = match fit {
            Ok(fit) => (ctx.with_offset(CellRow::from_ls(&fit, t.elapsed().as_secs_f64())), fit.alternatives),
            Err(e) => {
                let reason = format!("least-squares phase panicked: {}", panic_message(e));
                (CellRow::failed(RowKey::ls(pair), None, reason), Vec::new())
            }
        };
        if let Some(row) = resumed {
            return Some((PairLs::from_row(ctx, row.clone(), alternatives), false));
        }
        if p < own {
            (self.on_row)(&row);
        }
        Some((PairLs::from_row(ctx, row, alternatives), p < own))
    }

    /// Start strategy `ls`: every Huber cell on its own from its pair's least-squares fit, in
    /// parallel over cells.
    fn independent_cells(&self, ls: &LsPhase) -> Vec<CellRow> {
        self.plan
            .cells()
            .par_iter()
            .map(|&cell| {
                self.workspaces.with(|ws| {
                    if self.done.contains_key(&self.huber_key(cell)) || self.stopped() {
                        return None;
                    }
                    // A pair without a fit here was skipped because of a stop.
                    let (pair_ls, _) = ls[cell.pair].as_ref()?;
                    let row = huber_cell(self.plan, self.ctx, &self.judge, pair_ls, cell, None, ws);
                    (self.on_row)(&row);
                    self.progress.inc(1);
                    Some(row)
                })
            })
            .flatten()
            .collect()
    }

    /// Start strategy `chains`: each pair's k values walked in increasing order
    /// ([`chain_cells`]), in parallel over pairs, the costliest first.
    fn k_chains(&self, ls: &LsPhase) -> Vec<CellRow> {
        let order = self.plan.k_ascending();
        self.plan
            .pairs_by_cost()
            .par_iter()
            .with_max_len(1)
            .map(|&p| {
                self.workspaces.with(|ws| {
                    let Some((pair_ls, _)) = &ls[p] else { return Vec::new() };
                    let keys: Vec<bool> = order
                        .iter()
                        .map(|&ki| self.done.contains_key(&self.huber_key(Cell { pair: p, k_index: ki })))
                        .collect();
                    if keys.iter().all(|&d| d) {
                        return Vec::new();
                    }
                    let (plan, ctx, judge) = (self.plan, self.ctx, &self.judge);
                    let stopped = || self.stopped();
                    chain_cells(plan, ctx, judge, pair_ls, p, &order, &keys, ws, &stopped, self.on_row, self.progress)
                })
            })
            .flatten()
            .collect()
    }

    /// Start strategies `neighbour` and `best`: each pair walked from the largest k down, a
    /// cell starting from the previous cell's solution, in parallel over pairs.
    fn neighbour_chains(&self, ls: &LsPhase) -> Vec<CellRow> {
        let chain = self.plan.k_descending();
        (0..self.plan.pairs.len())
            .into_par_iter()
            .map(|p| {
                self.workspaces.with(|ws| {
                    let mut out = Vec::new();
                    let Some((pair_ls, _)) = &ls[p] else { return out };
                    let mut prev: Option<Vec<f64>> = None;
                    for &ki in &chain {
                        let cell = Cell { pair: p, k_index: ki };
                        let row = match self.done.get(&self.huber_key(cell)) {
                            Some(row) => {
                                prev = chain_theta(self.ctx, row).or(prev);
                                continue;
                            }
                            None if self.stopped() => break,
                            None => huber_cell(self.plan, self.ctx, &self.judge, pair_ls, cell, prev.as_deref(), ws),
                        };
                        // From the row, like a resumed chain: one path, the same bits.
                        prev = chain_theta(self.ctx, &row).or(prev);
                        (self.on_row)(&row);
                        self.progress.inc(1);
                        out.push(row);
                    }
                    out
                })
            })
            .flatten()
            .collect()
    }
}

/// The Huber cells of pair `p` under the `chains` strategy, in increasing k (`order`), those
/// an earlier run finished (`done[i]` for `order[i]`) left out; empty when stopped mid-walk
/// (see [`walk_pair`]).
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
        crate::failpoint::before_cell(pair.nb, pair.nf, cell.k_index);
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
