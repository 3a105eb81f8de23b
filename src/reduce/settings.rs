//! The settings of the model choice (METHOD.md 7): the job's `selection` with its one set of
//! defaults, and what [`super::select`] takes.

use super::{DEFAULT_FIT_TOLERANCE, DEFAULT_MIN_TOLERANCE, FitBasis, Rule};
use serde::{Deserialize, Serialize};

/// The settings of the model choice, the job's `selection` (METHOD.md 7): its tolerances and
/// lead rule, with their one set of defaults.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SelectionSettings {
    /// A point of a W (or L1C) curve along nF is a local minimum when it is not above either
    /// neighbour by more than this (relative for W, absolute share for L1C).
    pub min_tolerance: f64,
    /// Candidates within this many fit-percentage points of the best count as ties; the one
    /// with the fewest parameters wins.
    pub fit_tolerance: f64,
    /// The pick rule the summary leads with (every rule is reported; METHOD.md 7.1); absent:
    /// `paper_m2` with a validation record, `rbic` without ([`crate::reduce::rules::lead_rule`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rule: Option<Rule>,
}

impl Default for SelectionSettings {
    fn default() -> Self {
        SelectionSettings { min_tolerance: DEFAULT_MIN_TOLERANCE, fit_tolerance: DEFAULT_FIT_TOLERANCE, rule: None }
    }
}

/// What the model choice needs: the fit column that ranks (from the job's records) and the
/// job's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReduceOptions {
    pub basis: FitBasis,
    pub settings: SelectionSettings,
}

impl ReduceOptions {
    /// Default settings with the given basis.
    pub fn new(basis: FitBasis) -> Self {
        ReduceOptions { basis, settings: SelectionSettings::default() }
    }
}
