//! A candidate of the model choice: a table row that is a local minimum of a W or L1C curve,
//! with its score; in `selection.json`, the row's reproducible columns and the score.

use super::takes_part;
use crate::table::RowJson;
use crate::table::{CellRow, FitKind, RowKey, Status};
use serde::{Deserialize, Serialize};

/// A local minimum of a W or L1C curve: its table row and its score.
///
/// In `selection.json` a candidate is the row's reproducible columns (all but the wall time,
/// [`crate::table::RowJson`]) with `score` after `fit_band`; read back, the wall time
/// is 0.
#[derive(Clone, Debug)]
pub struct Candidate {
    pub row: CellRow,
    /// The fit that ranks candidates (the basis column; NaN, null in JSON, for a rule's pick
    /// that has none).
    pub score: f64,
}

impl std::ops::Deref for Candidate {
    type Target = CellRow;
    fn deref(&self) -> &CellRow {
        &self.row
    }
}

/// Equal as `selection.json` shows them: the wall time is not part of a candidate.
impl PartialEq for Candidate {
    fn eq(&self, other: &Self) -> bool {
        self.score.total_cmp(&other.score).is_eq()
            && crate::table::COLUMNS
                .iter()
                .filter(|c| c.reproducible)
                .all(|c| (c.get)(&self.row) == (c.get)(&other.row))
    }
}

impl Serialize for Candidate {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        RowJson { row: &self.row, extra: &[("score", self.score)], after: "fit_band" }.serialize(s)
    }
}

impl<'de> Deserialize<'de> for Candidate {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let obj = serde_json::Map::<String, serde_json::Value>::deserialize(d)?;
        // A null score (a rule's pick without a fit in the basis) reads back as NaN.
        let score = match obj.get("score") {
            Some(serde_json::Value::Null) => f64::NAN,
            v => v.and_then(serde_json::Value::as_f64).ok_or_else(|| D::Error::missing_field("score"))?,
        };
        // Files of older versions hold only some columns; a candidate is an ok Huber row (rule 1).
        let key = RowKey::blank(FitKind::Huber, 1);
        let base = CellRow { status: Status::Ok, ..CellRow::empty(key) };
        let row = crate::table::row_from_json(&obj, base).map_err(D::Error::custom)?;
        Ok(Candidate { row, score })
    }
}

impl Candidate {
    /// The row as a candidate, if it takes part in the choice (rule 1).
    pub(super) fn new(row: &CellRow, score: f64) -> Option<Self> {
        takes_part(row).then(|| Candidate { row: row.clone(), score })
    }

    /// The candidate's k index (every candidate has one, rule 1).
    pub fn k_index(&self) -> u32 {
        self.key.k_index.unwrap_or(u32::MAX)
    }

    /// The candidate's k, gamma, W and L1C (finite for every candidate, rule 1).
    pub fn k(&self) -> f64 {
        self.row.k.unwrap_or(f64::NAN)
    }
    pub fn gamma(&self) -> f64 {
        self.fit.gamma.unwrap_or(f64::NAN)
    }
    pub fn criterion(&self) -> f64 {
        self.fit.criterion.unwrap_or(f64::NAN)
    }
    pub fn l1c(&self) -> f64 {
        self.fit.l1c.unwrap_or(f64::NAN)
    }
}
