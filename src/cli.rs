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
use crate::simulate;
use crate::spectral::SpectralEstimate;
use crate::spectral::{self, WelchOptions};
use crate::sweep::{self, Context};
use crate::table::{CellRow, Method};
use clap::{Args, Parser, Subcommand};
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
                .map_err(|e| Error::input(&job.job.data.path, format!("spectral estimate: {e}")))?;
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
    Ok(0)
}

/// `job.json` in the output folder: the normalised job and the program that ran it.
#[derive(serde::Serialize)]
struct JobAsRun<'a> {
    oesweep_version: &'static str,
    #[serde(flatten)]
    job: &'a job::Job,
}

/// `oesweep run`: validate everything (job, data, an existing checkpoint) before writing
/// anything; resume from `<output>/parts` when it holds an interrupted run of this job (see
/// [`checkpoint`]); run the remaining cells while the checkpoint writer saves them; on a signal
/// stop, save and return 130; otherwise merge, reduce, write the results and delete the parts.
fn run_job(a: &RunArgs) -> Result<u8> {
    if !(a.checkpoint_every.is_finite() && a.checkpoint_every > 0.0) {
        return Err(Error::Invalid(format!(
            "--checkpoint-every must be a positive number of seconds, got {}",
            a.checkpoint_every
        )));
    }
    let p = prepare(&a.job)?;
    let out = p.job.output().to_path_buf();
    let parts = out.join(checkpoint::PARTS_DIR);
    let manifest = Manifest::of_job(&p.job)?;
    // A checkpoint of another job is bad input too: refused before anything is written.
    let existing =
        if a.force { checkpoint::Existing::default() } else { checkpoint::inspect(&parts, &manifest, &p.plan)? };

    std::fs::create_dir_all(&out).map_err(|e| Error::output(&out, format!("cannot create output folder: {e}")))?;
    checkpoint::open(&out, &manifest, a.force)?;
    let (pairs, cells) = (p.plan.pairs.len(), p.plan.n_cells());
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
        sweep::run(&p.plan, &ctx, a.threads, &progress, control)
    };
    progress.finish();
    let saved = writer.finish();
    if let Some(e) = &saved.error {
        eprintln!("warning: {} finished rows could not be saved to the checkpoint: {e}", saved.unsaved);
    }
    if outcome.interrupted {
        let done_huber = outcome.rows.iter().filter(|r| r.method == Method::Huber).count();
        eprintln!(
            "interrupted: {} of {cells} cells finished ({} in this run); they are saved in {}",
            done_huber,
            outcome.computed,
            parts.display()
        );
        eprintln!("to resume, run `oesweep run {}` again (with --force to start over instead)", a.job.display());
        return Ok(130);
    }

    let basis = reduce::choose_basis(p.inputs.val.is_some(), p.spectral.is_some());
    let sel_opts = ReduceOptions {
        basis,
        min_tolerance: p.job.job.selection.min_tolerance,
        fit_tolerance: p.job.job.selection.fit_tolerance,
    };
    let selection = reduce::select(&outcome.rows, &sel_opts);
    export::parquet::write_cells(&out.join("cells.parquet"), &outcome.rows)?;
    export::json::write_json(&out.join("selection.json"), &selection)?;
    export::json::write_json(
        &out.join("job.json"),
        &JobAsRun { oesweep_version: env!("CARGO_PKG_VERSION"), job: &p.job.job },
    )?;

    let failed = outcome.failed_cells();
    println!("{}: {} cells ({} failed) + {} least-squares fits", p.job.job.name, cells, failed, pairs);
    if resumed_rows > 0 {
        println!(
            "{} cells and {} least-squares fits resumed from the checkpoint, {} cells computed in this run",
            outcome.resumed,
            resumed_rows - outcome.resumed,
            outcome.computed
        );
    }
    println!("wall time {:.2} s, {:.1} cells/s", outcome.seconds, outcome.computed as f64 / outcome.seconds.max(1e-9));
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
