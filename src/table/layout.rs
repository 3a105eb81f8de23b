//! The table's columns for a number of inputs m: [`super::COLUMNS`] as they are for one input
//! (every file written for one input is what it always was); for several inputs the columns
//! that hold orders or coefficients are split by input ([`Split`]):
//!
//! - `nb`, `nf`, `delay` become plain integer columns `nb_1 .. nb_m`, `nf_1 .. nf_m`,
//!   `delay_1 .. delay_m` (what polars' `filter` and DuckDB's `WHERE` take directly);
//! - `b`, `f`, `b_std`, `f_std` become lists of lists, one list per input (input i's nB_i or
//!   nF_i values; an empty outer list where the row has none, as a failed row);
//! - `fit_band_i` (each input's band fit) becomes `fit_band_1 .. fit_band_m`; a one-input
//!   table has no such column (its `fit_band` is the input's).
//!
//! A row's JSON ([`RowJson`], the picks of `selection.json`) follows the same layout.
//!
//! A reader learns m from the names ([`inputs_of_names`]): `nb` for one input, `nb_1 ..` for
//! several. Order columns precede the coefficient columns, so a reader sets a row's orders
//! before it splits its coefficients, and checks every input's list against them.

use super::columns::{self, COLUMNS, Column, ColumnType, Split, Value};
use super::{CellRow, RowKey};
use crate::oe::MAX_INPUTS;
use serde::ser::{Serialize, SerializeMap, Serializer};

/// One column of a table of m inputs.
pub struct TableColumn {
    pub name: String,
    pub ty: ColumnType,
    /// The column of [`COLUMNS`] it comes from (nulls, optional, reproducible as there).
    pub column: &'static Column,
    /// The input of a split order or per-input column (0-based).
    input: Option<usize>,
    m: usize,
}

/// The columns of a table of `m` inputs, in table order.
pub fn layout(m: usize) -> Vec<TableColumn> {
    let mut out = Vec::with_capacity(COLUMNS.len() + 3 * m);
    for c in COLUMNS {
        let one = |name: String, ty, input| TableColumn { name, ty, column: c, input, m };
        match c.split {
            Split::Order(_) if m > 1 => {
                out.extend((0..m).map(|i| one(format!("{}_{}", c.name, i + 1), ColumnType::U32, Some(i))))
            }
            Split::Coefficients(_) if m > 1 => out.push(one(c.name.to_string(), ColumnType::ListListF64, None)),
            Split::PerInput if m > 1 => {
                let stem = c.name.strip_suffix("_i").expect("a per-input column's name ends in `_i`");
                out.extend((0..m).map(|i| one(format!("{stem}_{}", i + 1), ColumnType::F64, Some(i))))
            }
            // One input's number is the column without `_i` (`fit_band`).
            Split::PerInput => {}
            _ => out.push(one(c.name.to_string(), c.ty, None)),
        }
    }
    out
}

/// The number of inputs of a table whose column (or JSON field) names `has`: 1 with `nb`,
/// m with `nb_1 .. nb_m`.
pub fn inputs_of_names(has: impl Fn(&str) -> bool) -> Result<usize, String> {
    if has("nb") {
        return Ok(1);
    }
    let m = (1..=MAX_INPUTS + 1).take_while(|i| has(&format!("nb_{i}"))).count();
    match m {
        0 => Err("missing column `nb` (not a table written by oesweep)".into()),
        m if m > MAX_INPUTS => Err(format!("more than {MAX_INPUTS} inputs (`nb_1` .. `nb_{m}`)")),
        m => Ok(m),
    }
}

impl TableColumn {
    pub fn nullable(&self) -> bool {
        self.column.nullable
    }
    pub fn optional(&self) -> bool {
        self.column.optional
    }
    pub fn reproducible(&self) -> bool {
        self.column.reproducible
    }

    /// The column's value in `row` (a row of this layout's m inputs).
    pub fn get(&self, row: &CellRow) -> Value {
        let c = self.column;
        match (c.split, self.m) {
            (_, 1) | (Split::No, _) => (c.get)(row),
            (Split::PerInput, _) => {
                let Value::ListF64(list) = (c.get)(row) else { return Value::F64(None) };
                Value::F64(list.and_then(|l| self.input.and_then(|i| l.get(i).copied())))
            }
            (Split::Order(field), _) => {
                let s = row.key.structure();
                Value::U32(self.input.and_then(|i| s.inputs().get(i)).map(|o| field.get(o) as u32))
            }
            (Split::Coefficients(field), _) => {
                let Value::ListF64(Some(flat)) = (c.get)(row) else { return Value::ListListF64(None) };
                if flat.is_empty() {
                    return Value::ListListF64(Some(Vec::new()));
                }
                let lens: Vec<usize> = row.key.structure().inputs().iter().map(|o| field.get(o)).collect();
                if lens.iter().sum::<usize>() != flat.len() {
                    // Not a row of its orders (the reader refuses it): kept whole.
                    return Value::ListListF64(Some(vec![flat]));
                }
                let mut at = 0;
                let lists = lens
                    .iter()
                    .map(|&n| {
                        at += n;
                        flat[at - n..at].to_vec()
                    })
                    .collect();
                Value::ListListF64(Some(lists))
            }
        }
    }

    /// Set the column of `row` (whose key has this layout's m inputs) from `v`, checking
    /// nulls and, for coefficients, every input's list against the row's orders: the message
    /// names the column.
    pub fn set(&self, row: &mut CellRow, v: Value) -> Result<(), String> {
        let c = self.column;
        let name = &self.name;
        if v.is_null() && !c.nullable {
            return Err(format!("column `{name}`: null in a column that must not have nulls"));
        }
        match (c.split, self.m) {
            (_, 1) | (Split::No, _) => columns::set(row, c, v),
            (Split::PerInput, m) => {
                let i = self.input.expect("a per-input column names its input");
                let Value::F64(x) = v else { return Err(format!("column `{name}`: unexpected value {v:?}")) };
                let Value::ListF64(list) = (c.get)(row) else { unreachable!("a per-input column holds a list") };
                let list = match (list, x) {
                    (list, None) => list,
                    (list, Some(x)) => {
                        let mut l = list.unwrap_or_else(|| vec![f64::NAN; m]);
                        l[i] = x;
                        Some(l)
                    }
                };
                columns::set(row, c, Value::ListF64(list))
            }
            (Split::Order(field), _) => {
                let Value::U32(Some(x)) = v else { return Err(format!("column `{name}`: unexpected value {v:?}")) };
                let i = self.input.expect("an order column of several inputs names its input");
                let mut o = row.key.structure().inputs()[i];
                field.set(&mut o, x as usize);
                row.key = row.key.with(i, o);
                Ok(())
            }
            (Split::Coefficients(field), m) => {
                let Value::ListListF64(Some(lists)) = v else {
                    return Err(format!("column `{name}`: unexpected value {v:?}"));
                };
                if !lists.is_empty() {
                    if lists.len() != m {
                        return Err(format!("column `{name}`: {} lists for {m} inputs", lists.len()));
                    }
                    let s = row.key.structure();
                    for (i, (l, o)) in lists.iter().zip(s.inputs()).enumerate() {
                        if l.len() != field.get(o) {
                            return Err(format!(
                                "column `{name}`: {} values for input {}, its orders need {}",
                                l.len(),
                                i + 1,
                                field.get(o)
                            ));
                        }
                    }
                }
                columns::set(row, c, Value::ListF64(Some(lists.concat())))
            }
        }
    }
}

/// A row as a JSON object of its reproducible columns, in table order, with `extra` entries
/// written right after the column `after` (how a pick carries its score).
pub struct RowJson<'a> {
    pub row: &'a CellRow,
    pub extra: &'a [(&'a str, f64)],
    pub after: &'a str,
}

impl Serialize for RowJson<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        for c in layout(self.row.key.m()).iter().filter(|c| c.reproducible()) {
            map.serialize_entry(&c.name, &c.get(self.row))?;
            if c.name == self.after {
                for (name, v) in self.extra {
                    map.serialize_entry(name, v)?;
                }
            }
        }
        map.end()
    }
}

/// A row as JSON: every column, in table order.
impl Serialize for CellRow {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let columns = layout(self.key.m());
        let mut map = s.serialize_map(Some(columns.len()))?;
        for c in &columns {
            map.serialize_entry(&c.name, &c.get(self))?;
        }
        map.end()
    }
}

/// A row from a JSON object written by [`RowJson`]: columns absent from it take the values of
/// `base`; other keys are ignored. The number of inputs is the object's (`nb_1 ..` for
/// several, [`super::inputs_of_names`]); a one-input object without orders keeps `base`'s.
pub fn row_from_json(obj: &serde_json::Map<String, serde_json::Value>, mut base: CellRow) -> Result<CellRow, String> {
    let m = inputs_of_names(|n| obj.contains_key(n)).unwrap_or(1);
    if m != base.key.m() {
        let kind = base.key.kind;
        base.key = RowKey { k_index: base.key.k_index, ..RowKey::blank(kind, m) };
    }
    for c in layout(m).iter().filter(|c| c.reproducible()) {
        if let Some(v) = obj.get(&c.name) {
            c.set(&mut base, Value::from_json(c.ty, v).map_err(|e| format!("field `{}`: {e}", c.name))?)?;
        }
    }
    // selection.json files of older versions hold only some columns: a row without parameters
    // is read as before, one with parameters must fit its orders.
    let has_parameters = !(base.fit.b.is_empty() && base.fit.f.is_empty());
    match base.shape_error().filter(|_| has_parameters) {
        Some(why) => Err(format!("{}: {why}", base.key)),
        None => Ok(base),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::{Orders, Structure};
    use crate::table::FitKind;

    #[test]
    fn one_input_layout_is_the_column_list() {
        let names: Vec<String> = layout(1).into_iter().map(|c| c.name).collect();
        let listed = COLUMNS.iter().filter(|c| c.split != Split::PerInput).map(|c| c.name.to_string());
        assert_eq!(names, listed.collect::<Vec<_>>());
    }

    #[test]
    fn several_input_rows_roundtrip_through_their_columns() {
        let o = |nb, nf, delay| Orders { nb, nf, delay };
        let s = Structure::new(&[o(2, 1, 0), o(1, 2, 3)]).unwrap();
        let mut row = CellRow::failed(RowKey::huber(&s, 1), Some(0.5), "x".into());
        row.status = crate::table::Status::Ok;
        row.fit.b = vec![1.0, 2.0, 3.0];
        row.fit.f = vec![0.1, 0.2, 0.3];
        row.fit.fit_band_inputs = Some(vec![91.0, 83.0]);
        let cols = layout(2);
        let per_input = |name: &str| cols.iter().find(|c| c.name == name).unwrap().get(&row);
        assert_eq!(
            (per_input("fit_band_1"), per_input("fit_band_2")),
            (Value::F64(Some(91.0)), Value::F64(Some(83.0)))
        );
        assert!(!cols.iter().any(|c| c.name == "fit_band_i"));
        let names: Vec<&str> = cols.iter().map(|c| c.name.as_str()).take(7).collect();
        assert_eq!(names, ["method", "nb_1", "nb_2", "nf_1", "nf_2", "delay_1", "delay_2"]);
        let b = cols.iter().find(|c| c.name == "b").unwrap();
        assert_eq!(b.get(&row), Value::ListListF64(Some(vec![vec![1.0, 2.0], vec![3.0]])));
        let mut back = CellRow::empty(RowKey::blank(FitKind::Ls, 2));
        for c in &cols {
            c.set(&mut back, c.get(&row)).unwrap();
        }
        assert_eq!(back, row);
        let err = b.set(&mut back, Value::ListListF64(Some(vec![vec![1.0], vec![2.0, 3.0]]))).unwrap_err();
        assert!(err.contains("`b`") && err.contains("input 1"), "{err}");
        assert_eq!(inputs_of_names(|n| ["nb_1", "nb_2"].contains(&n)), Ok(2));
    }
}
