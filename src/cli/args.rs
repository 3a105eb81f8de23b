//! The command line's arguments (clap).

use crate::checkpoint;
use crate::estimate::{HuberHessian, SolverMethod, SolverOptions};
use crate::shard::Shard;
use clap::{Args, Parser, Subcommand};
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
    Fit(Box<FitArgs>),
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
    /// Nonparametric frequency response of a record (robust to output spikes by default).
    Spectrum(SpectrumArgs),
    /// Write one model of a finished run for python-control, scipy or MATLAB.
    Export(ExportArgs),
}

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Output folder of a finished `oesweep run` (or merge).
    pub folder: PathBuf,
    /// The model: m1, m2, a rule of selection.json's picks (rbic, evidence, ...), or NB,NF,K[,D]
    /// (K a k of the grid, or `ls` for the least-squares fit; several inputs: NB, NF, D one value
    /// per input as 2/1, or one for all); default: the lead rule's pick.
    #[arg(long, value_name = "PICK")]
    pub pick: Option<crate::engine::PickSpec>,
    /// json: num, den, dt (python-control, scipy) with offset, delay, covariance; matlab: a script
    /// that builds the tf (and the idpoly); mat: a MAT-file (needs --out).
    #[arg(long, value_enum)]
    pub to: ExportFormat,
    /// File to write (default: standard output; required for mat).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Also write the continuous-time equivalent for control design: zoh (the inverse of the
    /// zero-order hold) or tustin (the inverse bilinear map); the delay becomes a dead time.
    #[arg(long, value_name = "zoh|tustin")]
    pub continuous: Option<crate::export::continuous::Method>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportFormat {
    Json,
    Matlab,
    Mat,
}

crate::names::names!(ExportFormat { Json = "json", Matlab = "matlab", Mat = "mat" });

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
    #[arg(required_unless_present = "next_round")]
    pub job: Option<PathBuf>,
    /// Number of shards (array tasks).
    #[arg(long, required_unless_present = "next_round")]
    pub shards: Option<usize>,
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
    /// A coordinate search: the most arrays (rounds) its merge jobs submit [default: 10 per
    /// input].
    #[arg(long, value_name = "R")]
    pub max_rounds: Option<usize>,
    /// Submit the next round of the coordinate search that `oesweep slurm` submitted into this
    /// output folder, as its merge job does when `oesweep merge` exits 3.
    #[arg(long, value_name = "FOLDER", conflicts_with_all = [
        "job", "shards", "sbatch", "cpus_per_task", "sbatch_arg", "report", "dry_run", "max_rounds",
    ])]
    pub next_round: Option<PathBuf>,
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
    /// Count solver iterations by role and time by phase; print the table and write it as
    /// JSON to FILE.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct FitArgs {
    /// Estimation record (delimited text, Parquet or MATLAB level-5 .mat).
    #[arg(long)]
    pub data: PathBuf,
    /// Data rows A:B of the estimation record (1-based, inclusive) [default: all].
    #[arg(long, value_name = "A:B", value_parser = parse_rows)]
    pub rows: Option<[usize; 2]>,
    /// Validation record, used only to judge the model [default with --val-rows: the --data file].
    #[arg(long)]
    pub validation: Option<PathBuf>,
    /// Data rows A:B of the validation record (1-based, inclusive) [default: all].
    #[arg(long, value_name = "A:B", value_parser = parse_rows)]
    pub val_rows: Option<[usize; 2]>,
    /// Number of B coefficients (numerator), >= 1; with several inputs one for every input or
    /// a comma-separated list, one per input (2,1).
    #[arg(long, value_delimiter = ',', required = true, num_args = 1)]
    pub nb: Vec<usize>,
    /// Number of F coefficients (denominator order), >= 0; one, or one per input (2,1).
    #[arg(long, value_delimiter = ',', required = true, num_args = 1)]
    pub nf: Vec<usize>,
    /// Huber tuning constant: gamma = k * sigma (sigma from the least-squares fit).
    #[arg(long)]
    pub k: f64,
    /// Input delay d in samples; one, or one per input (1,0).
    #[arg(long, value_delimiter = ',', default_value = "1", num_args = 1)]
    pub delay: Vec<usize>,
    /// Sampling period in seconds (needed for --band).
    #[arg(long)]
    pub ts: Option<f64>,
    /// Frequency band LO,HI in Hz for the band fit against a spectral estimate.
    #[arg(long, value_parser = parse_band)]
    pub band: Option<(f64, f64)>,
    /// Spectral estimate of the band fit: robust (spikes cleaned out first) or plain Welch.
    #[arg(long, value_enum, default_value = "robust")]
    pub spectrum: crate::spectral::SpectrumMethod,
    /// Input column: a name, or a 1-based position; several inputs: a comma-separated list of
    /// them (fuel,fan,feed).
    #[arg(long, value_delimiter = ',', default_value = "u", num_args = 1)]
    pub u: Vec<String>,
    /// Output column of the estimation record: a name, or a 1-based position.
    #[arg(long, default_value = "y")]
    pub y: String,
    /// Output column of the validation record [default: `y0` (noise-free output, as written
    /// by `oesweep simulate`) when the file has one, else the --y column].
    #[arg(long)]
    pub val_y: Option<String>,
    /// Signal offsets: estimate a constant output offset (input mean removed), subtract the
    /// estimation record's mean or median, or none (the paper's model).
    #[arg(long, value_enum, default_value = "estimate")]
    pub offset: crate::data::Offset,
    /// Initial state of the judged fits: estimated by least squares on each record (as
    /// MATLAB's compare), or zero (the paper's).
    #[arg(long, value_enum, default_value = "estimate")]
    pub initial_state: crate::estimate::InitialState,
    /// Iteration cap of each minimisation.
    #[arg(long, default_value_t = SolverOptions::default().max_iterations)]
    pub max_iterations: usize,
    /// Relative criterion-change tolerance of each minimisation.
    #[arg(long, default_value_t = SolverOptions::default().ftol)]
    pub ftol: f64,
    /// Huber Hessian: exact Gauss-Newton (L1 rows weight 0) or IRLS (weight gamma/|e|).
    #[arg(long, value_enum, default_value = "gauss_newton")]
    pub huber_hessian: HuberHessian,
    /// Solver: Levenberg-Marquardt over all parameters, or variable projection (F searched,
    /// b and the offset solved for).
    #[arg(long, value_enum, default_value = "lm")]
    pub method: SolverMethod,
    /// Bootstrap the whole estimation B times (parametric, residual blocks; refits in
    /// parallel) for percentile intervals of the parameters and of |G| and its phase
    /// (METHOD.md 17.3). `--bootstrap` alone: B = 200.
    #[arg(long, value_name = "B", num_args = 0..=1, default_missing_value = "200")]
    pub bootstrap: Option<usize>,
    /// Worker threads of the bootstrap's refits (default: all cores). The intervals do not
    /// depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// A value that marks a missing sample in the files besides NaN and empty fields (-999);
    /// repeat or separate by commas for several (METHOD.md 21.1).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub missing: Vec<String>,
    /// Fill input gaps of at most L samples by linear interpolation (said in a warning);
    /// 0: cut the record at every input gap.
    #[arg(long, value_name = "L", default_value_t = 0)]
    pub interpolate_inputs: usize,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct SpectrumArgs {
    /// The record (delimited text, Parquet or MATLAB level-5 .mat).
    #[arg(long)]
    pub data: PathBuf,
    /// Input column: a name, or a 1-based position; several inputs: a comma-separated list of
    /// them (each input's response from the inputs' cross-spectra, METHOD.md 19).
    #[arg(long, value_delimiter = ',', default_value = "u", num_args = 1)]
    pub u: Vec<String>,
    /// Output column: a name, or a 1-based position.
    #[arg(long, default_value = "y")]
    pub y: String,
    /// Sampling period in seconds.
    #[arg(long)]
    pub ts: f64,
    /// Data rows A:B (1-based, inclusive) [default: all].
    #[arg(long, value_name = "A:B", value_parser = parse_rows)]
    pub rows: Option<[usize; 2]>,
    /// robust: the output's spikes cleaned out before Welch's estimate; welch: as it is.
    #[arg(long, value_enum, default_value = "robust")]
    pub method: crate::spectral::SpectrumMethod,
    /// Print one JSON object (freq_hz, re, im, coherence, mag_lower, mag_upper; several inputs:
    /// re, im, mag_lower, mag_upper one list per input) instead of a table.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// System file: {"b": [...], "f": [...], "delay": 1}; several inputs:
    /// {"inputs": [{"b": [...], "f": [...], "delay": 1}, ...]}.
    #[arg(long)]
    pub system: PathBuf,
    /// Output CSV (columns u, y, y0; several inputs: u1, .., um, y, y0).
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
    /// Share of the outputs left missing (empty fields; records with gaps, METHOD.md 21.1).
    #[arg(long, value_name = "P", default_value_t = 0.0)]
    pub missing: f64,
    /// Share of the rows whose input is left missing (one input per gap, chosen at random).
    #[arg(long, value_name = "P", default_value_t = 0.0)]
    pub missing_inputs: f64,
    /// Length in samples of every gap of --missing and --missing-inputs.
    #[arg(long, value_name = "L", default_value_t = 1)]
    pub missing_burst: usize,
}

fn parse_band(s: &str) -> std::result::Result<(f64, f64), String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 2 {
        return Err(format!("expected two numbers LO,HI, got '{s}'"));
    }
    let p = |x: &str| x.trim().parse::<f64>().map_err(|_| format!("'{x}' is not a number"));
    Ok((p(parts[0])?, p(parts[1])?))
}

/// `A:B` -> [A, B] (checked by the library, which names the flag).
fn parse_rows(s: &str) -> std::result::Result<[usize; 2], String> {
    let (a, b) = s.split_once(':').ok_or_else(|| format!("'{s}': expected FIRST:LAST, e.g. 1:700"))?;
    let n = |t: &str| t.trim().parse::<usize>().map_err(|_| format!("'{s}': '{t}' is not a row number"));
    Ok([n(a)?, n(b)?])
}
