//! `oesweep export`: one model of a finished run, by rule or by cell, with its covariance, in
//! the forms of [`crate::export::model`].

use super::uncertainty::covariance_of;
use crate::error::{Error, Result};
use crate::export::model::ModelOut;
use crate::reduce::Rule;
use crate::results::{Results, read_results};
use crate::table::{CellRow, FitKind};
use std::path::Path;

/// Which model to export.
#[derive(Clone, Debug, PartialEq)]
pub enum PickSpec {
    /// A rule's pick (`m1`, `m2` are `paper_m1`, `paper_m2`).
    Rule(Rule),
    /// A cell of the table: nB, nF, k (None: the least-squares fit of the structure) and the
    /// delay (None: the table's only delay).
    Cell { nb: u32, nf: u32, k: Option<f64>, delay: Option<u32> },
}

impl std::str::FromStr for PickSpec {
    type Err = String;

    /// `m1`, `m2`, a rule name (`rbic`, ...), or `NB,NF,K[,D]` with K a k of the grid or `ls`.
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let rule = |name: &str| serde_json::from_value::<Rule>(serde_json::Value::String(name.into())).ok();
        match s {
            "m1" => return Ok(PickSpec::Rule(Rule::PaperM1)),
            "m2" => return Ok(PickSpec::Rule(Rule::PaperM2)),
            _ => {}
        }
        if let Some(r) = rule(s) {
            return Ok(PickSpec::Rule(r));
        }
        let bad = || {
            format!(
                "--pick {s}: expected m1, m2, a rule ({}) or NB,NF,K[,D] with K a k of the grid or `ls`",
                Rule::NAMES.join(", ")
            )
        };
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        if !(3..=4).contains(&parts.len()) {
            return Err(bad());
        }
        let int = |p: &str| p.parse::<u32>().map_err(|_| bad());
        let k = match parts[2] {
            "ls" => None,
            p => Some(p.parse::<f64>().ok().filter(|k| k.is_finite() && *k > 0.0).ok_or_else(bad)?),
        };
        let delay = parts.get(3).map(|p| int(p)).transpose()?;
        Ok(PickSpec::Cell { nb: int(parts[0])?, nf: int(parts[1])?, k, delay })
    }
}

/// The model `spec` names in the results folder `folder` (the lead rule's pick when None), with
/// its covariance: the one `selection.json` holds for the paper's picks, else computed from
/// the job's records when they can be read. The second value says what could not be done.
pub fn export_model(folder: &Path, spec: Option<&PickSpec>) -> Result<(ModelOut, Vec<String>)> {
    let res = read_results(folder)?;
    let spec = spec.cloned().unwrap_or(PickSpec::Rule(res.selection.rule));
    let (row, label, stored) = chosen(&res, &spec)?;
    // The pick's covariance belongs to the pick's row of selection.json, which an edit could
    // have moved away from the table's.
    let stored = stored.filter(|c| crate::results::covariance_fits(c, &row));
    let mut notes = Vec::new();
    let covariance = match stored {
        Some(c) => Some(c),
        None => match crate::job::load_inputs(&res.job) {
            Ok(inputs) => covariance_of(&row, &inputs),
            Err(e) => {
                notes.push(format!("no covariance: the run's records cannot be read ({e})"));
                None
            }
        },
    };
    let estimated = res.selection.offset.is_some_and(|o| o.estimated());
    let parameters = crate::export::model::parameter_names(row.fit.b.len(), row.fit.f.len(), estimated);
    let k = row.k.map_or(" (least squares)".to_string(), |k| format!(" at k = {}", crate::text::k(k)));
    let model = ModelOut {
        name: format!("OE({},{}) delay {}{k}, {label}", row.key.nb, row.key.nf, row.key.delay),
        delay: row.key.delay,
        k: row.k,
        ts: res.job.ts(),
        b: row.fit.b.clone(),
        f: row.fit.f.clone(),
        offset: row.fit.offset,
        input_level: res.selection.input_level.unwrap_or(0.0),
        covariance,
        parameters,
        noise_variance: row.fit.sigma.map(|s| s * s),
    };
    Ok((model, notes))
}

/// The row `spec` names, a label saying how it was chosen, and its stored covariance.
fn chosen(res: &Results, spec: &PickSpec) -> Result<(CellRow, String, Option<Vec<f64>>)> {
    let sel_file = res.folder.join(crate::export::SELECTION_FILE);
    match spec {
        PickSpec::Rule(rule) => {
            let stored = match rule {
                Rule::PaperM1 => res.selection.m1.as_ref().and_then(|p| p.covariance.clone()),
                Rule::PaperM2 => res.selection.m2.as_ref().and_then(|p| p.covariance.clone()),
                _ => None,
            };
            let pick = res.selection.picks.get(rule).ok_or_else(|| {
                Error::input(&sel_file, format!("no pick of rule {} (a file of an older version?)", rule.as_str()))
            })?;
            let model = pick.model.as_ref().ok_or_else(|| {
                Error::input(&sel_file, format!("rule {} picked no model: {}", rule.as_str(), pick.why))
            })?;
            Ok((model.row.clone(), format!("picked by {}", rule.as_str()), stored))
        }
        PickSpec::Cell { nb, nf, k, delay } => {
            let cells_file = res.folder.join(crate::export::CELLS_FILE);
            let delays: std::collections::BTreeSet<u32> = res.rows.iter().map(|r| r.key.delay).collect();
            let delay = match (delay, delays.len()) {
                (Some(d), _) => *d,
                (None, 1) => *delays.first().expect("one delay"),
                (None, _) => {
                    return Err(Error::input(
                        &cells_file,
                        format!("the table holds delays {delays:?}: name one as NB,NF,K,D"),
                    ));
                }
            };
            let same_k = |r: &CellRow| match (k, r.k) {
                (None, _) => r.key.kind == FitKind::Ls,
                (Some(k), Some(rk)) => r.key.kind == FitKind::Huber && (rk - k).abs() <= 1e-9 * k.abs().max(1.0),
                (Some(_), None) => false,
            };
            let row = res
                .rows
                .iter()
                .find(|r| r.key.nb == *nb && r.key.nf == *nf && r.key.delay == delay && same_k(r))
                .ok_or_else(|| {
                    let k = k.map_or("ls".to_string(), |k| k.to_string());
                    Error::input(&cells_file, format!("no row OE({nb},{nf}) delay {delay} k {k}"))
                })?;
            if !row.ok() {
                return Err(Error::input(
                    &cells_file,
                    format!("{} failed: {}", row.key, row.reason.as_deref().unwrap_or("no reason")),
                ));
            }
            Ok((row.clone(), "chosen by cell".to_string(), None))
        }
    }
}
