//! `oesweep slurm`: submit a job to Slurm as an array job of N shards (`oesweep run JOB --shard
//! I/N` per task) and a merge job that waits for it (`afterok`). Slurm does the scheduling,
//! retries and accounting; this only spares the user two sbatch lines and the dependency id,
//! after checking the job here, on the login node, rather than in N array tasks an hour later.
//!
//! A coordinate search (METHOD.md 20) is sharded round by round, so it is submitted as a loop
//! ([`rounds`]): each array fits the shards' share of the first round whose rows are missing;
//! its merge job either writes the results (the search is finished) or finds the next round
//! waiting with none of its cells there (`oesweep merge` exits [`NEXT_ROUND`]), and then
//! `merge.sbatch` runs `oesweep slurm --next-round OUTPUT` ([`next_round`]), which submits that
//! round's array and the merge after it from the request kept in `<output>/slurm/search.json`.

mod rounds;

pub use crate::engine::NEXT_ROUND;
pub use rounds::{Array, Decision, Found, Loop, Next, STATE_FILE, next_round};

use crate::error::{Error, Result};
use crate::search::Search;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The sbatch templates built into the binary (the files of `jobs/slurm/`), so that
/// `oesweep slurm` works from an installed binary without the source tree.
pub const SWEEP_SBATCH: &str = include_str!("../../jobs/slurm/sweep.sbatch");
pub const MERGE_SBATCH: &str = include_str!("../../jobs/slurm/merge.sbatch");

/// `--max-rounds` by default: arrays per input of a coordinate search. The searches of METHOD.md
/// 20 end within two cycles over the inputs; ten are room for a long one, and a bound for a
/// loop that would not end.
pub const ROUNDS_PER_INPUT: usize = 10;

/// What to submit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SlurmRequest {
    pub job: PathBuf,
    /// Number of shards (array tasks), >= 1.
    pub shards: usize,
    /// A folder with the user's own `sweep.sbatch` and `merge.sbatch` (default: the built-in
    /// templates, written to `<output>/slurm/`).
    pub sbatch: Option<PathBuf>,
    pub cpus_per_task: Option<usize>,
    /// Extra options for both sbatch calls.
    pub sbatch_args: Vec<String>,
    /// Let the merge job write the report too.
    pub report: bool,
    /// A coordinate search: the most arrays (rounds) the loop submits (default
    /// [`ROUNDS_PER_INPUT`] per input). A product's one array takes none.
    pub max_rounds: Option<usize>,
}

impl SlurmRequest {
    /// The command line that submits this request (for a message saying how to go on).
    pub fn command_line(&self) -> String {
        let quote = |s: String| if s.contains(char::is_whitespace) { format!("'{s}'") } else { s };
        let mut words = vec![
            "oesweep slurm".to_string(),
            quote(self.job.display().to_string()),
            format!("--shards {}", self.shards),
        ];
        words.extend(self.cpus_per_task.map(|c| format!("--cpus-per-task {c}")));
        words.extend(self.sbatch.as_ref().map(|d| format!("--sbatch {}", quote(d.display().to_string()))));
        words.extend(self.sbatch_args.iter().map(|a| quote(format!("--sbatch-arg={a}"))));
        words.extend(self.report.then(|| "--report".to_string()));
        words.extend(self.max_rounds.map(|r| format!("--max-rounds {r}")));
        words.join(" ")
    }
}

/// One sbatch call: its arguments, and the oesweep binary the scripts run (`OESWEEP`).
#[derive(Clone, Debug)]
pub struct Sbatch {
    pub exe: PathBuf,
    pub args: Vec<String>,
}

/// The ids of a submission.
#[derive(Clone, Debug)]
pub struct Submitted {
    pub sweep_id: String,
    pub merge_id: String,
    /// The job's output folder and the Slurm logs in it.
    pub out: PathBuf,
    pub logs: PathBuf,
    /// A coordinate search: the round of the array (None: the rows of an earlier run say which
    /// one) and the most arrays the loop submits.
    pub search: Option<(Option<usize>, usize)>,
}

struct Layout {
    out: PathBuf,
    logs: PathBuf,
    sweep_script: PathBuf,
    merge_script: PathBuf,
    sweep: Sbatch,
    merge: Sbatch,
    /// The request with its paths made absolute (what a merge job submits the next round from).
    request: SlurmRequest,
    /// A coordinate search: its most arrays.
    max_rounds: Option<usize>,
}

fn layout(req: &SlurmRequest) -> Result<Layout> {
    if req.shards == 0 {
        return Err(Error::Invalid("--shards must be at least 1".into()));
    }
    if req.cpus_per_task == Some(0) {
        return Err(Error::Invalid("--cpus-per-task must be at least 1".into()));
    }
    if req.max_rounds == Some(0) {
        return Err(Error::Invalid("--max-rounds must be at least 1".into()));
    }
    // Bad input is found here, not in N array tasks an hour later in the queue.
    let p = crate::engine::prepare(&req.job)?;
    let n = req.shards;
    let max_rounds = match &p.search {
        Search::Product if req.max_rounds.is_some() => {
            return Err(Error::Invalid(
                "--max-rounds: the job runs the full product of its grid in one array (grid.search), not a \
                 coordinate search round by round"
                    .into(),
            ));
        }
        Search::Product => None,
        Search::Coordinate(_) => Some(req.max_rounds.unwrap_or(ROUNDS_PER_INPUT * p.job.m)),
    };
    crate::shard::check_count(n, &p.plan).map_err(|m| Error::Invalid(format!("--shards {n}: {m}")))?;
    let out = p.job.output().to_path_buf();
    let job_file = absolute(&req.job)?;
    let logs = out.join("slurm");
    let (sbatch, sweep_script, merge_script) = match &req.sbatch {
        Some(dir) => {
            let (s, m) = (dir.join("sweep.sbatch"), dir.join("merge.sbatch"));
            for f in [&s, &m] {
                if !f.is_file() {
                    return Err(Error::input(
                        f,
                        "not found (--sbatch names a folder with sweep.sbatch and merge.sbatch)",
                    ));
                }
            }
            let text = std::fs::read_to_string(&m).map_err(|e| Error::input(&m, format!("cannot read: {e}")))?;
            if max_rounds.is_some() && !text.contains("--next-round") {
                return Err(Error::input(
                    &m,
                    "does not go on with a coordinate search (grid.search): when `oesweep merge` exits 3 it must run \
                     `oesweep slurm --next-round OUTPUT_FOLDER`, as jobs/slurm/merge.sbatch does, or the search stops \
                     after its first round",
                ));
            }
            let dir = absolute(dir)?;
            (Some(dir.clone()), dir.join("sweep.sbatch"), dir.join("merge.sbatch"))
        }
        None => (None, logs.join("sweep.sbatch"), logs.join("merge.sbatch")),
    };
    let exe = std::env::current_exe().map_err(|e| Error::Invalid(format!("cannot locate the oesweep binary: {e}")))?;
    let name = p.job.job.name.replace(char::is_whitespace, "_");
    let mut sweep: Vec<String> = vec![
        "--parsable".into(),
        format!("--array=0-{}", req.shards - 1),
        format!("--job-name=oesweep-{name}"),
        format!("--output={}", logs.join("sweep-%A_%a.out").display()),
    ];
    if let Some(c) = req.cpus_per_task {
        sweep.push(format!("--cpus-per-task={c}"));
    }
    sweep.extend(req.sbatch_args.iter().cloned());
    sweep.extend([sweep_script.display().to_string(), job_file.display().to_string(), req.shards.to_string()]);
    let mut merge: Vec<String> = vec![
        "--parsable".into(),
        format!("--job-name=oesweep-{name}-merge"),
        format!("--output={}", logs.join("merge-%j.out").display()),
    ];
    merge.extend(req.sbatch_args.iter().cloned());
    merge.extend([merge_script.display().to_string(), out.display().to_string()]);
    if req.report {
        merge.push("--report".into());
    }
    let request = SlurmRequest { job: job_file, sbatch, ..req.clone() };
    Ok(Layout {
        out,
        logs,
        sweep_script,
        merge_script,
        sweep: Sbatch { exe: exe.clone(), args: sweep },
        merge: Sbatch { exe, args: merge },
        request,
        max_rounds,
    })
}

/// `path` made absolute: a job's tasks and merges run in other folders, at other times.
fn absolute(path: &Path) -> Result<PathBuf> {
    path.canonicalize().map_err(|e| Error::input(path, format!("cannot resolve: {e}")))
}

/// The two sbatch calls [`submit`] would make (the merge's without its dependency), for a dry
/// run, and whether the job is a coordinate search (its merge job submits the next rounds).
/// Checks the job; writes nothing.
pub fn commands(req: &SlurmRequest) -> Result<(Sbatch, Sbatch, bool)> {
    let l = layout(req)?;
    Ok((l.sweep, l.merge, l.max_rounds.is_some()))
}

/// Submit the array job, then the merge job depending on it; for a coordinate search, also
/// start the loop's state (`<output>/slurm/search.json`), from which its merge jobs submit the
/// next rounds.
pub fn submit(req: &SlurmRequest) -> Result<Submitted> {
    let l = layout(req)?;
    // Slurm opens the log files there, so the folder must exist before the tasks start.
    std::fs::create_dir_all(&l.logs).map_err(|e| Error::output(&l.logs, format!("cannot create: {e}")))?;
    if req.sbatch.is_none() {
        for (path, text) in [(&l.sweep_script, SWEEP_SBATCH), (&l.merge_script, MERGE_SBATCH)] {
            std::fs::write(path, text).map_err(|e| Error::output(path, format!("cannot write: {e}")))?;
        }
    }
    match l.max_rounds {
        None => submit_pair(l, None),
        Some(max_rounds) => {
            // A fresh folder's search starts at round 1; in a checkpoint the rows say which round
            // waits, and the merge after the array finds it.
            let round = (!l.out.join(crate::checkpoint::PARTS_DIR).exists()).then_some(1);
            let state = Loop { request: l.request.clone(), max_rounds, arrays: Vec::new() };
            state.submit(l, round)
        }
    }
}

/// The array, then the merge that depends on it.
fn submit_pair(mut l: Layout, search: Option<(Option<usize>, usize)>) -> Result<Submitted> {
    let sweep_id = sbatch(&l.sweep)?;
    l.merge.args.insert(1, format!("--dependency=afterok:{sweep_id}"));
    let merge_id = sbatch(&l.merge)?;
    Ok(Submitted { sweep_id, merge_id, out: l.out, logs: l.logs, search })
}

/// sbatch's own input variables among the `SLURM_*` ones (sbatch(1), "INPUT ENVIRONMENT
/// VARIABLES"), kept for the sbatch a merge job runs.
const SBATCH_INPUTS: [&str; 7] = [
    "SLURM_CONF",
    "SLURM_CLUSTERS",
    "SLURM_HINT",
    "SLURM_DEBUG_FLAGS",
    "SLURM_EXIT_ERROR",
    "SLURM_STEP_KILLED_MSG_NODE_ID",
    "SLURM_UMASK",
];

/// A variable a job's environment has from Slurm, which sbatch would export into the jobs a
/// merge job submits (`--export=ALL`): where those jobs ask for less (no `--cpus-per-task`),
/// Slurm does not set it again and they would read the merge job's (its cpus, its id).
fn from_the_job(name: &str) -> bool {
    name.starts_with("SLURM_") && !SBATCH_INPUTS.contains(&name)
}

/// Run sbatch; returns the job id it printed.
fn sbatch(call: &Sbatch) -> Result<String> {
    let mut command = std::process::Command::new("sbatch");
    command.args(&call.args).env("OESWEEP", &call.exe);
    for (name, _) in std::env::vars_os() {
        if name.to_str().is_some_and(from_the_job) {
            command.env_remove(name);
        }
    }
    let o = command
        .output()
        .map_err(|e| Error::Invalid(format!("cannot run sbatch: {e} (is this a Slurm login node?)")))?;
    let stdout = String::from_utf8_lossy(&o.stdout);
    // --parsable prints `id` or `id;cluster`.
    let id = stdout.trim().split(';').next().unwrap_or("").to_string();
    if !o.status.success() || id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
        return Err(Error::Invalid(format!(
            "sbatch {} failed: {}{}",
            call.args.join(" "),
            String::from_utf8_lossy(&o.stderr).trim(),
            stdout.trim()
        )));
    }
    Ok(id)
}

#[cfg(test)]
mod tests;
