//! One row of the result table: a least-squares fit of an order pair or a Huber fit of a cell.
//!
//! A row is built from small parts: its [`RowKey`] (which fit of which cell), a [`Status`] with
//! its reason, the numbers of the fit ([`Fit`]) and its [`Evidence`] (parameter uncertainty and
//! residual tests, [`crate::estimate::evidence`]). The columns of `cells.parquet` are listed
//! once, in [`columns::COLUMNS`]: that table drives the Parquet schema, the writer and the
//! reader ([`crate::export::parquet`]), the row's JSON (a pick in `selection.json` is a row
//! plus its score, [`crate::reduce::Candidate`]) and README's column reference (checked by a
//! test). Adding a column is one line there, the field in one of the parts, and the code that
//! computes its value.
//!
//! Outcome fields are `Option` so a failed cell is a row with `status = "failed"`, a `reason`,
//! and nulls instead of numbers.

pub mod columns;
mod key;
mod layout;

use crate::estimate::evidence::Evidence;
use crate::estimate::{Assessment, HuberFit, LsFit, StartKind, Termination};
use crate::oe::Structure;
pub use columns::{COLUMNS, Column, ColumnType, Value};
pub use key::{More, PerInput, RowKey};
pub use layout::{RowJson, TableColumn, inputs_of_names, layout, row_from_json};

/// Which fit a row holds (the `method` column).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum FitKind {
    /// Least-squares OE fit of an order pair (shared by all k of the pair; `k`, `gamma`,
    /// `l1c` are null).
    Ls,
    /// Huber fit of a cell (nb, nf, k).
    Huber,
}

crate::names::names!(FitKind { Ls = "ls", Huber = "huber" });

impl FitKind {
    pub fn parse(s: &str) -> Result<Self, String> {
        Self::from_name(s).ok_or_else(|| format!("unknown method {s:?}"))
    }
}

/// Whether a row's numbers are usable (the `status` column).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Status {
    Ok,
    /// The fit ended unusable or could not run; `reason` says why.
    #[default]
    Failed,
}

crate::names::names!(Status { Ok = "ok", Failed = "failed" });

impl Status {
    pub fn parse(s: &str) -> Result<Self, String> {
        Self::from_name(s).ok_or_else(|| format!("unknown status {s:?}"))
    }
}

/// The numbers of one fit (null where the fit has none: a least-squares row has no `gamma`
/// nor `l1c`, a failed cell none at all).
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Fit {
    /// Standard deviation of the least-squares residuals of this order pair.
    pub sigma: Option<f64>,
    /// gamma = k sigma.
    pub gamma: Option<f64>,
    /// W_{N,gamma} for huber rows, (1/N) sum e^2 / 2 for ls rows.
    pub criterion: Option<f64>,
    /// Share of residuals beyond gamma.
    pub l1c: Option<f64>,
    /// Fit % on the estimation record, the validation record, in the frequency band.
    pub fit: Option<f64>,
    pub fit_val: Option<f64>,
    pub fit_band: Option<f64>,
    /// Several inputs: each input's band fit, `fit_band` their mean (null where `fit_band` is,
    /// and for one input, whose table has no such columns).
    pub fit_band_inputs: Option<Vec<f64>>,
    pub iterations: Option<u32>,
    /// [`Termination::as_str`].
    pub termination: Option<String>,
    pub converged: bool,
    pub max_pole_radius: Option<f64>,
    pub reflections: Option<u32>,
    /// Where the fit started ([`StartKind::as_str`]; empty for a failed cell).
    pub start: String,
    /// Wall time of this fit in seconds (not reproducible: left out of comparisons and of
    /// `selection.json`).
    pub seconds: f64,
    pub b: Vec<f64>,
    pub f: Vec<f64>,
    /// The model's output offset in the data's units: estimated c, or the level taken out
    /// (`offset` "mean"/"median"); null for "none" ([`crate::data::levels`]).
    pub offset: Option<f64>,
    /// Information criteria of a least-squares fit as MATLAB defines them
    /// ([`crate::estimate::criteria`]; null for `huber` rows).
    pub aic: Option<f64>,
    pub aicc: Option<f64>,
    pub bic: Option<f64>,
    pub fpe: Option<f64>,
    /// Robust AIC and BIC of a Huber fit ([`crate::estimate::criteria::robust`]; null for `ls`
    /// rows).
    pub raic: Option<f64>,
    pub rbic: Option<f64>,
    /// Fit % of each estimation and validation experiment of a job whose records are lists
    /// (null for one experiment; METHOD.md 16).
    pub fit_exp: Option<Vec<f64>>,
    pub fit_val_exp: Option<Vec<f64>>,
}

/// A result row (see the module documentation; columns in [`COLUMNS`]).
#[derive(Clone, Debug, PartialEq)]
pub struct CellRow {
    pub key: RowKey,
    /// The tuning constant of `key.k_index` (null for `ls` rows).
    pub k: Option<f64>,
    pub status: Status,
    /// Why a cell failed (null when ok).
    pub reason: Option<String>,
    pub fit: Fit,
    pub evidence: Evidence,
}

/// What a least-squares and a Huber fit have in common, as the row needs it.
struct Fitted<'a> {
    criterion: f64,
    assessment: &'a Assessment,
    iterations: usize,
    termination: Termination,
    reflections: usize,
    b: &'a [f64],
    f: &'a [f64],
    offset: Option<f64>,
}

impl CellRow {
    /// A row with every outcome empty (the base of the constructors and of the reader).
    pub fn empty(key: RowKey) -> Self {
        CellRow {
            key,
            k: None,
            status: Status::Failed,
            reason: None,
            fit: Fit::default(),
            evidence: Evidence::default(),
        }
    }

    /// The row of a finished fit; `usable` says whether its numbers can be used, `what` names
    /// the fit in the reason of a failure.
    fn of_fit(
        key: RowKey,
        k: Option<f64>,
        x: Fitted,
        usable: bool,
        what: &str,
        start: StartKind,
        seconds: f64,
    ) -> Self {
        let finite = |v: f64| Some(v).filter(|v| v.is_finite());
        CellRow {
            key,
            k,
            status: if usable { Status::Ok } else { Status::Failed },
            reason: (!usable).then(|| format!("{what} fit ended {}", x.termination)),
            fit: Fit {
                criterion: finite(x.criterion),
                fit: finite(x.assessment.fit),
                fit_val: x.assessment.fit_val,
                fit_band: x.assessment.fit_band,
                fit_band_inputs: x.assessment.fit_band_inputs.clone(),
                iterations: Some(x.iterations as u32),
                termination: Some(x.termination.as_str().to_string()),
                converged: x.termination.converged(),
                max_pole_radius: Some(x.assessment.max_pole_radius),
                reflections: Some(x.reflections as u32),
                start: start.as_str().to_string(),
                seconds,
                b: x.b.to_vec(),
                f: x.f.to_vec(),
                offset: x.offset,
                fit_exp: x.assessment.fit_exp.clone(),
                fit_val_exp: x.assessment.fit_val_exp.clone(),
                ..Fit::default()
            },
            evidence: x.assessment.evidence.clone(),
        }
    }

    /// Row of a least-squares fit.
    pub fn from_ls(ls: &LsFit, seconds: f64) -> Self {
        let pair = ls.structure;
        let fitted = Fitted {
            criterion: ls.criterion,
            assessment: &ls.assessment,
            iterations: ls.iterations,
            termination: ls.termination,
            reflections: ls.reflections,
            b: &ls.b,
            f: &ls.f,
            offset: ls.offset,
        };
        let mut row = Self::of_fit(RowKey::ls(&pair), None, fitted, ls.ok(), "least-squares", StartKind::Init, seconds);
        row.fit.sigma = Some(ls.sigma).filter(|v| v.is_finite());
        let finite = |v: f64| Some(v).filter(|v| v.is_finite());
        let c = ls.criteria;
        (row.fit.aic, row.fit.aicc, row.fit.bic, row.fit.fpe) =
            (finite(c.aic), finite(c.aicc), finite(c.bic), finite(c.fpe));
        row
    }

    /// Row of a Huber fit of cell (`pair`, `k_index`) whose least-squares fit has scale
    /// `sigma` (a resumed sweep has the pair's `ls` row, not its [`LsFit`]).
    pub fn from_huber(
        h: &HuberFit,
        pair: &Structure,
        sigma: f64,
        k_index: usize,
        start: StartKind,
        seconds: f64,
    ) -> Self {
        let fitted = Fitted {
            criterion: h.criterion,
            assessment: &h.assessment,
            iterations: h.iterations,
            termination: h.termination,
            reflections: h.reflections,
            b: &h.b,
            f: &h.f,
            offset: h.offset,
        };
        let usable = h.termination.usable(h.criterion);
        let mut row = Self::of_fit(RowKey::huber(pair, k_index), Some(h.k), fitted, usable, "Huber", start, seconds);
        row.fit.sigma = Some(sigma);
        row.fit.gamma = Some(h.gamma);
        row.fit.l1c = Some(h.l1c);
        let finite = |v: f64| Some(v).filter(|v| v.is_finite());
        (row.fit.raic, row.fit.rbic) = (finite(h.criteria.raic), finite(h.criteria.rbic));
        row
    }

    /// Row of a cell that could not be estimated at all (panic, failed L2 phase, ...): the
    /// key, k for a Huber cell, and the reason.
    pub fn failed(key: RowKey, k: Option<f64>, reason: String) -> Self {
        CellRow { k, reason: Some(reason), ..Self::empty(key) }
    }

    pub fn ok(&self) -> bool {
        self.status == Status::Ok
    }

    /// Why the row's parameters do not fit its orders (None: they do). A row read back from a
    /// file a user may have edited (a checkpoint part, `cells.parquet`) is refused on this,
    /// since the nested pass, a resumed chain and the exports embed its parameters by its
    /// orders. A failed row holds no parameters; standard deviations may be absent.
    pub fn shape_error(&self) -> Option<String> {
        let s = self.key.structure();
        let nb: usize = s.inputs().iter().map(|o| o.nb).sum();
        let nf: usize = s.inputs().iter().map(|o| o.nf).sum();
        let fits = |what: &str, len: usize, want: usize, may_be_empty: bool| {
            (len != want && !(may_be_empty && len == 0))
                .then(|| format!("{len} values in `{what}`, its orders need {want}"))
        };
        if !self.ok() {
            return None;
        }
        fits("b", self.fit.b.len(), nb, false)
            .or_else(|| fits("f", self.fit.f.len(), nf, false))
            .or_else(|| fits("b_std", self.evidence.b_std.len(), nb, true))
            .or_else(|| fits("f_std", self.evidence.f_std.len(), nf, true))
    }

    /// The same result as `other`: equal in every column but the wall time (two runs of the
    /// same cell, e.g. a cell saved by two shards).
    pub fn same_result(&self, other: &CellRow) -> bool {
        COLUMNS.iter().filter(|c| c.reproducible).all(|c| (c.get)(self) == (c.get)(other))
    }

    /// A Huber row.
    pub fn is_huber(&self) -> bool {
        self.key.kind == FitKind::Huber
    }

    /// Number of estimated polynomial coefficients, nB + nF (several inputs: the sum over
    /// the inputs, [`Structure::dim`]).
    pub fn parameters(&self) -> u32 {
        self.key.structure().dim() as u32
    }
}

/// Sort rows as in `cells.parquet`: `ls` rows first, then by delay, nb, nf (input after
/// input), k_index.
pub fn sort_rows(rows: &mut [CellRow]) {
    rows.sort_by_key(|r| r.key);
}

/// Failed Huber cells of a table (the count a run, a merge and `selection.json` report).
pub fn failed_cells(rows: &[CellRow]) -> usize {
    rows.iter().filter(|r| r.is_huber() && !r.ok()).count()
}

/// Huber rows of a table.
pub fn huber_rows(rows: &[CellRow]) -> usize {
    rows.iter().filter(|r| r.is_huber()).count()
}
