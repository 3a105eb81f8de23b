//! Whole operations, one function each, read top to bottom: [`prepare`] a job, [`run`] it,
//! [`merge`] the shards of an output folder, [`fit`] one model, [`simulate`] a record. The
//! command line (`cli.rs`) only turns arguments into the requests here and prints the
//! outcomes; tests call these functions directly.
//!
//! A run is: validate the job and its data ([`prepare`]) -> lock the output folder
//! ([`crate::lock`]) -> read the checkpoint of an interrupted run ([`crate::checkpoint`]) ->
//! sweep the cells left, each finished row going to the checkpoint writer ([`crate::sweep`]) ->
//! once stopped ([`Watch::stop`]), return (resumable) -> otherwise reduce to the picks
//! ([`crate::reduce`]), write the result files ([`crate::export`]), delete the checkpoint, and
//! optionally the report ([`crate::report`]). A shard (`--shard I/N`) runs its share of the
//! plan ([`crate::shard`]) and stops once its rows are saved; [`merge`] combines the shards.
//!
//! Nothing here changes the host process: no signal handler, no panic hook, no process-wide
//! setting of a dependency. The caller stops a run through [`Watch::stop`]; the command line
//! arms SIGINT/SIGTERM for that ([`crate::checkpoint::StopOnSignal`]) around its own run.

use crate::checkpoint::{self, Manifest, Writer};

use crate::error::{Error, Result};
use crate::job::{self, Inputs, ValidJob};
use crate::plan::Plan;
use crate::profile::{Phase, Profile, ProfileReport, Span};
use crate::progress::Progress;
use crate::reduce::{self, Selection};
use crate::search::{Search, Step};
use crate::shard::{self, Shard};
pub use write::lead_structure;
use write::write_results;

use crate::spectral;
use crate::sweep::{self, Context};
use crate::table::CellRow;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::SyncSender;
use std::time::{Duration, Instant};

mod beyond;
mod export_model;
mod merge;
pub mod per_input;
mod single;
mod spectrum;
mod uncertainty;
mod write;

pub use export_model::{PickSpec, export_model};
pub use merge::{MergeEnd, MergeOutcome, NEXT_ROUND, merge};
pub use single::{FitReport, FitRequest, fit, fit_arrays, simulate};
pub use spectrum::{SpectrumReport, SpectrumRequest, spectrum, spectrum_arrays};

/// A job, its data and everything derived from them before estimation starts.
pub struct Prepared {
    pub job: ValidJob,
    pub inputs: Inputs,
    /// The spectral estimate of the estimation record (one per input) and the bins of
    /// `band_hz`, the estimate computed on first use (a task of the sweep).
    pub spectral: Option<spectral::Deferred>,
    pub plan: Plan,
    /// The product of `plan`, or the coordinate search in it ([`crate::search`]).
    pub search: Search,
    /// What was missing in the records and what became of it (METHOD.md 21.1).
    pub gaps: crate::data::RecordGaps,
}

impl Prepared {
    /// What every cell of this job needs besides its orders and k.
    pub fn context(&self) -> Context<'_> {
        Context {
            est: &self.inputs.est,
            val: self.inputs.val.as_ref(),
            band: self.spectral.as_ref(),
            solver: self.job.job.solver.clone(),
            levels: self.inputs.levels.clone(),
            initial_state: self.job.job.initial_state,
            profile: None,
        }
    }

    /// The fit column the picks are ranked by.
    pub fn ranking(&self) -> reduce::FitBasis {
        reduce::choose_basis(self.inputs.val.is_some(), self.spectral.is_some())
    }
}

/// Read and check a job file and every data file it names; nothing is written.
pub fn prepare(path: &Path) -> Result<Prepared> {
    prepare_job(job::load(path)?)
}

/// [`prepare`] of a job already read and checked.
fn prepare_job(job: job::ValidJob) -> Result<Prepared> {
    let path = &job.file;
    let (inputs, gaps) = job::load_inputs_gaps(&job)?;
    // The bins are checked here, the estimate is made during the run (spectral::Deferred).
    let spectral = match job.job.band_hz {
        Some([lo, hi]) => {
            let d = spectral::Deferred::new(&inputs.est, job.ts(), job.job.spectrum, lo, hi)
                .map_err(|e| Error::data(&job.job.data.first().path, e.to_string()))?;
            let Some(d) = d else {
                return Err(Error::input(
                    path,
                    format!("field 'band_hz': [{lo}, {hi}] Hz holds no frequency bin of the spectral estimate"),
                ));
            };
            Some(d)
        }
        None => None,
    };
    let plan = Plan::from_job(&job);
    let search = Search::of_job(&job, &plan);
    Ok(Prepared { job, inputs, spectral, plan, search, gaps })
}

/// How to run a job.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Worker threads (0: all cores). The table does not depend on it.
    pub threads: usize,
    /// No progress output.
    pub quiet: bool,
    /// Delete the checkpoint of an interrupted run instead of resuming from it.
    pub force: bool,
    /// Save finished rows at least this often (seconds), and every [`checkpoint::BATCH_ROWS`].
    pub checkpoint_every: f64,
    /// Run only this shard of the plan, without merging.
    pub shard: Option<Shard>,
    /// Also write the HTML report (whole runs only).
    pub report: bool,
    /// A caller that watches the run: it stops the run through [`Watch::stop`] (the command
    /// line arms SIGINT/SIGTERM to set it, the Python package its `KeyboardInterrupt`) and
    /// reads the progress from [`Watch::done`]. None: the run goes to the end. The library
    /// installs no signal handler either way.
    pub watch: Option<Watch>,
    /// Count solver iterations by role and time by phase ([`RunOutcome::profile`]).
    pub profile: bool,
}

/// The progress and stop switch of a run shared with the caller ([`RunOptions::watch`]).
#[derive(Clone, Debug, Default)]
pub struct Watch {
    /// Set by the caller: the workers hand out no more cells, the run returns
    /// [`RunEnd::Interrupted`] with the finished rows saved, and the same call resumes.
    pub stop: Arc<AtomicBool>,
    /// Huber cells finished, those of a resumed checkpoint included.
    pub done: Arc<AtomicUsize>,
    /// Huber cells of the plan (set once the job is read; 0 before).
    pub total: Arc<AtomicUsize>,
    /// Told of every Huber cell as it finishes, after [`Watch::done`] counts it and before its
    /// worker takes another cell: a worker waits while the channel is full, so a caller that
    /// sets [`Watch::stop`] on a message it received stops the run within the channel's bound
    /// plus the cells in flight, however fast the cells are. None: nobody is told.
    pub finished: Option<SyncSender<()>>,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            threads: 0,
            quiet: true,
            force: false,
            checkpoint_every: checkpoint::BATCH_SECONDS,
            shard: None,
            report: false,
            watch: None,
            profile: false,
        }
    }
}

impl RunOptions {
    fn check(&self) -> Result<()> {
        let every = self.checkpoint_every;
        if !(every.is_finite() && every > 0.0 && every <= checkpoint::MAX_BATCH_SECONDS) {
            return Err(Error::Invalid(format!(
                "--checkpoint-every must be a positive number of seconds up to {:e}, got {every}",
                checkpoint::MAX_BATCH_SECONDS
            )));
        }
        crate::pool::check_threads(self.threads).map_err(|m| Error::Invalid(format!("--threads {m}")))?;
        if self.shard.is_some() && self.report {
            return Err(Error::Invalid(
                "--report needs the merged table: use `oesweep merge OUTPUT --report` once all shards are done".into(),
            ));
        }
        Ok(())
    }
}

/// What a run found in its checkpoint before it started (reported before the sweep).
#[derive(Clone, Debug)]
pub struct Resumed {
    /// The checkpoint folder.
    pub folder: PathBuf,
    pub parts: usize,
    /// Huber cells and least-squares fits found done.
    pub cells: usize,
    pub ls: usize,
    /// Of this run's plan.
    pub plan_cells: usize,
    pub plan_pairs: usize,
    /// Rows dropped because an earlier part had their cell (parts copied in by hand).
    pub duplicates: usize,
    /// What the user should know about the data (also kept in selection.json).
    pub warnings: Vec<String>,
}

/// How a run ended.
#[derive(Debug)]
pub enum RunEnd {
    /// Stopped through [`Watch::stop`]: the finished rows are in the checkpoint, nothing merged.
    Interrupted,
    /// A shard whose rows are all saved in its checkpoint folder, for [`merge`].
    ShardSaved,
    /// The result files are written; `report` is the report's page when one was asked for
    /// (or the error that stopped it, after the results were written).
    Merged { selection: Box<Selection>, report: Option<Result<PathBuf>> },
}

/// The outcome of [`run`].
#[derive(Debug)]
pub struct RunOutcome {
    /// The job's name (and shard).
    pub label: String,
    pub out: PathBuf,
    /// This run's checkpoint folder.
    pub checkpoint: PathBuf,
    pub shard: Option<Shard>,
    /// Cells and least-squares fits of this run's plan.
    pub cells: usize,
    pub pairs: usize,
    /// Huber cells finished in all (resumed and computed).
    pub finished: usize,
    /// Huber cells computed by this run.
    pub computed: usize,
    /// Huber cells taken from the checkpoint.
    pub resumed: usize,
    /// Rows (cells and fits) taken from the checkpoint.
    pub resumed_rows: usize,
    /// Failed Huber cells in the table.
    pub failed: usize,
    /// Wall time of the sweep.
    pub seconds: f64,
    /// Finished rows the checkpoint writer could not save, and why (they are in the results).
    pub unsaved: Option<(usize, Error)>,
    /// The checkpoint could not be deleted after the results were written.
    pub cleanup: Option<Error>,
    /// Where the work went, when [`RunOptions::profile`] asked.
    pub profile: Option<ProfileReport>,
    /// The coordinate search's rounds (None: the product).
    pub search: Option<crate::search::Rounds>,
    pub end: RunEnd,
}

impl RunOutcome {
    /// 130 interrupted, 1 when a cell failed, else 0.
    pub fn exit_code(&self) -> u8 {
        match self.end {
            RunEnd::Interrupted => 130,
            _ if self.failed > 0 => 1,
            _ => 0,
        }
    }
}

/// Run a job (see the module documentation). Everything that can be checked is checked before
/// anything is written; `on_resume` hears what the checkpoint held before the sweep starts.
pub fn run(job_file: &Path, opts: &RunOptions, on_resume: &dyn Fn(&Resumed)) -> Result<RunOutcome> {
    run_loaded(&|| job::load(job_file), opts, on_resume)
}

/// [`run`] of a job given as JSON text ([`job::from_text`]: `job_file` names it and locates its
/// relative paths, and is not read), so that a caller holding the job in memory writes no file
/// for it.
pub fn run_text(job_file: &Path, text: &str, opts: &RunOptions, on_resume: &dyn Fn(&Resumed)) -> Result<RunOutcome> {
    run_loaded(&|| job::from_text(job_file, text), opts, on_resume)
}

fn run_loaded(
    load: &dyn Fn() -> Result<job::ValidJob>,
    opts: &RunOptions,
    on_resume: &dyn Fn(&Resumed),
) -> Result<RunOutcome> {
    opts.check()?;
    let profile = opts.profile.then(|| Arc::new(Profile::default()));
    let reading = Span::start(profile.as_deref(), Phase::Read);
    let job = load()?;
    // The checkpoint's manifest hashes the data files: beside their reading, not after it.
    let (p, manifest) = std::thread::scope(|s| {
        let manifest = s.spawn(|| Manifest::of_job(&job));
        (prepare_job(job.clone()), manifest.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)))
    });
    let p = p?;
    drop(reading);
    let setup = Instant::now();
    if let Some(prof) = &profile {
        prof.serial("read", prof.report().seconds(Phase::Read));
    }
    let out = p.job.output().to_path_buf();
    let (plan, label) = match opts.shard {
        Some(s) => {
            shard::check_count(s.count, &p.plan).map_err(|m| Error::Invalid(format!("--shard {s}: {m}")))?;
            // A coordinate search's shard splits its rounds ([`crate::search::Step::Shard`]):
            // the whole plan, the round found from the rows.
            let plan = match p.search {
                Search::Product => shard::plan_of(&p.plan, s).0,
                Search::Coordinate(_) => p.plan.clone(),
            };
            (plan, format!("{} shard {s}", p.job.job.name))
        }
        None => (p.plan.clone(), p.job.job.name.clone()),
    };
    let parts = checkpoint::folder(&out, opts.shard);
    let manifest = manifest?;

    // Locked before the checkpoint is read: another run of this folder could be changing it.
    std::fs::create_dir_all(&out).map_err(|e| Error::output(&out, format!("cannot create output folder: {e}")))?;
    let _lock = match opts.shard {
        Some(s) => crate::lock::lock_shard(&out, s)?,
        None => crate::lock::lock_output(&out)?,
    };
    // A checkpoint of another job is bad input too: refused before anything is written.
    let existing = match (opts.force, opts.shard, &p.search) {
        (true, _, _) => checkpoint::Existing::default(),
        // A coordinate search's shard reads every folder's rows (the rounds so far), and
        // numbers its parts on in its own folder.
        (false, Some(_), Search::Coordinate(_)) => checkpoint::Existing {
            next_part: checkpoint::inspect(&parts, &manifest, &plan)?.next_part,
            ..checkpoint::inspect_all(&out, &manifest, &plan)?
        },
        (false, Some(_), Search::Product) => checkpoint::inspect(&parts, &manifest, &plan)?,
        (false, None, _) => checkpoint::inspect_all(&out, &manifest, &plan)?,
    };
    checkpoint::open(&out, opts.shard, &manifest, &p.job, opts.force)?;
    // A coordinate search learns its cells round by round: counted from none.
    let (pairs, cells) = match p.search {
        Search::Product => (plan.pairs.len(), plan.n_cells()),
        Search::Coordinate(_) => (0, 0),
    };
    let resumed_huber = existing.huber_rows();
    let resumed_rows = existing.rows.len();
    on_resume(&Resumed {
        folder: parts.clone(),
        parts: existing.parts,
        cells: resumed_huber,
        ls: resumed_rows - resumed_huber,
        plan_cells: cells,
        plan_pairs: pairs,
        duplicates: existing.duplicates,
        warnings: p.inputs.warnings.clone(),
    });

    // The sweep, every finished row handed to the checkpoint writer at once.
    let writer = Writer::start(
        parts.clone(),
        existing.next_part,
        Duration::from_secs_f64(opts.checkpoint_every),
        checkpoint::BATCH_ROWS,
    );
    // A coordinate search counts from none and grows by each round's cells left to fit.
    let progress = Progress::new(cells.saturating_sub(resumed_huber), opts.quiet);
    if let Some(w) = &opts.watch {
        w.total.store(cells, Ordering::Relaxed);
        w.done.store(resumed_huber, Ordering::Relaxed);
    }
    let ctx = sweep::Context { profile: profile.clone(), ..p.context() };
    let mut searched = None;
    let outcome = {
        let never = AtomicBool::new(false);
        let stop: &AtomicBool = opts.watch.as_ref().map_or(&never, |w| &w.stop);
        let tx = writer.sender();
        // A send fails only if the writer thread is gone; the row is still in the outcome.
        let on_row = |row: &CellRow| {
            let _ = tx.send(row.clone());
            if let Some(w) = opts.watch.as_ref().filter(|_| row.is_huber()) {
                w.done.fetch_add(1, Ordering::Relaxed);
                // A send fails only once the caller stopped listening.
                if let Some(tx) = &w.finished {
                    let _ = tx.send(());
                }
            }
        };
        let nested = opts.shard.is_none();
        let control = sweep::Control { done: existing.rows, on_row: &on_row, stop, nested };
        if let Some(prof) = &profile {
            prof.serial("setup", setup.elapsed().as_secs_f64());
        }
        let _span = Span::start(profile.as_deref(), Phase::Sweep);
        match &p.search {
            Search::Product => sweep::run(&plan, &ctx, opts.threads, &progress, control),
            Search::Coordinate(c) => {
                let lead = |rows: &[CellRow]| write::lead_structure(&p.job, rows);
                let grow = |n: usize| {
                    if let Some(w) = &opts.watch {
                        w.total.fetch_add(n, Ordering::Relaxed);
                    }
                };
                let step = opts.shard.map_or(Step::Whole, Step::Shard);
                let guide = crate::search::Guide { lead: &lead, grow: &grow, step };
                crate::search::coordinate(c, &plan, &ctx, opts.threads, &progress, control, guide).map(|(o, r)| {
                    searched = Some(r);
                    o
                })
            }
        }
    };
    progress.finish();
    let saved = writer.finish();
    // Workers refused: no cell was computed, a rerun starts where this one would have.
    let outcome = outcome?;
    let (cells, pairs) = match &searched {
        // A shard's cells: its share of the round it ran.
        Some(r) => {
            let structures = match (&r.pending, opts.shard) {
                (Some(p), Some(_)) => p.share.len(),
                (None, Some(_)) => 0,
                _ => r.structures,
            };
            (structures * plan.ks.len(), structures)
        }
        None => (cells, pairs),
    };
    let mut result = RunOutcome {
        label,
        out: out.clone(),
        checkpoint: parts.clone(),
        shard: opts.shard,
        cells,
        pairs,
        finished: crate::table::huber_rows(&outcome.rows),
        computed: outcome.computed,
        resumed: outcome.resumed,
        resumed_rows,
        failed: outcome.failed_cells(),
        seconds: outcome.seconds,
        unsaved: saved.error.map(|e| (saved.unsaved, e)),
        cleanup: None,
        profile: None,
        search: searched,
        end: RunEnd::Interrupted,
    };
    result.profile = profile.as_ref().map(|p| p.report());
    if outcome.interrupted {
        return Ok(result);
    }
    if opts.shard.is_some() {
        // The checkpoint is this shard's only result: rows that did not reach it are lost.
        if let Some((n, e)) = result.unsaved {
            return Err(Error::output(
                &parts,
                format!("{n} finished rows could not be saved ({e}); run the shard again to redo them"),
            ));
        }
        result.end = RunEnd::ShardSaved;
        return Ok(result);
    }

    // A whole run (its rows nested-checked by the sweep): the results, then the checkpoint has
    // served (if deleting it fails, a rerun finds every cell done and merges again), then the
    // report.
    let writing = Instant::now();
    let selection = write_results(&out, &p.job, &outcome.rows, Some((&p.inputs, &p.gaps)), opts.threads)?;
    if let Some(prof) = &profile {
        prof.add(Phase::Write, writing);
        prof.serial("write", writing.elapsed().as_secs_f64());
    }
    result.profile = profile.as_ref().map(|p| p.report());
    crate::failpoint::before_checkpoint_removal();
    result.cleanup = checkpoint::remove(&out).err();
    let report = opts.report.then(|| crate::report::write_report(&out));
    result.end = RunEnd::Merged { selection: Box::new(selection), report };
    Ok(result)
}
