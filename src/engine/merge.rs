//! `oesweep merge`: the checkpoint folders of an output folder (shards, or an interrupted whole
//! run) made into the result files a whole run writes. A product's rows are nested-checked in
//! one pass ([`sweep::nested_pass`]); a coordinate search's rounds are replayed from the rows
//! ([`search::Step::Replay`], METHOD.md 20): each round's nested check and lead pick made again
//! as the whole run made them, up to the end of the search or to the first round whose rows are
//! not all there (the shards' next round).

use super::prepare_job;
use super::write::{lead_structure, write_results};
use crate::checkpoint::{self, Gathered};
use crate::error::{Error, Result};
use crate::export;
use crate::plan::Plan;
use crate::progress::Progress;
use crate::reduce::Selection;
use crate::search::{self, Coordinate, Search};
use crate::shard::{self, Missing};
use crate::sweep;
use crate::table::CellRow;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// How [`merge`] ended.
#[derive(Debug)]
pub enum MergeEnd {
    /// No checkpoint left and the result files are there: merged before, nothing to do.
    AlreadyMerged,
    /// Cells are missing and `partial` was not asked for: nothing written.
    Incomplete,
    /// The result files are written (with `missing` cells left out under `partial`; the
    /// checkpoint is then kept, else deleted).
    Merged { selection: Box<Selection> },
}

/// The outcome of [`merge`].
#[derive(Debug)]
pub struct MergeOutcome {
    pub end: MergeEnd,
    /// The job's name.
    pub name: String,
    pub plan: Option<Plan>,
    /// Cells and fits missing from the checkpoint folders.
    pub missing: Missing,
    /// When the folders say how the job was split into N shards: N and the shards that hold
    /// the missing cells.
    pub owners: Option<(usize, Vec<usize>)>,
    /// Checkpoint folders read with their part counts (those with parts).
    pub folders: Vec<(PathBuf, usize)>,
    /// Cells saved twice (identical rows), kept once.
    pub duplicates: usize,
    /// Huber cells and least-squares fits merged; failed Huber cells in the table.
    pub huber: usize,
    pub ls: usize,
    pub failed: usize,
    pub cleanup: Option<Error>,
    pub report: Option<Result<PathBuf>>,
    /// A coordinate search's rounds replayed from the rows; [`search::Rounds::pending`] is the
    /// round the shards run next (None: the product, or a folder merged before).
    pub search: Option<search::Rounds>,
}

/// The exit code of a merge that found a coordinate search waiting for its next round, none of
/// whose cells is there yet: the shards have that round to run, not cells to rerun (README's
/// reference; `jobs/slurm/merge.sbatch` submits the round on it).
pub const NEXT_ROUND: u8 = 3;

impl MergeOutcome {
    /// [`NEXT_ROUND`] when a coordinate search waits for a round none of whose cells is there
    /// ([`MergeOutcome::next_round`]); 1 when cells are missing (without `partial`) or a cell
    /// of the table failed; else 0.
    pub fn exit_code(&self) -> u8 {
        match self.end {
            MergeEnd::Incomplete if self.next_round().is_some() => NEXT_ROUND,
            MergeEnd::Incomplete => 1,
            _ if self.failed > 0 => 1,
            _ => 0,
        }
    }

    /// The round a coordinate search waits for when the merge wrote nothing and none of the
    /// round's cells or least-squares fits is there yet: every earlier round finished, the
    /// shards' next round. None when the search is finished or merged, for a product, and for
    /// a round some of whose cells are there (its shards ran: the rest are missing cells).
    pub fn next_round(&self) -> Option<&search::Pending> {
        if !matches!(self.end, MergeEnd::Incomplete) {
            return None;
        }
        let pending = self.search.as_ref()?.pending.as_ref()?;
        let round = self.plan.as_ref()?;
        (self.missing.cells == round.n_cells() && self.missing.ls == round.pairs.len()).then_some(pending)
    }
}

/// Merge every checkpoint folder of an output folder (shards, or an interrupted whole run):
/// check that together they hold every cell of the job exactly once and write the result files
/// exactly as a whole run does (same rows, same order, same reducer). Missing cells: nothing
/// is written unless `partial`. A complete merge deletes the checkpoint, like a whole run; a
/// folder already merged is left as it is (so a merge job that runs twice succeeds twice).
pub fn merge(out: &Path, partial: bool, report: bool) -> Result<MergeOutcome> {
    if !out.is_dir() {
        return Err(Error::input(out, "not a folder"));
    }
    let _lock = crate::lock::lock_output(out)?;
    let mut result = MergeOutcome {
        end: MergeEnd::AlreadyMerged,
        name: String::new(),
        plan: None,
        missing: Missing::default(),
        owners: None,
        folders: Vec::new(),
        duplicates: 0,
        huber: 0,
        ls: 0,
        failed: 0,
        cleanup: None,
        report: None,
        search: None,
    };
    let merged = export::RESULT_FILES.iter().all(|f| out.join(f).is_file());
    if !merged || out.join(checkpoint::PARTS_DIR).exists() {
        let g = checkpoint::gather(out)?;
        result.name = g.job.job.name.clone();
        result.duplicates = g.duplicates;
        result.folders = g.folders.iter().filter(|(_, _, n)| *n > 0).map(|(d, _, n)| (d.clone(), *n)).collect();
        // The shards to rerun, when the folders say how the job was split.
        let counts: BTreeSet<usize> = g.folders.iter().filter_map(|(_, s, _)| s.map(|s| s.count)).collect();
        let split = match counts.iter().copied().collect::<Vec<_>>()[..] {
            [n] => Some(n),
            _ => None,
        };
        let owners = |plan: &Plan, missing: &Missing| {
            split.map(|n| {
                let layout = shard::layout(plan, n);
                let owners = (0..n)
                    .filter(|&s| layout[s].iter().any(|p| missing.pairs.iter().any(|(q, _, _)| q == p)))
                    .collect();
                (n, owners)
            })
        };
        let (rows, prepared) = match Search::of_job(&g.job, &g.plan) {
            Search::Product => {
                result.missing = shard::missing(&g.plan, &g.rows);
                result.owners = owners(&g.plan, &result.missing);
                result.plan = Some(g.plan.clone());
                if !result.missing.is_empty() && !partial {
                    result.end = MergeEnd::Incomplete;
                    return Ok(result);
                }
                // The records read again (not kept in the folder), for the nested pass of a whole run.
                let mut prepared = prepare_job(g.job.clone()).ok();
                let mut rows = g.rows;
                if let Some(p) = &mut prepared {
                    let skipped = sweep::nested_pass_of_rows_from(&g.kernels, &g.plan, &p.context(), &mut rows)?;
                    p.inputs.warnings.extend(skipped);
                }
                (rows, prepared)
            }
            Search::Coordinate(c) => {
                let (rows, rounds, prepared) = replay(&g, &c)?;
                match &rounds.pending {
                    Some(pending) => {
                        let round = pending.plan(&g.plan);
                        result.missing = shard::missing(&round, &g.rows);
                        result.owners = owners(&round, &result.missing);
                        result.plan = Some(round);
                    }
                    None => {
                        let pairs = rows.iter().filter(|r| !r.is_huber()).map(|r| r.key.structure()).collect();
                        result.plan =
                            Some(Plan { pairs, ls_support: Vec::new(), ks: g.plan.ks.clone(), start: g.plan.start });
                    }
                }
                let finished = rounds.pending.is_none();
                result.search = Some(rounds);
                if !finished && !partial {
                    result.end = MergeEnd::Incomplete;
                    return Ok(result);
                }
                (rows, Some(prepared))
            }
        };
        let inputs = prepared.as_ref().map(|p| (&p.inputs, &p.gaps));
        let selection = write_results(out, &g.job, &rows, inputs, 0)?;
        result.huber = crate::table::huber_rows(&rows);
        result.ls = rows.len() - result.huber;
        if result.missing.is_empty() {
            result.cleanup = checkpoint::remove(out).err();
        }
        result.end = MergeEnd::Merged { selection: Box::new(selection) };
    }
    if report {
        result.report = Some(crate::report::write_report(out));
    }
    result.failed = crate::table::failed_cells(&export::parquet::read_cells(&out.join(export::CELLS_FILE))?);
    Ok(result)
}

/// A coordinate search's rounds replayed from the gathered rows ([`search::Step::Replay`]): the
/// rows of its finished rounds as the whole run leaves them (each round's nested check made
/// again), the rounds (with the one waiting for rows, if any) and the job prepared. The records
/// must be there and the rows of this machine's kernels: the replay refits (nested checks) and
/// picks again, which the shards did on their kernels.
fn replay(g: &Gathered, c: &Coordinate) -> Result<(Vec<CellRow>, search::Rounds, super::Prepared)> {
    let here = crate::kernels::flavour().name();
    if g.kernels != here {
        return Err(Error::Invalid(format!(
            "merge: the coordinate search's rows were computed with the {} kernels and this machine runs the {here} \
             kernels; the merge replays its rounds (nested checks and lead picks) from the rows, so merge on a \
             machine of the rows' kind",
            g.kernels
        )));
    }
    let p = prepare_job(g.job.clone())?;
    let lead = |rows: &[CellRow]| lead_structure(&p.job, rows);
    let guide = search::Guide { lead: &lead, grow: &|_| (), step: search::Step::Replay };
    let never = AtomicBool::new(false);
    let control = sweep::Control { done: g.rows.clone(), on_row: &|_: &CellRow| (), stop: &never, nested: true };
    let quiet = Progress::new(0, true);
    let (out, rounds) = search::coordinate(c, &g.plan, &p.context(), 0, &quiet, control, guide)?;
    Ok((out.rows, rounds, p))
}
