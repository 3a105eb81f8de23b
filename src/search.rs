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

    /// Shards split a plan's structures, which a coordinate search learns round by round from
    /// the rows of the rounds before: `what` (`--shard 1/4`, `merge`) is refused for it.
    pub fn check_shardable(&self, what: &str) -> Result<()> {
        match self {
            Search::Product => Ok(()),
            Search::Coordinate(c) => Err(crate::error::Error::Invalid(format!(
                "{what}: the job's coordinate search (grid.search; {} structures per cycle over the inputs) runs \
                 whole with `oesweep run JOB`, which resumes from its checkpoint; set grid.search to \"product\" \
                 to split the full product into shards",
                c.cycle()
            ))),
        }
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
/// row takes part), and who hears of each round's cells (a caller's progress).
pub struct Guide<'a> {
    pub lead: &'a dyn Fn(&[CellRow]) -> Option<Structure>,
    pub grow: &'a dyn Fn(usize),
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

/// Run the coordinate search `c` over `full` (the product plan: its ks and start strategy),
/// each round a [`sweep::run`] of the structures fitted so far and the round's line, starting
/// from `control.done`, steered by `guide`. Rows finished go to `control.on_row` as in a sweep; the nested check of the search's
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
    let Guide { lead, grow } = guide;
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
    // Step 3's next line: the next input whose line through `current` is not swept.
    while let Some(i) = (0..m).map(|j| (next_input + j) % m).find(|&j| !swept.contains(&line_key(&current, j))) {
        swept.insert(line_key(&current, i));
        let line: Vec<usize> = c.line(&current, i).iter().map(|s| order[s]).collect();
        let new = line.iter().filter(|p| !fitted.contains(p)).count();
        fitted.extend(line);
        // The progress's length grows by the round's cells.
        progress.grow(new * full.ks.len());
        grow(new * full.ks.len());
        let plan =
            Plan { pairs: fitted.iter().map(|&p| full.pairs[p]).collect(), ls_support: Vec::new(), ..full.clone() };
        let round = Control { done: std::mem::take(&mut rows), ..control };
        let out = sweep::run(&plan, ctx, threads, progress, round)?;
        computed += out.computed;
        rows = out.rows;
        if out.interrupted {
            let seconds = t0.elapsed().as_secs_f64();
            rounds.structures = fitted.len();
            return Ok((Outcome { rows, seconds, resumed, computed, interrupted: true }, rounds));
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
    let seconds = t0.elapsed().as_secs_f64();
    Ok((Outcome { rows, seconds, resumed, computed, interrupted: false }, rounds))
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
