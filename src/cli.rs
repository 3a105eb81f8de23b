//! Command-line interface: argument definitions, their conversion into the library's
//! requests ([`crate::engine`], [`crate::slurm`]), and the printing of the outcomes. No
//! estimation, file layout or rule lives here.

use crate::checkpoint;
use crate::engine::{self, FitReport, FitRequest, MergeEnd, RunEnd, RunOptions};
use crate::error::{Error, Result};
use crate::estimate::{HuberHessian, SolverOptions};
use crate::plan::Plan;
use crate::reduce;
use crate::shard::{self, Shard};
use crate::simulate;
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(name = "oesweep", version, about = "Robust (Huber) output-error identification and model-order search")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Estimate one OE(nB, nF) model under Huber's criterion and report its quality.
    Fit(FitArgs),
    /// Make example data: PRBS input through an OE system, plus noise and outliers.
    Simulate(SimulateArgs),
    /// Validate a job file and its data without estimating; print the grid and the output folder.
    Plan(PlanArgs),
    /// Run a job: estimate every cell, write the result tables and the model picks.
    Run(RunArgs),
    /// Write report.html with figures for a finished sweep's output folder.
    Report(ReportArgs),
    /// Merge the shards (`run --shard I/N`) in an output folder into the result files.
    Merge(MergeArgs),
    /// Submit a job to Slurm: an array job of N shards, then a merge job that waits for them.
    Slurm(SlurmArgs),
}

#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Output folder the shards wrote into (the job's `output`).
    pub folder: PathBuf,
    /// Merge even when some cells are missing (the checkpoint is then kept).
    #[arg(long)]
    pub partial: bool,
    /// Also write the HTML report (see `oesweep report`).
    #[arg(long)]
    pub report: bool,
}

#[derive(Args, Debug)]
pub struct SlurmArgs {
    /// Job file (JSON).
    pub job: PathBuf,
    /// Number of shards (array tasks).
    #[arg(long)]
    pub shards: usize,
    /// Folder holding your own `sweep.sbatch` and `merge.sbatch` [default: the templates of
    /// jobs/slurm/ built into oesweep, written to <output>/slurm/].
    #[arg(long, value_name = "DIR")]
    pub sbatch: Option<PathBuf>,
    /// CPUs per array task (sbatch --cpus-per-task; each shard uses that many threads).
    #[arg(long)]
    pub cpus_per_task: Option<usize>,
    /// Extra option for both sbatch calls, e.g. --sbatch-arg=--partition=long (repeatable).
    #[arg(long, value_name = "OPTION", allow_hyphen_values = true)]
    pub sbatch_arg: Vec<String>,
    /// Let the merge job write the HTML report too.
    #[arg(long)]
    pub report: bool,
    /// Print the sbatch commands instead of running them.
    #[arg(long)]
    pub dry_run: bool,
}

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Output folder of a finished `oesweep run`.
    pub folder: PathBuf,
}

#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Job file (JSON).
    pub job: PathBuf,
    /// Also print how `run --shard I/N` splits the job into N shards.
    #[arg(long, value_name = "N")]
    pub shards: Option<usize>,
}

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Job file (JSON).
    pub job: PathBuf,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// No progress output.
    #[arg(long)]
    pub quiet: bool,
    /// Also write the HTML report (see `oesweep report`).
    #[arg(long)]
    pub report: bool,
    /// Start over: delete the checkpoint of an interrupted run in the output folder instead of
    /// resuming from it (needed when the job or its data changed since).
    #[arg(long)]
    pub force: bool,
    /// Save finished cells to the checkpoint at least this often (and every 500 cells).
    #[arg(long, value_name = "SECONDS", default_value_t = checkpoint::BATCH_SECONDS)]
    pub checkpoint_every: f64,
    /// Run only shard I (0-based) of N: a share of the order pairs, saved in
    /// <output>/parts/shard-I-of-N/ and not merged (see `oesweep merge`).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<Shard>,
}

#[derive(Args, Debug)]
pub struct FitArgs {
    /// Estimation record (CSV with a header row, or Parquet).
    #[arg(long)]
    pub data: PathBuf,
    /// Validation record, used only to judge the model.
    #[arg(long)]
    pub validation: Option<PathBuf>,
    /// Number of B coefficients (numerator), >= 1.
    #[arg(long)]
    pub nb: usize,
    /// Number of F coefficients (denominator order), >= 0.
    #[arg(long)]
    pub nf: usize,
    /// Huber tuning constant: gamma = k * sigma (sigma from the least-squares fit).
    #[arg(long)]
    pub k: f64,
    /// Input delay d in samples.
    #[arg(long, default_value_t = 1)]
    pub delay: usize,
    /// Sampling period in seconds (needed for --band).
    #[arg(long)]
    pub ts: Option<f64>,
    /// Frequency band LO,HI in Hz for the band fit against a Welch spectral estimate.
    #[arg(long, value_parser = parse_band)]
    pub band: Option<(f64, f64)>,
    /// Input column name.
    #[arg(long, default_value = "u")]
    pub u: String,
    /// Output column name of the estimation record.
    #[arg(long, default_value = "y")]
    pub y: String,
    /// Output column of the validation record [default: `y0` (noise-free output, as written
    /// by `oesweep simulate`) when the file has one, else the --y column].
    #[arg(long)]
    pub val_y: Option<String>,
    /// Iteration cap of each minimisation.
    #[arg(long, default_value_t = SolverOptions::default().max_iterations)]
    pub max_iterations: usize,
    /// Relative criterion-change tolerance of each minimisation.
    #[arg(long, default_value_t = SolverOptions::default().ftol)]
    pub ftol: f64,
    /// Huber Hessian: exact Gauss-Newton (L1 rows weight 0) or IRLS (weight gamma/|e|).
    #[arg(long, value_enum, default_value = "gauss-newton")]
    pub huber_hessian: HessianArg,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// System file: {"b": [...], "f": [...], "delay": 1}.
    #[arg(long)]
    pub system: PathBuf,
    /// Output CSV (columns u, y, y0).
    #[arg(long)]
    pub out: PathBuf,
    /// Number of samples.
    #[arg(long, default_value_t = 5000)]
    pub n: usize,
    /// Seed of the PRBS state and of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// PRBS shift-register length (period 2^bits - 1).
    #[arg(long, default_value_t = 10)]
    pub bits: u32,
    /// PRBS level: the input is +/- amplitude.
    #[arg(long, default_value_t = 10.0)]
    pub amplitude: f64,
    /// Standard deviation (Gaussian) or scale (Student-t) of the output noise.
    #[arg(long, default_value_t = 0.0)]
    pub noise_std: f64,
    /// Student-t noise with this many degrees of freedom instead of Gaussian.
    #[arg(long)]
    pub student_t: Option<f64>,
    /// Probability of an output spike per sample.
    #[arg(long, default_value_t = 0.0)]
    pub outlier_prob: f64,
    /// Spike magnitude range MIN,MAX (random sign).
    #[arg(long, value_parser = parse_band, default_value = "5,10")]
    pub outlier_range: (f64, f64),
}

/// `--huber-hessian` ([`HuberHessian`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum HessianArg {
    GaussNewton,
    Irls,
}

impl From<HessianArg> for HuberHessian {
    fn from(a: HessianArg) -> Self {
        match a {
            HessianArg::GaussNewton => HuberHessian::GaussNewton,
            HessianArg::Irls => HuberHessian::Irls,
        }
    }
}

fn parse_band(s: &str) -> std::result::Result<(f64, f64), String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 2 {
        return Err(format!("expected two numbers LO,HI, got '{s}'"));
    }
    let p = |x: &str| x.trim().parse::<f64>().map_err(|_| format!("'{x}' is not a number"));
    Ok((p(parts[0])?, p(parts[1])?))
}

/// Run a parsed command; returns the process exit code.
pub fn run(cli: Cli) -> Result<u8> {
    match cli.command {
        Command::Fit(a) => run_fit(&a),
        Command::Simulate(a) => run_simulate(&a),
        Command::Plan(a) => run_plan(&a),
        Command::Run(a) => run_job(&a),
        Command::Report(a) => {
            let page = crate::report::write_report(&a.folder)?;
            println!("wrote {}", page.display());
            Ok(0)
        }
        Command::Merge(a) => run_merge(&a),
        Command::Slurm(a) => run_slurm(&a),
    }
}

fn run_fit(a: &FitArgs) -> Result<u8> {
    let req = FitRequest {
        data: a.data.clone(),
        u: a.u.clone(),
        y: a.y.clone(),
        validation: a.validation.clone(),
        val_y: a.val_y.clone(),
        nb: a.nb,
        nf: a.nf,
        k: a.k,
        delay: a.delay,
        ts: a.ts,
        band: a.band,
        solver: SolverOptions {
            max_iterations: a.max_iterations,
            ftol: a.ftol,
            huber_hessian: a.huber_hessian.into(),
            ..Default::default()
        },
    };
    let report = engine::fit(&req)?;
    if a.json {
        println!("{}", serde_json::to_string(&report).expect("report serialises"));
    } else {
        print_fit_summary(&report);
    }
    Ok(0)
}

fn opt_pct(v: Option<f64>) -> String {
    v.map_or_else(|| "-".to_string(), |x| format!("{x:.2} %"))
}

fn print_fit_summary(r: &FitReport) {
    let h = &r.huber;
    let l = &r.ls;
    println!("OE(nB={}, nF={}) delay {} on {} ({} samples)", r.nb, r.nf, r.delay, r.data.display(), r.n);
    if let (Some(p), Some(c)) = (&r.validation, &r.validation_column) {
        println!("validation: {} (column '{c}')", p.display());
    }
    println!();
    println!("{:<22}{:>18}{:>18}", "", "least squares", format!("Huber k={}", h.k));
    println!("{:<22}{:>18.6e}{:>18.6e}", "criterion", l.criterion, h.criterion);
    println!("{:<22}{:>18}{:>18.6e}", "gamma", "-", h.gamma);
    println!("{:<22}{:>18.6e}{:>18}", "sigma", l.sigma, "");
    println!("{:<22}{:>18}{:>18}", "L1C", "-", format!("{:.2} %", 100.0 * h.l1c));
    println!(
        "{:<22}{:>18}{:>18}",
        "fit (estimation)",
        opt_pct(Some(l.assessment.fit)),
        opt_pct(Some(h.assessment.fit))
    );
    println!("{:<22}{:>18}{:>18}", "fit (validation)", opt_pct(l.assessment.fit_val), opt_pct(h.assessment.fit_val));
    println!("{:<22}{:>18}{:>18}", "fit (band)", opt_pct(l.assessment.fit_band), opt_pct(h.assessment.fit_band));
    println!("{:<22}{:>18}{:>18}", "iterations", l.iterations, h.iterations);
    println!("{:<22}{:>18}{:>18}", "termination", l.termination.as_str(), h.termination.as_str());
    println!("{:<22}{:>18.6}{:>18.6}", "max pole radius", l.assessment.max_pole_radius, h.assessment.max_pole_radius);
    println!();
    println!("Huber b = {:?}", h.b);
    println!("Huber f = {:?}", h.f);
    println!("({:.3} s)", r.seconds);
}

fn run_simulate(a: &SimulateArgs) -> Result<u8> {
    let (lo, hi) = a.outlier_range;
    if a.n == 0 {
        return Err(Error::Invalid("--n must be at least 1".into()));
    }
    if !(a.noise_std >= 0.0 && a.noise_std.is_finite()) {
        return Err(Error::Invalid(format!("--noise-std must be >= 0, got {}", a.noise_std)));
    }
    if !(0.0..=1.0).contains(&a.outlier_prob) {
        return Err(Error::Invalid(format!("--outlier-prob must be in [0, 1], got {}", a.outlier_prob)));
    }
    if !(lo >= 0.0 && hi >= lo && hi.is_finite()) {
        return Err(Error::Invalid(format!("--outlier-range {lo},{hi}: need 0 <= MIN <= MAX")));
    }
    if let Some(dof) = a.student_t
        && (dof <= 0.0 || dof.is_nan())
    {
        return Err(Error::Invalid(format!("--student-t needs positive degrees of freedom, got {dof}")));
    }
    let opts = simulate::SimOptions {
        n: a.n,
        bits: a.bits,
        amplitude: a.amplitude,
        seed: a.seed,
        noise_std: a.noise_std,
        noise: match a.student_t {
            Some(dof) => simulate::NoiseKind::StudentT { dof },
            None => simulate::NoiseKind::Gaussian,
        },
        outliers: (a.outlier_prob > 0.0).then_some(simulate::Outliers {
            probability: a.outlier_prob,
            min: a.outlier_range.0,
            max: a.outlier_range.1,
        }),
    };
    let n = engine::simulate(&a.system, &a.out, &opts)?;
    eprintln!("wrote {} ({n} samples)", a.out.display());
    Ok(0)
}

fn describe_grid(p: &engine::Prepared) -> String {
    let (job, ks) = (&p.job, &p.job.ks);
    let (kmin, kmax) = ks.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &k| (a.min(k), b.max(k)));
    format!(
        "nB {}..{} x nF {}..{} x {} values of k in [{kmin}, {kmax}]",
        job.nb[0],
        job.nb[job.nb.len() - 1],
        job.nf[0],
        job.nf[job.nf.len() - 1],
        ks.len()
    )
}

fn run_plan(a: &PlanArgs) -> Result<u8> {
    let p = engine::prepare(&a.job)?;
    let j = &p.job;
    println!("job        {} ({})", j.job.name, j.file.display());
    println!("data       {} ({} samples, Ts = {} s)", j.job.data.path.display(), p.inputs.est.u.len(), j.ts());
    if let (Some(v), Some(rec)) = (&j.job.validation, &p.inputs.val) {
        println!("validation {} ({} samples, column '{}')", v.path.display(), rec.u.len(), rec.y_name);
    }
    println!("grid       {}", describe_grid(&p));
    println!("cells      {} Huber cells + {} least-squares fits", j.n_cells(), j.n_pairs());
    println!("start      {}", j.job.start.as_str());
    println!("ranking    by {:?} fit", p.ranking());
    println!("output     {}", j.output().display());
    if let Some(n) = a.shards {
        if n == 0 {
            return Err(Error::Invalid("--shards must be at least 1".into()));
        }
        print_layout(&p.plan, n);
    }
    Ok(0)
}

/// The shard layout of `oesweep plan --shards N`: per shard its pairs, cells and estimated cost.
fn print_layout(plan: &Plan, n: usize) {
    let layout = shard::layout(plan, n);
    let total: f64 = (0..plan.pairs.len()).map(|p| shard::pair_cost(plan, p)).sum();
    println!("shards     {n} (run each with `oesweep run JOB --shard I/{n}`, then `oesweep merge OUTPUT`)");
    println!("{:>7} {:>6} {:>7} {:>11} {:>7}  order pairs (nB,nF)", "shard", "pairs", "cells", "est. cost", "share");
    for (i, pairs) in layout.iter().enumerate() {
        let cost: f64 = pairs.iter().map(|&p| shard::pair_cost(plan, p)).sum();
        let list: Vec<String> = pairs.iter().map(|&p| format!("({},{})", plan.pairs[p].nb, plan.pairs[p].nf)).collect();
        println!(
            "{:>7} {:>6} {:>7} {:>11} {:>6.1}%  {}",
            format!("{i}/{n}"),
            pairs.len(),
            pairs.len() * plan.ks.len(),
            cost,
            100.0 * cost / total.max(1.0),
            list.join(" ")
        );
    }
}

fn print_picks(selection: &reduce::Selection) {
    for (label, pick) in [("M1 (W minima)  ", &selection.m1), ("M2 (L1C minima)", &selection.m2)] {
        match pick {
            Some(m) => println!(
                "{label} OE({}, {}) k = {} gamma = {:.4e}  W = {:.4e}  L1C = {:.2} %  fit = {}",
                m.model.nb,
                m.model.nf,
                m.model.k,
                m.model.gamma,
                m.model.criterion,
                100.0 * m.model.l1c,
                opt_pct(Some(m.model.score))
            ),
            None => println!("{label} none (no usable cell)"),
        }
    }
}

/// The page of a report, or its error after the summary was printed.
fn print_report(report: Option<Result<PathBuf>>) -> Result<()> {
    if let Some(page) = report {
        println!("report in {}", page?.display());
    }
    Ok(())
}

/// `oesweep run` ([`engine::run`]).
fn run_job(a: &RunArgs) -> Result<u8> {
    let opts = RunOptions {
        threads: a.threads,
        quiet: a.quiet,
        force: a.force,
        checkpoint_every: a.checkpoint_every,
        shard: a.shard,
        report: a.report,
    };
    let on_resume = |r: &engine::Resumed| {
        if r.cells + r.ls > 0 && !a.quiet {
            eprintln!(
                "resuming from {} ({} parts): {} of {} cells and {} of {} least-squares fits already done",
                r.folder.display(),
                r.parts,
                r.cells,
                r.plan_cells,
                r.ls,
                r.plan_pairs,
            );
        }
        if r.duplicates > 0 {
            eprintln!(
                "warning: {}: {} duplicate rows ignored (the first of each cell is kept)",
                r.folder.display(),
                r.duplicates
            );
        }
    };
    let o = engine::run(&a.job, &opts, &on_resume)?;
    if let Some((n, e)) = &o.unsaved {
        eprintln!("warning: {n} finished rows could not be saved to the checkpoint: {e}");
    }
    let (cells, pairs, failed) = (o.cells, o.pairs, o.failed);
    let rate = o.computed as f64 / o.seconds.max(1e-9);
    match o.end {
        RunEnd::Interrupted => {
            let shard_arg = o.shard.map_or(String::new(), |s| format!(" --shard {s}"));
            eprintln!(
                "interrupted: {} of {cells} cells finished ({} in this run); they are saved in {}",
                o.finished,
                o.computed,
                o.checkpoint.display()
            );
            eprintln!(
                "to resume, run `oesweep run {}{shard_arg}` again (with --force to start over instead)",
                a.job.display()
            );
        }
        RunEnd::ShardSaved => {
            let label = &o.label;
            println!(
                "{label}: {cells} cells ({failed} failed) + {pairs} least-squares fits, saved in {}",
                o.checkpoint.display()
            );
            if o.resumed_rows > 0 {
                println!("{} cells resumed from the checkpoint, {} computed in this run", o.resumed, o.computed);
            }
            println!("wall time {:.2} s, {rate:.1} cells/s", o.seconds);
            let count = o.shard.map_or(1, |s| s.count);
            println!("when all {count} shards are done: oesweep merge {}", o.out.display());
        }
        RunEnd::Merged { ref selection, .. } => {
            println!("{}: {cells} cells ({failed} failed) + {pairs} least-squares fits", o.label);
            if o.resumed_rows > 0 {
                println!(
                    "{} cells and {} least-squares fits resumed from the checkpoint, {} cells computed in this run",
                    o.resumed,
                    o.resumed_rows - o.resumed,
                    o.computed
                );
            }
            println!("wall time {:.2} s, {rate:.1} cells/s", o.seconds);
            print_picks(selection);
            println!("results in {}", o.out.display());
            if let Some(e) = &o.cleanup {
                eprintln!("warning: {e}");
            }
        }
    }
    let code = o.exit_code();
    if let RunEnd::Merged { report, .. } = o.end {
        print_report(report)?;
    }
    Ok(code)
}

/// `oesweep merge` ([`engine::merge`]).
fn run_merge(a: &MergeArgs) -> Result<u8> {
    let out = &a.folder;
    let m = engine::merge(out, a.partial, a.report)?;
    if m.duplicates > 0 {
        eprintln!("note: {} cells were saved twice (identical rows); each is kept once", m.duplicates);
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
        MergeEnd::AlreadyMerged => println!("{}: already merged (no checkpoint left), nothing to do", out.display()),
        MergeEnd::Incomplete => {
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
            println!("merged {}", read.join(", "));
            println!(
                "{}: {} of {} cells ({} failed) + {} of {} least-squares fits",
                m.name,
                m.huber,
                plan.n_cells(),
                m.failed,
                m.ls,
                plan.pairs.len()
            );
            print_picks(selection);
            println!("results in {}", out.display());
            if m.missing.is_empty() {
                if let Some(e) = &m.cleanup {
                    eprintln!("warning: {e}");
                }
            } else {
                println!("partial merge: the checkpoint is kept; merge again once the missing cells are done");
            }
        }
    }
    let code = m.exit_code();
    print_report(m.report)?;
    Ok(code)
}

/// `oesweep slurm` ([`crate::slurm::submit`]).
fn run_slurm(a: &SlurmArgs) -> Result<u8> {
    let req = crate::slurm::SlurmRequest {
        job: a.job.clone(),
        shards: a.shards,
        sbatch: a.sbatch.clone(),
        cpus_per_task: a.cpus_per_task,
        sbatch_args: a.sbatch_arg.clone(),
        report: a.report,
    };
    if a.dry_run {
        let (sweep, merge) = crate::slurm::commands(&req)?;
        println!("OESWEEP={} sbatch {}", sweep.exe.display(), sweep.args.join(" "));
        println!("OESWEEP={} sbatch --dependency=afterok:<sweep job id> {}", merge.exe.display(), merge.args.join(" "));
        return Ok(0);
    }
    let s = crate::slurm::submit(&req)?;
    println!("sweep job {} (array of {} shards)", s.sweep_id, a.shards);
    println!("merge job {} (starts when every shard succeeded)", s.merge_id);
    println!("results in {}, Slurm logs in {}", s.out.display(), s.logs.display());
    Ok(0)
}
