//! `oesweep merge` and `oesweep slurm`: the shards of a job brought together, by hand or by
//! Slurm, and what they print.

use super::args::{MergeArgs, SlurmArgs};
use super::print::{print_gaps, print_pick_bootstraps, print_picks, print_report, print_rules};
use crate::engine::{self, MergeEnd};
use crate::error::Result;
use crate::shard;

/// `oesweep merge` ([`engine::merge`]).
pub(super) fn run_merge(a: &MergeArgs) -> Result<u8> {
    let out = &a.folder;
    let m = engine::merge(out, a.partial, a.report)?;
    if m.duplicates > 0 {
        eprintln!("note: {} cells were saved twice (identical rows); each is kept once", m.duplicates);
    }
    if let Some(p) = m.next_round() {
        let n = m.owners.as_ref().map_or("N".to_string(), |(n, _)| n.to_string());
        eprintln!("the search goes on: {}, none of whose cells is there yet", p.describe());
        eprintln!("nothing written; run `oesweep run JOB --shard I/{n}` for every I, then merge again (exit 3)");
        return Ok(m.exit_code());
    }
    if !m.missing.is_empty() {
        let plan = m.plan.as_ref().expect("a merge that found missing cells has a plan");
        eprintln!(
            "{}: {} of {} cells and {} of {} least-squares fits are missing:",
            out.display(),
            m.missing.cells,
            plan.n_cells(),
            m.missing.ls,
            plan.pairs.len()
        );
        for line in m.missing.lines(plan, 20) {
            eprintln!("  {line}");
        }
        if let Some((n, owners)) = &m.owners {
            eprintln!(
                "  they belong to shard {} of {n}: run `oesweep run JOB --shard I/{n}` for each",
                shard::ranges(owners)
            );
        }
    }
    match &m.end {
        MergeEnd::AlreadyMerged => outln!("{}: already merged (no checkpoint left), nothing to do", out.display()),
        MergeEnd::Incomplete => {
            if let Some(p) = m.search.as_ref().and_then(|r| r.pending.as_ref()) {
                eprintln!("the coordinate search goes on: {} waits for its rows", p.describe());
            }
            eprintln!(
                "nothing written; rerun the missing shards and merge again, or merge what there is with --partial"
            );
            return Ok(m.exit_code());
        }
        MergeEnd::Merged { selection } => {
            let plan = m.plan.as_ref().expect("merged from a plan");
            let read: Vec<String> = m
                .folders
                .iter()
                .map(|(d, n)| format!("{} ({n} parts)", d.file_name().unwrap_or_default().to_string_lossy()))
                .collect();
            outln!("merged {}", read.join(", "));
            outln!(
                "{}: {} of {} cells ({} failed) + {} of {} least-squares fits",
                m.name,
                m.huber,
                plan.n_cells(),
                m.failed,
                m.ls,
                plan.pairs.len()
            );
            print_gaps(selection.gaps.as_ref());
            print_picks(selection);
            print_rules(selection);
            print_pick_bootstraps(selection);
            for w in &selection.warnings {
                eprintln!("warning: {w}");
            }
            outln!("results in {}", out.display());
            if m.missing.is_empty() {
                if let Some(e) = &m.cleanup {
                    eprintln!("warning: {e}");
                }
            } else {
                outln!("partial merge: the checkpoint is kept; merge again once the missing cells are done");
            }
        }
    }
    let code = m.exit_code();
    print_report(m.report)?;
    Ok(code)
}

/// `oesweep slurm` ([`crate::slurm::submit`]; `--next-round`: [`crate::slurm::next_round`]).
pub(super) fn run_slurm(a: &SlurmArgs) -> Result<u8> {
    use crate::slurm::Next;
    let (job, shards) = match (&a.next_round, &a.job, a.shards) {
        (Some(out), _, _) => {
            return Ok(match crate::slurm::next_round(out)? {
                Next::Finished { code } => {
                    outln!("the coordinate search is finished: results in {}", out.display());
                    code
                }
                Next::Stopped(why) => {
                    eprintln!("{why}");
                    1
                }
                Next::Submitted { round, shards, submitted: s } => {
                    outln!(
                        "round {round} of the coordinate search: sweep job {} (array of {shards} shards)",
                        s.sweep_id
                    );
                    outln!("merge job {} (starts when every shard succeeded)", s.merge_id);
                    0
                }
            });
        }
        (None, Some(job), Some(shards)) => (job.clone(), shards),
        _ => unreachable!("clap requires JOB and --shards without --next-round"),
    };
    let req = crate::slurm::SlurmRequest {
        job,
        shards,
        sbatch: a.sbatch.clone(),
        cpus_per_task: a.cpus_per_task,
        sbatch_args: a.sbatch_arg.clone(),
        report: a.report,
        max_rounds: a.max_rounds,
    };
    if a.dry_run {
        let (sweep, merge, search) = crate::slurm::commands(&req)?;
        outln!("OESWEEP={} sbatch {}", sweep.exe.display(), sweep.args.join(" "));
        outln!("OESWEEP={} sbatch --dependency=afterok:<sweep job id> {}", merge.exe.display(), merge.args.join(" "));
        if search {
            outln!("(a coordinate search: its merge job submits each next round with `oesweep slurm --next-round`)");
        }
        return Ok(0);
    }
    let s = crate::slurm::submit(&req)?;
    match s.search {
        None => outln!("sweep job {} (array of {shards} shards)", s.sweep_id),
        Some((round, _)) => outln!(
            "sweep job {} (array of {shards} shards: {} of the coordinate search)",
            s.sweep_id,
            round.map_or("the round the rows wait for".into(), |r| format!("round {r}"))
        ),
    }
    outln!("merge job {} (starts when every shard succeeded)", s.merge_id);
    if let Some((_, max)) = s.search {
        let most = crate::text::count(max, "round");
        outln!("each merge job submits the next round until the search is finished (at most {most})");
    }
    outln!("results in {}, Slurm logs in {}", s.out.display(), s.logs.display());
    Ok(0)
}
