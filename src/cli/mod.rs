//! Command-line interface: argument definitions ([`args`]), their conversion into the
//! library's requests ([`crate::engine`], [`crate::slurm`]), and the printing of the outcomes
//! (`print`). No estimation, file layout or rule lives here.

/// `println!` for the commands' standard output, through [`stdout::write`].
macro_rules! outln {
    () => { $crate::cli::stdout::write(format_args!("\n")) };
    ($($arg:tt)*) => { $crate::cli::stdout::write(format_args!("{}\n", format_args!($($arg)*))) };
}

/// `print!` for the commands' standard output, through [`stdout::write`].
macro_rules! out {
    ($($arg:tt)*) => { $crate::cli::stdout::write(format_args!($($arg)*)) };
}

mod args;
mod cluster;
mod print;
mod stdout;

pub use args::*;

use crate::data::ColumnRef;
use crate::engine::{self, FitRequest, RunEnd, RunOptions};
use crate::error::{Error, Result};
use crate::estimate::SolverOptions;
use crate::shard;
use crate::simulate;
use print::{
    describe_grid, print_fit_summary, print_gaps, print_layout, print_pick_bootstraps, print_picks, print_report,
    print_rules,
};

/// The whole command line of a process that is the command's own (the `oesweep` binaries):
/// [`quiet_reader_panics`], then [`main_with_args`] with the process's arguments. Prints an
/// error as one line and maps it to the exit code (0 success, 1 failure of the work itself, 2
/// bad input).
pub fn main() -> std::process::ExitCode {
    quiet_reader_panics();
    std::process::ExitCode::from(main_with_args(std::env::args_os()))
}

/// For a process that is the command's own: a bad data file is one line of error, not also a
/// panic message. The library catches a data reader's panic and makes it an input error
/// ([`crate::data::reading_data`]); this panic hook leaves that panic unprinted and hands every
/// other to the hook in place before. Set for the rest of the process: [`main`] calls it, never
/// [`main_with_args`], which a host runs in its own process.
pub fn quiet_reader_panics() {
    let print = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !crate::data::reading_data() {
            print(info);
        }
    }));
}

/// [`main`] with the arguments given (the program's name first) rather than the process's:
/// for a host process that runs the command line in-process (the Python package's `oesweep`
/// command). Returns the exit code instead of exiting, also for `--help` and usage errors.
/// It leaves the host's panic hook alone (a data reader's panic, an input error here too,
/// reaches that hook), and `run`'s SIGINT/SIGTERM handlers are the host's again when it
/// returns.
pub fn main_with_args<I, T>(args: I) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    use clap::Parser;
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        // Help and version as clap prints them (stdout, code 0); a bad command line is one line
        // and exit 2, like every other bad input (clap's usage and tips follow with --help).
        Err(e) if !e.use_stderr() => {
            let _ = e.print();
            return u8::try_from(e.exit_code()).unwrap_or(0);
        }
        Err(e) => {
            let text = e.to_string();
            let first = text.lines().next().unwrap_or_default().trim_start_matches("error: ");
            eprintln!("error: {first} (see oesweep --help)");
            return 2;
        }
    };
    drop(stdout::take_error());
    match run(cli) {
        Ok(code) => stdout::settle(code),
        Err(e) => {
            // One line, whatever the paths contain: control characters are escaped.
            let msg: String = e
                .to_string()
                .chars()
                .map(|c| if c.is_control() { c.escape_default().to_string() } else { c.to_string() })
                .collect();
            eprintln!("error: {msg}");
            if e.is_bad_input() { 2 } else { 1 }
        }
    }
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
            outln!("wrote {}", page.display());
            Ok(0)
        }
        Command::Merge(a) => cluster::run_merge(&a),
        Command::Slurm(a) => cluster::run_slurm(&a),
        Command::Spectrum(a) => run_spectrum(&a),
        Command::Export(a) => run_export(&a),
    }
}

/// `oesweep export` ([`engine::export_model`]).
fn run_export(a: &args::ExportArgs) -> Result<u8> {
    use args::ExportFormat;
    if a.to == ExportFormat::Mat && a.out.is_none() {
        return Err(Error::Invalid("--to mat writes a binary file: name it with --out FILE".into()));
    }
    let (model, notes) = engine::export_model(&a.folder, a.pick.as_ref())?;
    let continuous = a
        .continuous
        .map(|m| model.to_continuous(m).map_err(|e| Error::Invalid(format!("--continuous {m}: {}: {e}", model.name))))
        .transpose()?
        .unwrap_or_default();
    for n in &notes {
        eprintln!("warning: {n}");
    }
    let text = match a.to {
        ExportFormat::Json => model.to_json_text_with(&continuous),
        ExportFormat::Matlab => model.to_matlab_with(&continuous),
        ExportFormat::Mat => {
            let out = a.out.as_ref().expect("checked above");
            model.write_mat_with(out, &continuous)?;
            eprintln!("wrote {} ({})", out.display(), model.name);
            return Ok(0);
        }
    };
    match &a.out {
        Some(out) => {
            crate::export::write_atomically(out, |f| {
                std::io::Write::write_all(f, text.as_bytes()).map_err(|e| e.to_string())
            })?;
            eprintln!("wrote {} ({})", out.display(), model.name);
        }
        None => out!("{text}"),
    }
    Ok(0)
}

/// `oesweep spectrum` ([`engine::spectrum`]).
fn run_spectrum(a: &args::SpectrumArgs) -> Result<u8> {
    let req = engine::SpectrumRequest {
        data: a.data.clone(),
        u: a.u.iter().map(|c| ColumnRef::parse(c)).collect(),
        y: ColumnRef::parse(&a.y),
        rows: a.rows,
        ts: a.ts,
        method: a.method,
    };
    let r = engine::spectrum(&req)?;
    if a.json {
        outln!("{}", serde_json::to_string(&r).expect("report serialises"));
    } else {
        print::print_spectrum(&r);
    }
    Ok(0)
}

fn run_fit(a: &FitArgs) -> Result<u8> {
    let u: Vec<ColumnRef> = a.u.iter().map(|c| ColumnRef::parse(c)).collect();
    let structure = crate::job::structure_of(u.len(), (&a.nb, &a.nf, &a.delay))
        .map_err(|(flag, m)| Error::Invalid(format!("{flag} {m}")))?;
    let req = FitRequest {
        data: a.data.clone(),
        u,
        y: ColumnRef::parse(&a.y),
        rows: a.rows,
        validation: a.validation.clone(),
        val_y: a.val_y.as_deref().map(ColumnRef::parse),
        val_rows: a.val_rows,
        offset: a.offset,
        initial_state: a.initial_state,
        spectrum: a.spectrum,
        structure,
        k: a.k,
        ts: a.ts,
        band: a.band,
        solver: SolverOptions {
            max_iterations: a.max_iterations,
            ftol: a.ftol,
            huber_hessian: a.huber_hessian,
            method: a.method,
            ..Default::default()
        },
        bootstrap: a.bootstrap,
        threads: a.threads,
        missing: a.missing.iter().map(|m| crate::data::Marker::parse(m)).collect(),
        interpolate_inputs: a.interpolate_inputs,
    };
    let report = engine::fit(&req)?;
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    if a.json {
        outln!("{}", report.to_json());
    } else {
        print_fit_summary(&report);
        print_gaps(report.gaps.as_ref());
    }
    Ok(0)
}

fn run_simulate(a: &SimulateArgs) -> Result<u8> {
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
        // Always given, so that the library checks the range whatever the probability; with
        // probability 0 no spike is added (the spikes have their own random stream).
        outliers: Some(simulate::Outliers {
            probability: a.outlier_prob,
            min: a.outlier_range.0,
            max: a.outlier_range.1,
        }),
    };
    let gaps = simulate::GapOptions { outputs: a.missing, inputs: a.missing_inputs, burst: a.missing_burst };
    let n = simulate::simulate_csv(&a.system, &a.out, &opts, &gaps)?;
    eprintln!("wrote {} ({n} samples)", a.out.display());
    Ok(0)
}

fn run_plan(a: &PlanArgs) -> Result<u8> {
    let p = engine::prepare(&a.job)?;
    if let Some(n) = a.shards {
        shard::check_count(n, &p.plan).map_err(|m| Error::Invalid(format!("--shards {n}: {m}")))?;
    }
    let j = &p.job;
    outln!("job        {} ({})", j.job.name, j.file.display());
    let more = |n: usize| if n > 1 { format!(" and {} more experiments", n - 1) } else { String::new() };
    outln!(
        "data       {}{} ({} samples, Ts = {} s)",
        j.job.data.first().path.display(),
        more(j.job.data.specs.len()),
        p.inputs.est.len(),
        j.ts()
    );
    if let (Some(v), Some(rec)) = (&j.job.validation, &p.inputs.val) {
        outln!(
            "validation {}{} ({} samples, column '{}')",
            v.first().path.display(),
            more(v.specs.len()),
            rec.len(),
            rec.y_name
        );
    }
    print_gaps(Some(&p.gaps));
    outln!("grid       {}", describe_grid(&p));
    match &p.search {
        crate::search::Search::Product => {
            outln!("cells      {} Huber cells + {} least-squares fits", j.n_cells(), j.n_pairs())
        }
        crate::search::Search::Coordinate(c) => outln!(
            "search     coordinate (grid.search): one input's orders at a time, {} structures ({} cells) per cycle \
             over the inputs, of the product's {}",
            c.cycle(),
            c.cycle() * j.ks.len(),
            p.plan.pairs.len()
        ),
    }
    let t = crate::search::estimate_time(&p.plan, &p.search, &p.context(), 0)?;
    outln!(
        "time       about {} on all cores{} (a model: {} swept at every k in {:.2} s on one thread, scaled by size)",
        duration(t.seconds),
        match p.search {
            crate::search::Search::Product => String::new(),
            crate::search::Search::Coordinate(_) => " per cycle over the inputs".to_string(),
        },
        t.sample.label(),
        t.sample_seconds
    );
    outln!("start      {}", j.job.start.as_str());
    outln!("ranking    by the {} (`{}`)", p.ranking().describe(), p.ranking().column());
    outln!("output     {}", j.output().display());
    for w in &p.inputs.warnings {
        eprintln!("warning: {w}");
    }
    match (a.shards, &p.search) {
        (Some(n), crate::search::Search::Product) => print_layout(&p.plan, n),
        (Some(n), crate::search::Search::Coordinate(_)) => outln!(
            "shards     {n}, round by round: each round's new structures dealt among them (`oesweep run JOB --shard \
             I/{n}` for every I, again for each round, until `oesweep merge` finds the search finished)"
        ),
        (None, _) => {}
    }
    Ok(0)
}

/// Seconds as a person reads them: seconds, minutes or hours.
fn duration(seconds: f64) -> String {
    match seconds {
        s if s < 90.0 => format!("{s:.0} s"),
        s if s < 5400.0 => format!("{:.0} min", s / 60.0),
        s => format!("{:.1} h", s / 3600.0),
    }
}

/// `oesweep run` ([`engine::run`]).
fn run_job(a: &RunArgs) -> Result<u8> {
    // Checked before the run, which may take hours: the file is written after it.
    if let Some(path) = &a.profile {
        let folder = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(std::path::Path::new("."));
        if !folder.is_dir() {
            return Err(Error::Invalid(format!(
                "--profile {}: the folder {} does not exist",
                path.display(),
                folder.display()
            )));
        }
    }
    let watch = engine::Watch::default();
    let opts = RunOptions {
        threads: a.threads,
        quiet: a.quiet,
        force: a.force,
        checkpoint_every: a.checkpoint_every,
        shard: a.shard,
        report: a.report,
        watch: Some(watch.clone()),
        profile: a.profile.is_some(),
    };
    // The data's warnings are printed when the records are read; the picks' at the end.
    let printed = std::cell::RefCell::new(Vec::new());
    let on_resume = |r: &engine::Resumed| {
        for w in &r.warnings {
            eprintln!("warning: {w}");
        }
        printed.borrow_mut().extend(r.warnings.iter().cloned());
        if r.cells + r.ls > 0 && !a.quiet && r.plan_cells == 0 {
            // A coordinate search: its plan grows round by round.
            eprintln!(
                "resuming from {} ({} parts): {} cells and {} least-squares fits already done",
                r.folder.display(),
                r.parts,
                r.cells,
                r.ls,
            );
        } else if r.cells + r.ls > 0 && !a.quiet {
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
    // Ctrl-C/SIGTERM stop this run (a second one exits), and do what they did before once it
    // returns.
    let signals = crate::checkpoint::StopOnSignal::arm(watch.stop.clone());
    let o = engine::run(&a.job, &opts, &on_resume);
    drop(signals);
    let o = o?;
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
            outln!(
                "{label}: {cells} cells ({failed} failed) + {pairs} least-squares fits, saved in {}",
                o.checkpoint.display()
            );
            if o.resumed_rows > 0 {
                outln!("{} cells resumed from the checkpoint, {} computed in this run", o.resumed, o.computed);
            }
            outln!("wall time {:.2} s, {rate:.1} cells/s", o.seconds);
            let count = o.shard.map_or(1, |s| s.count);
            match o.search.as_ref().map(|r| &r.pending) {
                Some(Some(p)) => outln!(
                    "{}: this shard's {} saved; when all {count} shards are done with it, run them again for the \
                     next round (`oesweep merge {}` says whether the search has finished)",
                    p.describe(),
                    p.share.len(),
                    o.out.display()
                ),
                Some(None) => outln!("the coordinate search is finished: oesweep merge {}", o.out.display()),
                None => outln!("when all {count} shards are done: oesweep merge {}", o.out.display()),
            }
        }
        RunEnd::Merged { ref selection, .. } => {
            outln!("{}: {cells} cells ({failed} failed) + {pairs} least-squares fits", o.label);
            if let Some(r) = &o.search {
                outln!("{}", r.describe());
            }
            if o.resumed_rows > 0 {
                outln!(
                    "{} cells and {} least-squares fits resumed from the checkpoint, {} cells computed in this run",
                    o.resumed,
                    o.resumed_rows - o.resumed,
                    o.computed
                );
            }
            outln!("wall time {:.2} s, {rate:.1} cells/s", o.seconds);
            print_gaps(selection.gaps.as_ref());
            print_picks(selection);
            print_rules(selection);
            print_pick_bootstraps(selection);
            for w in selection.warnings.iter().filter(|w| !printed.borrow().contains(w)) {
                eprintln!("warning: {w}");
            }
            outln!("results in {}", o.out.display());
            if let Some(e) = &o.cleanup {
                eprintln!("warning: {e}");
            }
        }
    }
    if let (Some(path), Some(profile)) = (&a.profile, &o.profile) {
        eprint!("{}", profile.table());
        crate::export::json::write_json(path, profile)?;
    }
    let code = o.exit_code();
    if let RunEnd::Merged { report, .. } = o.end {
        print_report(report)?;
    }
    Ok(code)
}
