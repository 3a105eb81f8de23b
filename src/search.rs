//! The order search of several inputs (METHOD.md 20): the full product of the inputs' order
//! grids where it is small, a coordinate search where it is large.
//!
//! The product of m inputs' grids grows as the product of their sizes (three inputs with nB,
//! nF in 1..3 and delays 0..2: 27^3 = 19 683 structures per k). The coordinate search sweeps
//! one input's orders at a time, the others held at the current lead pick, so its cost grows
//! with the sum of the grids' sizes:
//!
//! 1. Start at every input's smallest delay and largest nB and nF (a model that holds every
//!    smaller one of its delay, and the larger delays through leading zeros of B): the other
//!    inputs' dynamics are then never under-modelled while one input's orders are swept.
//! 2. A round is one input's *line* through the current structure: every order of that input's
//!    grid, the other inputs' orders fixed. Its structures that are not fitted yet run as a
//!    sweep of their own (least squares, the k chains, the nested check against the sub-models
//!    fitted so far), beside every row of the earlier rounds.
//! 3. The current structure becomes the lead pick (the job's lead rule, [`crate::reduce`]) of
//!    all rows so far; the next round is the next input (cyclically) whose line through it
//!    has not been swept.
//! 4. The search ends when every input's line through the current structure has been swept.
//!
//! Every step reads only the rows of the rounds before it, so the rounds, their structures and
//! the table are the same on any number of threads, and a resumed run replays the finished
//! rounds from the checkpoint's rows without fitting anything again (a round's rows are those
//! of [`sweep::run`], which skips the rows it is given).

use crate::error::Result;
use crate::job::{SearchMode, ValidJob};
use crate::oe::{Orders, Structure};
use crate::plan::{Plan, one_input_orders};
use crate::progress::Progress;
use crate::shard::Shard;
use crate::sweep::{self, Context, Control, Outcome};
use crate::table::CellRow;
use std::collections::{BTreeSet, HashMap};
use std::time::Instant;

/// `grid.search: "auto"` runs the full product up to this many structures and the coordinate
/// search above.
pub const PRODUCT_LIMIT: usize = 1000;

/// How the structures of a job are searched.
#[derive(Clone, Debug, PartialEq)]
pub enum Search {
    /// Every structure of the plan.
    Product,
    /// The coordinate search over each input's orders (the plan is the product it walks in).
    Coordinate(Coordinate),
}

impl Search {
    /// The search `job.grid.search` asks for (`auto`: the product up to [`PRODUCT_LIMIT`]
    /// structures). One input is always the product: its line is the whole grid.
    pub fn of_job(job: &ValidJob, plan: &Plan) -> Search {
        let coordinate = match job.job.grid.search {
            SearchMode::Product => false,
            SearchMode::Coordinate => true,
            SearchMode::Auto => plan.pairs.len() > PRODUCT_LIMIT,
        };
        if job.m == 1 || !coordinate {
            return Search::Product;
        }
        let per_input = job.grids.iter().map(|g| one_input_orders(&g.nb, &g.nf, &g.delays)).collect();
        Search::Coordinate(Coordinate { per_input })
    }

    pub fn name(&self) -> &'static str {
        match self {
            Search::Product => "product",
            Search::Coordinate(_) => "coordinate",
        }
    }
}

/// The coordinate search's grid: each input's orders in (delay, nB, nF) order.
#[derive(Clone, Debug, PartialEq)]
pub struct Coordinate {
    pub per_input: Vec<Vec<Orders>>,
}

impl Coordinate {
    /// Step 1: every input's smallest delay with its largest nB and nF.
    pub fn start(&self) -> Structure {
        let orders: Vec<Orders> = self
            .per_input
            .iter()
            .map(|o| {
                let delay = o.iter().map(|x| x.delay).min().expect("an input has orders");
                Orders {
                    delay,
                    nb: o.iter().map(|x| x.nb).max().expect("an input has orders"),
                    nf: o.iter().map(|x| x.nf).max().expect("an input has orders"),
                }
            })
            .collect();
        Structure::new(&orders).expect("a valid grid's structure")
    }

    /// Input `i`'s line through `at`: `at` with each of input i's orders.
    pub fn line(&self, at: &Structure, i: usize) -> Vec<Structure> {
        self.per_input[i].iter().map(|o| at.with(i, *o)).collect()
    }

    /// Structures of one cycle over the inputs: every input's line through one structure (the
    /// sum of the grids' sizes, the structure itself counted once).
    pub fn cycle(&self) -> usize {
        1 + self.per_input.iter().map(|o| o.len() - 1).sum::<usize>()
    }
}

/// What the engine tells the coordinate search: the job's lead pick of a set of rows (None: no
/// row takes part), who hears of each round's cells (a caller's progress), and what a round
/// whose rows are missing does (a whole run, a shard, a merge).
pub struct Guide<'a> {
    pub lead: &'a dyn Fn(&[CellRow]) -> Option<Structure>,
    pub grow: &'a dyn Fn(usize),
    pub step: Step,
}

/// A line: the structure with input i's orders blanked, and i.
type LineKey = (Structure, usize);

fn line_key(at: &Structure, i: usize) -> LineKey {
    (at.with(i, Orders { nb: 0, nf: 0, delay: 0 }), i)
}

/// What the coordinate search did, besides its rows.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Rounds {
    /// Structures fitted (the search's rows are these at every k).
    pub structures: usize,
    /// Per round: the input swept (0-based), the structure it went through and the lead pick
    /// after it.
    pub rounds: Vec<(usize, Structure, Structure)>,
    /// A sharded search ([`Step::Shard`], [`Step::Replay`]): the round whose rows are not all
    /// there yet (None: the search is finished).
    pub pending: Option<Pending>,
}

impl Rounds {
    /// One line for a run's summary: the rounds, each input swept and the lead after it.
    pub fn describe(&self) -> String {
        let steps: Vec<String> =
            self.rounds.iter().map(|(i, _, lead)| format!("u{} -> {}", i + 1, lead.label())).collect();
        format!(
            "coordinate search: {} rounds over {} structures ({})",
            self.rounds.len(),
            self.structures,
            steps.join("; ")
        )
    }
}

/// The round of a sharded coordinate search that waits for its rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Pending {
    /// Its number (1-based): the rounds before it are finished.
    pub round: usize,
    /// The input it sweeps (0-based) and the structure its line goes through.
    pub input: usize,
    pub through: Structure,
    /// Its structures that no earlier round fitted (in the plan's order): what the shards split.
    pub structures: Vec<Structure>,
    /// Of these, the share of the shard that called ([`Step::Shard`]; empty for a merge).
    pub share: Vec<Structure>,
}

impl Pending {
    /// The round's structures as a plan of `full`'s k and start (its cells, the shards' layout).
    pub fn plan(&self, full: &Plan) -> Plan {
        Plan { pairs: self.structures.clone(), ks: full.ks.clone(), start: full.start, ls_support: Vec::new() }
    }

    /// One line: `round 3 (input 2 through OE(..)): 4 structures`.
    pub fn describe(&self) -> String {
        format!(
            "round {} of the coordinate search (input {} through {}): {} structures",
            self.round,
            self.input + 1,
            self.through.label(),
            self.structures.len()
        )
    }
}

/// What [`coordinate`] does with a round whose structures lack rows (METHOD.md 20, sharded
/// search).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// A whole run: every round's structures are fitted, to the end of the search.
    Whole,
    /// Shard I/N: the rounds whose rows are all given are replayed (nothing fitted, each
    /// round's nested check run again as in a whole run); of the first round with rows missing,
    /// the shard's share of its structures ([`crate::shard::layout`] of the round's) is fitted,
    /// without the nested check (left to the replay, as a merge leaves it), and the call
    /// returns with [`Rounds::pending`].
    Shard(Shard),
    /// A merge: the rounds whose rows are all given are replayed; the call returns at the first
    /// round with rows missing ([`Rounds::pending`]; the rows of the finished rounds only).
    Replay,
}
/// Run the coordinate search `c` over `full` (the product plan: its ks and start strategy),
/// each round a [`sweep::run`] of the structures fitted so far and the round's line, starting
/// from `control.done`, steered by `guide` (its `step` says what a round whose rows are
/// missing does). Rows finished go to `control.on_row` as in a sweep; the nested check of the search's
/// rows is the sweep's (against the sub-models fitted so far).
pub fn coordinate(
    c: &Coordinate,
    full: &Plan,
    ctx: &Context,
    threads: usize,
    progress: &Progress,
    control: Control,
    guide: Guide,
) -> Result<(Outcome, Rounds)> {
    let Guide { lead, grow, step } = guide;
    let t0 = Instant::now();
    let order: HashMap<Structure, usize> = full.pairs.iter().enumerate().map(|(i, p)| (*p, i)).collect();
    let mut rows = control.done;
    let mut computed = 0;
    let resumed = crate::table::huber_rows(&rows);
    let mut fitted: BTreeSet<usize> = BTreeSet::new();
    let mut swept: BTreeSet<LineKey> = BTreeSet::new();
    let mut current = c.start();
    let mut next_input = 0;
    let mut rounds = Rounds::default();
    let m = current.m();
    let nks = full.ks.len();
    let outcome = |rows: Vec<CellRow>, computed: usize, interrupted: bool| {
        let seconds = t0.elapsed().as_secs_f64();
        Outcome { rows, seconds, resumed, computed, interrupted }
    };
    // Step 3's next line: the next input whose line through `current` is not swept.
    while let Some(i) = (0..m).map(|j| (next_input + j) % m).find(|&j| !swept.contains(&line_key(&current, j))) {
        swept.insert(line_key(&current, i));
        let line: Vec<usize> = c.line(&current, i).iter().map(|s| order[s]).collect();
        let new: Vec<usize> =
            line.iter().copied().filter(|p| !fitted.contains(p)).collect::<BTreeSet<usize>>().into_iter().collect();
        let round_plan = restricted(full, &new);
        let missing = crate::shard::missing(&round_plan, &rows);
        if step != Step::Whole && !missing.is_empty() {
            let mut pending = Pending {
                round: rounds.rounds.len() + 1,
                input: i,
                through: current,
                structures: round_plan.pairs.clone(),
                share: Vec::new(),
            };
            let mut interrupted = false;
            match step {
                Step::Shard(s) => {
                    let mine: Vec<usize> = crate::shard::layout(&round_plan, s.count)
                        .swap_remove(s.index)
                        .into_iter()
                        .map(|j| new[j])
                        .collect();
                    pending.share = mine.iter().map(|&p| full.pairs[p]).collect();
                    let share = restricted(full, &mine);
                    let todo = crate::shard::missing(&share, &rows).cells;
                    progress.grow(todo);
                    grow(todo);
                    if !mine.is_empty() {
                        let plan = share_plan(full, &fitted, &new, &mine);
                        let round = Control { done: std::mem::take(&mut rows), nested: false, ..control };
                        let out = sweep::run(&plan, ctx, threads, progress, round)?;
                        computed += out.computed;
                        rows = out.rows;
                        interrupted = !crate::shard::missing(&share, &rows).is_empty();
                    }
                }
                // The rows of the finished rounds, checked as in a whole run.
                _ => rows.retain(|r| is_fitted(&fitted, &order, r)),
            }
            rounds.structures = fitted.len();
            rounds.pending = Some(pending);
            return Ok((outcome(rows, computed, interrupted), rounds));
        }
        fitted.extend(line);
        // The progress's length grows by the round's cells left to fit.
        progress.grow(missing.cells);
        grow(new.len() * nks);
        let plan = restricted(full, &fitted.iter().copied().collect::<Vec<usize>>());
        let round = Control { done: std::mem::take(&mut rows), nested: true, ..control };
        let out = sweep::run(&plan, ctx, threads, progress, round)?;
        computed += out.computed;
        rows = out.rows;
        // Rows of later rounds (a resumed run's) are not this round's: its own must all be there.
        if out.interrupted || !crate::shard::missing(&round_plan, &rows).is_empty() {
            rounds.structures = fitted.len();
            return Ok((outcome(rows, computed, true), rounds));
        }
        let before = current;
        // A resumed run's checkpoint holds rows of later rounds: the lead of the rows fitted
        // so far, as in a run that was never stopped.
        let so_far: Vec<CellRow> = rows.iter().filter(|r| is_fitted(&fitted, &order, r)).cloned().collect();
        if let Some(best) = lead(&so_far) {
            current = best;
        }
        rounds.rounds.push((i, before, current));
        next_input = (i + 1) % m;
    }
    rows.retain(|r| is_fitted(&fitted, &order, r));
    rounds.structures = fitted.len();
    Ok((outcome(rows, computed, false), rounds))
}

/// The plan of a shard's share `mine` of a round whose new structures are `new` (indices into
/// `full.pairs`): the structures of the earlier rounds (`earlier`; their rows are given, so
/// nothing of them is fitted again and their least-squares fits are read from their rows, as in
/// a whole run) and `mine`, with the round's other new structures that `mine` starts from
/// (sub-models, and theirs in turn) as least-squares support ([`Plan::ls_support`], as
/// [`Plan::with_pairs`] keeps a product shard's): each structure of the share starts from the
/// same nested fits as in the whole round, so its rows are the whole round's bits.
fn share_plan(full: &Plan, earlier: &BTreeSet<usize>, new: &[usize], mine: &[usize]) -> Plan {
    let others: HashMap<Structure, usize> =
        new.iter().filter(|p| !mine.contains(p)).map(|&p| (full.pairs[p], p)).collect();
    let mut support = BTreeSet::new();
    let mut stack: Vec<Structure> = mine.iter().map(|&p| full.pairs[p]).collect();
    while let Some(s) = stack.pop() {
        for sub in crate::plan::sub_structures(&s) {
            if let Some(&p) = others.get(&sub)
                && support.insert(p)
            {
                stack.push(sub);
            }
        }
    }
    let own: Vec<usize> = earlier.iter().chain(mine).copied().collect::<BTreeSet<usize>>().into_iter().collect();
    Plan { ls_support: support.iter().map(|&p| full.pairs[p]).collect(), ..restricted(full, &own) }
}

/// `full` restricted to its pairs `pairs` (indices, in the order given), without support.
fn restricted(full: &Plan, pairs: &[usize]) -> Plan {
    Plan {
        pairs: pairs.iter().map(|&p| full.pairs[p]).collect(),
        ks: full.ks.clone(),
        start: full.start,
        ls_support: Vec::new(),
    }
}

fn is_fitted(fitted: &BTreeSet<usize>, order: &HashMap<Structure, usize>, row: &CellRow) -> bool {
    order.get(&row.key.structure()).is_some_and(|p| fitted.contains(p))
}

/// A job's wall time estimated before it runs (`oesweep plan`).
#[derive(Clone, Debug)]
pub struct TimeEstimate {
    /// The structure swept as a sample, and its seconds on one thread.
    pub sample: Structure,
    pub sample_seconds: f64,
    /// The structures the estimate covers: the plan's (product), or one cycle of the
    /// coordinate search (every input's line through its start).
    pub structures: usize,
    /// Their estimated wall time on `threads` workers.
    pub seconds: f64,
}

/// Sweep one structure of `plan` (of the upper quartile's cost) at every k on one thread and scale its time
/// by the shards' cost model ([`crate::shard::pair_cost`]: dim x (K + 1)) to the structures
/// `search` runs, shared among `threads` workers (0: all cores). A model, not a measurement:
/// the iterations a structure takes vary with its fit, the k chains and the nested starts
/// (PERFORMANCE.md "Several inputs" compares it with runs).
pub fn estimate_time(plan: &Plan, search: &Search, ctx: &Context, threads: usize) -> Result<TimeEstimate> {
    let structures: Vec<usize> = match search {
        Search::Product => (0..plan.pairs.len()).collect(),
        Search::Coordinate(c) => {
            let order: HashMap<Structure, usize> = plan.pairs.iter().enumerate().map(|(i, p)| (*p, i)).collect();
            let start = c.start();
            let lines: BTreeSet<usize> = (0..start.m()).flat_map(|i| c.line(&start, i)).map(|s| order[&s]).collect();
            lines.into_iter().collect()
        }
    };
    let mut by_cost = structures.clone();
    by_cost.sort_by(|&a, &b| crate::shard::pair_cost(plan, a).total_cmp(&crate::shard::pair_cost(plan, b)));
    let sample = by_cost[by_cost.len() * 3 / 4];
    let one = Plan { pairs: vec![plan.pairs[sample]], ls_support: Vec::new(), ..plan.clone() };
    let t = Instant::now();
    sweep::run(&one, ctx, 1, &Progress::new(0, true), Control::none())?;
    let sample_seconds = t.elapsed().as_secs_f64();
    let per_unit = sample_seconds / crate::shard::pair_cost(plan, sample);
    let total: f64 = structures.iter().map(|&p| crate::shard::pair_cost(plan, p)).sum();
    let workers = crate::pool::local(threads, "to estimate the time")?.current_num_threads();
    Ok(TimeEstimate {
        sample: plan.pairs[sample],
        sample_seconds,
        structures: structures.len(),
        seconds: per_unit * total / workers.min(structures.len()).max(1) as f64,
    })
}
