//! The job's fields that take one value for every input or a list of them, one per input
//! (issue 46): the input columns (`data.u`), the order and delay ranges of the grid
//! (`grid.nb`, `grid.nf`, `grid.delay`) and the fixed `delay`. Each is written back in the form
//! it was read, so a one-input job's job.json is what it always was; and each says what it
//! accepts in its own visitor ([`super::parse`]), with the element at fault named by its place
//! (`grid.nb[1]`, `data.u[0]`).

use crate::data::ColumnRef;
use serde::de::{self, DeserializeSeed, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;

/// The input columns of a record: one column (one input, the usual job) or a list of them, one
/// per input in the model's order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputColumns {
    /// At least one.
    pub cols: Vec<ColumnRef>,
    /// Given as a list (even of one column).
    pub list: bool,
}

impl InputColumns {
    /// One input's column.
    pub fn one(col: ColumnRef) -> InputColumns {
        InputColumns { cols: vec![col], list: false }
    }

    /// Several inputs' columns (a list, even of one).
    pub fn list(cols: Vec<ColumnRef>) -> InputColumns {
        InputColumns { cols, list: true }
    }
}

impl Serialize for InputColumns {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if self.list { self.cols.serialize(s) } else { self.cols[0].serialize(s) }
    }
}

impl<'de> Deserialize<'de> for InputColumns {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = InputColumns;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                // As a one-input job's message always read (users' scripts match it); the list of
                // several inputs is in docs/JOBS.md and in the message of an empty list.
                f.write_str("a column name or a 1-based column index")
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<InputColumns, E> {
                usize::try_from(v)
                    .map(|p| InputColumns::one(ColumnRef::Position(p)))
                    .map_err(|_| E::invalid_value(de::Unexpected::Unsigned(v), &self))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<InputColumns, E> {
                u64::try_from(v)
                    .map_err(|_| E::invalid_value(de::Unexpected::Signed(v), &self))
                    .and_then(|v| self.visit_u64(v))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<InputColumns, E> {
                Ok(InputColumns::one(ColumnRef::Name(v.to_string())))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<InputColumns, A::Error> {
                let mut cols = Vec::new();
                while let Some(c) = seq.next_element::<ColumnRef>()? {
                    cols.push(c);
                }
                if cols.is_empty() {
                    return Err(de::Error::custom(
                        "an empty list, expected a column name or a 1-based column index, or a list of them",
                    ));
                }
                Ok(InputColumns::list(cols))
            }
        }
        d.deserialize_any(V)
    }
}

/// A range with the name of its field (`grid.nb[1]`).
pub type NamedRange = (String, [usize; 2]);

/// An inclusive range `[from, to]` of an order or a delay: one for every input, or a list of
/// them, one per input.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(untagged)]
pub enum Ranges {
    One([usize; 2]),
    PerInput(Vec<[usize; 2]>),
}

impl Ranges {
    /// The ranges of `m` inputs, each with its field name (`grid.nb` for one range of every
    /// input, `grid.nb[i]` in a list), or the error naming the field when a list's length is
    /// not `m`.
    pub fn per_input(&self, field: &str, m: usize) -> Result<Vec<NamedRange>, (String, String)> {
        match self {
            Ranges::One(r) => Ok(vec![(field.to_string(), *r); m]),
            Ranges::PerInput(v) => {
                check_count(field, "ranges", v.len(), m)?;
                Ok(v.iter().enumerate().map(|(i, r)| (format!("{field}[{i}]"), *r)).collect())
            }
        }
    }
}

/// What a list of one value per input must have: `m` values. `what` names the values in the
/// message (`ranges`, `delays`, `values`).
pub fn check_count(field: &str, what: &str, n: usize, m: usize) -> Result<(), (String, String)> {
    if n == m {
        return Ok(());
    }
    Err((
        field.to_string(),
        format!(
            "has {} for {}: give one for every input or a list of {m}, one per input",
            counted(n, what),
            counted(m, "inputs")
        ),
    ))
}

/// `1 range`, `2 ranges`: `n` of `plural`.
pub fn counted(n: usize, plural: &str) -> String {
    if n == 1 { format!("1 {}", plural.strip_suffix('s').unwrap_or(plural)) } else { format!("{n} {plural}") }
}

/// Which form a list of ranges took at its first element.
#[derive(Clone, Copy, PartialEq)]
enum Form {
    /// `[from, to]`: numbers.
    Number,
    /// `[[from, to], ...]`: ranges.
    Range,
}

/// An element of a [`Ranges`] list: a number of the one range or one input's range.
enum Item {
    Number(usize),
    Range([usize; 2]),
}

/// Reads an element of a [`Ranges`] list as `0` says (None: the first element, either form).
struct ItemSeed(Option<Form>);

impl<'de> DeserializeSeed<'de> for ItemSeed {
    type Value = Item;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Item, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for ItemSeed {
    type Value = Item;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(match self.0 {
            None => {
                "a whole number >= 0 (of one range [from, to] for every input) or a range [from, to] (one per input)"
            }
            Some(Form::Number) => "a whole number >= 0 (the other end of the range [from, to])",
            Some(Form::Range) => "a range [from, to] (one per input, as the list's first element)",
        })
    }
    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Item, E> {
        match (self.0, usize::try_from(v)) {
            (Some(Form::Range), _) => Err(E::invalid_type(de::Unexpected::Unsigned(v), &self)),
            (_, Ok(n)) => Ok(Item::Number(n)),
            (_, Err(_)) => Err(E::invalid_value(de::Unexpected::Unsigned(v), &self)),
        }
    }
    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Item, E> {
        match u64::try_from(v) {
            Ok(v) => self.visit_u64(v),
            Err(_) => Err(E::invalid_value(de::Unexpected::Signed(v), &self)),
        }
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Item, A::Error> {
        if self.0 == Some(Form::Number) {
            return Err(de::Error::invalid_type(de::Unexpected::Seq, &self));
        }
        let mut ends = Vec::with_capacity(2);
        while let Some(n) = seq.next_element::<usize>()? {
            ends.push(n);
            if ends.len() > 2 {
                break;
            }
        }
        match ends[..] {
            [a, b] => Ok(Item::Range([a, b])),
            _ => Err(de::Error::invalid_length(ends.len(), &"a range of two values [from, to]")),
        }
    }
}

impl<'de> Deserialize<'de> for Ranges {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Ranges;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(
                    "a list of two values [a, b] (one range for every input) or a list of ranges [[a, b], ...], one \
                     per input",
                )
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Ranges, A::Error> {
                let (mut numbers, mut ranges) = (Vec::new(), Vec::new());
                let mut form = None;
                while let Some(item) = seq.next_element_seed(ItemSeed(form))? {
                    match item {
                        Item::Number(n) => {
                            form = Some(Form::Number);
                            numbers.push(n);
                        }
                        Item::Range(r) => {
                            form = Some(Form::Range);
                            ranges.push(r);
                        }
                    }
                }
                match (form, &numbers[..]) {
                    (Some(Form::Range), _) => Ok(Ranges::PerInput(ranges)),
                    (Some(Form::Number), &[a, b]) => Ok(Ranges::One([a, b])),
                    (_, _) => Err(de::Error::invalid_length(numbers.len(), &self)),
                }
            }
        }
        d.deserialize_seq(V)
    }
}

/// The fixed `delay`: one for every input, or a list of them, one per input.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(untagged)]
pub enum Delays {
    One(usize),
    PerInput(Vec<usize>),
}

impl Delays {
    /// As the ranges `[d, d]` of `grid.delay`, in the same form.
    pub fn as_ranges(&self) -> Ranges {
        match self {
            Delays::One(d) => Ranges::One([*d, *d]),
            Delays::PerInput(v) => Ranges::PerInput(v.iter().map(|&d| [d, d]).collect()),
        }
    }
}

impl<'de> Deserialize<'de> for Delays {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Delays;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a whole number >= 0 (one delay for every input) or a list of them, one per input")
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Delays, E> {
                usize::try_from(v).map(Delays::One).map_err(|_| E::invalid_value(de::Unexpected::Unsigned(v), &self))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Delays, E> {
                u64::try_from(v)
                    .map_err(|_| E::invalid_value(de::Unexpected::Signed(v), &self))
                    .and_then(|v| self.visit_u64(v))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Delays, A::Error> {
                let mut v = Vec::new();
                while let Some(d) = seq.next_element::<usize>()? {
                    v.push(d);
                }
                if v.is_empty() {
                    return Err(de::Error::invalid_length(0, &self));
                }
                Ok(Delays::PerInput(v))
            }
        }
        d.deserialize_any(V)
    }
}

/// One input's grid: its nB, nF and delay values, in increasing order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputGrid {
    pub nb: Vec<usize>,
    pub nf: Vec<usize>,
    pub delays: Vec<usize>,
}

impl InputGrid {
    /// The structures of this input's grid: (nB, nF, delay) combinations.
    pub fn len(&self) -> usize {
        self.nb.len() * self.nf.len() * self.delays.len()
    }

    /// Never true for a checked job.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The orders of `oesweep fit` given as lists (`--nb 2,1 --nf 2,1 --delay 1,0`): one value for
/// every input or one per input, for `m` inputs. The list-length rule of the job's grid
/// ([`check_count`]), named by the flags (`--nb`, `--nf`, `--delay`); each order is checked as
/// the job's ([`super::check_order`]).
pub fn structure_of(
    m: usize,
    (nb, nf, delay): (&[usize], &[usize], &[usize]),
) -> Result<crate::oe::Structure, (String, String)> {
    if m > crate::oe::MAX_INPUTS {
        return Err((
            "--u".into(),
            format!("{m} input columns: at most {} inputs are supported", crate::oe::MAX_INPUTS),
        ));
    }
    let spread = |flag: &str, v: &[usize]| -> Result<Vec<usize>, (String, String)> {
        match v {
            [one] => Ok(vec![*one; m]),
            all => check_count(flag, "values", all.len(), m).map(|_| all.to_vec()),
        }
    };
    let (nb, nf, delay) = (spread("--nb", nb)?, spread("--nf", nf)?, spread("--delay", delay)?);
    let mut orders = Vec::with_capacity(m);
    for i in 0..m {
        let at = |flag: &str| if m == 1 { flag.to_string() } else { format!("{flag} (input {})", i + 1) };
        super::check_order(nb[i], 1).map_err(|e| (at("--nb"), e))?;
        super::check_order(nf[i], 0).map_err(|e| (at("--nf"), e))?;
        orders.push(crate::oe::Orders { nb: nb[i], nf: nf[i], delay: delay[i] });
    }
    Ok(crate::oe::Structure::new(&orders).expect("1 to MAX_INPUTS inputs"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_forms_read_and_write_back_as_given() {
        for text in ["[1, 3]", "[[1, 3], [2, 2]]", "[[0, 1]]"] {
            let r: Ranges = serde_json::from_str(text).unwrap();
            assert_eq!(serde_json::to_string(&r).unwrap(), text.replace(' ', ""));
        }
        assert_eq!(serde_json::from_str::<Ranges>("[[1, 3], [2, 2]]").unwrap(), Ranges::PerInput(vec![[1, 3], [2, 2]]));
        for bad in ["[]", "[1]", "[1, 2, 3]", "[1, [2, 2]]", "[[1, 2], 3]", "[[1, 2, 3]]", "7"] {
            assert!(serde_json::from_str::<Ranges>(bad).is_err(), "{bad}");
        }
        assert_eq!(serde_json::from_str::<Delays>("[1, 0]").unwrap(), Delays::PerInput(vec![1, 0]));
        assert_eq!(Delays::One(2).as_ranges(), Ranges::One([2, 2]));
        assert!(serde_json::from_str::<Delays>("[]").is_err());
        let cols: InputColumns = serde_json::from_str(r#"["fuel", 2]"#).unwrap();
        assert_eq!(cols.cols, vec![ColumnRef::name("fuel"), ColumnRef::Position(2)]);
        assert_eq!(serde_json::to_string(&cols).unwrap(), r#"["fuel",2]"#);
        assert_eq!(serde_json::to_string(&InputColumns::one(ColumnRef::Position(1))).unwrap(), "1");
        assert!(serde_json::from_str::<InputColumns>("[]").is_err());
    }

    #[test]
    fn fit_lists_spread_one_value_and_name_a_wrong_count() {
        let s = structure_of(2, (&[2, 1], &[2], &[1, 0])).unwrap();
        let o = |nb, nf, delay| crate::oe::Orders { nb, nf, delay };
        assert_eq!(s.inputs(), &[o(2, 2, 1), o(1, 2, 0)]);
        assert_eq!(structure_of(1, (&[3], &[2], &[1])).unwrap(), crate::oe::Structure::siso(3, 2, 1));
        let (f, m) = structure_of(3, (&[2, 1], &[1], &[1])).unwrap_err();
        assert_eq!(
            (f.as_str(), m.as_str()),
            ("--nb", "has 2 values for 3 inputs: give one for every input or a list of 3, one per input")
        );
        assert_eq!(structure_of(2, (&[1, 0], &[1], &[1])).unwrap_err().0, "--nb (input 2)");
    }
}
