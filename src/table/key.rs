//! Which fit of which cell a row holds: [`RowKey`], for any number of inputs.
//!
//! A key keeps the first input's orders in `nb`, `nf`, `delay` (for one input: the only
//! input's, as the table has always named them) and the other inputs' in `more`, so a
//! one-input key is what it always was. The sort order is the row order of `cells.parquet`:
//! fit kind (`ls` first), then each input's (delay, nB, nF) in the job's order of the inputs,
//! then the k index; for one input (kind, delay, nB, nF, k index) exactly as before.

use super::FitKind;
use crate::oe::{MAX_INPUTS, Orders, Structure};
use serde::{Deserialize, Serialize};
use std::cmp::Ordering;

/// The orders of inputs 2..m of a row's structure (none for one input).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct More {
    n: u8,
    orders: [Orders; MAX_INPUTS - 1],
}

impl More {
    pub fn inputs(&self) -> &[Orders] {
        &self.orders[..self.n as usize]
    }
}

/// Input by input, (delay, nB, nF): the table's order of structures.
fn order_key(o: &Orders) -> (usize, usize, usize) {
    (o.delay, o.nb, o.nf)
}

impl Ord for More {
    fn cmp(&self, other: &Self) -> Ordering {
        self.inputs().iter().map(order_key).cmp(other.inputs().iter().map(order_key))
    }
}

impl PartialOrd for More {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Identity of a row in a table. A complete table has exactly one row per key of its plan.
/// The derived order (fit kind with `ls` first, then delay, nB, nF of the first input, then
/// the other inputs' (delay, nB, nF), then the k index) is the row order of `cells.parquet`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct RowKey {
    pub kind: FitKind,
    /// The first input's orders (the only input's for a single-input model).
    pub delay: u32,
    pub nb: u32,
    pub nf: u32,
    /// The orders of inputs 2..m ([`RowKey::structure`] has them all).
    pub more: More,
    /// Index of k in the job's k grid (None for `ls` rows).
    pub k_index: Option<u32>,
}

impl RowKey {
    /// The key of a fit of `kind` of `structure` (at k index `k_index` for a Huber row).
    pub fn new(kind: FitKind, structure: &Structure, k_index: Option<u32>) -> Self {
        let inputs = structure.inputs();
        let first = inputs[0];
        let mut orders = [Orders::default(); MAX_INPUTS - 1];
        orders[..inputs.len() - 1].copy_from_slice(&inputs[1..]);
        let more = More { n: (inputs.len() - 1) as u8, orders };
        RowKey { kind, delay: first.delay as u32, nb: first.nb as u32, nf: first.nf as u32, more, k_index }
    }

    /// A single-input key (nB, nF, delay).
    pub fn siso(kind: FitKind, nb: u32, nf: u32, delay: u32, k_index: Option<u32>) -> Self {
        RowKey::new(kind, &Structure::siso(nb as usize, nf as usize, delay as usize), k_index)
    }

    /// Key of the Huber row of cell (pair, k_index).
    pub fn huber(pair: &Structure, k_index: usize) -> Self {
        RowKey::new(FitKind::Huber, pair, Some(k_index as u32))
    }

    /// Key of the least-squares row of a pair.
    pub fn ls(pair: &Structure) -> Self {
        RowKey::new(FitKind::Ls, pair, None)
    }

    /// A key of `m` inputs with every order 0 (the base a reader fills in).
    pub fn blank(kind: FitKind, m: usize) -> Self {
        let o = Orders::default();
        RowKey::new(kind, &Structure::new(&vec![o; m.clamp(1, MAX_INPUTS)]).expect("1..=MAX_INPUTS inputs"), None)
    }

    /// Number of inputs m.
    pub fn m(&self) -> usize {
        1 + self.more.n as usize
    }

    /// The structure (every input's orders) of the row.
    pub fn structure(&self) -> Structure {
        let first = Orders { nb: self.nb as usize, nf: self.nf as usize, delay: self.delay as usize };
        let mut all = vec![first];
        all.extend_from_slice(self.more.inputs());
        Structure::new(&all).expect("1..=MAX_INPUTS inputs")
    }

    /// The same key with input `i`'s orders replaced.
    pub fn with(&self, i: usize, o: Orders) -> Self {
        RowKey::new(self.kind, &self.structure().with(i, o), self.k_index)
    }

    /// Per input, (delay, nB, nF): a key of the structure that sorts as the table does.
    pub fn orders(&self) -> Vec<(u32, u32, u32)> {
        self.structure().inputs().iter().map(|o| (o.delay as u32, o.nb as u32, o.nf as u32)).collect()
    }

    /// `OE(nB,nF)` for one input (as messages have named a model), the structure's
    /// [`Structure::label`] for several (which holds the delays).
    pub fn short_label(&self) -> String {
        if self.m() == 1 { format!("OE({},{})", self.nb, self.nf) } else { self.structure().label() }
    }

    /// `OE(nB,nF) delay d` for one input, the structure's [`Structure::label`] for several.
    pub fn label(&self) -> String {
        self.structure().label()
    }

    /// Total number of nF over the inputs (the tie-break's "smaller nF").
    pub fn nf_total(&self) -> u32 {
        self.structure().inputs().iter().map(|o| o.nf as u32).sum()
    }
}

/// As messages name a row: `huber nb=3 nf=4 k_index=Some(0)` (several inputs: the structure's
/// label in place of nb and nf).
impl std::fmt::Display for RowKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.m() == 1 {
            write!(f, "{} nb={} nf={} k_index={:?}", self.kind.as_str(), self.nb, self.nf, self.k_index)
        } else {
            write!(f, "{} {} k_index={:?}", self.kind.as_str(), self.label(), self.k_index)
        }
    }
}

/// An order of every input as `selection.json` writes it: a number for one input, a list
/// (one entry per input) for several.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PerInput {
    One(u32),
    Several(Vec<u32>),
}

impl PerInput {
    pub fn of(key: &RowKey, field: impl Fn(&Orders) -> usize) -> Self {
        let s = key.structure();
        match s.single() {
            Some(o) => PerInput::One(field(&o) as u32),
            None => PerInput::Several(s.inputs().iter().map(|o| field(o) as u32).collect()),
        }
    }
}

impl std::fmt::Display for PerInput {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PerInput::One(v) => write!(f, "{v}"),
            PerInput::Several(v) => {
                let parts: Vec<String> = v.iter().map(u32::to_string).collect();
                write!(f, "[{}]", parts.join(", "))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_input_keys_sort_by_kind_delay_nb_nf_k() {
        let k = |kind, nb, nf, d, ki| RowKey::siso(kind, nb, nf, d, ki);
        let mut keys = [
            k(FitKind::Huber, 1, 1, 1, Some(0)),
            k(FitKind::Huber, 1, 2, 0, Some(1)),
            k(FitKind::Huber, 1, 2, 0, Some(0)),
            k(FitKind::Ls, 3, 3, 2, None),
            k(FitKind::Huber, 2, 1, 0, Some(0)),
        ];
        keys.sort();
        let got: Vec<_> = keys.iter().map(|k| (k.kind, k.delay, k.nb, k.nf, k.k_index)).collect();
        assert_eq!(
            got,
            vec![
                (FitKind::Ls, 2, 3, 3, None),
                (FitKind::Huber, 0, 1, 2, Some(0)),
                (FitKind::Huber, 0, 1, 2, Some(1)),
                (FitKind::Huber, 0, 2, 1, Some(0)),
                (FitKind::Huber, 1, 1, 1, Some(0)),
            ]
        );
    }

    #[test]
    fn several_input_keys_roundtrip_their_structure() {
        let o = |nb, nf, delay| Orders { nb, nf, delay };
        let s = Structure::new(&[o(2, 1, 0), o(1, 3, 2)]).unwrap();
        let key = RowKey::huber(&s, 3);
        assert_eq!((key.structure(), key.m(), key.k_index), (s, 2, Some(3)));
        assert_eq!(key.orders(), vec![(0, 2, 1), (2, 1, 3)]);
        assert_eq!(key.to_string(), "huber OE(2,1 d0; 1,3 d2) k_index=Some(3)");
        assert!(RowKey::huber(&s.with(1, o(1, 3, 1)), 9) < key);
    }
}
