//! The columns of the result table, listed once.
//!
//! Each [`Column`] names a column, its type, whether it may hold nulls, whether older tables
//! may lack it, and how to read it from and write it into a [`CellRow`]. The Parquet writer
//! and reader ([`crate::export::parquet`]), the row's JSON (the picks in `selection.json`) and
//! README's column reference all follow this list, so they cannot disagree.

use super::{CellRow, FitKind, Status};
use serde::ser::{Serialize, Serializer};

/// The storage type of a column (Parquet: String, UInt32, Float64, Boolean, List(Float64),
/// List(List(Float64))). `ListListF64` only holds a several-input row's coefficients, one list
/// per input ([`super::layout`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColumnType {
    Str,
    U32,
    F64,
    Bool,
    ListF64,
    ListListF64,
}

/// One value of a column (`None`: null).
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Str(Option<String>),
    U32(Option<u32>),
    F64(Option<f64>),
    Bool(Option<bool>),
    ListF64(Option<Vec<f64>>),
    ListListF64(Option<Vec<Vec<f64>>>),
}

impl Value {
    pub fn is_null(&self) -> bool {
        match self {
            Value::Str(v) => v.is_none(),
            Value::U32(v) => v.is_none(),
            Value::F64(v) => v.is_none(),
            Value::Bool(v) => v.is_none(),
            Value::ListF64(v) => v.is_none(),
            Value::ListListF64(v) => v.is_none(),
        }
    }

    /// A null of a column type.
    pub fn null(ty: ColumnType) -> Value {
        match ty {
            ColumnType::Str => Value::Str(None),
            ColumnType::U32 => Value::U32(None),
            ColumnType::F64 => Value::F64(None),
            ColumnType::Bool => Value::Bool(None),
            ColumnType::ListF64 => Value::ListF64(None),
            ColumnType::ListListF64 => Value::ListListF64(None),
        }
    }

    /// The value of a JSON document's field (as [`Value`]'s `Serialize` writes it). JSON has
    /// no non-finite numbers: serde_json writes them as null, which reads back as NaN inside
    /// a list and as a null elsewhere.
    pub fn from_json(ty: ColumnType, v: &serde_json::Value) -> Result<Value, String> {
        use serde_json::Value as J;
        let bad = || format!("expected {ty:?}, got {v}");
        if v.is_null() {
            return Ok(Value::null(ty));
        }
        if ty == ColumnType::ListListF64 {
            let lists = v.as_array().ok_or_else(bad)?;
            let inner = lists
                .iter()
                .map(|l| match Value::from_json(ColumnType::ListF64, l)? {
                    Value::ListF64(Some(l)) => Ok(l),
                    _ => Err(bad()),
                })
                .collect::<Result<_, _>>()?;
            return Ok(Value::ListListF64(Some(inner)));
        }
        Ok(match ty {
            ColumnType::Str => Value::Str(Some(v.as_str().ok_or_else(bad)?.to_string())),
            ColumnType::U32 => Value::U32(Some(v.as_u64().and_then(|x| u32::try_from(x).ok()).ok_or_else(bad)?)),
            ColumnType::F64 => Value::F64(Some(v.as_f64().ok_or_else(bad)?)),
            ColumnType::Bool => Value::Bool(Some(v.as_bool().ok_or_else(bad)?)),
            ColumnType::ListListF64 => unreachable!("read above"),
            ColumnType::ListF64 => Value::ListF64(Some(
                v.as_array()
                    .ok_or_else(bad)?
                    .iter()
                    .map(|x| match x {
                        J::Null => Ok(f64::NAN),
                        x => x.as_f64().ok_or_else(bad),
                    })
                    .collect::<Result<_, _>>()?,
            )),
        })
    }
}

impl Serialize for Value {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Value::Str(v) => v.serialize(s),
            Value::U32(v) => v.serialize(s),
            Value::F64(v) => v.serialize(s),
            Value::Bool(v) => v.serialize(s),
            Value::ListF64(v) => v.serialize(s),
            Value::ListListF64(v) => v.serialize(s),
        }
    }
}

/// A field type of [`CellRow`] and the column type that stores it. A field that is not an
/// `Option` is a column without nulls.
pub trait Cell: Sized {
    const TYPE: ColumnType;
    const NULLABLE: bool;
    fn to_value(&self) -> Value;
    /// `v` is of [`Cell::TYPE`], and not null unless [`Cell::NULLABLE`] (the reader checks).
    fn from_value(v: Value) -> Result<Self, String>;
}

fn wrong(v: &Value) -> String {
    format!("unexpected value {v:?}")
}

macro_rules! cell {
    ($t:ty, $variant:ident) => {
        impl Cell for $t {
            const TYPE: ColumnType = ColumnType::$variant;
            const NULLABLE: bool = false;
            fn to_value(&self) -> Value {
                Value::$variant(Some(self.clone()))
            }
            fn from_value(v: Value) -> Result<Self, String> {
                match v {
                    Value::$variant(Some(x)) => Ok(x),
                    v => Err(wrong(&v)),
                }
            }
        }
        impl Cell for Option<$t> {
            const TYPE: ColumnType = ColumnType::$variant;
            const NULLABLE: bool = true;
            fn to_value(&self) -> Value {
                Value::$variant(self.clone())
            }
            fn from_value(v: Value) -> Result<Self, String> {
                match v {
                    Value::$variant(x) => Ok(x),
                    v => Err(wrong(&v)),
                }
            }
        }
    };
}

cell!(String, Str);
cell!(u32, U32);
cell!(f64, F64);
cell!(bool, Bool);
cell!(Vec<f64>, ListF64);

/// Enums stored as their names.
macro_rules! named_cell {
    ($t:ty) => {
        impl Cell for $t {
            const TYPE: ColumnType = ColumnType::Str;
            const NULLABLE: bool = false;
            fn to_value(&self) -> Value {
                Value::Str(Some(self.as_str().to_string()))
            }
            fn from_value(v: Value) -> Result<Self, String> {
                match v {
                    Value::Str(Some(s)) => <$t>::parse(&s),
                    v => Err(wrong(&v)),
                }
            }
        }
    };
}

named_cell!(FitKind);
named_cell!(Status);

/// How a column of one input's table becomes columns of a several-input table
/// ([`super::layout`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Split {
    /// The same column.
    No,
    /// An order (`nb`, `nf`, `delay`): one plain integer column per input, `nb_1 .. nb_m`.
    Order(OrderField),
    /// Coefficients held flat (every input's after the other) in the row: one list per input,
    /// of nB_i (`b`, `b_std`) or nF_i (`f`, `f_std`) values.
    Coefficients(OrderField),
    /// One number per input held as a list in the row (`fit_band_i`): no column for one
    /// input, a float column per input for several, named with the input's number in place of
    /// the `i` (`fit_band_1 .. fit_band_m`; every input's null where the row has no list).
    PerInput,
}

/// One of an input's orders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OrderField {
    Nb,
    Nf,
    Delay,
}

impl OrderField {
    pub fn get(self, o: &crate::oe::Orders) -> usize {
        match self {
            OrderField::Nb => o.nb,
            OrderField::Nf => o.nf,
            OrderField::Delay => o.delay,
        }
    }
    pub fn set(self, o: &mut crate::oe::Orders, v: usize) {
        match self {
            OrderField::Nb => o.nb = v,
            OrderField::Nf => o.nf = v,
            OrderField::Delay => o.delay = v,
        }
    }
}

/// One column of the table.
pub struct Column {
    pub name: &'static str,
    pub ty: ColumnType,
    /// May hold nulls (else a null is a malformed file).
    pub nullable: bool,
    /// Added after the first layout: tables of older versions lack it, and a reader then
    /// takes the empty row's value (null, an empty list).
    pub optional: bool,
    /// The value is the same on every run of the same job (all but the wall time): such
    /// columns make up a pick in `selection.json`.
    pub reproducible: bool,
    /// What the column becomes in a table of several inputs.
    pub split: Split,
    pub get: fn(&CellRow) -> Value,
    pub set: fn(&mut CellRow, Value) -> Result<(), String>,
}

macro_rules! column {
    (@opt optional) => {
        true
    };
    (@opt) => {
        false
    };
    (@ $name:literal, $t:ty, $optional:expr, $reproducible:expr, $split:expr, |$r:ident| $place:expr) => {
        Column {
            name: $name,
            ty: <$t as Cell>::TYPE,
            nullable: <$t as Cell>::NULLABLE,
            optional: $optional,
            reproducible: $reproducible,
            split: $split,
            get: |$r| Cell::to_value(&$place),
            set: |$r, v| {
                $place = <$t as Cell>::from_value(v)?;
                Ok(())
            },
        }
    };
    ($name:literal, $t:ty, |$r:ident| $place:expr) => {
        column!(@ $name, $t, false, true, Split::No, |$r| $place)
    };
    (optional $name:literal, $t:ty, |$r:ident| $place:expr) => {
        column!(@ $name, $t, true, true, Split::No, |$r| $place)
    };
    (wall_time $name:literal, $t:ty, |$r:ident| $place:expr) => {
        column!(@ $name, $t, false, false, Split::No, |$r| $place)
    };
    (order $field:ident $name:literal, |$r:ident| $place:expr) => {
        column!(@ $name, u32, false, true, Split::Order(OrderField::$field), |$r| $place)
    };
    (per_input $name:literal, |$r:ident| $place:expr) => {
        column!(@ $name, Option<Vec<f64>>, true, true, Split::PerInput, |$r| $place)
    };
    (coefficients $field:ident $($opt:ident)? $name:literal, |$r:ident| $place:expr) => {
        column!(@ $name, Vec<f64>, column!(@opt $($opt)?), true, Split::Coefficients(OrderField::$field), |$r| $place)
    };
}

/// The columns of `cells.parquet`, in table order (docs/JOBS.md "Columns of cells.parquet").
pub const COLUMNS: &[Column] = &[
    column!("method", FitKind, |r| r.key.kind),
    column!(order Nb "nb", |r| r.key.nb),
    column!(order Nf "nf", |r| r.key.nf),
    column!(order Delay "delay", |r| r.key.delay),
    column!("k_index", Option<u32>, |r| r.key.k_index),
    column!("k", Option<f64>, |r| r.k),
    column!("sigma", Option<f64>, |r| r.fit.sigma),
    column!("gamma", Option<f64>, |r| r.fit.gamma),
    column!("criterion", Option<f64>, |r| r.fit.criterion),
    column!("l1c", Option<f64>, |r| r.fit.l1c),
    column!("fit", Option<f64>, |r| r.fit.fit),
    column!("fit_val", Option<f64>, |r| r.fit.fit_val),
    column!("fit_band", Option<f64>, |r| r.fit.fit_band),
    column!(per_input "fit_band_i", |r| r.fit.fit_band_inputs),
    column!("iterations", Option<u32>, |r| r.fit.iterations),
    column!("termination", Option<String>, |r| r.fit.termination),
    column!("converged", bool, |r| r.fit.converged),
    column!("status", Status, |r| r.status),
    column!("reason", Option<String>, |r| r.reason),
    column!("max_pole_radius", Option<f64>, |r| r.fit.max_pole_radius),
    column!("reflections", Option<u32>, |r| r.fit.reflections),
    column!("start", String, |r| r.fit.start),
    column!(wall_time "seconds", f64, |r| r.fit.seconds),
    column!(coefficients Nb "b", |r| r.fit.b),
    column!(coefficients Nf "f", |r| r.fit.f),
    column!(optional "offset", Option<f64>, |r| r.fit.offset),
    column!(coefficients Nb optional "b_std", |r| r.evidence.b_std),
    column!(coefficients Nf optional "f_std", |r| r.evidence.f_std),
    column!(optional "offset_std", Option<f64>, |r| r.evidence.offset_std),
    column!(optional "max_rel_std", Option<f64>, |r| r.evidence.max_rel_std),
    column!(optional "resid_white_p", Option<f64>, |r| r.evidence.resid_white_p),
    column!(optional "resid_indep_p", Option<f64>, |r| r.evidence.resid_indep_p),
    column!(optional "cancellations", Option<u32>, |r| r.evidence.cancellations),
    column!(optional "aic", Option<f64>, |r| r.fit.aic),
    column!(optional "aicc", Option<f64>, |r| r.fit.aicc),
    column!(optional "bic", Option<f64>, |r| r.fit.bic),
    column!(optional "fpe", Option<f64>, |r| r.fit.fpe),
    column!(optional "raic", Option<f64>, |r| r.fit.raic),
    column!(optional "rbic", Option<f64>, |r| r.fit.rbic),
    column!(optional "fit_exp", Option<Vec<f64>>, |r| r.fit.fit_exp),
    column!(optional "fit_val_exp", Option<Vec<f64>>, |r| r.fit.fit_val_exp),
];

/// The column called `name`.
pub fn column(name: &str) -> Option<&'static Column> {
    COLUMNS.iter().find(|c| c.name == name)
}

/// Set column `c` of `row` from `v`, checking nulls: the message names the column.
pub fn set(row: &mut CellRow, c: &Column, v: Value) -> Result<(), String> {
    if v.is_null() && !c.nullable {
        return Err(format!("column `{}`: null in a column that must not have nulls", c.name));
    }
    (c.set)(row, v).map_err(|e| format!("column `{}`: {e}", c.name))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::table::RowKey;

    /// docs/JOBS.md, the column reference, lists exactly the table's columns, in table order.
    #[test]
    fn the_column_reference_lists_the_columns_in_order() {
        let reference = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/JOBS.md")).unwrap();
        let section =
            reference.split("## Columns of cells.parquet").nth(1).expect("docs/JOBS.md has the column reference");
        let listed: Vec<&str> = section
            .lines()
            .skip_while(|l| !l.starts_with('|'))
            .take_while(|l| l.starts_with('|'))
            .filter_map(|l| l.trim_start_matches('|').trim().strip_prefix('`')?.split('`').next())
            .collect();
        let names: Vec<&str> = COLUMNS.iter().map(|c| c.name).collect();
        assert_eq!(listed, names, "docs/JOBS.md \"Columns of cells.parquet\" against table::COLUMNS");
    }

    #[test]
    fn table_columns_have_unique_names_and_roundtrip_through_get_and_set() {
        let mut names: Vec<&str> = COLUMNS.iter().map(|c| c.name).collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), COLUMNS.len());
        let key = RowKey::siso(FitKind::Huber, 3, 4, 2, Some(5));
        let mut row = CellRow::failed(key, Some(0.5), "why".into());
        row.fit.b = vec![1.0, 2.0];
        row.evidence.max_rel_std = Some(f64::INFINITY);
        let mut back = CellRow::empty(RowKey::blank(FitKind::Ls, 1));
        for c in COLUMNS {
            let v = (c.get)(&row);
            assert_eq!(std::mem::discriminant(&v), std::mem::discriminant(&Value::null(c.ty)), "{}", c.name);
            set(&mut back, c, v).unwrap();
        }
        assert_eq!(back, row);
    }
}
