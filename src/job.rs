//! The job file: read, default, validate -> [`ValidJob`], the only thing the planner accepts.
//!
//! A job is JSON (unknown fields are rejected). Relative paths resolve against the job file's
//! folder. Grid values of k are built from integer indices (`from + (to-from) i/(count-1)` or
//! its logarithmic twin), never by repeated float addition, so the same job always gives the
//! same k values bit for bit. Every field, default and allowed range is documented in README.

use crate::data::{self, Record};
use crate::error::{Error, Result};
use crate::estimate::SolverOptions;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Largest number of Huber cells a job may ask for.
pub const MAX_CELLS: usize = 200_000;
/// Largest order (nB or nF) a job may ask for.
pub const MAX_ORDER: usize = 60;

/// A data record as named in the job file.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DataSpec {
    /// CSV or Parquet file.
    pub path: PathBuf,
    /// Input column (default "u").
    #[serde(default = "default_u")]
    pub u: String,
    /// Output column. Default: "y" for the estimation record; for the validation record
    /// "y0" (noise-free output written by `oesweep simulate`) when the file has it, else "y".
    #[serde(default)]
    pub y: Option<String>,
    /// Sampling period in seconds (required for the estimation record; the validation
    /// record's, when given, must be equal).
    #[serde(default)]
    pub ts: Option<f64>,
}

fn default_u() -> String {
    "u".into()
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
}

/// Where each Huber fit starts.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum StartStrategy {
    /// From the order pair's least-squares fit (METHOD.md 5), every cell independent.
    #[default]
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

/// The job file as written (before validation).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Job {
    pub name: String,
    pub data: DataSpec,
    #[serde(default)]
    pub validation: Option<DataSpec>,
    #[serde(default = "default_delay")]
    pub delay: usize,
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

fn default_delay() -> usize {
    1
}

/// A checked job: every field in range, paths resolved, k grid expanded.
#[derive(Clone, Debug)]
pub struct ValidJob {
    /// The job file.
    pub file: PathBuf,
    /// Normalised job (resolved paths and columns, k as an explicit list): written as job.json.
    pub job: Job,
    pub nb: Vec<usize>,
    pub nf: Vec<usize>,
    pub ks: Vec<f64>,
}

impl ValidJob {
    pub fn n_pairs(&self) -> usize {
        self.nb.len() * self.nf.len()
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
    let job: Job = serde_json::from_str(&text).map_err(|e| Error::input(path, format!("invalid job: {e}")))?;
    validate(path, job)
}

fn validate(path: &Path, mut job: Job) -> Result<ValidJob> {
    let bad = |field: &str, msg: String| Error::input(path, format!("field '{field}': {msg}"));
    // Absolute base: job.json in the output folder must locate the data from anywhere.
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let base = parent.canonicalize().unwrap_or_else(|_| parent.to_path_buf());
    if job.name.trim().is_empty() {
        return Err(bad("name", "must not be empty".into()));
    }
    job.data.path = resolve(&base, &job.data.path);
    job.data.y.get_or_insert_with(|| "y".into());
    match job.data.ts {
        Some(ts) if ts.is_finite() && ts > 0.0 => {}
        Some(ts) => return Err(bad("data.ts", format!("must be a positive number of seconds, got {ts}"))),
        None => return Err(bad("data.ts", "missing: the sampling period in seconds is required".into())),
    }
    if let Some(v) = job.validation.as_mut() {
        v.path = resolve(&base, &v.path);
        if let Some(ts) = v.ts {
            let ets = job.data.ts.unwrap();
            if !(ts.is_finite() && ts > 0.0) {
                return Err(bad("validation.ts", format!("must be a positive number of seconds, got {ts}")));
            }
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
    let ks = k_values(&job.grid.k);
    if ks.is_empty() {
        return Err(bad("grid.k", "the list of k values is empty".into()));
    }
    if let Some(k) = ks.iter().find(|k| !(k.is_finite() && **k > 0.0)) {
        return Err(bad("grid.k", format!("k must be positive, got {k}")));
    }
    for w in ks.windows(2) {
        if w[0] == w[1] {
            return Err(bad("grid.k", format!("k = {} appears twice", w[0])));
        }
    }
    let nb: Vec<usize> = (b0..=b1).collect();
    let nf: Vec<usize> = (f0..=f1).collect();
    let cells = nb.len() * nf.len() * ks.len();
    if cells > MAX_CELLS {
        return Err(bad("grid", format!("{cells} cells is above the limit of {MAX_CELLS}")));
    }
    if let Some([lo, hi]) = job.band_hz {
        let nyq = 0.5 / job.data.ts.unwrap();
        if !(lo >= 0.0 && hi > lo && hi <= nyq * (1.0 + 1e-12)) {
            return Err(bad("band_hz", format!("[{lo}, {hi}]: need 0 <= lo < hi <= Nyquist frequency {nyq} Hz")));
        }
    }
    let s = &job.solver;
    if s.max_iterations == 0 {
        return Err(bad("solver.max_iterations", "must be at least 1".into()));
    }
    for (name, v) in [("ftol", s.ftol), ("xtol", s.xtol), ("gtol", s.gtol), ("lambda0", s.lambda0)] {
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
    if job.output.is_file() {
        return Err(bad("output", format!("{} is a file, not a folder", job.output.display())));
    }
    job.grid.k = KGrid::List(ks.clone());
    Ok(ValidJob { file: path.to_path_buf(), job, nb, nf, ks })
}

/// The records a job names, read and checked.
pub struct Inputs {
    pub est: Record,
    pub val: Option<Record>,
}

/// Read the job's data files and check them against the largest orders of the grid.
/// Fills in the validation output column actually used.
pub fn load_inputs(vj: &mut ValidJob) -> Result<Inputs> {
    let d = &vj.job.data;
    let est = data::read_record(&d.path, &d.u, d.y.as_deref().unwrap_or("y"))?;
    let (nb_max, nf_max) = (*vj.nb.last().unwrap(), *vj.nf.last().unwrap());
    data::check_for_model(&est, nb_max, nf_max, vj.job.delay)?;
    let val = match vj.job.validation.as_mut() {
        Some(v) => {
            let col = match &v.y {
                Some(c) => c.clone(),
                None => {
                    if data::column_names(&v.path)?.iter().any(|c| c == "y0") {
                        "y0".to_string()
                    } else {
                        "y".to_string()
                    }
                }
            };
            let rec = data::read_record(&v.path, &v.u, &col)?;
            data::check_for_model(&rec, nb_max, nf_max, vj.job.delay)?;
            v.y = Some(col);
            v.ts.get_or_insert(vj.job.data.ts.unwrap());
            Some(rec)
        }
        None => None,
    };
    Ok(Inputs { est, val })
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
}
