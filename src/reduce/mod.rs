//! Model choice from the result table (METHOD.md section 7).
//!
//! The sweep fills a table of cells (nB, nF, k). Following the paper, a model is not chosen by
//! its fit alone (the fit keeps growing with the orders) but among the *local minima over nF* of
//! two validation curves, computed separately for every (nB, k):
//!
//! - **M1** ("M1-style" model): local minima of the Huber criterion W(nF);
//! - **M2** ("M2-style" model): local minima of the L1 contribution L1C(nF).
//!
//! # Rules
//!
//! 1. **Participating rows.** Only `huber` rows with status `"ok"` and a finite criterion take
//!    part (`ls` rows are the initialisation of a pair, not a model of the grid). They must also
//!    have a finite L1C and a k index, k and gamma, which every Huber fit has; a row lacking one is
//!    malformed and ignored like a failed one. `failed` counts the `huber` rows with status
//!    `"failed"`; `cells` counts all `huber` rows.
//! 2. **Curves.** Rows are grouped by (delay, nB, k index) and sorted by nF (several inputs:
//!    one line per input's nF through each row, a minimum on all of them, `lines`). Neighbours
//!    are the adjacent nF values *present* in the table: a failed cell is simply absent, so its
//!    two neighbours become adjacent. (Should a cell appear twice, the row with the smaller
//!    criterion is kept.) The W and L1C curves have the same points.
//! 3. **Local minimum of W.** Point i is a candidate when it is not significantly above either
//!    existing neighbour: `W_i <= W_{i-1} (1 + min_tolerance)` and
//!    `W_i <= W_{i+1} (1 + min_tolerance)`. A missing neighbour (the ends of a curve) counts as
//!    satisfied, so a curve with one point makes that point a candidate and a monotone curve
//!    makes its lower end a candidate. The tolerance is relative because W scales with the data
//!    (W >= 0); it also makes a flat stretch (equal within the tolerance) all candidates, since
//!    two solvers can differ in the 5th digit on the same minimum (METHOD.md section 8).
//! 4. **Local minimum of L1C.** The same test with an *absolute* tolerance on the share
//!    (L1C is in [0, 1]): `L1C_i <= L1C_{i-1} + min_tolerance` and
//!    `L1C_i <= L1C_{i+1} + min_tolerance`.
//! 5. **Score.** A candidate's score is its fit in the chosen basis: `fit_val` (validation record),
//!    `fit_band` (frequency band) or `fit` (estimation record); see [`choose_basis`]. Candidates
//!    whose score is null (or not finite) are skipped and not listed.
//! 6. **Pick.** Let `best` be the highest score. Every candidate with
//!    `score >= best - fit_tolerance` (percentage points) is a tie. Among the ties the model with
//!    the fewest parameters nB + nF wins, then the smaller nF, then the higher score, then the
//!    smaller k index, then the smaller delay. The choice is fully deterministic: it does not
//!    depend on the row order of the table.
//! 7. **Listing.** Each [`Pick`] lists all scored candidates of its curves, sorted by score
//!    descending, then by the tie-break of rule 6.
//!
//! Defaults: `min_tolerance = 1e-3`, `fit_tolerance = 0.05` points.

mod candidate;
pub mod doubts;
mod lines;
pub mod rules;
mod settings;

use crate::table::CellRow;
pub use candidate::Candidate;
pub use lines::{CurveKey, curves};
pub use rules::{Rule, RulePick};
use serde::{Deserialize, Serialize};
pub use settings::{ReduceOptions, SelectionSettings};
use std::cmp::Ordering;
use std::collections::BTreeMap;

/// Default tolerance of the local-minimum test (relative on W, absolute on L1C).
pub const DEFAULT_MIN_TOLERANCE: f64 = 1e-3;
/// Default width, in percentage points of fit, within which candidates count as tied.
pub const DEFAULT_FIT_TOLERANCE: f64 = 0.05;

/// Which fit column ranks the candidate models.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitBasis {
    /// `fit_val`: time-domain fit on the validation record.
    Validation,
    /// `fit_band`: frequency-domain fit in the job's band.
    Band,
    /// `fit`: time-domain fit on the estimation record (optimistic; the last resort).
    Estimation,
}

crate::names::names!(FitBasis { Validation = "validation", Band = "band", Estimation = "estimation" });

impl FitBasis {
    /// The row's fit in this basis, if it has one.
    pub fn score(self, row: &CellRow) -> Option<f64> {
        match self {
            FitBasis::Validation => row.fit.fit_val,
            FitBasis::Band => row.fit.fit_band,
            FitBasis::Estimation => row.fit.fit,
        }
    }

    /// The table column of this basis.
    pub fn column(self) -> &'static str {
        match self {
            FitBasis::Validation => "fit_val",
            FitBasis::Band => "fit_band",
            FitBasis::Estimation => "fit",
        }
    }

    /// Human-readable name used in [`Pick::rule`].
    pub fn describe(self) -> &'static str {
        match self {
            FitBasis::Validation => "validation fit",
            FitBasis::Band => "band fit",
            FitBasis::Estimation => "estimation fit",
        }
    }
}

/// Tie-break among candidates whose scores are within the fit tolerance (rule 6).
fn tie_break(a: &Candidate, b: &Candidate) -> Ordering {
    let nfs = |c: &Candidate| c.key.orders().iter().map(|o| o.2).collect::<Vec<_>>();
    let delays = |c: &Candidate| c.key.orders().iter().map(|o| o.0).collect::<Vec<_>>();
    a.parameters()
        .cmp(&b.parameters())
        .then(a.key.nf_total().cmp(&b.key.nf_total()))
        .then_with(|| nfs(a).cmp(&nfs(b)))
        .then(b.score.total_cmp(&a.score))
        .then(a.k_index().cmp(&b.k_index()))
        .then_with(|| delays(a).cmp(&delays(b)))
        .then(a.key.cmp(&b.key))
}

/// Listing order: score descending, then the tie-break (rule 7).
fn listing_order(a: &Candidate, b: &Candidate) -> Ordering {
    b.score.total_cmp(&a.score).then_with(|| tie_break(a, b))
}

/// The chosen model of one kind, how it was chosen, and the candidates it was chosen from.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Pick {
    #[serde(flatten)]
    pub model: Candidate,
    /// One sentence saying how the model was chosen.
    pub rule: String,
    /// All scored candidates, best first.
    pub candidates: Vec<Candidate>,
    /// The robust covariance of the model's parameters `[b, f(, c)]`, row-major (METHOD.md
    /// 10), as the run computed it on the estimation record; absent when the run could not
    /// (a merge without its data files, a singular Gram matrix) and in files of older versions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<Vec<f64>>,
}

/// Result of the model choice (written as `selection.json`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Selection {
    pub basis: FitBasis,
    /// Best-fitting local minimum of the W curves (null when there is none with a score).
    pub m1: Option<Pick>,
    /// Best-fitting local minimum of the L1C curves (null when there is none with a score).
    pub m2: Option<Pick>,
    /// Number of `huber` rows in the table.
    pub cells: usize,
    /// Number of `huber` rows with status `"failed"`.
    pub failed: usize,
    pub min_tolerance: f64,
    pub fit_tolerance: f64,
    /// The job's `offset` mode (absent in files of older versions).
    #[serde(default)]
    pub offset: Option<crate::data::Offset>,
    /// The input level u0 taken out of both records (the model is `B/F (u - u0) + offset`).
    #[serde(default)]
    pub input_level: Option<f64>,
    /// Several inputs: one level per input (and no `input_level`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_levels: Option<Vec<f64>>,
    /// The initial state `fit` and `fit_val` were computed with.
    #[serde(default)]
    pub initial_state: Option<crate::estimate::InitialState>,
    /// What the user should know about the data (e.g. a large output mean with offset "none").
    #[serde(default)]
    pub warnings: Vec<String>,
    /// The rule the summary leads with ([`rules::lead_rule`]).
    #[serde(default = "default_rule")]
    pub rule: Rule,
    /// Why `rule` leads: named by the job, or the default with or without a validation record
    /// (empty in files of older versions).
    #[serde(default)]
    pub rule_why: String,
    /// Every rule's pick ([`rules`]; empty in files of older versions).
    #[serde(default)]
    pub picks: BTreeMap<Rule, RulePick>,
    /// The bootstrap of the watched picks, when the job's `uncertainty` asked for it (METHOD.md
    /// 17.3): one entry per model.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub bootstrap: Vec<PickBootstrap>,
    /// What was missing in the records (METHOD.md 21.1): absent when nothing was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gaps: Option<crate::data::RecordGaps>,
}

/// The bootstrap of one picked model (METHOD.md 17.3) beside its sandwich standard deviations.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PickBootstrap {
    /// The rules that picked it.
    pub rules: Vec<Rule>,
    /// Its orders: a number for one input, one entry per input for several.
    pub nb: crate::table::PerInput,
    pub nf: crate::table::PerInput,
    pub delay: crate::table::PerInput,
    /// None: a least-squares model.
    pub k: Option<f64>,
    /// The parameters' names, values and sandwich standard deviations (None without a
    /// covariance), in the order of the bootstrap's intervals.
    pub parameters: Vec<String>,
    pub values: Vec<f64>,
    pub sandwich_std: Vec<Option<f64>>,
    /// The sampling period (s): the intervals' frequencies are in rad/sample, f = w / (2 pi ts) Hz.
    pub ts: f64,
    pub intervals: crate::estimate::bootstrap::Bootstrap,
}

impl PickBootstrap {
    /// `OE(nB,nF) delay d` for one input, [`crate::oe::Structure::label`] for several.
    pub fn label(&self) -> String {
        rules::orders_label(&self.nb, &self.nf, &self.delay)
    }
}

fn default_rule() -> Rule {
    rules::DEFAULT_RULE
}

/// The fit that ranks models: validation when a validation record was given, else the band fit
/// when a band was given, else the estimation fit.
pub fn choose_basis(has_validation: bool, has_band: bool) -> FitBasis {
    if has_validation {
        FitBasis::Validation
    } else if has_band {
        FitBasis::Band
    } else {
        FitBasis::Estimation
    }
}

/// How a curve point is compared with its neighbours (rules 3-4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Tolerance {
    Relative(f64),
    Absolute(f64),
}

impl Tolerance {
    fn not_above(self, value: f64, neighbour: f64) -> bool {
        match self {
            Tolerance::Relative(t) => value <= neighbour * (1.0 + t),
            Tolerance::Absolute(t) => value <= neighbour + t,
        }
    }
}

/// Indices of the local minima of `values` (a curve already sorted by nF): not above either
/// existing neighbour beyond `tolerance` (rules 3-4).
pub fn local_minima(values: &[f64], tolerance: Tolerance) -> Vec<usize> {
    (0..values.len())
        .filter(|&i| {
            let below_prev = i == 0 || tolerance.not_above(values[i], values[i - 1]);
            let below_next = i + 1 == values.len() || tolerance.not_above(values[i], values[i + 1]);
            below_prev && below_next
        })
        .collect()
}

/// The two curves over nF: W for the M1-style pick, L1C for the M2-style pick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Curve {
    W,
    L1c,
}

impl Curve {
    /// The curve's value at a row that takes part ([`takes_part`]; finite there).
    pub fn value(self, r: &CellRow) -> f64 {
        match self {
            Curve::W => r.fit.criterion.unwrap_or(f64::NAN),
            Curve::L1c => r.fit.l1c.unwrap_or(f64::NAN),
        }
    }

    /// The local-minimum test of this curve (rule 3): relative on W, absolute on the share L1C.
    pub fn tolerance(self, min_tolerance: f64) -> Tolerance {
        match self {
            Curve::W => Tolerance::Relative(min_tolerance),
            Curve::L1c => Tolerance::Absolute(min_tolerance),
        }
    }
}

/// Apply rules 1-7 to a result table.
pub fn select(rows: &[CellRow], opts: &ReduceOptions) -> Selection {
    let cells = crate::table::huber_rows(rows);
    let failed = crate::table::failed_cells(rows);

    let w_minima = lines::minima(rows, Curve::W, opts.settings.min_tolerance);
    let l1c_minima = lines::minima(rows, Curve::L1c, opts.settings.min_tolerance);

    let m1 = pick(&w_minima, opts, Curve::W);
    let m2 = pick(&l1c_minima, opts, Curve::L1c);
    let (rule, rule_why) = rules::lead_rule(opts.settings.rule, opts.basis);
    Selection {
        basis: opts.basis,
        picks: rules::picks(rows, m1.as_ref(), m2.as_ref(), opts),
        rule,
        rule_why,
        m1,
        m2,
        cells,
        failed,
        min_tolerance: opts.settings.min_tolerance,
        fit_tolerance: opts.settings.fit_tolerance,
        offset: None,
        input_level: None,
        input_levels: None,
        initial_state: None,
        warnings: Vec::new(),
        bootstrap: Vec::new(),
        gaps: None,
    }
}

/// Rule 1: does a row take part in the choice?
pub fn takes_part(r: &CellRow) -> bool {
    let finite = |v: Option<f64>| v.is_some_and(f64::is_finite);
    r.is_huber()
        && r.ok()
        && r.key.k_index.is_some()
        && finite(r.fit.criterion)
        && finite(r.fit.l1c)
        && finite(r.k)
        && finite(r.fit.gamma)
}

/// Rules 5-7 on the local minima of one kind of curve.
fn pick(minima: &[&CellRow], opts: &ReduceOptions, curve: Curve) -> Option<Pick> {
    let mut candidates: Vec<Candidate> = minima
        .iter()
        .filter_map(|r| opts.basis.score(r).filter(|s| s.is_finite()).and_then(|s| Candidate::new(r, s)))
        .collect();
    candidates.sort_by(listing_order);
    let best = candidates.first()?.score;
    let threshold = best - opts.settings.fit_tolerance;
    let ties: Vec<&Candidate> = candidates.iter().filter(|c| c.score >= threshold).collect();
    let model = (*ties.iter().min_by(|a, b| tie_break(a, b))?).clone();

    let (curve_name, tolerance) = match curve {
        Curve::W => ("the criterion W", format!("relative tolerance {}", opts.settings.min_tolerance)),
        Curve::L1c => ("the L1 contribution L1C", format!("absolute tolerance {}", opts.settings.min_tolerance)),
    };
    let basis = opts.basis.describe();
    let skipped = minima.len() - candidates.len();
    let skipped =
        if skipped > 0 { format!(" ({skipped} more had no {basis} and were skipped)") } else { String::new() };
    let how = if ties.len() == 1 {
        "the only one within that margin".to_string()
    } else {
        format!(
            "among the {} candidates within that margin, the one with the fewest parameters (nB + nF = {}), \
             then smaller nF, higher fit, smaller k index",
            ties.len(),
            model.parameters()
        )
    };
    let (over, per) = match model.key.m() {
        1 => ("nF", "nB and k"),
        _ => ("each input's nF", "input and the other orders and k"),
    };
    let rule = format!(
        "{} at k = {} (k index {}) with {basis} {:.3}%: chosen among {} local {} over {over} of {curve_name} \
         (one curve per {per}, {tolerance}){skipped}; the best {basis} is {best:.3}%, ties are \
         within {} points of it; this model is {how}",
        model.key.short_label(),
        crate::text::k(model.k()),
        model.k_index(),
        model.score,
        candidates.len(),
        if candidates.len() == 1 { "minimum" } else { "minima" },
        opts.settings.fit_tolerance,
    );
    Some(Pick { model, rule, candidates, covariance: None })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::table::{FitKind, RowKey, Status};

    fn key(kind: FitKind, nb: u32, nf: u32, k_index: Option<u32>) -> RowKey {
        RowKey::siso(kind, nb, nf, 1, k_index)
    }

    /// An ok Huber row; `fit` is used for all three fit columns unless changed.
    fn row(nb: u32, nf: u32, k_index: u32, criterion: f64, l1c: f64, fit: f64) -> CellRow {
        let mut r = CellRow::failed(key(FitKind::Huber, nb, nf, Some(k_index)), Some(0.05), "".into());
        r.status = Status::Ok;
        r.reason = None;
        r.fit.sigma = Some(2.0);
        r.fit.gamma = Some(0.1);
        r.fit.criterion = Some(criterion);
        r.fit.l1c = Some(l1c);
        r.fit.fit = Some(fit);
        r.fit.fit_val = Some(fit);
        r.fit.fit_band = Some(fit);
        r.fit.b = vec![1.0; nb as usize];
        r.fit.f = vec![0.1; nf as usize];
        r
    }

    /// One curve (nb, k_index) over nf = 2.. with the given W values; l1c constant, fit = 90 + nf.
    fn w_curve(nb: u32, k_index: u32, w: &[f64]) -> Vec<CellRow> {
        w.iter().enumerate().map(|(i, &w)| row(nb, 2 + i as u32, k_index, w, 0.5, 90.0 + i as f64)).collect()
    }

    fn minima_nf(rows: &[CellRow]) -> Vec<u32> {
        let sel = select(rows, &ReduceOptions::new(FitBasis::Validation));
        let mut nf: Vec<u32> = sel.m1.map(|p| p.candidates.iter().map(|c| c.key.nf).collect()).unwrap_or_default();
        nf.sort();
        nf
    }

    #[test]
    fn reduce_local_minima_rules() {
        let rel = Tolerance::Relative(1e-3);
        assert_eq!(local_minima(&[5.0, 4.0, 3.0, 4.0, 5.0], rel), vec![2]);
        assert_eq!(local_minima(&[5.0, 4.0, 3.0], rel), vec![2]);
        assert_eq!(local_minima(&[3.0, 4.0, 5.0], rel), vec![0]);
        assert_eq!(local_minima(&[7.0], rel), vec![0]);
        assert!(local_minima(&[], rel).is_empty());
        // 3.002 is within 0.1% of 3.0, so the flat stretch is all candidates; 3.01 is not.
        assert_eq!(local_minima(&[3.0, 3.002, 3.0, 5.0], rel), vec![0, 1, 2]);
        assert_eq!(local_minima(&[3.0, 3.01, 3.0, 5.0], rel), vec![0, 2]);
        let abs = Tolerance::Absolute(1e-3);
        assert_eq!(local_minima(&[0.5, 0.3, 0.3005, 0.6], abs), vec![1, 2]);
        assert_eq!(local_minima(&[0.5, 0.3, 0.302, 0.6], abs), vec![1]);
    }

    #[test]
    fn reduce_interior_minimum_found() {
        assert_eq!(minima_nf(&w_curve(3, 0, &[5.0, 4.0, 3.0, 4.0, 5.0])), vec![4]);
        let sel = select(&w_curve(3, 0, &[5.0, 4.0, 3.0, 4.0, 5.0]), &ReduceOptions::new(FitBasis::Validation));
        let m1 = sel.m1.unwrap();
        assert_eq!((m1.model.key.nb, m1.model.key.nf, m1.model.k_index()), (3, 4, 0));
        assert_eq!(m1.model.score, 92.0);
        assert_eq!(m1.model.fit.b.len(), 3);
        assert!(m1.rule.contains("OE(3,4)") && m1.rule.contains("criterion W"), "{}", m1.rule);
    }

    #[test]
    fn reduce_flat_within_tolerance_and_ends() {
        assert_eq!(minima_nf(&w_curve(3, 0, &[3.0, 3.002, 3.0, 5.0])), vec![2, 3, 4]);
        assert_eq!(minima_nf(&w_curve(3, 0, &[5.0, 4.0, 3.0])), vec![4]);
        assert_eq!(minima_nf(&w_curve(3, 0, &[3.0, 4.0, 5.0])), vec![2]);
        assert_eq!(minima_nf(&w_curve(3, 0, &[3.0])), vec![2]);
    }

    #[test]
    fn reduce_failed_and_unusable_rows_ignored() {
        // nf = 3 failed: nf = 4 (W = 4) has neighbours nf = 2 (W = 5) and nf = 5 (W = 6).
        let mut rows = vec![row(3, 2, 0, 5.0, 0.5, 90.0), row(3, 4, 0, 4.0, 0.5, 91.0), row(3, 5, 0, 6.0, 0.5, 92.0)];
        rows.push(CellRow::failed(key(FitKind::Huber, 3, 3, Some(0)), Some(0.05), "diverged".into()));
        // An ok row without a finite criterion does not take part either.
        let mut nan = row(3, 6, 0, 1.0, 0.5, 99.0);
        nan.fit.criterion = Some(f64::NAN);
        rows.push(nan);
        // Nor a malformed ok row without gamma.
        let mut no_gamma = row(3, 3, 0, 0.5, 0.5, 99.0);
        no_gamma.fit.gamma = None;
        rows.push(no_gamma);
        // Nor does a least-squares row, however small its criterion.
        let mut ls = row(3, 3, 0, 0.1, 0.5, 99.0);
        ls.key.kind = FitKind::Ls;
        ls.key.k_index = None;
        rows.push(ls);
        rows.push(CellRow::failed(key(FitKind::Ls, 3, 7, None), None, "ls failed".into()));
        assert_eq!(minima_nf(&rows), vec![4]);
        let sel = select(&rows, &ReduceOptions::new(FitBasis::Validation));
        assert_eq!((sel.cells, sel.failed), (6, 1));
    }

    #[test]
    fn reduce_ties_resolved_by_fewest_parameters() {
        // Curve nb = 3 has its minimum at nf = 5 (fit 90.00); curve nb = 2 at nf = 4 (fit 89.97).
        let mut rows = vec![row(3, 4, 0, 2.0, 0.5, 85.0), row(3, 5, 0, 1.0, 0.5, 90.0), row(3, 6, 0, 2.0, 0.5, 95.0)];
        rows.extend([row(2, 3, 0, 2.0, 0.5, 80.0), row(2, 4, 0, 1.0, 0.5, 89.97), row(2, 5, 0, 2.0, 0.5, 96.0)]);
        let opts = ReduceOptions::new(FitBasis::Validation);
        let m1 = select(&rows, &opts).m1.unwrap();
        assert_eq!((m1.model.key.nb, m1.model.key.nf), (2, 4));
        // The listing stays best-first.
        assert_eq!(m1.candidates.iter().map(|c| (c.key.nb, c.key.nf)).collect::<Vec<_>>(), vec![(3, 5), (2, 4)]);
        assert!(m1.rule.contains("fewest parameters"), "{}", m1.rule);
        // Outside the margin the best fit wins.
        let m1 = select(
            &rows,
            &ReduceOptions { settings: SelectionSettings { fit_tolerance: 0.01, ..opts.settings }, ..opts },
        )
        .m1
        .unwrap();
        assert_eq!((m1.model.key.nb, m1.model.key.nf), (3, 5));
        assert!(m1.rule.contains("the only one"), "{}", m1.rule);
    }

    #[test]
    fn reduce_equal_parameters_then_nf_then_score_then_k_index() {
        // OE(3,4) and OE(4,3) tie on parameters: smaller nf wins.
        let rows = vec![row(3, 4, 0, 1.0, 0.5, 90.0), row(4, 3, 0, 1.0, 0.5, 90.02)];
        assert_eq!(select(&rows, &ReduceOptions::new(FitBasis::Validation)).m1.unwrap().model.key.nb, 4);
        // Same orders at two k: the higher score, and on an exact tie the smaller k index.
        let rows = vec![row(3, 4, 2, 1.0, 0.5, 90.0), row(3, 4, 1, 1.0, 0.5, 90.03)];
        assert_eq!(select(&rows, &ReduceOptions::new(FitBasis::Validation)).m1.unwrap().model.k_index(), 1);
        let rows = vec![row(3, 4, 2, 1.0, 0.5, 90.0), row(3, 4, 1, 1.0, 0.5, 90.0)];
        assert_eq!(select(&rows, &ReduceOptions::new(FitBasis::Validation)).m1.unwrap().model.k_index(), 1);
    }

    #[test]
    fn reduce_independent_of_row_order() {
        let mut rows = w_curve(3, 0, &[5.0, 4.0, 3.0, 3.001, 5.0]);
        rows.extend(w_curve(4, 1, &[2.0, 2.0, 2.0]));
        rows.extend(w_curve(2, 1, &[2.0, 1.0, 2.0]));
        let opts = ReduceOptions::new(FitBasis::Estimation);
        let a = select(&rows, &opts);
        rows.reverse();
        rows.swap(1, 7);
        assert_eq!(a, select(&rows, &opts));
    }

    #[test]
    fn reduce_basis_choice_and_null_scores() {
        assert_eq!(choose_basis(true, true), FitBasis::Validation);
        assert_eq!(choose_basis(true, false), FitBasis::Validation);
        assert_eq!(choose_basis(false, true), FitBasis::Band);
        assert_eq!(choose_basis(false, false), FitBasis::Estimation);

        // Two single-point curves; the band fit prefers nb = 2, the estimation fit nb = 3.
        let mut a = row(3, 4, 0, 1.0, 0.5, 95.0);
        a.fit.fit_band = Some(80.0);
        a.fit.fit_val = None;
        let mut b = row(2, 4, 0, 1.0, 0.5, 90.0);
        b.fit.fit_band = Some(85.0);
        b.fit.fit_val = None;
        let rows = vec![a, b];
        let band = select(&rows, &ReduceOptions::new(FitBasis::Band)).m1.unwrap();
        assert_eq!((band.model.key.nb, band.model.score), (2, 85.0));
        assert!(band.rule.contains("band fit"), "{}", band.rule);
        let est = select(&rows, &ReduceOptions::new(FitBasis::Estimation)).m1.unwrap();
        assert_eq!((est.model.key.nb, est.model.score), (3, 95.0));
        // No row has a validation fit: no pick, not a panic.
        let val = select(&rows, &ReduceOptions::new(FitBasis::Validation));
        assert!(val.m1.is_none() && val.m2.is_none());
        assert_eq!(val.cells, 2);
    }

    #[test]
    fn reduce_l1c_curve_gives_m2() {
        // W is monotone (minimum at the last nf); L1C has interior minima at nf = 3 and 4 (within
        // the absolute tolerance of each other).
        let rows = vec![
            row(5, 2, 0, 5.0, 0.50, 90.0),
            row(5, 3, 0, 4.0, 0.30, 91.0),
            row(5, 4, 0, 3.0, 0.3005, 92.0),
            row(5, 5, 0, 2.0, 0.60, 93.0),
        ];
        let sel = select(&rows, &ReduceOptions::new(FitBasis::Validation));
        let m1 = sel.m1.unwrap();
        assert_eq!(m1.model.key.nf, 5);
        let m2 = sel.m2.unwrap();
        assert_eq!(m2.candidates.iter().map(|c| c.key.nf).collect::<Vec<_>>(), vec![4, 3]);
        // 92 vs 91 is outside the 0.05 margin: the better fit wins.
        assert_eq!((m2.model.key.nf, m2.model.l1c()), (4, 0.3005));
        assert!(m2.rule.contains("L1C") && m2.rule.contains("absolute tolerance"), "{}", m2.rule);
    }

    #[test]
    fn reduce_empty_table() {
        let sel = select(&[], &ReduceOptions::new(FitBasis::Estimation));
        assert!(sel.m1.is_none() && sel.m2.is_none());
        assert_eq!((sel.cells, sel.failed), (0, 0));
    }

    #[test]
    fn reduce_selection_json_shape() {
        let sel = select(&w_curve(3, 0, &[5.0, 3.0, 4.0]), &ReduceOptions::new(FitBasis::Validation));
        let v = serde_json::to_value(&sel).unwrap();
        assert_eq!(v["basis"], "validation");
        // The model's fields are flattened into the pick next to `rule` and `candidates`.
        assert_eq!(v["m1"]["nf"], 3);
        assert_eq!(v["m1"]["score"], 91.0);
        // A candidate is its row without the wall time, the score after `fit_band`.
        assert!(v["m1"].get("seconds").is_none() && v["m1"]["method"] == "huber");
        let text = serde_json::to_string(&sel.m1.as_ref().unwrap().model).unwrap();
        assert!(
            text.contains(r#""fit_band":92.0,"score":91.0,"iterations""#)
                || text.contains(r#""fit_band":91.0,"score":91.0,"iterations""#),
            "{text}"
        );
        assert!(v["m1"]["rule"].is_string());
        assert_eq!(v["m1"]["candidates"].as_array().unwrap().len(), 1);
        assert_eq!(v["fit_tolerance"], 0.05);
        let back: Selection = serde_json::from_value(v).unwrap();
        assert_eq!(back, sel);
    }
}
