//! `oesweep export`: one model of a finished run, by rule or by cell, with its covariance, in
//! the forms of [`crate::export::model`].

use super::uncertainty::covariance_of;
use crate::error::{Error, Result};
use crate::export::model::{InputModel, ModelOut};
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
    /// delay (None: the table's only delay). Several inputs: one value per input, or one value
    /// for every input.
    Cell { nb: Vec<u32>, nf: Vec<u32>, k: Option<f64>, delay: Option<Vec<u32>> },
}

impl std::str::FromStr for PickSpec {
    type Err = String;

    /// `m1`, `m2`, a rule name (`rbic`, ...), or `NB,NF,K[,D]` with K a k of the grid or `ls`;
    /// for several inputs NB, NF and D may list one value per input, separated by `/`
    /// (`2/1,2/1,0.5,1/0`).
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
                "--pick {s}: expected m1, m2, a rule ({}) or NB,NF,K[,D] with K a k of the grid or `ls` \
                 (several inputs: NB, NF, D one value per input, as 2/1)",
                Rule::NAMES.join(", ")
            )
        };
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        if !(3..=4).contains(&parts.len()) {
            return Err(bad());
        }
        let ints = |p: &str| p.split('/').map(|v| v.trim().parse::<u32>().map_err(|_| bad())).collect();
        let k = match parts[2] {
            "ls" => None,
            p => Some(p.parse::<f64>().ok().filter(|k| k.is_finite() && *k > 0.0).ok_or_else(bad)?),
        };
        let delay = parts.get(3).map(|p| ints(p)).transpose()?;
        Ok(PickSpec::Cell { nb: ints(parts[0])?, nf: ints(parts[1])?, k, delay })
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
    let structure = row.key.structure();
    let parameters = crate::export::model::structure_parameter_names(&structure, estimated);
    let k = row.k.map_or(" (least squares)".to_string(), |k| format!(" at k = {}", crate::text::k(k)));
    // One input's level is `input_level`; several inputs' are `input_levels`.
    let level = |i: usize| match &res.selection.input_levels {
        Some(levels) => levels.get(i).copied().unwrap_or(0.0),
        None if i == 0 => res.selection.input_level.unwrap_or(0.0),
        None => 0.0,
    };
    let (b, f) = (structure.split_b(&row.fit.b), structure.split_f(&row.fit.f));
    let inputs = structure
        .inputs()
        .iter()
        .enumerate()
        .map(|(i, o)| InputModel { b: b[i].clone(), f: f[i].clone(), delay: o.delay as u32, input_level: level(i) })
        .collect();
    let model = ModelOut {
        name: format!("{}{k}, {label}", row.key.label()),
        k: row.k,
        ts: res.job.ts(),
        inputs,
        offset: row.fit.offset,
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
            let m = res.job.m;
            // One value serves every input; a list has one per input.
            let per_input = |v: &[u32], flag: &str| -> Result<Vec<u32>> {
                match v.len() {
                    1 => Ok(vec![v[0]; m]),
                    n if n == m => Ok(v.to_vec()),
                    n => Err(Error::Invalid(format!("--pick: {n} values of {flag} for a model of {m} inputs"))),
                }
            };
            let (nb, nf) = (per_input(nb, "NB")?, per_input(nf, "NF")?);
            let delays: std::collections::BTreeSet<Vec<u32>> =
                res.rows.iter().map(|r| r.key.orders().iter().map(|o| o.0).collect()).collect();
            let delay = match (delay, delays.len()) {
                (Some(d), _) => per_input(d, "D")?,
                (None, 1) => delays.first().expect("one delay").clone(),
                (None, _) => {
                    let shown: Vec<String> = delays.iter().map(|d| slashed(d)).collect();
                    return Err(Error::input(
                        &cells_file,
                        format!("the table holds delays {}: name one as NB,NF,K,D", list_of(&shown)),
                    ));
                }
            };
            let same_k = |r: &CellRow| match (k, r.k) {
                (None, _) => r.key.kind == FitKind::Ls,
                (Some(k), Some(rk)) => r.key.kind == FitKind::Huber && (rk - k).abs() <= 1e-9 * k.abs().max(1.0),
                (Some(_), None) => false,
            };
            let orders: Vec<(u32, u32, u32)> = (0..m).map(|i| (delay[i], nb[i], nf[i])).collect();
            let row = res.rows.iter().find(|r| r.key.orders() == orders && same_k(r)).ok_or_else(|| {
                let k = k.map_or("ls".to_string(), |k| k.to_string());
                let what = if m == 1 {
                    format!("OE({},{}) delay {}", nb[0], nf[0], delay[0])
                } else {
                    format!("nB {}, nF {}, delay {}", slashed(&nb), slashed(&nf), slashed(&delay))
                };
                Error::input(&cells_file, format!("no row {what} k {k}"))
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

/// `1/0/2`: one value per input (one input: the value).
fn slashed(v: &[u32]) -> String {
    v.iter().map(u32::to_string).collect::<Vec<_>>().join("/")
}

/// `{0, 1}` as the one-input message has always written a set of delays.
fn list_of(items: &[String]) -> String {
    format!("{{{}}}", items.join(", "))
}
