//! The grid of a job file: each input's orders (one range for every input or one per input,
//! [`Ranges`]), the k values (a list or a generated range) and how several inputs' structures
//! are searched ([`SearchMode`]).

use super::Ranges;
use serde::{Deserialize, Serialize};

/// k values: an explicit list or a generated range.
#[derive(Clone, Debug, Serialize, PartialEq)]
#[serde(untagged)]
pub enum KGrid {
    List(Vec<f64>),
    Range(KRange),
}

/// By hand rather than `untagged`, whose error names neither form (`job/parse.rs`).
impl<'de> Deserialize<'de> for KGrid {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = KGrid;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a list of k values [k1, k2, ...] or a range {\"from\": a, \"to\": b, \"count\": n}")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> std::result::Result<KGrid, A::Error> {
                KRange::deserialize(serde::de::value::MapAccessDeserializer::new(map)).map(KGrid::Range)
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<KGrid, A::Error> {
                let mut ks = Vec::new();
                while let Some(k) = seq.next_element::<f64>()? {
                    ks.push(k);
                }
                Ok(KGrid::List(ks))
            }
        }
        d.deserialize_any(Visitor)
    }
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

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Spacing {
    #[default]
    Linear,
    Log,
}

crate::names::names!(Spacing { Linear = "linear", Log = "log" });

/// The grid: each of `nb`, `nf` and `delay` one range for every input or a list of ranges, one
/// per input ([`Ranges`]); the structures are the product over the inputs.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Grid {
    /// Inclusive range [from, to] of nB.
    pub nb: Ranges,
    /// Inclusive range [from, to] of nF.
    pub nf: Ranges,
    pub k: KGrid,
    /// Inclusive range [from, to] of the input delay d in samples (default: the job's
    /// top-level `delay`, itself 1 by default).
    #[serde(default)]
    pub delay: Option<Ranges>,
    /// How several inputs' structures are searched ([`crate::search`]): written only when not
    /// the default, so a job of today writes the job.json it always did.
    #[serde(default, skip_serializing_if = "SearchMode::is_auto")]
    pub search: SearchMode,
}

/// `grid.search`: the full product of several inputs' grids, the coordinate search, or
/// (`auto`, the default) the product up to [`crate::search::PRODUCT_LIMIT`] structures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SearchMode {
    #[default]
    Auto,
    Product,
    Coordinate,
}

crate::names::names!(SearchMode { Auto = "auto", Product = "product", Coordinate = "coordinate" });

impl SearchMode {
    fn is_auto(&self) -> bool {
        *self == SearchMode::Auto
    }
}
