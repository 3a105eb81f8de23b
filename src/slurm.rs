//! `oesweep slurm`: submit a job to Slurm as an array job of N shards (`oesweep run JOB --shard
//! I/N` per task) and a merge job that waits for it (`afterok`). Slurm does the scheduling,
//! retries and accounting; this only spares the user two sbatch lines and the dependency id,
//! after checking the job here, on the login node, rather than in N array tasks an hour later.

use crate::error::{Error, Result};
use std::path::PathBuf;

/// The sbatch templates built into the binary (the files of `jobs/slurm/`), so that
/// `oesweep slurm` works from an installed binary without the source tree.
const SWEEP_SBATCH: &str = include_str!("../jobs/slurm/sweep.sbatch");
const MERGE_SBATCH: &str = include_str!("../jobs/slurm/merge.sbatch");

/// What to submit.
#[derive(Clone, Debug)]
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
}

struct Layout {
    out: PathBuf,
    logs: PathBuf,
    sweep_script: PathBuf,
    merge_script: PathBuf,
    sweep: Sbatch,
    merge: Sbatch,
}

fn layout(req: &SlurmRequest) -> Result<Layout> {
    if req.shards == 0 {
        return Err(Error::Invalid("--shards must be at least 1".into()));
    }
    if req.cpus_per_task == Some(0) {
        return Err(Error::Invalid("--cpus-per-task must be at least 1".into()));
    }
    // Bad input is found here, not in N array tasks an hour later in the queue.
    let p = crate::engine::prepare(&req.job)?;
    let n = req.shards;
    p.search.check_slurm(&format!("--shards {n}"))?;
    crate::shard::check_count(n, &p.plan).map_err(|m| Error::Invalid(format!("--shards {n}: {m}")))?;
    let out = p.job.output().to_path_buf();
    let job_file = req.job.canonicalize().map_err(|e| Error::input(&req.job, format!("cannot resolve: {e}")))?;
    let logs = out.join("slurm");
    let (sweep_script, merge_script) = match &req.sbatch {
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
            (s, m)
        }
        None => (logs.join("sweep.sbatch"), logs.join("merge.sbatch")),
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
    Ok(Layout {
        out,
        logs,
        sweep_script,
        merge_script,
        sweep: Sbatch { exe: exe.clone(), args: sweep },
        merge: Sbatch { exe, args: merge },
    })
}

/// The two sbatch calls [`submit`] would make (the merge's without its dependency), for a dry
/// run. Checks the job; writes nothing.
pub fn commands(req: &SlurmRequest) -> Result<(Sbatch, Sbatch)> {
    let l = layout(req)?;
    Ok((l.sweep, l.merge))
}

/// Submit the array job, then the merge job depending on it.
pub fn submit(req: &SlurmRequest) -> Result<Submitted> {
    let mut l = layout(req)?;
    // Slurm opens the log files there, so the folder must exist before the tasks start.
    std::fs::create_dir_all(&l.logs).map_err(|e| Error::output(&l.logs, format!("cannot create: {e}")))?;
    if req.sbatch.is_none() {
        for (path, text) in [(&l.sweep_script, SWEEP_SBATCH), (&l.merge_script, MERGE_SBATCH)] {
            std::fs::write(path, text).map_err(|e| Error::output(path, format!("cannot write: {e}")))?;
        }
    }
    let sweep_id = sbatch(&l.sweep)?;
    l.merge.args.insert(1, format!("--dependency=afterok:{sweep_id}"));
    let merge_id = sbatch(&l.merge)?;
    Ok(Submitted { sweep_id, merge_id, out: l.out, logs: l.logs })
}

/// Run sbatch; returns the job id it printed.
fn sbatch(call: &Sbatch) -> Result<String> {
    let o = std::process::Command::new("sbatch")
        .args(&call.args)
        .env("OESWEEP", &call.exe)
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
