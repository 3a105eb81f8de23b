//! Every pick rule, side by side (METHOD.md 7.1): the paper's two, the classical information
//! criteria of the least-squares fits, their robust versions on the Huber fits, the best
//! validation fit, and the evidence rule. `selection.json` reports them all under `picks`;
//! `selection.rule` names the one the summary leads with.
//!
//! - `paper_m1`, `paper_m2`: today's `m1`, `m2` (rules 1-7 of the module above).
//! - `aic`, `aicc`, `bic`, `fpe`: the smallest value over the `ls` rows with status ok.
//! - `raic`, `rbic`: the smallest value over the Huber rows that take part (rule 1), any k.
//! - `validation`: the best score (the basis column) over the Huber rows that take part, ties
//!   within `fit_tolerance` resolved by the tie-break of rule 6 (fewest parameters first).
//! - `evidence`: the `validation` rule restricted to the models whose residuals are independent
//!   of the input at 1 % (`resid_indep_p >= 0.01`) and that are not over-fitted: no pole-zero
//!   pair cancels within its confidence region (`cancellations = 0`) and every parameter is
//!   determined (finite `max_rel_std`). Whiteness is reported, not required: an OE model does
//!   not model the noise. When no model passes, the pick is empty and says why.
//!
//! Each pick names its measure, its value, the runner-up (the best model of another structure
//! (nB, nF, delay) by the same measure) and one sentence saying why.

use super::{Candidate, FitBasis, Pick, ReduceOptions, takes_part, tie_break};
use crate::table::{CellRow, FitKind, PerInput};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The residual-input independence test's level in the evidence rule.
pub const INDEPENDENCE_LEVEL: f64 = 0.01;

/// A pick rule (its `selection.json` name in snake case).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Rule {
    PaperM1,
    PaperM2,
    Aic,
    Aicc,
    Bic,
    Fpe,
    Raic,
    Rbic,
    Validation,
    Evidence,
}

crate::names::names!(Rule { PaperM1 = "paper_m1", PaperM2 = "paper_m2", Aic = "aic", Aicc = "aicc", Bic = "bic", Fpe = "fpe", Raic = "raic", Rbic = "rbic", Validation = "validation", Evidence = "evidence" });

impl Rule {
    /// The criterion a minimising rule ranks by, as the table column holds it.
    fn criterion(self) -> Option<fn(&CellRow) -> Option<f64>> {
        Some(match self {
            Rule::Aic => |r| r.fit.aic,
            Rule::Aicc => |r| r.fit.aicc,
            Rule::Bic => |r| r.fit.bic,
            Rule::Fpe => |r| r.fit.fpe,
            Rule::Raic => |r| r.fit.raic,
            Rule::Rbic => |r| r.fit.rbic,
            _ => return None,
        })
    }
}

/// The rule the summary leads with, with a validation record, unless the job says otherwise
/// (METHOD.md 7.1 gives the benchmark behind the choice).
pub const DEFAULT_RULE: Rule = Rule::PaperM2;

/// The rule the summary leads with, without a validation record, unless the job says otherwise:
/// the fit-based rules would then rank by a fit on the estimation record itself (or its spectral
/// estimate), which grows with the orders, while RBIC penalises size (METHOD.md 7.1's one-record
/// benchmark).
pub const ONE_RECORD_RULE: Rule = Rule::Rbic;

/// The lead rule and one sentence saying why: the job's `selection.rule` when it names one,
/// else [`DEFAULT_RULE`] with a validation record and [`ONE_RECORD_RULE`] without.
pub fn lead_rule(named: Option<Rule>, basis: FitBasis) -> (Rule, String) {
    match named {
        Some(rule) => (rule, format!("{}: named by the job's selection.rule", rule.as_str())),
        None if basis == FitBasis::Validation => {
            (DEFAULT_RULE, format!("{}: the default with a validation record (METHOD.md 7.1)", DEFAULT_RULE.as_str()))
        }
        None => (
            ONE_RECORD_RULE,
            format!(
                "{}: the default without a validation record, where the fit-based rules (paper_m1, paper_m2, \
                 validation, evidence) rank by the {}, which grows with the orders; RBIC penalises the size \
                 (METHOD.md 7.1)",
                ONE_RECORD_RULE.as_str(),
                basis.describe()
            ),
        ),
    }
}

/// What a fit-based rule's `why` adds when its basis is not a held-out record.
fn in_sample_note(basis: FitBasis) -> String {
    match basis {
        FitBasis::Validation => String::new(),
        _ => format!(
            " (without a validation record the basis is the {}, which grows with the orders: \
             this rule tends to pick the larger models; see rbic)",
            basis.describe()
        ),
    }
}

/// The best model of another structure by the same measure.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunnerUp {
    /// Its orders: numbers for one input, one entry per input for several.
    pub nb: PerInput,
    pub nf: PerInput,
    pub delay: PerInput,
    /// Null for an `ls` row.
    pub k: Option<f64>,
    pub value: f64,
}

/// What one rule picked, and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RulePick {
    /// The column the rule ranks by (`aic`, ..., or the basis column for the fit rules).
    pub measure: String,
    /// The measure at the pick (null without a pick).
    pub value: Option<f64>,
    /// The chosen model: its row as in `cells.parquet` (without the wall time) and its score
    /// in the basis column (null when the row has none). Null when the rule found none.
    pub model: Option<Candidate>,
    pub runner_up: Option<RunnerUp>,
    /// One sentence: how the model was chosen, or why there is none.
    pub why: String,
}

/// Every rule's pick; `m1`, `m2` are the paper's picks already made.
pub fn picks(rows: &[CellRow], m1: Option<&Pick>, m2: Option<&Pick>, opts: &ReduceOptions) -> BTreeMap<Rule, RulePick> {
    Rule::ALL
        .iter()
        .map(|&rule| {
            let pick = match rule {
                Rule::PaperM1 => paper(m1, opts),
                Rule::PaperM2 => paper(m2, opts),
                Rule::Validation => best_fit(rows.iter().filter(|r| takes_part(r)).collect(), opts, None),
                Rule::Evidence => evidence(rows, opts),
                _ => minimum(rows, rule, opts),
            };
            (rule, pick)
        })
        .collect()
}

fn candidate(row: &CellRow, opts: &ReduceOptions) -> Candidate {
    Candidate { row: row.clone(), score: opts.basis.score(row).filter(|s| s.is_finite()).unwrap_or(f64::NAN) }
}

impl RunnerUp {
    /// `OE(nB,nF) delay d` for one input, [`crate::oe::Structure::label`] for several.
    pub fn label(&self) -> String {
        orders_label(&self.nb, &self.nf, &self.delay)
    }
}

/// `OE(nB,nF) delay d` for one input's orders, [`crate::oe::Structure::label`] for several's.
pub fn orders_label(nb: &PerInput, nf: &PerInput, delay: &PerInput) -> String {
    match (nb, nf, delay) {
        (PerInput::Several(nb), PerInput::Several(nf), PerInput::Several(d)) => {
            let parts: Vec<String> = nb.iter().zip(nf).zip(d).map(|((b, f), d)| format!("{b},{f} d{d}")).collect();
            format!("OE({})", parts.join("; "))
        }
        (nb, nf, d) => format!("OE({nb},{nf}) delay {d}"),
    }
}

fn runner_up(chosen: &CellRow, ranked: &[(&CellRow, f64)]) -> Option<RunnerUp> {
    ranked.iter().find(|(r, _)| r.key.structure() != chosen.key.structure()).map(|(r, v)| RunnerUp {
        nb: PerInput::of(&r.key, |o| o.nb),
        nf: PerInput::of(&r.key, |o| o.nf),
        delay: PerInput::of(&r.key, |o| o.delay),
        k: r.k,
        value: *v,
    })
}

fn name(r: &CellRow) -> String {
    match r.k {
        Some(k) => format!("{} at k = {}", r.key.label(), crate::text::k(k)),
        None => format!("{} (least squares)", r.key.label()),
    }
}

fn empty(measure: &str, why: String) -> RulePick {
    RulePick { measure: measure.to_string(), value: None, model: None, runner_up: None, why }
}

/// `paper_m1`, `paper_m2`: the paper's pick with its runner-up among its candidates.
fn paper(pick: Option<&Pick>, opts: &ReduceOptions) -> RulePick {
    let measure = opts.basis.column();
    let Some(p) = pick else {
        return empty(measure, format!("no local minimum has a {}", opts.basis.describe()));
    };
    let ranked: Vec<(&CellRow, f64)> = p.candidates.iter().map(|c| (&c.row, c.score)).collect();
    RulePick {
        measure: measure.to_string(),
        value: Some(p.model.score),
        model: Some(p.model.clone()),
        runner_up: runner_up(&p.model.row, &ranked),
        why: format!("{}{}", p.rule, in_sample_note(opts.basis)),
    }
}

/// The information-criterion rules: the smallest value.
fn minimum(rows: &[CellRow], rule: Rule, opts: &ReduceOptions) -> RulePick {
    let value = rule.criterion().expect("a criterion rule");
    let measure = rule.as_str();
    let (kind, over) = if matches!(rule, Rule::Raic | Rule::Rbic) {
        (FitKind::Huber, "Huber fits (all k)")
    } else {
        (FitKind::Ls, "least-squares fits")
    };
    let mut ranked: Vec<(&CellRow, f64)> = rows
        .iter()
        .filter(|r| r.key.kind == kind && r.ok() && (kind == FitKind::Ls || takes_part(r)))
        .filter_map(|r| value(r).filter(|v| v.is_finite()).map(|v| (r, v)))
        .collect();
    ranked.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.key.cmp(&b.0.key)));
    let Some(&(best, v)) = ranked.first() else {
        return empty(measure, format!("no {over} with a finite {measure}"));
    };
    let up = runner_up(best, &ranked);
    let versus = up.as_ref().map_or(String::new(), |u| {
        format!("; the runner-up {} has {measure} = {:.4} ({:+.4})", u.label(), u.value, u.value - v)
    });
    RulePick {
        measure: measure.to_string(),
        value: Some(v),
        model: Some(candidate(best, opts)),
        runner_up: up,
        why: format!("{}: the smallest {measure} = {v:.4} among {} {over}{versus}", name(best), ranked.len()),
    }
}

/// The best score among `pool`, ties within the fit tolerance resolved by rule 6. `note`
/// prefixes the sentence (the evidence rule's filter).
fn best_fit(pool: Vec<&CellRow>, opts: &ReduceOptions, note: Option<String>) -> RulePick {
    let measure = opts.basis.column();
    let basis = opts.basis.describe();
    let mut scored: Vec<Candidate> =
        pool.iter().filter(|r| opts.basis.score(r).is_some_and(f64::is_finite)).map(|r| candidate(r, opts)).collect();
    scored.sort_by(|a, b| b.score.total_cmp(&a.score).then_with(|| tie_break(a, b)));
    let note = note.map_or(String::new(), |n| format!("{n}; "));
    let Some(best) = scored.first().map(|c| c.score) else {
        return empty(measure, format!("{note}no model has a {basis}"));
    };
    let ties: Vec<&Candidate> = scored.iter().filter(|c| c.score >= best - opts.settings.fit_tolerance).collect();
    let model = (*ties.iter().min_by(|a, b| tie_break(a, b)).expect("the best is a tie")).clone();
    let ranked: Vec<(&CellRow, f64)> = scored.iter().map(|c| (&c.row, c.score)).collect();
    let up = runner_up(&model.row, &ranked);
    let how = if ties.len() == 1 {
        "the best".to_string()
    } else {
        format!(
            "the fewest parameters (nB + nF = {}) among the {} within {} points of the best {best:.3} %",
            model.parameters(),
            ties.len(),
            opts.settings.fit_tolerance
        )
    };
    let versus = up.as_ref().map_or(String::new(), |u| format!("; the runner-up {} has {:.3} %", u.label(), u.value));
    RulePick {
        measure: measure.to_string(),
        value: Some(model.score),
        why: format!(
            "{note}{}: {basis} {:.3} %, {how} of {} models{versus}{}",
            name(&model.row),
            model.score,
            scored.len(),
            in_sample_note(opts.basis)
        ),
        model: Some(model),
        runner_up: up,
    }
}

/// The evidence rule: [`best_fit`] over the models that pass the independence test and are not
/// over-fitted.
fn evidence(rows: &[CellRow], opts: &ReduceOptions) -> RulePick {
    let models: Vec<&CellRow> = rows.iter().filter(|r| takes_part(r)).collect();
    let independent: Vec<&CellRow> =
        models.iter().copied().filter(|r| r.evidence.resid_indep_p.is_some_and(|p| p >= INDEPENDENCE_LEVEL)).collect();
    let over_fitted =
        |r: &CellRow| r.evidence.cancellations != Some(0) || !r.evidence.max_rel_std.is_some_and(f64::is_finite);
    let pool: Vec<&CellRow> = independent.iter().copied().filter(|r| !over_fitted(r)).collect();
    let note = format!(
        "{} of {} models have residuals independent of the input at {} %, {} of them not over-fitted \
         (no pole-zero pair cancelling within its 95 % region, every parameter determined)",
        independent.len(),
        models.len(),
        INDEPENDENCE_LEVEL * 100.0,
        pool.len()
    );
    if pool.is_empty() {
        let best_p = models
            .iter()
            .filter_map(|r| r.evidence.resid_indep_p.map(|p| (r, p)))
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.key.cmp(&a.0.key)));
        let hint = match (independent.is_empty(), best_p) {
            (true, Some((r, p))) => format!(
                "; the most independent is {} with p = {p:.2e}: the grid may lack the orders or delay the data need",
                name(r)
            ),
            (false, _) => "; every independent model is over-fitted: the data do not support a smaller one".into(),
            _ => String::new(),
        };
        return empty(opts.basis.column(), format!("no pick: {note}{hint}"));
    }
    best_fit(pool, opts, Some(note))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reduce::{FitBasis, select};
    use crate::table::{RowKey, Status};

    fn row(kind: FitKind, nb: u32, nf: u32, k_index: Option<u32>, fit_val: f64) -> CellRow {
        let key = RowKey::siso(kind, nb, nf, 1, k_index);
        let mut r = CellRow::failed(key, k_index.map(|i| 0.5 + i as f64), String::new());
        r.status = Status::Ok;
        r.reason = None;
        r.fit.sigma = Some(1.0);
        r.fit.gamma = k_index.map(|_| 0.5);
        r.fit.criterion = Some(1.0);
        r.fit.l1c = k_index.map(|_| 0.1);
        r.fit.fit = Some(fit_val);
        r.fit.fit_val = Some(fit_val);
        r.evidence.resid_indep_p = Some(0.5);
        r.evidence.cancellations = Some(0);
        r.evidence.max_rel_std = Some(0.1);
        r
    }

    fn table() -> Vec<CellRow> {
        let mut rows = Vec::new();
        for (nb, nf, fit) in [(1, 1, 80.0), (2, 2, 95.0), (3, 3, 95.02), (4, 4, 95.04)] {
            let mut ls = row(FitKind::Ls, nb, nf, None, fit - 1.0);
            let p = (nb + nf) as f64;
            // AIC is smallest at (3,3), BIC at (2,2).
            ls.fit.aic = Some([100.0, 60.0, 50.0, 55.0][nb as usize - 1]);
            ls.fit.bic = Some(100.0 + p - fit);
            rows.push(ls);
            for k in 0..2 {
                let mut h = row(FitKind::Huber, nb, nf, Some(k), fit - 0.01 * k as f64);
                h.fit.raic = Some(-fit + 0.1 * k as f64);
                h.fit.rbic = Some(-fit + 2.0 * p);
                rows.push(h);
            }
        }
        rows
    }

    #[test]
    fn every_rule_picks_and_names_its_runner_up() {
        let rows = table();
        let sel = select(&rows, &ReduceOptions::new(FitBasis::Validation));
        let picks = &sel.picks;
        assert_eq!(picks.len(), Rule::ALL.len());
        let orders = |rule: Rule| picks[&rule].model.as_ref().map(|m| (m.key.nb, m.key.nf, m.key.kind));
        assert_eq!(orders(Rule::Aic), Some((3, 3, FitKind::Ls)));
        assert_eq!(picks[&Rule::Aic].value, Some(50.0));
        assert_eq!(
            picks[&Rule::Aic].runner_up.as_ref().map(|u| (u.nb.clone(), u.value)),
            Some((PerInput::One(4), 55.0))
        );
        assert_eq!(orders(Rule::Raic), Some((4, 4, FitKind::Huber)));
        assert_eq!(picks[&Rule::Raic].model.as_ref().unwrap().k_index(), 0);
        // RBIC = -fit + 2 np: (2,2) at -87, (3,3) at -83.02.
        assert_eq!(orders(Rule::Rbic), Some((2, 2, FitKind::Huber)));
        // 95.00, 95.02, 95.04 are ties: the fewest parameters win.
        assert_eq!(orders(Rule::Validation), Some((2, 2, FitKind::Huber)));
        assert!(picks[&Rule::Validation].why.contains("fewest parameters"), "{}", picks[&Rule::Validation].why);
        assert_eq!(orders(Rule::Evidence), Some((2, 2, FitKind::Huber)));
        // The paper's picks are today's m1, m2.
        assert_eq!(picks[&Rule::PaperM2].model.as_ref().map(|m| m.key), sel.m2.as_ref().map(|m| m.model.key));
        // No rule without its criterion: fpe is null everywhere here.
        assert!(picks[&Rule::Fpe].model.is_none() && picks[&Rule::Fpe].why.contains("no least-squares"));
        // The JSON round trip keeps every pick.
        let back: crate::reduce::Selection = serde_json::from_value(serde_json::to_value(&sel).unwrap()).unwrap();
        assert_eq!(back, sel);
        assert_eq!(back.rule, DEFAULT_RULE);
    }

    #[test]
    fn the_evidence_rule_skips_dependent_and_over_fitted_models_and_says_when_none_is_left() {
        let mut rows = table();
        for r in rows.iter_mut().filter(|r| r.key.nb == 2) {
            r.evidence.resid_indep_p = Some(0.001);
        }
        for r in rows.iter_mut().filter(|r| r.key.nb == 3) {
            r.evidence.cancellations = Some(1);
        }
        let opts = ReduceOptions::new(FitBasis::Validation);
        let pick = &select(&rows, &opts).picks[&Rule::Evidence];
        assert_eq!(pick.model.as_ref().map(|m| (m.key.nb, m.key.nf)), Some((4, 4)));
        assert!(pick.why.starts_with("6 of 8 models"), "{}", pick.why);

        for r in rows.iter_mut() {
            r.evidence.resid_indep_p = Some(1e-5);
        }
        rows[2].evidence.resid_indep_p = Some(2e-3);
        let pick = &select(&rows, &opts).picks[&Rule::Evidence];
        assert!(pick.model.is_none() && pick.value.is_none());
        assert!(pick.why.contains("no pick") && pick.why.contains("p = 2.00e-3"), "{}", pick.why);
    }
}
