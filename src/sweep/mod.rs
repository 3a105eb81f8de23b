//! Running a plan: rayon workers estimate the cells; the module that knows about the worker pool.
//!
//! The sweep is a graph of tasks ([`tasks`], run by [`schedule::run`]): the least-squares phase
//! (initial guesses, L2 fits, sigma) of every order pair (`Sweep::least_squares`), each after
//! its sub-models' (their fits are its nested starts), and the Huber cells of each pair after its
//! own least-squares phase, as the plan's start strategy says: `chains` (the default) walks the
//! pair's k values in increasing order ([`estimate::chains::walk_pair`]), one task per pair
//! (`Sweep::k_chain`); `ls` makes every cell a task of its own (`Sweep::independent_cell`);
//! `neighbour`/`best` walk the pair from the largest k down, one task per pair
//! (`Sweep::neighbour_chain`). In a whole run ([`Control::nested`]) each Huber cell is then
//! checked against its sub-models' cells at the same k (METHOD.md 5.6, `Sweep::nested_check`),
//! after the checks of those. No barrier between them: a pair's Huber cells start as soon as
//! its least-squares fit is done, a cell's check as soon as its row and its sub-models' checked
//! rows are, and the ready task on the longest estimated path to the end runs first. Each task
//! is sequential and deterministic and reads nothing but the results of the tasks it comes
//! after, so the table does not depend on the thread count or the order.
//! One [`Workspace`] per running task ([`Workspaces`]), at most [`live_workspaces`] of them.
//! A panic inside a fit is caught and becomes a failed row; the sweep goes on.
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
use crate::error::Result;
use crate::estimate::chains::panic_message;
use crate::estimate::{self, InitialState, Judge, Problem, SolverOptions, Workspace};
use crate::job::StartStrategy;
use crate::oe::Structure;
use crate::plan::{Cell, Plan};
use crate::profile::{Phase, Profile, Role, Span, Workers};
use crate::progress::Progress;
use crate::schedule;

mod cells;
mod graph;
mod nested;

use crate::spectral::Deferred;
use crate::table::{CellRow, RowKey, sort_rows};
use cells::{chain_cells, huber_cell};
pub use graph::{MIN_LIVE_WORKSPACES, WORKSPACE_BUDGET_BYTES, live_workspaces};
use graph::{Task, task_times, tasks};
pub use nested::{nested_pass, nested_pass_of_rows_from};
use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

/// Everything a cell needs besides its orders and k.
pub struct Context<'a> {
    /// The records with their levels taken out ([`Levels::apply`]).
    pub est: &'a Record,
    pub val: Option<&'a Record>,
    /// The spectral estimate (one per input, made on first use: [`Task::Spectrum`]) and the
    /// band's bins.
    pub band: Option<&'a Deferred>,
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
            validation_missing: self.val.map_or(&[][..], |v| &v.missing[..]),
            band: self.band.map(|d| (d.estimate(self.est), &d.bins[..])),
            initial_state: self.initial_state,
            criterion_only: false,
        }
    }

    fn problem(&self, pair: &Structure) -> Problem<'_> {
        Problem {
            u: &self.est.u,
            y: &self.est.y,
            structure: *pair,
            offset: self.levels.mode.estimated(),
            seams: &self.est.seams,
            missing: &self.est.missing,
        }
    }

    /// The parameters a row holds, as the solver takes them.
    fn theta(&self, row: &CellRow) -> Vec<f64> {
        estimate::theta_in(&row.key.structure(), &row.fit.b, &row.fit.f, self.levels.estimated_c(row.fit.offset))
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

/// How a sweep continues an earlier run and reports to a checkpoint, and whether it checks
/// its cells against their sub-models'.
pub struct Control<'a> {
    /// Rows finished by an earlier run of the same job (one per key; rows of keys seen before
    /// are ignored). Their cells are not computed again and they are part of the outcome.
    pub done: Vec<CellRow>,
    /// Called from the worker threads with every row finished in this run, as soon as it is.
    pub on_row: &'a (dyn Fn(&CellRow) + Sync),
    /// Once true, no further cell is started; running cells finish.
    pub stop: &'a AtomicBool,
    /// The nested check of each cell (METHOD.md 5.6) as a task of the graph: a whole run's.
    /// A shard's plan lacks the sub-models other shards own, so a shard leaves the check to
    /// the merge (`nested_pass` over all rows). The check's refits reach the outcome, never
    /// `on_row`: the checkpoint keeps the walks' rows, from which a resumed run and a merge
    /// compute the same check.
    pub nested: bool,
}

static NEVER: AtomicBool = AtomicBool::new(false);

fn ignore(_: &CellRow) {}

impl Control<'static> {
    /// A run from scratch that is never stopped and reports nowhere.
    pub fn none() -> Self {
        Control { done: Vec::new(), on_row: &ignore, stop: &NEVER, nested: true }
    }
}

/// Result of a sweep: rows sorted by (method, nb, nf, k_index), `ls` rows first; the Huber rows
/// after the nested check when [`Control::nested`].
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

/// Run the cells of `plan` that `control.done` does not hold, on `threads` workers of a pool of
/// their own ([`crate::pool::local`]; 0 = all cores; at most [`crate::pool::MAX_THREADS`],
/// checked by the caller). The only error: the system refused the workers.
pub fn run(plan: &Plan, ctx: &Context, threads: usize, progress: &Progress, control: Control) -> Result<Outcome> {
    let pool = crate::pool::local(threads, "for the sweep")?;
    let t0 = Instant::now();
    let mut done: HashMap<RowKey, CellRow> = HashMap::with_capacity(control.done.len());
    for row in control.done {
        done.entry(row.key).or_insert(row);
    }
    let resumed = done.values().filter(|r| r.is_huber()).count();
    let (new_rows, checked) =
        pool.install(|| run_in_pool(plan, ctx, progress, &done, control.on_row, control.stop, control.nested));
    let computed = crate::table::huber_rows(&new_rows);
    let mut rows: Vec<CellRow> = done.into_values().chain(new_rows).collect();
    let mut checked: HashMap<RowKey, CellRow> = checked.into_iter().map(|r| (r.key, r)).collect();
    for row in &mut rows {
        if let Some(c) = checked.remove(&row.key) {
            *row = c;
        }
    }
    sort_rows(&mut rows);
    let interrupted = rows.len() < plan.pairs.len() + plan.n_cells();
    let seconds = t0.elapsed().as_secs_f64();
    if let Some(p) = &ctx.profile {
        p.serial("sweep_serial", (seconds - p.report().schedule.wall_seconds).max(0.0));
    }
    Ok(Outcome { rows, seconds, resumed, computed, interrupted })
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

/// One sweep's plan, context and bookkeeping, shared by its tasks.
struct Sweep<'s> {
    plan: &'s Plan,
    ctx: &'s Context<'s>,
    workspaces: Workspaces,
    progress: &'s Progress,
    /// Rows of earlier runs.
    done: &'s HashMap<RowKey, CellRow>,
    on_row: &'s (dyn Fn(&CellRow) + Sync),
    stop: &'s AtomicBool,
    /// `plan.ls_pairs()` and their sub-models (`plan.ls_sub_models()`).
    ls_pairs: Vec<Structure>,
    subs: Vec<Vec<usize>>,
    /// Per pair of `ls_pairs`, once its task is done: what its least-squares phase gave (None:
    /// stopped before it) and whether its `ls` row was computed in this run (else an earlier
    /// run's row was taken).
    ls: Vec<OnceLock<Option<(PairLs, bool)>>>,
    /// Per pair of `ls_pairs`, its own minima until its least-squares phase takes them (None:
    /// not found, or a panic while finding them; the phase then finds them itself).
    /// With the seconds they took (part of the `ls` row's).
    own: Vec<Mutex<Option<(estimate::OwnMinima, f64)>>>,
    /// Per plan pair, its Huber rows computed so far.
    huber: Vec<Mutex<Vec<CellRow>>>,
    /// Per cell of `plan.cells()`, once its nested check is done: its row (of an earlier run or
    /// this one; None: none, stopped before it) after the check.
    checked: Vec<OnceLock<Option<CellRow>>>,
}

/// The sweep in the pool: every task of [`tasks`] as soon as those it reads from are done, on at
/// most [`live_workspaces`] threads. Returns the rows computed in this run (as the walks left
/// them) and, with `nested`, every Huber row after the nested check.
fn run_in_pool<'s>(
    plan: &'s Plan,
    ctx: &'s Context<'s>,
    progress: &'s Progress,
    done: &'s HashMap<RowKey, CellRow>,
    on_row: &'s (dyn Fn(&CellRow) + Sync),
    stop: &'s AtomicBool,
    nested: bool,
) -> (Vec<CellRow>, Vec<CellRow>) {
    let (tasks, graph) = tasks(plan, ctx.solver.nested_starts, nested, ctx.band.is_some_and(|d| !d.is_ready()));
    let rows = ctx.est.u.len().max(ctx.val.map_or(0, |v| v.u.len()));
    let threads = rayon::current_num_threads();
    let live = live_workspaces(threads, rows);
    let profile = ctx.profile.as_deref();
    if let Some(p) = profile {
        let workers = Workers {
            threads,
            live,
            record_rows: rows,
            workspace_bytes: Workspace::bytes(rows),
            budget_bytes: WORKSPACE_BUDGET_BYTES,
            min_live: MIN_LIVE_WORKSPACES,
        };
        p.plan_tasks(task_times(plan, &tasks, &graph), workers);
    }
    let sweep = Sweep {
        plan,
        ctx,
        workspaces: Workspaces::new(ctx),
        progress,
        done,
        on_row,
        stop,
        ls_pairs: plan.ls_pairs(),
        subs: plan.ls_sub_models(),
        ls: plan.ls_pairs().iter().map(|_| OnceLock::new()).collect(),
        own: plan.ls_pairs().iter().map(|_| Mutex::new(None)).collect(),
        huber: plan.pairs.iter().map(|_| Mutex::new(Vec::new())).collect(),
        checked: (0..plan.n_cells()).map(|_| OnceLock::new()).collect(),
    };
    progress.message("least squares and Huber cells");
    // Without a profile no clock is read.
    let t = profile.map(|_| Instant::now());
    schedule::run(&graph, live, &|i| {
        let since = profile.map(|_| Instant::now());
        match tasks[i] {
            Task::LsOwn(p) => sweep.own_minima(p),
            Task::Ls(p) => sweep.least_squares(p),
            Task::Pair(p) if plan.start == StartStrategy::Chains => sweep.k_chain(p),
            Task::Pair(p) => sweep.neighbour_chain(p),
            Task::Cell(cell) => sweep.independent_cell(cell),
            Task::Nested(cell) => sweep.nested_check(cell),
            Task::Spectrum => sweep.spectrum(),
        }
        if let (Some(prof), Some(since)) = (profile, since) {
            prof.task(i, since);
        }
    });
    if let (Some(p), Some(t)) = (profile, t) {
        p.tasks_wall(t.elapsed().as_secs_f64());
    }
    let Sweep { ls, huber, checked, .. } = sweep;
    let fresh_ls = ls.into_iter().take(plan.pairs.len()).filter_map(|l| l.into_inner().flatten());
    let mut rows: Vec<CellRow> = fresh_ls.filter(|(_, fresh)| *fresh).map(|(p, _)| p.row).collect();
    rows.extend(huber.into_iter().flat_map(|h| h.into_inner().unwrap_or_else(|e| e.into_inner())));
    (rows, checked.into_iter().filter_map(|c| c.into_inner().flatten()).collect())
}

impl<'s> Sweep<'s> {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// What the fits are judged against; the spectral estimate made if no task made it yet
    /// (the judging tasks come after [`Task::Spectrum`], so none waits for it in a sweep).
    fn judge(&self) -> Judge<'s> {
        self.ctx.judge()
    }

    /// Task [`Task::Spectrum`]: the spectral estimate the band fits compare with, beside the
    /// pairs' own least-squares minima (none of which needs it). Not after a stop: a judging
    /// task still to come would make it.
    fn spectrum(&self) {
        if let Some(d) = self.ctx.band.filter(|_| !self.stopped()) {
            let _span = Span::start(self.ctx.profile.as_deref(), Phase::Spectrum);
            d.estimate(self.ctx.est);
        }
    }

    fn huber_key(&self, cell: Cell) -> RowKey {
        RowKey::huber(&self.plan.pairs[cell.pair], cell.k_index)
    }

    /// The least-squares phase of pair `p` of `plan.ls_pairs()`, once its sub-models' are done;
    /// None for a plan pair stopped before it.
    fn pair_fit(&self, p: usize) -> Option<&(PairLs, bool)> {
        self.ls[p].get().and_then(Option::as_ref)
    }

    /// Huber rows of plan pair `p` computed in this run.
    fn add_rows(&self, p: usize, rows: Vec<CellRow>) {
        self.huber[p].lock().unwrap_or_else(|e| e.into_inner()).extend(rows);
    }

    /// Whether pair `p` of `ls_pairs` is fitted in this run: not when an earlier run finished
    /// it and all its cells (its row is taken), nor after a stop, nor a sub-model kept for its
    /// nested start when there are none.
    fn fits_ls(&self, p: usize) -> bool {
        let own = self.plan.pairs.len();
        if p >= own {
            return self.ctx.solver.nested_starts && !self.stopped();
        }
        let pair = &self.ls_pairs[p];
        let all_done = self.done.contains_key(&RowKey::ls(pair))
            && (0..self.plan.ks.len()).all(|k| self.done.contains_key(&self.huber_key(Cell { pair: p, k_index: k })));
        !all_done && !self.stopped()
    }

    /// Task [`Task::LsOwn`]: pair `p`'s own least-squares minima, for its [`Task::Ls`].
    fn own_minima(&self, p: usize) {
        if !self.fits_ls(p) {
            return;
        }
        let prob = self.ctx.problem(&self.ls_pairs[p]);
        let alone = !self.ctx.solver.nested_starts || self.subs[p].is_empty();
        let _span = Span::start(self.ctx.profile.as_deref(), Phase::LeastSquares);
        let t = Instant::now();
        let found = self.workspaces.with(|ws| {
            ws.role = Role::LeastSquares;
            catch_unwind(AssertUnwindSafe(|| estimate::own_minima(&prob, &self.ctx.solver, alone, ws))).ok()
        });
        let found = found.map(|o| (o, t.elapsed().as_secs_f64()));
        *self.own[p].lock().unwrap_or_else(|e| e.into_inner()) = found;
    }

    /// Task [`Task::Ls`]: the least-squares phase of pair `p` of `plan.ls_pairs()`. The nested
    /// starts are read from the sub-models' rows, as a resumed run reads them, so both give the
    /// same bits.
    fn least_squares(&self, p: usize) {
        let fit = self.workspaces.with(|ws| {
            let ls_pairs = &self.ls_pairs;
            let pair = &ls_pairs[p];
            let prob = self.ctx.problem(pair);
            let subs: &[usize] = if self.ctx.solver.nested_starts { &self.subs[p] } else { &[] };
            let nested: Vec<Vec<f64>> = subs
                .iter()
                .filter_map(|&s| {
                    let (sub, _) = self.pair_fit(s)?;
                    let (_, theta) = sub.start.as_ref()?;
                    Some(crate::plan::embed(theta, &ls_pairs[s], pair, prob.offset))
                })
                .collect();
            self.pair_ls(pair, p, &nested, ws)
        });
        // Each task runs once, so the cell is empty.
        let _ = self.ls[p].set(fit);
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
        // The own minima of task `LsOwn`, unless a sub-model's fit failed and took the nested
        // starts down to none: `fit_ls_nested` then explores as for a pair alone.
        let found = self.own[p].lock().unwrap_or_else(|e| e.into_inner()).take();
        let (found, own_seconds) = match found.filter(|(o, _)| o.alone == nested.is_empty()) {
            Some((o, seconds)) => (Some(o), seconds),
            None => (None, 0.0),
        };
        let fit = catch_unwind(AssertUnwindSafe(|| {
            let found = found.unwrap_or_else(|| estimate::own_minima(&prob, &ctx.solver, nested.is_empty(), ws));
            estimate::finish_ls(&prob, &self.judge(), &ctx.solver, found, nested, ws)
        }));
        let (row, alternatives) = match fit {
            Ok(fit) => {
                let seconds = own_seconds + t.elapsed().as_secs_f64();
                (ctx.with_offset(CellRow::from_ls(&fit, seconds)), fit.alternatives)
            }
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

    /// Task [`Task::Cell`], start strategy `ls`: a Huber cell on its own from its pair's
    /// least-squares fit.
    fn independent_cell(&self, cell: Cell) {
        if self.done.contains_key(&self.huber_key(cell)) || self.stopped() {
            return;
        }
        // A pair without a fit here was skipped because of a stop.
        let Some((pair_ls, _)) = self.pair_fit(cell.pair) else { return };
        let row = self.workspaces.with(|ws| huber_cell(self.plan, self.ctx, &self.judge(), pair_ls, cell, None, ws));
        (self.on_row)(&row);
        self.progress.inc(1);
        self.add_rows(cell.pair, vec![row]);
    }

    /// Task [`Task::Pair`], start strategy `chains`: pair `p`'s k values walked in increasing
    /// order ([`chain_cells`]).
    fn k_chain(&self, p: usize) {
        let Some((pair_ls, _)) = self.pair_fit(p) else { return };
        let order = self.plan.k_ascending();
        let keys: Vec<bool> =
            order.iter().map(|&ki| self.done.contains_key(&self.huber_key(Cell { pair: p, k_index: ki }))).collect();
        if keys.iter().all(|&d| d) {
            return;
        }
        let (plan, ctx, judge) = (self.plan, self.ctx, &self.judge());
        let stopped = || self.stopped();
        let rows = self.workspaces.with(|ws| {
            chain_cells(plan, ctx, judge, pair_ls, p, &order, &keys, ws, &stopped, self.on_row, self.progress)
        });
        self.add_rows(p, rows);
    }

    /// Task [`Task::Pair`], start strategies `neighbour` and `best`: pair `p` walked from the
    /// largest k down, a cell starting from the previous cell's solution.
    fn neighbour_chain(&self, p: usize) {
        let Some((pair_ls, _)) = self.pair_fit(p) else { return };
        let rows = self.workspaces.with(|ws| {
            let mut out = Vec::new();
            let mut prev: Option<Vec<f64>> = None;
            for ki in self.plan.k_descending() {
                let cell = Cell { pair: p, k_index: ki };
                let row = match self.done.get(&self.huber_key(cell)) {
                    Some(row) => {
                        prev = chain_theta(self.ctx, row).or(prev);
                        continue;
                    }
                    None if self.stopped() => break,
                    None => huber_cell(self.plan, self.ctx, &self.judge(), pair_ls, cell, prev.as_deref(), ws),
                };
                // From the row, like a resumed chain: one path, the same bits.
                prev = chain_theta(self.ctx, &row).or(prev);
                (self.on_row)(&row);
                self.progress.inc(1);
                out.push(row);
            }
            out
        });
        self.add_rows(p, rows);
    }

    /// Task [`Task::Nested`]: the cell's row, of an earlier run or of this one, checked against
    /// its sub-models' rows at the same k after their checks ([`nested::check_cell`]); after a
    /// stop it stays as the walk left it (the outcome is an interrupted run's).
    fn nested_check(&self, cell: Cell) {
        let nks = self.plan.ks.len();
        let key = self.huber_key(cell);
        let row = match self.done.get(&key) {
            Some(row) => Some(row.clone()),
            None => {
                self.huber[cell.pair].lock().unwrap_or_else(|e| e.into_inner()).iter().find(|r| r.key == key).cloned()
            }
        };
        let checked = row.map(|row| {
            if self.stopped() {
                return row;
            }
            let subs: Vec<&CellRow> = graph::subs_in_plan(self.plan, &self.subs, cell.pair)
                .filter_map(|s| self.checked[s * nks + cell.k_index].get()?.as_ref())
                .collect();
            let sub = |key: RowKey| subs.iter().copied().find(|r| r.key == key);
            nested::check_cell(self.plan, self.ctx, &self.judge(), &self.workspaces, &row, &sub).unwrap_or(row)
        });
        let _ = self.checked[cell.pair * nks + cell.k_index].set(checked);
    }
}
