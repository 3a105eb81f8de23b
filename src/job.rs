//! The job file: read, default, validate -> [`ValidJob`], the only thing the planner accepts.
//!
//! A job is JSON (unknown fields are rejected). Relative paths resolve against the job file's
//! folder. Grid values of k are built from integer indices (`from + (to-from) i/(count-1)` or
//! its logarithmic twin), never by repeated float addition, so the same job always gives the
//! same k values bit for bit. Every field, default and allowed range is documented in README.

use crate::data::{self, ColumnRef, Delimiter, Header, Levels, Offset, ReadOptions, Record};
use crate::error::{Error, Result};
use crate::estimate::InitialState;
use crate::estimate::SolverOptions;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Largest number of Huber cells a job may ask for.
pub const MAX_CELLS: usize = 200_000;
/// Largest order (nB or nF) a job may ask for: above any model of a SISO actuator worth
/// fitting (the paper's grid ends at 15), and below the order up to which pole reflection
/// works without allocation ([`crate::oe::STACK_ORDER`], checked at compile time).
pub const MAX_ORDER: usize = 60;
const _: () = assert!(MAX_ORDER <= crate::oe::STACK_ORDER);
/// The delay of a job that names none.
pub const DEFAULT_DELAY: usize = 1;

/// A data record as named in the job file.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DataSpec {
    /// Data file (text, Parquet or MAT). Required for the estimation record; the validation
    /// record defaults to the estimation record's file (then `rows` tells them apart).
    #[serde(default)]
    pub path: PathBuf,
    /// Input column: a name, or a 1-based position (default "u"; for the validation record,
    /// the estimation record's).
    #[serde(default)]
    pub u: Option<ColumnRef>,
    /// Output column. Default: "y" for the estimation record; for the validation record
    /// "y0" (noise-free output written by `oesweep simulate`) when the file has it, else the
    /// estimation record's.
    #[serde(default)]
    pub y: Option<ColumnRef>,
    /// Sampling period in seconds (required for the estimation record; the validation
    /// record's, when given, must be equal).
    #[serde(default)]
    pub ts: Option<f64>,
    /// Text files: `","`, `";"`, `"tab"` or `"whitespace"`; default: sniffed from the file.
    #[serde(default)]
    pub delimiter: Option<String>,
    /// Text files: `true`, `false` or `"auto"` (default; a first line of numbers is data).
    /// The validation record defaults to the estimation record's setting.
    #[serde(default)]
    pub header: Option<Header>,
    /// Data rows `[first, last]` (1-based, inclusive; the header is not a row). Default: all.
    #[serde(default)]
    pub rows: Option<[usize; 2]>,
}

impl DataSpec {
    /// The reader's options (the spec is checked by [`load`]).
    pub fn read_options(&self) -> ReadOptions {
        ReadOptions {
            delimiter: self.delimiter.as_deref().and_then(|d| Delimiter::parse(d).ok()),
            header: self.header.unwrap_or_default(),
            rows: self.rows,
        }
    }

    /// The input column (validated specs always have one).
    pub fn u_col(&self) -> ColumnRef {
        self.u.clone().unwrap_or_else(|| ColumnRef::name("u"))
    }

    /// The output column (validated specs always have one).
    pub fn y_col(&self) -> ColumnRef {
        self.y.clone().unwrap_or_else(|| ColumnRef::name("y"))
    }
}

/// k values: an explicit list or a generated range.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum KGrid {
    List(Vec<f64>),
    Range(KRange),
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct KRange {
    pub from: f64,
    pub to: f64,
    pub count: usize,
    #[serde(default)]
    pub spacing: Spacing,
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum Spacing {
    #[default]
    Linear,
    Log,
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Grid {
    /// Inclusive range [from, to] of nB.
    pub nb: [usize; 2],
    /// Inclusive range [from, to] of nF.
    pub nf: [usize; 2],
    pub k: KGrid,
    /// Inclusive range [from, to] of the input delay d in samples (default: the job's
    /// top-level `delay`, itself 1 by default).
    #[serde(default)]
    pub delay: Option<[usize; 2]>,
}

/// Where each Huber fit starts.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum StartStrategy {
    /// Continuation chains along increasing k, one per start (theta_LS and the pair's extra
    /// starts), merged when they reach the same minimum; each cell keeps the best chain
    /// ([`crate::estimate::Chains`]). As good as `ls` against an independent solver at about a
    /// third of its cost.
    #[default]
    Chains,
    /// From the order pair's least-squares fit (METHOD.md 5), every cell independent.
    Ls,
    /// Continuation along k: from the solution at the next larger k (the largest k from the
    /// least-squares fit). About half the iterations, but it may end in another local minimum.
    Neighbour,
    /// Both starts; keep the lower criterion. Never worse than `ls`.
    Best,
}

impl StartStrategy {
    pub fn as_str(self) -> &'static str {
        match self {
            StartStrategy::Chains => "chains",
            StartStrategy::Ls => "ls",
            StartStrategy::Neighbour => "neighbour",
            StartStrategy::Best => "best",
        }
    }
}

/// Tolerances of the model choice (METHOD.md 7; rules in [`crate::reduce`]).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SelectionSettings {
    /// A point of a W (or L1C) curve along nF is a local minimum when it is not above either
    /// neighbour by more than this (relative for W, absolute share for L1C).
    pub min_tolerance: f64,
    /// Candidates within this many fit-percentage points of the best count as ties; the one
    /// with the fewest parameters wins.
    pub fit_tolerance: f64,
}

impl Default for SelectionSettings {
    fn default() -> Self {
        SelectionSettings { min_tolerance: 1e-3, fit_tolerance: 0.05 }
    }
}

/// Smallest `solver.explore_rows`: a shorter head says too little about lightly damped modes.
const MIN_EXPLORE_ROWS: usize = 1000;

/// The job file as written (before validation).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Job {
    pub name: String,
    pub data: DataSpec,
    #[serde(default)]
    pub validation: Option<DataSpec>,
    /// One input delay for the whole grid (shorthand of `grid.delay` = [d, d]).
    #[serde(default)]
    pub delay: Option<usize>,
    /// Offsets of the signals ([`data::levels`]).
    #[serde(default)]
    pub offset: Offset,
    /// The initial state the fits are judged with ([`InitialState`]).
    #[serde(default)]
    pub initial_state: InitialState,
    /// The spectral estimate `fit_band` compares with ([`crate::spectral::SpectrumMethod`]).
    #[serde(default)]
    pub spectrum: crate::spectral::SpectrumMethod,
    pub grid: Grid,
    #[serde(default)]
    pub band_hz: Option<[f64; 2]>,
    #[serde(default)]
    pub solver: SolverOptions,
    #[serde(default)]
    pub start: StartStrategy,
    #[serde(default)]
    pub selection: SelectionSettings,
    /// Output folder.
    pub output: PathBuf,
}

/// A checked job: every field in range, paths resolved, the validation record's output column
/// and sampling period filled in, the k grid expanded. Built once ([`load`], or [`read_as_run`]
/// for the job a run wrote) and never changed afterwards; the records are read beside it
/// ([`load_inputs`]).
#[derive(Clone, Debug)]
pub struct ValidJob {
    /// The job file (or the job.json it was read back from).
    pub file: PathBuf,
    /// Normalised job (resolved paths and columns, k as an explicit list): written as job.json.
    pub job: Job,
    pub nb: Vec<usize>,
    pub nf: Vec<usize>,
    pub delays: Vec<usize>,
    pub ks: Vec<f64>,
}

/// `job.json` of a run: the normalised job and the program that ran it.
#[derive(Serialize)]
struct JobAsRun<'a> {
    oesweep_version: &'static str,
    #[serde(flatten)]
    job: &'a Job,
}

impl ValidJob {
    /// The grid of a normalised job (`grid.delay` set, k a list; [`validate`] made it so):
    /// the one expansion of the grid into its values.
    fn of_normalised(file: &Path, job: Job) -> ValidJob {
        let range = |[a, b]: [usize; 2]| (a..=b).collect::<Vec<usize>>();
        let delays = range(job.grid.delay.unwrap_or([job.delay.unwrap_or(DEFAULT_DELAY); 2]));
        ValidJob {
            file: file.to_path_buf(),
            nb: range(job.grid.nb),
            nf: range(job.grid.nf),
            delays,
            ks: k_values(&job.grid.k),
            job,
        }
    }

    /// Write the job as run (`job.json` of an output or a checkpoint folder), for
    /// [`read_as_run`].
    pub fn write_as_run(&self, path: &Path) -> Result<()> {
        crate::export::json::write_json(path, &JobAsRun { oesweep_version: env!("CARGO_PKG_VERSION"), job: &self.job })
    }

    /// The largest orders and delay of the grid: the records must be long enough for them.
    pub fn largest(&self) -> (usize, usize, usize) {
        (*self.nb.last().unwrap(), *self.nf.last().unwrap(), *self.delays.last().unwrap())
    }

    pub fn n_pairs(&self) -> usize {
        self.nb.len() * self.nf.len() * self.delays.len()
    }
    pub fn n_cells(&self) -> usize {
        self.n_pairs() * self.ks.len()
    }
    pub fn output(&self) -> &Path {
        &self.job.output
    }
    pub fn ts(&self) -> f64 {
        self.job.data.ts.expect("validated")
    }
}

/// Expand a k grid (index-based, endpoints exact).
pub fn k_values(k: &KGrid) -> Vec<f64> {
    match k {
        KGrid::List(v) => v.clone(),
        KGrid::Range(r) => {
            if r.count == 1 {
                return vec![r.from];
            }
            let last = (r.count - 1) as f64;
            (0..r.count)
                .map(|i| {
                    if i == 0 {
                        r.from
                    } else if i == r.count - 1 {
                        r.to
                    } else {
                        let s = i as f64 / last;
                        match r.spacing {
                            Spacing::Linear => r.from + (r.to - r.from) * s,
                            Spacing::Log => (r.from.ln() + (r.to.ln() - r.from.ln()) * s).exp(),
                        }
                    }
                })
                .collect()
        }
    }
}

/// Rules that the job file and `oesweep fit` share. Each returns what is wrong; the caller
/// names the field or flag.
pub fn check_sampling_period(ts: f64) -> std::result::Result<(), String> {
    if ts.is_finite() && ts > 0.0 { Ok(()) } else { Err(format!("must be a positive number of seconds, got {ts}")) }
}

/// A tuning constant k (see [`check_sampling_period`]).
pub fn check_k(k: f64) -> std::result::Result<(), String> {
    if k.is_finite() && k > 0.0 { Ok(()) } else { Err(format!("must be positive, got {k}")) }
}

/// A frequency band [lo, hi] in Hz at sampling period `ts` (see [`check_sampling_period`]).
pub fn check_band(lo: f64, hi: f64, ts: f64) -> std::result::Result<(), String> {
    let nyq = 0.5 / ts;
    // The tolerance lets `hi` be the Nyquist frequency as written in decimal.
    if lo >= 0.0 && hi > lo && hi <= nyq * (1.0 + 1e-12) {
        Ok(())
    } else {
        Err(format!("need 0 <= lo < hi <= Nyquist frequency {nyq} Hz"))
    }
}

/// The reader fields of a data spec (`which` is "data" or "validation"): (field, message).
fn check_data_spec(d: &DataSpec, which: &str) -> std::result::Result<(), (String, String)> {
    if let Some(delim) = &d.delimiter {
        Delimiter::parse(delim).map_err(|m| (format!("{which}.delimiter"), m))?;
    }
    if let Some(rows) = d.rows {
        data::check_rows(rows).map_err(|m| (format!("{which}.rows"), m))?;
    }
    for (name, c) in [("u", &d.u), ("y", &d.y)] {
        if c == &Some(ColumnRef::Position(0)) {
            return Err((format!("{which}.{name}"), "column position 0: positions count from 1".into()));
        }
    }
    Ok(())
}

/// `p` relative to `base`, with `a/../` folded lexically so messages show readable paths.
fn resolve(base: &Path, p: &Path) -> PathBuf {
    use std::path::Component;
    let joined = if p.is_absolute() { p.to_path_buf() } else { base.join(p) };
    let mut out = PathBuf::new();
    for c in joined.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.components().next_back(), Some(Component::Normal(_))) => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    if out.as_os_str().is_empty() { PathBuf::from(".") } else { out }
}

/// Read and validate a job file. Does not touch the data files (see [`load_inputs`]).
pub fn load(path: &Path) -> Result<ValidJob> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::input(path, format!("cannot read job file: {e}")))?;
    // A byte-order mark (written by some Windows editors) is not JSON but is no error either.
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    // serde would read a top-level array positionally and complain about its first element.
    if let Ok(v) = serde_json::from_str::<serde_json::Value>(text)
        && !v.is_object()
    {
        return Err(Error::input(path, "invalid job: the file must hold one JSON object { ... }"));
    }
    // serde quotes unknown keys and variants verbatim: escape control characters so the
    // message stays the one line the CLI promises.
    let job: Job = serde_json::from_str(text)
        .map_err(|e| Error::input(path, format!("invalid job: {}", data::one_line(&e.to_string()))))?;
    let job = resolve_validation(validate(path, job)?)?;
    Ok(ValidJob::of_normalised(path, job))
}

/// Read back the job a run wrote ([`ValidJob::write_as_run`]: `job.json` of an output or a
/// checkpoint folder), for `oesweep merge` and the report: the same [`Job`] type, already
/// normalised, so nothing is checked again but its shape. Files of versions before the
/// `offset`, `initial_state` and `spectrum` fields ran the paper's model: absent, they read as
/// "none", "zero" and "welch". Relative data paths (a hand-made file) are taken from `path`'s
/// folder.
pub fn read_as_run(path: &Path) -> Result<(ValidJob, Option<String>)> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    let bad = |e: String| Error::input(path, format!("not the job.json `oesweep run` writes: {}", data::one_line(&e)));
    let mut v: serde_json::Value = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    let obj = v.as_object_mut().ok_or_else(|| bad("not a JSON object".into()))?;
    let version = obj.remove("oesweep_version").and_then(|v| v.as_str().map(str::to_string));
    for (field, paper) in [("offset", "none"), ("initial_state", "zero"), ("spectrum", "welch")] {
        obj.entry(field).or_insert_with(|| paper.into());
    }
    let mut job: Job = serde_json::from_value(v).map_err(|e| bad(e.to_string()))?;
    let folder = path.parent().unwrap_or(Path::new("."));
    let resolve = |p: &Path| if p.is_absolute() { p.to_path_buf() } else { folder.join(p) };
    job.data.path = resolve(&job.data.path);
    if let Some(v) = job.validation.as_mut() {
        v.path = resolve(&v.path);
    }
    if job.data.ts.is_none_or(|ts| check_sampling_period(ts).is_err()) {
        return Err(Error::input(path, "field 'data.ts': missing or not a positive number"));
    }
    Ok((ValidJob::of_normalised(path, job), version))
}

/// The validation record's output column (the file's `y0` when it has one,
/// [`data::validation_column`]) and sampling period, filled in so that the checked job is
/// complete. Reads the header of the validation file when its column is not given.
fn resolve_validation(mut job: Job) -> Result<Job> {
    let (data_y, ts) = (job.data.y_col(), job.data.ts);
    if let Some(v) = job.validation.as_mut() {
        v.y = Some(data::validation_column(&v.path, v.y.as_ref(), &data_y, &v.read_options())?);
        v.ts = v.ts.or(ts);
    }
    Ok(job)
}

/// Check every field and normalise the job: paths resolved, defaults filled in, the delay as
/// `grid.delay`, k as an explicit list.
fn validate(path: &Path, mut job: Job) -> Result<Job> {
    // Messages quote paths and values from the job, which may hold control characters.
    let bad = |field: &str, msg: String| Error::input(path, data::one_line(&format!("field '{field}': {msg}")));
    // Absolute base: job.json in the output folder must locate the data from anywhere.
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let base = parent.canonicalize().unwrap_or_else(|_| parent.to_path_buf());
    if job.name.trim().is_empty() {
        return Err(bad("name", "must not be empty".into()));
    }
    if job.data.path.as_os_str().is_empty() {
        return Err(bad("data.path", "missing: the data file is required".into()));
    }
    job.data.path = resolve(&base, &job.data.path);
    job.data.u.get_or_insert_with(|| ColumnRef::name("u"));
    job.data.y.get_or_insert_with(|| ColumnRef::name("y"));
    check_data_spec(&job.data, "data").map_err(|(f, m)| bad(&f, m))?;
    match job.data.ts {
        Some(ts) => check_sampling_period(ts).map_err(|m| bad("data.ts", m))?,
        None => return Err(bad("data.ts", "missing: the sampling period in seconds is required".into())),
    }
    if let Some(v) = job.validation.as_mut() {
        // The usual split of one experiment: same file and layout, other rows; or the same
        // rows, other columns (`uVal`, `yVal` beside `uEst`, `yEst`).
        if v.path.as_os_str().is_empty() {
            if v.rows.is_none() && v.u.is_none() && v.y.is_none() {
                return Err(bad(
                    "validation",
                    "give its 'path', or the 'rows' or columns ('u', 'y') it takes from the estimation file (as \
                     it is, it would be the estimation record)"
                        .into(),
                ));
            }
            v.path = job.data.path.clone();
        } else {
            v.path = resolve(&base, &v.path);
        }
        v.u.get_or_insert_with(|| job.data.u_col());
        if v.delimiter.is_none() && v.path == job.data.path {
            v.delimiter = job.data.delimiter.clone();
        }
        v.header.get_or_insert(job.data.header.unwrap_or_default());
        check_data_spec(v, "validation").map_err(|(f, m)| bad(&f, m))?;
        if let Some(ts) = v.ts {
            let ets = job.data.ts.unwrap();
            check_sampling_period(ts).map_err(|m| bad("validation.ts", m))?;
            if (ts - ets).abs() > 1e-9 * ets {
                return Err(bad(
                    "validation.ts",
                    format!("sampling period {ts} s differs from the estimation record's {ets} s"),
                ));
            }
        }
    }
    let [b0, b1] = job.grid.nb;
    let [f0, f1] = job.grid.nf;
    if b0 < 1 || b0 > b1 {
        return Err(bad("grid.nb", format!("[{b0}, {b1}] is not a range [from, to] with 1 <= from <= to")));
    }
    if f0 > f1 {
        return Err(bad("grid.nf", format!("[{f0}, {f1}] is not a range [from, to] with from <= to")));
    }
    if b1 > MAX_ORDER || f1 > MAX_ORDER {
        return Err(bad("grid", format!("orders above {MAX_ORDER} are not supported")));
    }
    let [d0, d1] = match (job.grid.delay, job.delay) {
        (Some(_), Some(_)) => {
            return Err(bad("delay", "give either 'delay' or 'grid.delay', not both".into()));
        }
        (Some(range), None) => range,
        (None, Some(d)) => [d, d],
        (None, None) => [DEFAULT_DELAY; 2],
    };
    if d0 > d1 {
        return Err(bad("grid.delay", format!("[{d0}, {d1}] is not a range [from, to] with from <= to")));
    }
    job.grid.delay = Some([d0, d1]);
    job.delay = None;
    if let KGrid::Range(r) = &job.grid.k {
        if r.count == 0 {
            return Err(bad("grid.k.count", "must be at least 1".into()));
        }
        if !(r.from.is_finite() && r.to.is_finite() && r.from > 0.0 && r.to >= r.from) {
            return Err(bad("grid.k", format!("from {} to {}: need 0 < from <= to", r.from, r.to)));
        }
        if r.count > 1 && r.from == r.to {
            return Err(bad("grid.k", format!("from == to == {} with count {}: the range is empty", r.from, r.count)));
        }
    }
    // The cell cap is checked before the k grid is expanded: a typo such as a count of 1e15
    // must be an error, not an allocation that aborts the process.
    let n_k = match &job.grid.k {
        KGrid::List(v) => v.len(),
        KGrid::Range(r) => r.count,
    };
    let cells = ((b1 - b0 + 1) * (f1 - f0 + 1)) as u128 * ((d1 - d0) as u128 + 1) * n_k as u128;
    if cells > MAX_CELLS as u128 {
        return Err(bad("grid", format!("{cells} cells is above the limit of {MAX_CELLS}")));
    }
    let ks = k_values(&job.grid.k);
    if ks.is_empty() {
        return Err(bad("grid.k", "the list of k values is empty".into()));
    }
    if let Some(m) = ks.iter().find_map(|&k| check_k(k).err()) {
        return Err(bad("grid.k", format!("k {m}")));
    }
    // Duplicates anywhere in the list (not only neighbours) would give two cells with the
    // same (nB, nF, k) and two identical rows in the table.
    let mut sorted = ks.clone();
    sorted.sort_by(f64::total_cmp);
    if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
        return Err(bad("grid.k", format!("k = {} appears twice", w[0])));
    }
    if let Some([lo, hi]) = job.band_hz {
        check_band(lo, hi, job.data.ts.unwrap()).map_err(|m| bad("band_hz", format!("[{lo}, {hi}]: {m}")))?;
    }
    let s = &job.solver;
    if s.max_iterations == 0 {
        return Err(bad("solver.max_iterations", "must be at least 1".into()));
    }
    if s.explore_rows != 0 && s.explore_rows < MIN_EXPLORE_ROWS {
        return Err(bad(
            "solver.explore_rows",
            format!("must be 0 (explore on the whole record) or at least {MIN_EXPLORE_ROWS}, got {}", s.explore_rows),
        ));
    }
    for (name, v) in [
        ("ftol", s.ftol),
        ("xtol", s.xtol),
        ("gtol", s.gtol),
        ("lambda0", s.lambda0),
        ("warm_lambda0", s.warm_lambda0),
        ("huber_tol", s.huber_tol),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(bad(&format!("solver.{name}"), format!("must be a non-negative number, got {v}")));
        }
    }
    let sel = &job.selection;
    if !(sel.min_tolerance.is_finite() && sel.min_tolerance >= 0.0) {
        return Err(bad("selection.min_tolerance", format!("must be >= 0, got {}", sel.min_tolerance)));
    }
    if !(sel.fit_tolerance.is_finite() && sel.fit_tolerance >= 0.0) {
        return Err(bad("selection.fit_tolerance", format!("must be >= 0, got {}", sel.fit_tolerance)));
    }
    job.output = resolve(&base, &job.output);
    check_output_folder(&job.output).map_err(|msg| bad("output", msg))?;
    job.grid.k = KGrid::List(ks);
    Ok(job)
}

/// Checks, without leaving a trace, that `out` is a folder `run` will be able to create or
/// write into: a typo in `output` must fail in `plan`, before a night of estimation.
///
/// The nearest existing ancestor (the folder itself when it exists) must be a folder in which
/// we can create an entry. That is tested by creating and at once removing a uniquely named
/// empty probe folder, not with `access(W_OK)`: the permission bits are no answer for root
/// (who may write almost anywhere, yet not under `/proc`), nor for read-only mounts, ACLs or
/// full quotas on some file systems, and `libc` is not a dependency.
fn check_output_folder(out: &Path) -> std::result::Result<(), String> {
    use std::io::ErrorKind;
    let mut existing = None;
    for a in out.ancestors() {
        match std::fs::metadata(a) {
            Ok(m) => {
                existing = Some((a, m));
                break;
            }
            // NotADirectory: a component further up is a file; the loop reaches it.
            Err(e) if matches!(e.kind(), ErrorKind::NotFound | ErrorKind::NotADirectory) => {}
            Err(e) => return Err(format!("cannot access {}: {e}", a.display())),
        }
    }
    let Some((dir, meta)) = existing else {
        return Err(format!("{}: no part of this path exists", out.display()));
    };
    if !meta.is_dir() {
        return Err(if dir == out {
            format!("{} is a file, not a folder", out.display())
        } else {
            format!("cannot create {}: {} is a file, not a folder", out.display(), dir.display())
        });
    }
    static PROBES: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    let probe = dir.join(format!(
        ".oesweep-probe-{}-{nanos}-{}",
        std::process::id(),
        PROBES.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    match std::fs::create_dir(&probe) {
        Ok(()) => {
            // A probe that cannot be removed again would be a trace; say so rather than hide it.
            std::fs::remove_dir(&probe).map_err(|e| format!("cannot remove the probe folder {}: {e}", probe.display()))
        }
        Err(e) if dir == out => Err(format!("cannot write into {} ({e})", out.display())),
        Err(e) => Err(format!("cannot create {}: {} does not accept new folders ({e})", out.display(), dir.display())),
    }
}

/// The records a job names, read and checked, with their levels taken out.
pub struct Inputs {
    pub est: Record,
    pub val: Option<Record>,
    /// The levels taken out of both records (the job's `offset`).
    pub levels: Levels,
    /// Things the user should know about the data (printed once, kept in selection.json).
    pub warnings: Vec<String>,
}

/// Read the job's data files and check them against the largest orders of the grid.
pub fn load_inputs(vj: &ValidJob) -> Result<Inputs> {
    read_inputs(&vj.job.data, vj.job.validation.as_ref(), vj.job.offset, vj.largest())
}

/// The one loader of records, for a job and for `oesweep fit`: read the estimation and the
/// validation record as their specs say (the validation output column resolved, see
/// [`resolve_validation`]), check both against the largest model `(nb, nf, delay)`, and take
/// out the levels of `offset` ([`Levels::of`], computed here only).
pub fn read_inputs(
    data: &DataSpec,
    validation: Option<&DataSpec>,
    offset: Offset,
    (nb_max, nf_max, delay_max): (usize, usize, usize),
) -> Result<Inputs> {
    let (mut est, mut val) = read_records(data, validation)?;
    data::check_for_model(&est, nb_max, nf_max, delay_max)?;
    if let Some(rec) = &val {
        data::check_for_model(rec, nb_max, nf_max, delay_max)?;
    }
    let levels = Levels::of(offset, &est);
    let warnings = data::levels::offset_warning(offset, &est).into_iter().collect();
    levels.apply(&mut est);
    if let Some(v) = val.as_mut() {
        levels.apply(v);
    }
    Ok(Inputs { est, val, levels, warnings })
}

/// The records of a checked job, as read from the files (levels not taken out): for the
/// report's plots, which show the data in its own units.
pub fn read_records(data: &DataSpec, validation: Option<&DataSpec>) -> Result<(Record, Option<Record>)> {
    let est = data::read_record_with(&data.path, &data.u_col(), &data.y_col(), &data.read_options())?;
    let val = match validation {
        Some(v) => Some(data::read_record_with(&v.path, &v.u_col(), &v.y_col(), &v.read_options())?),
        None => None,
    };
    Ok((est, val))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn k_grid_is_index_based_with_exact_ends() {
        let r = KGrid::Range(KRange { from: 0.05, to: 2.0, count: 40, spacing: Spacing::Log });
        let k = k_values(&r);
        assert_eq!(k.len(), 40);
        assert_eq!(k[0], 0.05);
        assert_eq!(k[39], 2.0);
        assert!(k.windows(2).all(|w| w[1] > w[0]));
        let lin = k_values(&KGrid::Range(KRange { from: 0.1, to: 1.0, count: 10, spacing: Spacing::Linear }));
        assert_eq!(lin[3], 0.1 + 0.9 * (3.0 / 9.0));
    }

    #[test]
    fn byte_order_mark_is_accepted_and_output_probe_leaves_no_trace() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("job.json");
        let job = r#"{"name": "x", "data": {"path": "d.csv", "ts": 1}, "grid": {"nb": [1, 1], "nf": [0, 0], "k": [1]},
            "output": "a/b"}"#;
        std::fs::write(&p, format!("\u{feff}{job}")).unwrap();
        let vj = load(&p).unwrap();
        assert!(vj.output().ends_with("a/b"));
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(left, vec![std::ffi::OsString::from("job.json")]);
    }
}
