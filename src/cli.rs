//! Command-line interface: argument definitions and the commands they run.
//!
//! Each command validates its inputs first (a bad input is one [`Error`] naming the file and
//! what is wrong; the binary exits 2), then calls the library.

use crate::checkpoint::{self, Manifest, StopOnSignal, Writer};
use crate::data::{self, Record};
use crate::error::{Error, Result};
use crate::estimate::{self, HuberFit, HuberHessian, Judge, LsFit, Problem, SolverOptions, Workspace};
use crate::export;
use crate::job::{self, Inputs, ValidJob};
use crate::plan::Plan;
use crate::progress::Progress;
use crate::reduce::{self, ReduceOptions};
use crate::shard::{self, Shard};
use crate::simulate;
use crate::spectral::SpectralEstimate;
use crate::spectral::{self, WelchOptions};
use crate::sweep::{self, Context};
use crate::table::{CellRow, Method};
use clap::{Args, Parser, Subcommand};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

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
    pub huber_hessian: HuberHessian,
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

/// Report of `oesweep fit`.
#[derive(serde::Serialize)]
pub struct FitReport {
    pub data: PathBuf,
    pub n: usize,
    pub validation: Option<PathBuf>,
    pub validation_column: Option<String>,
    pub nb: usize,
    pub nf: usize,
    pub delay: usize,
    pub band_hz: Option<(f64, f64)>,
    pub sigma: f64,
    #[serde(flatten)]
    pub huber: HuberFit,
    pub converged: bool,
    pub seconds: f64,
    pub ls: LsFit,
}

fn read_validation(path: &Path, u: &str, y: &str, val_y: Option<&str>) -> Result<Record> {
    let col = match val_y {
        Some(c) => c.to_string(),
        None => {
            if data::column_names(path)?.iter().any(|c| c == "y0") {
                "y0".to_string()
            } else {
                y.to_string()
            }
        }
    };
    data::read_record(path, u, &col)
}

fn validate_fit_args(a: &FitArgs) -> Result<()> {
    if a.nb == 0 {
        return Err(Error::Invalid("--nb must be at least 1".into()));
    }
    if !(a.k.is_finite() && a.k > 0.0) {
        return Err(Error::Invalid(format!("--k must be a positive number, got {}", a.k)));
    }
    if let Some(ts) = a.ts
        && !(ts.is_finite() && ts > 0.0)
    {
        return Err(Error::Invalid(format!("--ts must be a positive number of seconds, got {ts}")));
    }
    if let Some((lo, hi)) = a.band {
        let Some(ts) = a.ts else {
            return Err(Error::Invalid("--band needs --ts (the sampling period in seconds)".into()));
        };
        let nyq = 0.5 / ts;
        if !(lo >= 0.0 && hi > lo && hi <= nyq) {
            return Err(Error::Invalid(format!("--band {lo},{hi}: need 0 <= LO < HI <= Nyquist frequency {nyq} Hz")));
        }
    }
    if a.max_iterations == 0 {
        return Err(Error::Invalid("--max-iterations must be at least 1".into()));
    }
    Ok(())
}

fn run_fit(a: &FitArgs) -> Result<u8> {
    validate_fit_args(a)?;
    let est = data::read_record(&a.data, &a.u, &a.y)?;
    data::check_for_model(&est, a.nb, a.nf, a.delay)?;
    let val = match &a.validation {
        Some(p) => {
            let v = read_validation(p, &a.u, &a.y, a.val_y.as_deref())?;
            data::check_for_model(&v, a.nb, a.nf, a.delay)?;
            Some(v)
        }
        None => None,
    };
    let spec = match (a.band, a.ts) {
        (Some((lo, hi)), Some(ts)) => {
            let s = spectral::welch(&est.u, &est.y, ts, &WelchOptions::default())?;
            let bins = s.band(lo, hi);
            Some((s, bins))
        }
        _ => None,
    };
    let judge = Judge {
        validation: val.as_ref().map(|v| (&v.u[..], &v.y[..])),
        band: spec.as_ref().map(|(s, bins)| (s, &bins[..])),
    };
    let opts = SolverOptions {
        max_iterations: a.max_iterations,
        ftol: a.ftol,
        huber_hessian: a.huber_hessian,
        ..Default::default()
    };
    let prob = Problem { u: &est.u, y: &est.y, nb: a.nb, nf: a.nf, delay: a.delay };
    let mut ws = Workspace::new();
    let t0 = Instant::now();
    let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
    let (huber, _) = estimate::fit_huber_multi(&prob, &ls, a.k, &judge, &opts, &mut ws);
    let seconds = t0.elapsed().as_secs_f64();
    let report = FitReport {
        data: a.data.clone(),
        n: est.u.len(),
        validation: a.validation.clone(),
        validation_column: val.as_ref().map(|v| v.y_name.clone()),
        nb: a.nb,
        nf: a.nf,
        delay: a.delay,
        band_hz: a.band,
        sigma: ls.sigma,
        converged: huber.termination.converged(),
        huber,
        seconds,
        ls,
    };
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
    let sys = simulate::read_system(&a.system)?;
    if a.n == 0 {
        return Err(Error::Invalid("--n must be at least 1".into()));
    }
    let (lo, hi) = a.outlier_range;
    if !(a.noise_std >= 0.0 && a.noise_std.is_finite()) {
        return Err(Error::Invalid(format!("--noise-std must be >= 0, got {}", a.noise_std)));
    }
    if !(0.0..=1.0).contains(&a.outlier_prob) {
        return Err(Error::Invalid(format!("--outlier-prob must be in [0, 1], got {}", a.outlier_prob)));
    }
    if !(lo >= 0.0 && hi >= lo && hi.is_finite()) {
        return Err(Error::Invalid(format!("--outlier-range {lo},{hi}: need 0 <= MIN <= MAX")));
    }
    let noise = match a.student_t {
        Some(dof) if dof > 0.0 => simulate::NoiseKind::StudentT { dof },
        Some(dof) => return Err(Error::Invalid(format!("--student-t needs positive degrees of freedom, got {dof}"))),
        None => simulate::NoiseKind::Gaussian,
    };
    let opts = simulate::SimOptions {
        n: a.n,
        bits: a.bits,
        amplitude: a.amplitude,
        seed: a.seed,
        noise_std: a.noise_std,
        noise,
        outliers: (a.outlier_prob > 0.0).then_some(simulate::Outliers {
            probability: a.outlier_prob,
            min: lo,
            max: hi,
        }),
    };
    let rec = simulate::generate(&sys, &opts)?;
    simulate::write_csv(&a.out, &rec)?;
    eprintln!("wrote {} ({} samples)", a.out.display(), a.n);
    Ok(0)
}

/// A job, its data and everything derived from them before estimation starts.
struct Prepared {
    job: ValidJob,
    inputs: Inputs,
    spectral: Option<(SpectralEstimate, Vec<usize>)>,
    plan: Plan,
}

fn prepare(path: &Path) -> Result<Prepared> {
    let mut job = job::load(path)?;
    let inputs = job::load_inputs(&mut job)?;
    let spectral = match job.job.band_hz {
        Some([lo, hi]) => {
            let s = spectral::welch(&inputs.est.u, &inputs.est.y, job.ts(), &WelchOptions::default())
                .map_err(|e| Error::input(&job.job.data.path, e.to_string()))?;
            let bins = s.band(lo, hi);
            if bins.is_empty() {
                return Err(Error::input(
                    path,
                    format!("field 'band_hz': [{lo}, {hi}] Hz holds no frequency bin of the spectral estimate"),
                ));
            }
            Some((s, bins))
        }
        None => None,
    };
    let plan = Plan::from_job(&job);
    Ok(Prepared { job, inputs, spectral, plan })
}

fn describe_grid(job: &ValidJob) -> String {
    let ks = &job.ks;
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
    let p = prepare(&a.job)?;
    let j = &p.job;
    println!("job        {} ({})", j.job.name, j.file.display());
    println!("data       {} ({} samples, Ts = {} s)", j.job.data.path.display(), p.inputs.est.u.len(), j.ts());
    if let (Some(v), Some(rec)) = (&j.job.validation, &p.inputs.val) {
        println!("validation {} ({} samples, column '{}')", v.path.display(), rec.u.len(), rec.y_name);
    }
    println!("grid       {}", describe_grid(j));
    println!("cells      {} Huber cells + {} least-squares fits", j.n_cells(), j.n_pairs());
    println!("start      {}", j.job.start.as_str());
    println!("ranking    by {:?} fit", reduce::choose_basis(p.inputs.val.is_some(), p.spectral.is_some()));
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

/// `job.json` in the output folder: the normalised job and the program that ran it.
#[derive(serde::Serialize)]
struct JobAsRun<'a> {
    oesweep_version: &'static str,
    #[serde(flatten)]
    job: &'a job::Job,
}

/// The result files of a complete (or `--partial`) table: `cells.parquet`, `selection.json`,
/// `job.json`. Returns the picks.
fn write_results(out: &Path, job: &job::Job, rows: &[CellRow]) -> Result<reduce::Selection> {
    let sel_opts = ReduceOptions {
        basis: reduce::choose_basis(job.validation.is_some(), job.band_hz.is_some()),
        min_tolerance: job.selection.min_tolerance,
        fit_tolerance: job.selection.fit_tolerance,
    };
    let selection = reduce::select(rows, &sel_opts);
    // A report of the previous table would describe models this table may not have.
    crate::report::remove_report(out);
    export::parquet::write_cells(&out.join("cells.parquet"), rows)?;
    export::json::write_json(&out.join("selection.json"), &selection)?;
    export::json::write_json(&out.join("job.json"), &JobAsRun { oesweep_version: env!("CARGO_PKG_VERSION"), job })?;
    Ok(selection)
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

fn failed_cells(rows: &[CellRow]) -> usize {
    rows.iter().filter(|r| r.method == Method::Huber && !r.ok()).count()
}

/// `oesweep run`: validate everything (job, data, an existing checkpoint) before writing
/// anything; resume from the checkpoint when it holds an interrupted run of this job (see
/// [`checkpoint`]; a whole run also takes the cells of shard folders); run the remaining cells
/// while the checkpoint writer saves them; on a signal stop, save and return 130. A whole run
/// then merges, reduces, writes the results and deletes the parts; a shard (`--shard I/N`,
/// only its share of the plan, see [`shard`]) stops once its rows are saved, for `oesweep
/// merge` to combine.
fn run_job(a: &RunArgs) -> Result<u8> {
    if !(a.checkpoint_every.is_finite() && a.checkpoint_every > 0.0) {
        return Err(Error::Invalid(format!(
            "--checkpoint-every must be a positive number of seconds, got {}",
            a.checkpoint_every
        )));
    }
    if a.shard.is_some() && a.report {
        return Err(Error::Invalid(
            "--report needs the merged table: use `oesweep merge OUTPUT --report` once all shards are done".into(),
        ));
    }
    let p = prepare(&a.job)?;
    let out = p.job.output().to_path_buf();
    let (plan, label) = match a.shard {
        Some(s) => (shard::plan_of(&p.plan, s).0, format!("{} shard {s}", p.job.job.name)),
        None => (p.plan.clone(), p.job.job.name.clone()),
    };
    let parts = checkpoint::folder(&out, a.shard);
    let manifest = Manifest::of_job(&p.job)?;
    // Locked before the checkpoint is read: another run of this folder could be changing it.
    std::fs::create_dir_all(&out).map_err(|e| Error::output(&out, format!("cannot create output folder: {e}")))?;
    let _lock = match a.shard {
        Some(s) => crate::lock::lock_shard(&out, s)?,
        None => crate::lock::lock_output(&out)?,
    };
    // A checkpoint of another job is bad input too: refused before anything is written.
    let existing = match (a.force, a.shard) {
        (true, _) => checkpoint::Existing::default(),
        (false, Some(_)) => checkpoint::inspect(&parts, &manifest, &plan)?,
        (false, None) => checkpoint::inspect_all(&out, &manifest, &plan)?,
    };

    checkpoint::open(&out, a.shard, &manifest, &p.job.job, a.force)?;
    let (pairs, cells) = (plan.pairs.len(), plan.n_cells());
    let resumed_huber = existing.huber_rows();
    let resumed_rows = existing.rows.len();
    if resumed_rows > 0 && !a.quiet {
        eprintln!(
            "resuming from {} ({} parts): {} of {cells} cells and {} of {pairs} least-squares fits already done",
            parts.display(),
            existing.parts,
            resumed_huber,
            resumed_rows - resumed_huber,
        );
    }
    if existing.duplicates > 0 {
        eprintln!(
            "warning: {}: {} duplicate rows ignored (the first of each cell is kept)",
            parts.display(),
            existing.duplicates
        );
    }
    let ctx = Context {
        est: &p.inputs.est,
        val: p.inputs.val.as_ref(),
        band: p.spectral.as_ref().map(|(s, b)| (s, &b[..])),
        solver: p.job.job.solver.clone(),
    };
    let writer = Writer::start(
        parts.clone(),
        existing.next_part,
        Duration::from_secs_f64(a.checkpoint_every),
        checkpoint::BATCH_ROWS,
    );
    let progress = Progress::new(cells - resumed_huber, a.quiet);
    let outcome = {
        let signals = StopOnSignal::install();
        let tx = writer.sender();
        // A send fails only if the writer thread is gone; the row is still in the outcome.
        let on_row = |row: &CellRow| {
            let _ = tx.send(row.clone());
        };
        let control = sweep::Control { done: existing.rows, on_row: &on_row, stop: signals.flag() };
        sweep::run(&plan, &ctx, a.threads, &progress, control)
    };
    progress.finish();
    let saved = writer.finish();
    if let Some(e) = &saved.error {
        eprintln!("warning: {} finished rows could not be saved to the checkpoint: {e}", saved.unsaved);
    }
    let shard_arg = a.shard.map_or(String::new(), |s| format!(" --shard {s}"));
    if outcome.interrupted {
        let done_huber = outcome.rows.iter().filter(|r| r.method == Method::Huber).count();
        eprintln!(
            "interrupted: {} of {cells} cells finished ({} in this run); they are saved in {}",
            done_huber,
            outcome.computed,
            parts.display()
        );
        eprintln!(
            "to resume, run `oesweep run {}{shard_arg}` again (with --force to start over instead)",
            a.job.display()
        );
        return Ok(130);
    }
    let failed = outcome.failed_cells();
    let rate = outcome.computed as f64 / outcome.seconds.max(1e-9);

    if let Some(s) = a.shard {
        // The checkpoint is this shard's only result: rows that did not reach it are lost.
        if let Some(e) = saved.error {
            return Err(Error::output(
                &parts,
                format!("{} finished rows could not be saved ({e}); run the shard again to redo them", saved.unsaved),
            ));
        }
        println!("{label}: {cells} cells ({failed} failed) + {pairs} least-squares fits, saved in {}", parts.display());
        if resumed_rows > 0 {
            println!(
                "{} cells resumed from the checkpoint, {} computed in this run",
                outcome.resumed, outcome.computed
            );
        }
        println!("wall time {:.2} s, {rate:.1} cells/s", outcome.seconds);
        println!("when all {} shards are done: oesweep merge {}", s.count, out.display());
        return Ok(if failed > 0 { 1 } else { 0 });
    }

    let selection = write_results(&out, &p.job.job, &outcome.rows)?;
    println!("{label}: {cells} cells ({failed} failed) + {pairs} least-squares fits");
    if resumed_rows > 0 {
        println!(
            "{} cells and {} least-squares fits resumed from the checkpoint, {} cells computed in this run",
            outcome.resumed,
            resumed_rows - outcome.resumed,
            outcome.computed
        );
    }
    println!("wall time {:.2} s, {rate:.1} cells/s", outcome.seconds);
    print_picks(&selection);
    println!("results in {}", out.display());
    // cells.parquet is complete: the checkpoint has served. If this fails, a rerun finds every
    // cell done and merges again.
    if let Err(e) = checkpoint::remove(&out) {
        eprintln!("warning: {e}");
    }
    if a.report {
        let page = crate::report::write_report(&out)?;
        println!("report in {}", page.display());
    }
    Ok(if failed > 0 { 1 } else { 0 })
}

/// `oesweep merge`: read every checkpoint folder of an output folder (shards, or an
/// interrupted whole run), check that together they hold every cell of the job exactly once,
/// and write the result files exactly as a whole run does (same rows, same order, same
/// reducer). Missing cells: list them and exit 1 without writing, unless `--partial`. A
/// complete merge deletes the checkpoint, like a whole run; a folder already merged is left
/// as it is (so a merge job that runs twice succeeds twice).
fn run_merge(a: &MergeArgs) -> Result<u8> {
    let out = &a.folder;
    if !out.is_dir() {
        return Err(Error::input(out, "not a folder"));
    }
    let _lock = crate::lock::lock_output(out)?;
    let merged = ["cells.parquet", "selection.json", "job.json"].iter().all(|f| out.join(f).is_file());
    if !out.join(checkpoint::PARTS_DIR).exists() && merged {
        println!("{}: already merged (no checkpoint left), nothing to do", out.display());
    } else {
        let g = checkpoint::gather(out)?;
        if g.duplicates > 0 {
            eprintln!("note: {} cells were saved twice (identical rows); each is kept once", g.duplicates);
        }
        let missing = shard::missing(&g.plan, &g.rows);
        let (pairs, cells) = (g.plan.pairs.len(), g.plan.n_cells());
        if !missing.is_empty() {
            eprintln!(
                "{}: {} of {cells} cells and {} of {pairs} least-squares fits are missing:",
                out.display(),
                missing.cells,
                missing.ls
            );
            for line in missing.lines(&g.plan, 20) {
                eprintln!("  {line}");
            }
            // Name the shards to rerun when the folders say how the job was split.
            let counts: BTreeSet<usize> = g.folders.iter().filter_map(|(_, s, _)| s.map(|s| s.count)).collect();
            if let [n] = counts.iter().copied().collect::<Vec<_>>()[..] {
                let layout = shard::layout(&g.plan, n);
                let owners: Vec<usize> = (0..n)
                    .filter(|&s| layout[s].iter().any(|p| missing.pairs.iter().any(|(q, _, _)| q == p)))
                    .collect();
                eprintln!(
                    "  they belong to shard {} of {n}: run `oesweep run JOB --shard I/{n}` for each",
                    shard::ranges(&owners)
                );
            }
            if !a.partial {
                eprintln!(
                    "nothing written; rerun the missing shards and merge again, or merge what there is with --partial"
                );
                return Ok(1);
            }
        }
        let selection = write_results(out, &g.job, &g.rows)?;
        let failed = failed_cells(&g.rows);
        let huber = g.rows.iter().filter(|r| r.method == Method::Huber).count();
        let read: Vec<String> = g
            .folders
            .iter()
            .filter(|(_, _, n)| *n > 0)
            .map(|(d, _, n)| format!("{} ({n} parts)", d.file_name().unwrap_or_default().to_string_lossy()))
            .collect();
        println!("merged {}", read.join(", "));
        println!(
            "{}: {huber} of {cells} cells ({failed} failed) + {} of {pairs} least-squares fits",
            g.job.name,
            g.rows.len() - huber
        );
        print_picks(&selection);
        println!("results in {}", out.display());
        if missing.is_empty() {
            if let Err(e) = checkpoint::remove(out) {
                eprintln!("warning: {e}");
            }
        } else {
            println!("partial merge: the checkpoint is kept; merge again once the missing cells are done");
        }
    }
    if a.report {
        let page = crate::report::write_report(out)?;
        println!("report in {}", page.display());
    }
    let rows = export::parquet::read_cells(&out.join("cells.parquet"))?;
    Ok(if failed_cells(&rows) > 0 { 1 } else { 0 })
}

/// The sbatch templates built into the binary (the files of `jobs/slurm/`), so that
/// `oesweep slurm` works from an installed binary without the source tree.
const SWEEP_SBATCH: &str = include_str!("../jobs/slurm/sweep.sbatch");
const MERGE_SBATCH: &str = include_str!("../jobs/slurm/merge.sbatch");

/// `oesweep slurm`: validate the job, then submit the array job of N shards and a merge job
/// that depends on it (`afterok`), and print both job ids. Slurm does the scheduling, retries
/// and accounting; this only spares the user two sbatch lines and the dependency id.
fn run_slurm(a: &SlurmArgs) -> Result<u8> {
    if a.shards == 0 {
        return Err(Error::Invalid("--shards must be at least 1".into()));
    }
    if a.cpus_per_task == Some(0) {
        return Err(Error::Invalid("--cpus-per-task must be at least 1".into()));
    }
    // Bad input is found here, not in N array tasks an hour later in the queue.
    let p = prepare(&a.job)?;
    let out = p.job.output().to_path_buf();
    let job_file = a.job.canonicalize().map_err(|e| Error::input(&a.job, format!("cannot resolve: {e}")))?;
    let logs = out.join("slurm");
    let (sweep_script, merge_script) = match &a.sbatch {
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
    let mut sweep_cmd: Vec<String> = vec![
        "--parsable".into(),
        format!("--array=0-{}", a.shards - 1),
        format!("--job-name=oesweep-{}", p.job.job.name.replace(char::is_whitespace, "_")),
        format!("--output={}", logs.join("sweep-%A_%a.out").display()),
    ];
    if let Some(c) = a.cpus_per_task {
        sweep_cmd.push(format!("--cpus-per-task={c}"));
    }
    sweep_cmd.extend(a.sbatch_arg.iter().cloned());
    sweep_cmd.extend([sweep_script.display().to_string(), job_file.display().to_string(), a.shards.to_string()]);
    let mut merge_cmd: Vec<String> = vec![
        "--parsable".into(),
        format!("--job-name=oesweep-{}-merge", p.job.job.name.replace(char::is_whitespace, "_")),
        format!("--output={}", logs.join("merge-%j.out").display()),
    ];
    merge_cmd.extend(a.sbatch_arg.iter().cloned());
    merge_cmd.extend([merge_script.display().to_string(), out.display().to_string()]);
    if a.report {
        merge_cmd.push("--report".into());
    }
    if a.dry_run {
        println!("OESWEEP={} sbatch {}", exe.display(), sweep_cmd.join(" "));
        println!("OESWEEP={} sbatch --dependency=afterok:<sweep job id> {}", exe.display(), merge_cmd.join(" "));
        return Ok(0);
    }
    // Slurm opens the log files there, so the folder must exist before the tasks start.
    std::fs::create_dir_all(&logs).map_err(|e| Error::output(&logs, format!("cannot create: {e}")))?;
    if a.sbatch.is_none() {
        for (path, text) in [(&sweep_script, SWEEP_SBATCH), (&merge_script, MERGE_SBATCH)] {
            std::fs::write(path, text).map_err(|e| Error::output(path, format!("cannot write: {e}")))?;
        }
    }
    let submit = |args: &[String]| -> Result<String> {
        let o = std::process::Command::new("sbatch")
            .args(args)
            .env("OESWEEP", &exe)
            .output()
            .map_err(|e| Error::Invalid(format!("cannot run sbatch: {e} (is this a Slurm login node?)")))?;
        let stdout = String::from_utf8_lossy(&o.stdout);
        // --parsable prints `id` or `id;cluster`.
        let id = stdout.trim().split(';').next().unwrap_or("").to_string();
        if !o.status.success() || id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
            return Err(Error::Invalid(format!(
                "sbatch {} failed: {}{}",
                args.join(" "),
                String::from_utf8_lossy(&o.stderr).trim(),
                stdout.trim()
            )));
        }
        Ok(id)
    };
    let sweep_id = submit(&sweep_cmd)?;
    merge_cmd.insert(1, format!("--dependency=afterok:{sweep_id}"));
    let merge_id = submit(&merge_cmd)?;
    println!("sweep job {sweep_id} (array of {} shards)", a.shards);
    println!("merge job {merge_id} (starts when every shard succeeded)");
    println!("results in {}, Slurm logs in {}", out.display(), logs.display());
    Ok(0)
}
