//! The sweep as a graph of tasks for [`schedule::run`]: what the tasks are, what each waits
//! for, their priorities, and how many may run at once.

use crate::estimate::Workspace;
use crate::job::StartStrategy;
use crate::plan::{Cell, Plan, Structure};
use crate::profile::TaskTime;
use crate::schedule;

/// A unit of work of the pool: one task of the sweep's [`schedule::Graph`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Task {
    /// The least-squares minima of pair `i` of `plan.ls_pairs()` from its own starts
    /// (`estimate::own_minima`): they need no other pair's fit.
    LsOwn(usize),
    /// The least-squares phase of pair `i` of `plan.ls_pairs()` finished from its own minima and
    /// its sub-models' fits (nested starts, METHOD.md 5.2, step 2; `estimate::finish_ls`);
    /// after those.
    Ls(usize),
    /// The Huber cells of plan pair `p` under `chains` (`cells::chain_cells`) or `neighbour`/`best`
    /// (`Sweep::neighbour_chain`); after the pair's least-squares phase.
    Pair(usize),
    /// One Huber cell under `ls`; after its pair's least-squares phase.
    Cell(Cell),
    /// The nested check of one Huber cell (METHOD.md 5.6, `nested::check_cell`): after the task
    /// that computes the cell and the checks of its sub-models' cells at the same k (their
    /// final rows are what it reads). Per cell rather than per pair: a pair's refits then do
    /// not queue one behind the other along the chain of sub-models up the grid.
    Nested(Cell),
    /// The spectral estimate the band fits compare with (`spectral::Deferred`): before every
    /// least-squares finish (the first fits judged), beside the own minima.
    Spectrum,
}

/// A pair's least-squares phase costs about this many of its Huber cells, its own minima
/// [`LS_OWN_CELLS`] and the nested finish [`LS_NESTED_CELLS`]: what the schedule's priorities
/// weigh (never the results). On the paper grid (`--profile`) a least-squares phase took 8-12
/// times a Huber cell of its pair, on the 131 072-sample record 4 times.
const LS_OWN_CELLS: u64 = 6;
const LS_NESTED_CELLS: u64 = 2;
/// A cell's nested check is mostly a comparison (on the paper grid 353 of 3840 cells were
/// refitted, by warm fits): one unit, where a Huber cell weighs nB + nF.
const NESTED_CHECK: u64 = 1;
/// The robust spectral estimate costs about this many units (a Huber cell of d parameters
/// weighs d): on the paper grid it took 0.14-0.16 s, some 40 cells of its mean d = 20, and
/// both grow with the record's length. Only its place among the ready tasks depends on it.
const SPECTRUM: u64 = 800;

/// The sweep's tasks, their dependencies and priorities: every pair's own least-squares minima
/// on their own, the least-squares phase of a pair finished after its own minima and its
/// sub-models' phases, the Huber cells of a pair after its least-squares phase, and no other
/// barrier; with `nested_check`, the nested check of each cell after the task that computes it
/// and its sub-models' checks at the same k. The ready task on the longest estimated path to
/// the end first ([`schedule::Graph::with_bottom_levels`]), with a task's cost estimated as
/// nB + nF per cell (per-iteration work grows with the parameter count), [`LS_OWN_CELLS`] and
/// [`LS_NESTED_CELLS`] cells for the two parts of a least-squares phase and [`NESTED_CHECK`]
/// units for a nested check. Task `i` is the finish of pair `i` of `plan.ls_pairs()` (as the
/// sub-model indices are), the own minima follow them; the checks come last, in the order of
/// `plan.cells()`. With `spectrum`, the spectral estimate is the last task, and every
/// least-squares finish comes after it.
pub(super) fn tasks(
    plan: &Plan,
    nested_starts: bool,
    nested_check: bool,
    spectrum: bool,
) -> (Vec<Task>, schedule::Graph) {
    let ls_pairs = plan.ls_pairs();
    let subs = plan.ls_sub_models();
    let n = ls_pairs.len();
    let size = |s: &Structure| s.dim() as u64;
    let mut tasks: Vec<Task> = (0..n).map(Task::Ls).chain((0..n).map(Task::LsOwn)).collect();
    let mut after: Vec<Vec<usize>> = subs
        .iter()
        .enumerate()
        .map(|(i, s)| std::iter::once(n + i).chain(s.iter().copied().filter(|_| nested_starts)).collect())
        .chain((0..n).map(|_| Vec::new()))
        .collect();
    let mut cost: Vec<u64> = ls_pairs
        .iter()
        .map(|s| LS_NESTED_CELLS * size(s))
        .chain(ls_pairs.iter().map(|s| LS_OWN_CELLS * size(s)))
        .collect();
    // Per cell of `plan.cells()`, the Huber task that computes it.
    let mut huber: Vec<usize> = Vec::with_capacity(plan.n_cells());
    match plan.start {
        StartStrategy::Ls => {
            for cell in plan.cells() {
                huber.push(tasks.len());
                tasks.push(Task::Cell(cell));
                after.push(vec![cell.pair]);
                cost.push(size(&plan.pairs[cell.pair]));
            }
        }
        StartStrategy::Chains | StartStrategy::Neighbour | StartStrategy::Best => {
            for (p, pair) in plan.pairs.iter().enumerate() {
                huber.extend(std::iter::repeat_n(tasks.len(), plan.ks.len()));
                tasks.push(Task::Pair(p));
                after.push(vec![p]);
                cost.push(plan.ks.len() as u64 * size(pair));
            }
        }
    }
    if nested_check {
        // The checks follow in the order of `plan.cells()` (pair-major) from `first`.
        let first = tasks.len();
        let nks = plan.ks.len();
        for (cell, walk) in plan.cells().into_iter().zip(huber) {
            tasks.push(Task::Nested(cell));
            let checks = subs_in_plan(plan, &subs, cell.pair).map(|s| first + s * nks + cell.k_index);
            after.push(std::iter::once(walk).chain(checks).collect());
            cost.push(NESTED_CHECK);
        }
    }
    if spectrum {
        let id = tasks.len();
        tasks.push(Task::Spectrum);
        after.push(Vec::new());
        cost.push(SPECTRUM);
        after.iter_mut().take(n).for_each(|a| a.push(id));
    }
    (tasks, schedule::Graph::with_bottom_levels(after, &cost))
}

/// The sub-models of plan pair `p` that are plan pairs (indices into `plan.pairs`), from
/// `subs` = `plan.ls_sub_models()`: those whose rows the table holds, so the nested checks of
/// `p`'s cells read.
pub(super) fn subs_in_plan<'a>(plan: &Plan, subs: &'a [Vec<usize>], p: usize) -> impl Iterator<Item = usize> + 'a {
    let own = plan.pairs.len();
    subs[p].iter().copied().filter(move |&s| s < own)
}

/// The workspaces' budget on a long record ([`live_workspaces`]).
pub const WORKSPACE_BUDGET_BYTES: usize = 512 << 20;
/// Workspaces allowed whatever the budget. With M0 the memory outside the workspaces and w
/// one workspace's, M0 + 4 w <= 2 (M0 + 2 w): at most twice the memory of 2 workers.
pub const MIN_LIVE_WORKSPACES: usize = 4;

/// How many tasks, so workspaces, may run at once on `threads` threads when the longest record
/// has `rows` samples: min(threads, max([`MIN_LIVE_WORKSPACES`], [`WORKSPACE_BUDGET_BYTES`] /
/// [`Workspace::bytes`]`(rows)`)). A workspace holds record-length buffers
/// ([`Workspace::RECORD_VECTORS`]); on a 1 000 000-sample record (750 000 estimation rows) 16
/// of them took 1.45 GB against 216 MB for 2 (docs/PERFORMANCE.md, "Memory per worker"). The
/// cap binds from about 175 000 rows on at 16 threads; the paper grid's 5 000 rows allow 559.
pub fn live_workspaces(threads: usize, rows: usize) -> usize {
    let budget = WORKSPACE_BUDGET_BYTES / Workspace::bytes(rows).max(1);
    threads.min(budget.max(MIN_LIVE_WORKSPACES)).max(1)
}

/// The profile's view of the tasks ([`crate::profile::Schedule`]), before they run.
pub(super) fn task_times(plan: &Plan, tasks: &[Task], graph: &schedule::Graph) -> Vec<TaskTime> {
    let ls_pairs = plan.ls_pairs();
    tasks
        .iter()
        .enumerate()
        .map(|(id, task)| {
            let (kind, pair, k_index) = match *task {
                Task::LsOwn(i) => ("least_squares_own", Some(ls_pairs[i]), None),
                Task::Ls(i) => ("least_squares", Some(ls_pairs[i]), None),
                Task::Pair(p) if plan.start == StartStrategy::Chains => ("chains", Some(plan.pairs[p]), None),
                Task::Pair(p) => ("neighbour", Some(plan.pairs[p]), None),
                Task::Cell(c) => ("cell", Some(plan.pairs[c.pair]), Some(c.k_index)),
                Task::Nested(c) => ("nested", Some(plan.pairs[c.pair]), Some(c.k_index)),
                Task::Spectrum => ("spectrum", None, None),
            };
            let orders = pair.map(|p| p.inputs()[0]);
            TaskTime {
                id,
                kind,
                nb: orders.map_or(0, |o| o.nb),
                nf: orders.map_or(0, |o| o.nf),
                delay: orders.map_or(0, |o| o.delay),
                k_index,
                after: graph.after[id].clone(),
                priority: graph.priority[id],
                seconds: 0.0,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_workspace_cap_keeps_16_workers_within_twice_the_memory_of_2() {
        // The paper grid's records: no cap.
        assert_eq!(live_workspaces(16, 5000), 16);
        assert_eq!(live_workspaces(2, 5000), 2);
        // The 1M-sample record's 750 000 estimation rows: the minimum, 4.
        assert_eq!(live_workspaces(16, 750_000), MIN_LIVE_WORKSPACES);
        assert_eq!(live_workspaces(2, 750_000), 2);
        // Where the budget binds at 16 threads.
        let rows = WORKSPACE_BUDGET_BYTES / Workspace::bytes(16);
        assert_eq!(live_workspaces(16, rows), 16);
        assert!(live_workspaces(16, rows + 1) < 16);
        // Whatever the record, the live workspaces take at most the budget or 4 workspaces:
        // with M0 the rest, M0 + 4 w <= 2 (M0 + 2 w).
        for rows in [1, 1000, 100_000, 1 << 20, 1 << 26] {
            let live = live_workspaces(1024, rows);
            assert!(live * Workspace::bytes(rows) <= WORKSPACE_BUDGET_BYTES || live == MIN_LIVE_WORKSPACES);
        }
        assert_eq!(live_workspaces(1, 1 << 26), 1);
    }

    #[test]
    fn every_task_comes_after_what_it_reads() {
        let grid = |start| Plan {
            pairs: (1..=3).flat_map(|nb| (1..=3).map(move |nf| Structure::siso(nb, nf, 1))).collect(),
            ks: vec![0.1, 1.0],
            start,
            ls_support: Vec::new(),
        };
        for start in [StartStrategy::Chains, StartStrategy::Ls] {
            let plan = grid(start);
            let n = plan.pairs.len();
            let (tasks, graph) = tasks(&plan, true, true, false);
            let huber = if start == StartStrategy::Ls { plan.n_cells() } else { n };
            assert_eq!(tasks.len(), 2 * n + huber + plan.n_cells());
            let subs = plan.ls_sub_models();
            let id = |task: Task| tasks.iter().position(|t| *t == task).unwrap();
            for (i, t) in tasks.iter().enumerate() {
                let mut expected = match *t {
                    Task::LsOwn(_) => vec![],
                    Task::Ls(p) => std::iter::once(n + p).chain(subs[p].iter().copied()).collect(),
                    Task::Pair(p) => vec![p],
                    Task::Cell(c) => vec![c.pair],
                    Task::Spectrum => unreachable!("no spectral estimate in this graph"),
                    // The task that computes the cell and its sub-models' checks at its k.
                    Task::Nested(c) => (0..tasks.len())
                        .filter(|&j| match tasks[j] {
                            Task::Pair(q) => q == c.pair,
                            Task::Cell(d) => d == c,
                            Task::Nested(d) => d.k_index == c.k_index && subs[c.pair].contains(&d.pair),
                            _ => false,
                        })
                        .collect(),
                };
                let mut after = graph.after[i].clone();
                expected.sort();
                after.sort();
                assert_eq!(after, expected, "{t:?}");
            }
            // OE(3,3) is checked after OE(2,3) and OE(3,2), OE(1,1) after no other check.
            let checks = |pair| {
                let after = &graph.after[id(Task::Nested(Cell { pair, k_index: 1 }))];
                after.iter().filter(|&&j| matches!(tasks[j], Task::Nested(_))).count()
            };
            assert_eq!((checks(n - 1), checks(0)), (2, 0));
            // A single worker runs every task, those on the longest path (own minima, then the
            // chain of least-squares finishes up the grid) before the Huber walks, and the
            // largest pair's check last.
            let order = graph.serial_order();
            assert_eq!(order.len(), tasks.len());
            assert!(matches!(tasks[order[0]], Task::LsOwn(_)));
            assert!(matches!(tasks[*order.last().unwrap()], Task::Nested(Cell { pair, .. }) if pair == n - 1));
            // Without the nested check (a shard) no check tasks; without nested starts the
            // least-squares finishes wait for their own minima only.
            let (shard, _) = super::tasks(&plan, true, false, false);
            assert_eq!(shard.len(), 2 * n + huber);
            assert!(!shard.iter().any(|t| matches!(t, Task::Nested(_))));
            let (_, alone) = super::tasks(&plan, false, true, false);
            assert!((0..n).all(|p| alone.after[p] == [n + p]));
            // With a spectral estimate to make it is the last task, every least-squares finish
            // (the first task that judges a fit) comes after it, nothing else waits for it
            // directly, and a single worker makes it first.
            let (with, g) = super::tasks(&plan, true, true, true);
            let spectrum = with.len() - 1;
            assert_eq!((with.len(), with[spectrum]), (tasks.len() + 1, Task::Spectrum));
            assert!(g.after[spectrum].is_empty());
            for (i, t) in with.iter().enumerate() {
                assert_eq!(g.after[i].contains(&spectrum), matches!(t, Task::Ls(_)), "{t:?}");
            }
            assert_eq!(g.serial_order()[0], spectrum);
        }
    }
}
