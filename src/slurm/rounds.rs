//! A coordinate search on Slurm, round by round (METHOD.md 20, "In shards"): the loop of an
//! array of shards and the merge job after it, one pair per round.
//!
//! The round is read from the rows alone (every shard replays the finished rounds and fits its
//! share of the first one whose rows are missing), so an array needs nothing but the job and N.
//! What a merge job must know to go on is kept in `<output>/slurm/search.json` ([`Loop`]): the
//! request (job, N, the sbatch options) and the arrays submitted so far with their rounds.
//! After each array its merge finds one of three things ([`Found`]) and the loop decides
//! ([`Loop::decide`]):
//!
//! - the search finished: the merge wrote the results; the loop ends;
//! - the next round waiting with none of its cells there (`oesweep merge` exits 3): its array
//!   and merge are submitted, unless the array just run was for that same round (it left no
//!   rows: no progress, the loop stops rather than submit it again) or the loop has submitted
//!   `max_rounds` arrays (a bound, so that no fault can loop for ever);
//! - cells of a round missing (some shard did not finish): the loop stops; the merge named them.
//!
//! A loop that stops exits 1 (its merge job fails) with one line saying how to go on; nothing
//! is lost, since a new `oesweep slurm JOB` resumes from the rows.

use super::{Layout, SlurmRequest, Submitted};
use crate::engine::{MergeEnd, MergeOutcome};
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The loop's state, in the Slurm folder of the output (`<output>/slurm/`).
pub const STATE_FILE: &str = "search.json";

/// A coordinate search submitted to Slurm: what its merge jobs submit the next rounds from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Loop {
    /// The request, its paths absolute.
    pub request: SlurmRequest,
    /// The most arrays the loop submits.
    pub max_rounds: usize,
    /// The arrays submitted so far, in order.
    pub arrays: Vec<Array>,
}

/// One array of the loop.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Array {
    /// The round its shards run (None: the first array on rows of an earlier run, whose round
    /// only the merge after it finds).
    pub round: Option<usize>,
    /// Slurm's ids of the array and of its merge job (None until sbatch answered).
    pub sweep_job: Option<String>,
    pub merge_job: Option<String>,
}

/// What a merge found, as the loop reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Found {
    /// The search is finished: the result files are written.
    Finished,
    /// This round waits and none of its cells is there ([`MergeOutcome::next_round`]).
    NextRound(usize),
    /// Cells of a round are missing: some of its shards did not finish.
    Missing,
}

impl Found {
    pub fn of(m: &MergeOutcome) -> Found {
        match (&m.end, m.next_round()) {
            (MergeEnd::Incomplete, Some(p)) => Found::NextRound(p.round),
            (MergeEnd::Incomplete, None) => Found::Missing,
            (MergeEnd::AlreadyMerged | MergeEnd::Merged { .. }, _) => Found::Finished,
        }
    }
}

/// What the loop does after a merge.
#[derive(Clone, Debug, PartialEq)]
pub enum Decision {
    /// Nothing more to submit.
    Finished,
    /// Submit this round's array and its merge.
    Submit(usize),
    /// Stop, saying why and how to go on.
    Stop(String),
}

/// What [`next_round`] did.
#[derive(Debug)]
pub enum Next {
    /// The search is finished; the merge's exit code (1 when a cell of the table failed).
    Finished { code: u8 },
    /// The next round is submitted: its array of `shards` tasks and its merge.
    Submitted { round: usize, shards: usize, submitted: Submitted },
    /// The loop stops ([`Decision::Stop`]).
    Stopped(String),
}

impl Loop {
    fn path(out: &Path) -> PathBuf {
        out.join("slurm").join(STATE_FILE)
    }

    /// The state of the loop that submitted into the output folder `out`.
    pub fn read(out: &Path) -> Result<Loop> {
        let path = Loop::path(out);
        let text = std::fs::read_to_string(&path).map_err(|e| {
            Error::input(
                &path,
                format!(
                    "cannot read ({e}): `--next-round` goes on with a coordinate search that `oesweep slurm JOB` \
                     submitted into this folder"
                ),
            )
        })?;
        serde_json::from_str(&text).map_err(|e| Error::input(&path, format!("not the state of a Slurm search: {e}")))
    }

    pub(super) fn write(&self, out: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self).expect("the state serialises");
        crate::export::write_atomically(&Loop::path(out), |f| {
            std::io::Write::write_all(f, format!("{text}\n").as_bytes()).map_err(|e| e.to_string())
        })
    }

    /// The command that starts the loop again (from the rows: nothing is fitted twice), with
    /// `max_rounds` arrays.
    fn again(&self, max_rounds: usize) -> String {
        let max_rounds = (max_rounds != self.max_rounds).then_some(max_rounds).or(self.request.max_rounds);
        format!("`{}`", SlurmRequest { max_rounds, ..self.request.clone() }.command_line())
    }

    /// What to do after a merge found `found`: the rule of the module doc.
    pub fn decide(&self, found: Found) -> Decision {
        let round = match found {
            Found::Finished => return Decision::Finished,
            Found::Missing => {
                return Decision::Stop(format!(
                    "the coordinate search stops: cells of its round are missing (`oesweep merge` names them and \
                     their shards); once those shards are rerun, `oesweep slurm --next-round OUTPUT` goes on, or \
                     submit again with {}",
                    self.again(self.max_rounds)
                ));
            }
            Found::NextRound(r) => r,
        };
        if let Some(last) = self.arrays.last().and_then(|a| a.round).filter(|&last| round <= last) {
            let job = self.arrays.last().and_then(|a| a.sweep_job.clone()).unwrap_or_else(|| "?".into());
            return Decision::Stop(format!(
                "the coordinate search stops: round {round} still waits after the array submitted for round {last} \
                 (Slurm job {job}), whose shards wrote none of its rows; see their logs, then submit again with {}",
                self.again(self.max_rounds)
            ));
        }
        if self.arrays.len() >= self.max_rounds {
            return Decision::Stop(format!(
                "the coordinate search stops: round {round} waits after {}, the most --max-rounds allows; \
                 to go on, submit again with {}",
                crate::text::count(self.arrays.len(), "array"),
                self.again(2 * self.max_rounds)
            ));
        }
        Decision::Submit(round)
    }

    /// Submit the array of `round` and its merge (from `l`, the layout of the request), the
    /// state written before sbatch is called (a merge job that starts reads it) and again with
    /// Slurm's ids.
    pub(super) fn submit(mut self, l: Layout, round: Option<usize>) -> Result<Submitted> {
        let out = l.out.clone();
        self.arrays.push(Array { round, sweep_job: None, merge_job: None });
        self.write(&out)?;
        let submitted = super::submit_pair(l, Some((round, self.max_rounds)))?;
        let last = self.arrays.last_mut().expect("the array just pushed");
        last.sweep_job = Some(submitted.sweep_id.clone());
        last.merge_job = Some(submitted.merge_id.clone());
        self.write(&out)?;
        Ok(submitted)
    }
}

/// `oesweep slurm --next-round OUTPUT`, what a coordinate search's merge job runs when `oesweep
/// merge` exits 3: merge again (the rounds replayed from the rows, nothing written unless the
/// search is finished), decide ([`Loop::decide`]) and submit the next round's array and merge.
pub fn next_round(out: &Path) -> Result<Next> {
    let state = Loop::read(out)?;
    let m = crate::engine::merge(out, false, false)?;
    match state.decide(Found::of(&m)) {
        Decision::Finished => Ok(Next::Finished { code: m.exit_code() }),
        Decision::Stop(why) => Ok(Next::Stopped(why)),
        Decision::Submit(round) => {
            let l = super::layout(&state.request)?;
            // The job file could have been edited since: its rounds would go to another folder.
            if l.out.canonicalize().ok() != out.canonicalize().ok() {
                return Err(Error::input(
                    Loop::path(out),
                    format!("its job writes to {}, not to this folder", l.out.display()),
                ));
            }
            let shards = state.request.shards;
            let submitted = state.submit(l, Some(round))?;
            Ok(Next::Submitted { round, shards, submitted })
        }
    }
}
