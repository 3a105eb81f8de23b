//! One row of the result table: a least-squares fit of an order pair or a Huber fit of a cell.
//!
//! The same row type is written to Parquet (`cells.parquet`), read back by the reducer and the
//! report, and printed as JSON. Outcome fields are `Option` so a failed cell is a row with
//! `status = "failed"`, a `reason`, and nulls instead of numbers.

use crate::estimate::{HuberFit, LsFit, StartKind};
use crate::plan::Pair;
use serde::{Deserialize, Serialize};

/// Which fit a row holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Least-squares OE fit of an order pair (shared by all k of the pair; `k`, `gamma`,
    /// `l1c` are null).
    Ls,
    /// Huber fit of a cell (nb, nf, k).
    Huber,
}

impl Method {
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Ls => "ls",
            Method::Huber => "huber",
        }
    }
}

/// A result row. Column order and names are the table's public interface (README).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellRow {
    pub method: Method,
    pub nb: u32,
    pub nf: u32,
    pub delay: u32,
    /// Index of k in the job's k grid (null for `ls` rows).
    pub k_index: Option<u32>,
    pub k: Option<f64>,
    /// Standard deviation of the least-squares residuals of this order pair.
    pub sigma: Option<f64>,
    /// gamma = k sigma.
    pub gamma: Option<f64>,
    /// W_{N,gamma} for huber rows, (1/N) sum e^2 / 2 for ls rows.
    pub criterion: Option<f64>,
    /// Share of residuals beyond gamma.
    pub l1c: Option<f64>,
    pub fit: Option<f64>,
    pub fit_val: Option<f64>,
    pub fit_band: Option<f64>,
    pub iterations: Option<u32>,
    pub termination: Option<String>,
    pub converged: bool,
    /// "ok" or "failed".
    pub status: String,
    /// Why a cell failed (null when ok).
    pub reason: Option<String>,
    pub max_pole_radius: Option<f64>,
    pub reflections: Option<u32>,
    /// Where the fit started ([`StartKind::as_str`]; empty for a failed cell).
    pub start: String,
    /// Wall time of this fit in seconds (not reproducible; excluded from comparisons).
    pub seconds: f64,
    pub b: Vec<f64>,
    pub f: Vec<f64>,
    /// The model's output offset in the data's units: estimated c, or the level taken out
    /// (`offset` "mean"/"median"); null for "none" ([`crate::data::levels`]).
    #[serde(default)]
    pub offset: Option<f64>,
    /// Standard deviations of b, f and the estimated offset ([`crate::estimate::evidence`]).
    #[serde(default)]
    pub b_std: Vec<f64>,
    #[serde(default)]
    pub f_std: Vec<f64>,
    #[serde(default)]
    pub offset_std: Option<f64>,
    /// Largest std / |value| over the parameters (null: not computed).
    #[serde(default)]
    pub max_rel_std: Option<f64>,
    /// p-values of the residual tests: whiteness, independence from the input.
    #[serde(default)]
    pub resid_white_p: Option<f64>,
    #[serde(default)]
    pub resid_indep_p: Option<f64>,
}

impl CellRow {
    /// This row with the evidence of an assessment.
    fn with_evidence(mut self, e: &crate::estimate::evidence::Evidence) -> Self {
        self.b_std = e.b_std.clone();
        self.f_std = e.f_std.clone();
        self.offset_std = e.offset_std;
        // Infinity (an undetermined parameter) is kept: Parquet stores it.
        self.max_rel_std = Some(e.max_rel_std).filter(|v| !v.is_nan());
        self.resid_white_p = Some(e.resid_white_p).filter(|v| v.is_finite());
        self.resid_indep_p = Some(e.resid_indep_p).filter(|v| v.is_finite());
        self
    }
}

/// Identity of a row in a table: (is a Huber row, delay, nb, nf, k_index). A complete table
/// has exactly one row per key of its plan.
pub type RowKey = (bool, u32, u32, u32, Option<u32>);

/// Key of the Huber row of cell (pair, k_index).
pub fn huber_key(pair: &Pair, k_index: usize) -> RowKey {
    (true, pair.delay as u32, pair.nb as u32, pair.nf as u32, Some(k_index as u32))
}

/// Key of the least-squares row of a pair.
pub fn ls_key(pair: &Pair) -> RowKey {
    (false, pair.delay as u32, pair.nb as u32, pair.nf as u32, None)
}

/// Sort rows as in `cells.parquet`: `ls` rows first, then by delay, nb, nf, k_index.
pub fn sort_rows(rows: &mut [CellRow]) {
    rows.sort_by_key(CellRow::key);
}

pub const STATUS_OK: &str = "ok";
pub const STATUS_FAILED: &str = "failed";

impl CellRow {
    /// Row of a least-squares fit.
    pub fn from_ls(ls: &LsFit, seconds: f64) -> Self {
        let ok = ls.ok();
        CellRow {
            method: Method::Ls,
            nb: ls.nb as u32,
            nf: ls.nf as u32,
            delay: ls.delay as u32,
            k_index: None,
            k: None,
            sigma: Some(ls.sigma).filter(|v| v.is_finite()),
            gamma: None,
            criterion: Some(ls.criterion).filter(|v| v.is_finite()),
            l1c: None,
            fit: Some(ls.assessment.fit).filter(|v| v.is_finite()),
            fit_val: ls.assessment.fit_val,
            fit_band: ls.assessment.fit_band,
            iterations: Some(ls.iterations as u32),
            termination: Some(ls.termination.as_str().to_string()),
            converged: ls.termination.converged(),
            status: if ok { STATUS_OK } else { STATUS_FAILED }.to_string(),
            reason: (!ok).then(|| format!("least-squares fit ended {}", ls.termination)),
            max_pole_radius: Some(ls.assessment.max_pole_radius),
            reflections: Some(ls.reflections as u32),
            start: StartKind::Init.as_str().to_string(),
            seconds,
            b: ls.b.clone(),
            f: ls.f.clone(),
            offset: ls.offset,
            ..Self::empty()
        }
        .with_evidence(&ls.assessment.evidence)
    }

    /// Row of a Huber fit of the order pair whose least-squares fit is `ls`.
    pub fn from_huber(h: &HuberFit, ls: &LsFit, k_index: usize, start: StartKind, seconds: f64) -> Self {
        Self::from_huber_of_pair(h, (ls.nb, ls.nf, ls.delay), ls.sigma, k_index, start, seconds)
    }

    /// [`CellRow::from_huber`] from the pair's structure `(nb, nf, delay)` and sigma alone: a
    /// resumed sweep has the pair's `ls` row (from a checkpoint part), not its [`LsFit`].
    pub fn from_huber_of_pair(
        h: &HuberFit,
        (nb, nf, delay): (usize, usize, usize),
        sigma: f64,
        k_index: usize,
        start: StartKind,
        seconds: f64,
    ) -> Self {
        let ok = h.termination.usable(h.criterion);
        CellRow {
            method: Method::Huber,
            nb: nb as u32,
            nf: nf as u32,
            delay: delay as u32,
            k_index: Some(k_index as u32),
            k: Some(h.k),
            sigma: Some(sigma),
            gamma: Some(h.gamma),
            criterion: Some(h.criterion).filter(|v| v.is_finite()),
            l1c: Some(h.l1c),
            fit: Some(h.assessment.fit).filter(|v| v.is_finite()),
            fit_val: h.assessment.fit_val,
            fit_band: h.assessment.fit_band,
            iterations: Some(h.iterations as u32),
            termination: Some(h.termination.as_str().to_string()),
            converged: h.termination.converged(),
            status: if ok { STATUS_OK } else { STATUS_FAILED }.to_string(),
            reason: (!ok).then(|| format!("Huber fit ended {}", h.termination)),
            max_pole_radius: Some(h.assessment.max_pole_radius),
            reflections: Some(h.reflections as u32),
            start: start.as_str().to_string(),
            seconds,
            b: h.b.clone(),
            f: h.f.clone(),
            offset: h.offset,
            ..Self::empty()
        }
        .with_evidence(&h.assessment.evidence)
    }

    /// Row of a cell that could not be estimated at all (panic, failed L2 phase, ...).
    pub fn failed(method: Method, nb: usize, nf: usize, delay: usize, k: Option<(usize, f64)>, reason: String) -> Self {
        CellRow {
            method,
            nb: nb as u32,
            nf: nf as u32,
            delay: delay as u32,
            k_index: k.map(|(i, _)| i as u32),
            k: k.map(|(_, v)| v),
            reason: Some(reason),
            ..Self::empty()
        }
    }

    pub fn ok(&self) -> bool {
        self.status == STATUS_OK
    }

    /// A row with every outcome empty (the base of the constructors).
    fn empty() -> Self {
        CellRow {
            method: Method::Huber,
            nb: 0,
            nf: 0,
            delay: 0,
            k_index: None,
            k: None,
            sigma: None,
            gamma: None,
            criterion: None,
            l1c: None,
            fit: None,
            fit_val: None,
            fit_band: None,
            iterations: None,
            termination: None,
            converged: false,
            status: STATUS_FAILED.to_string(),
            reason: None,
            max_pole_radius: None,
            reflections: None,
            start: String::new(),
            seconds: 0.0,
            b: Vec::new(),
            f: Vec::new(),
            offset: None,
            b_std: Vec::new(),
            f_std: Vec::new(),
            offset_std: None,
            max_rel_std: None,
            resid_white_p: None,
            resid_indep_p: None,
        }
    }

    /// This row's [`RowKey`].
    pub fn key(&self) -> RowKey {
        (self.method == Method::Huber, self.delay, self.nb, self.nf, self.k_index)
    }
}
