//! Rules 2-4 for any number of inputs: the local minima of W and L1C over nF.
//!
//! For one input a curve is the rows of one (delay, nB, k index) sorted by nF
//! ([`super::curves`]). For m inputs a row lies on m lines, one per input i: the rows of the
//! same k index and the same orders but input i's nF, sorted by nF_i. A row is a local minimum
//! when it is one on every line through it (the neighbours on a line are the adjacent nF_i
//! present, as on a curve); for one input its one line is its curve, so the minima are the
//! curves' minima. A repeated cell keeps its lower criterion (the first of equal ones).

use super::{Curve, local_minima, takes_part};
use crate::oe::Orders;
use crate::table::{CellRow, RowKey};
use std::collections::{BTreeMap, HashMap};

/// The rows that take part, one per key (the lower W of a repeated cell), in key order.
fn unique(rows: &[CellRow]) -> BTreeMap<RowKey, &CellRow> {
    let mut out: BTreeMap<RowKey, &CellRow> = BTreeMap::new();
    for r in rows.iter().filter(|r| takes_part(r)) {
        let kept = out.entry(r.key).or_insert(r);
        if Curve::W.value(r) < Curve::W.value(kept) {
            *kept = r;
        }
    }
    out
}

/// The local minima of curve `kind` (rules 2-4) with tolerance `min_tolerance`, in key order.
pub(super) fn minima(rows: &[CellRow], kind: Curve, min_tolerance: f64) -> Vec<&CellRow> {
    let rows = unique(rows);
    let m = rows.keys().next().map_or(1, RowKey::m);
    let mut lines_passed: HashMap<RowKey, usize> = HashMap::new();
    for i in 0..m {
        // The line of a row: its key with input i's nF set to 0.
        let mut lines: BTreeMap<RowKey, Vec<&CellRow>> = BTreeMap::new();
        for (key, r) in &rows {
            let o = key.structure().inputs()[i];
            lines.entry(key.with(i, Orders { nf: 0, ..o })).or_default().push(r);
        }
        for line in lines.values_mut() {
            line.sort_by_key(|r| r.key.structure().inputs()[i].nf);
            let values: Vec<f64> = line.iter().map(|r| kind.value(r)).collect();
            for j in local_minima(&values, kind.tolerance(min_tolerance)) {
                *lines_passed.entry(line[j].key).or_default() += 1;
            }
        }
    }
    rows.into_iter().filter(|(key, _)| lines_passed.get(key) == Some(&m)).map(|(_, r)| r).collect()
}

/// Key of a curve: (delay, nB, k index).
pub type CurveKey = (u32, u32, Option<u32>);

/// Rules 1-2: the curves over nF, one per (delay, nB, k index), of the rows that take part,
/// sorted by nF; a repeated cell keeps its lower criterion. A BTreeMap, so the result does not
/// depend on the order of the rows.
pub fn curves(rows: &[CellRow]) -> BTreeMap<CurveKey, Vec<&CellRow>> {
    let mut curves: BTreeMap<CurveKey, Vec<&CellRow>> = BTreeMap::new();
    for r in rows.iter().filter(|r| takes_part(r)) {
        curves.entry((r.key.delay, r.key.nb, r.key.k_index)).or_default().push(r);
    }
    for curve in curves.values_mut() {
        // Sort by nF, duplicates by criterion, so dedup keeps the better fit of a repeated cell.
        curve.sort_by(|a, b| a.key.nf.cmp(&b.key.nf).then(Curve::W.value(a).total_cmp(&Curve::W.value(b))));
        curve.dedup_by_key(|r| r.key.nf);
    }
    curves
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::Structure;
    use crate::table::Status;

    /// An ok Huber row of two inputs (nF_1, nF_2), nB 1 and delay 0 each, with W = `w`.
    fn row(nf1: usize, nf2: usize, w: f64) -> CellRow {
        let o = |nf| Orders { nb: 1, nf, delay: 0 };
        let s = Structure::new(&[o(nf1), o(nf2)]).unwrap();
        let mut r = CellRow::failed(RowKey::huber(&s, 0), Some(1.0), String::new());
        (r.status, r.reason) = (Status::Ok, None);
        (r.fit.gamma, r.fit.criterion, r.fit.l1c) = (Some(0.1), Some(w), Some(0.1));
        r
    }

    #[test]
    fn a_minimum_of_several_inputs_is_one_on_every_inputs_line() {
        // W over (nF_1, nF_2) in 1..3: the minimum of each row of nF_1 is at nF_2 = 2, but only
        // (2, 2) is also the minimum of its column; (1, 3) is one on no line.
        let w = [[5.0, 4.0, 4.5], [3.0, 2.0, 2.5], [3.5, 2.8, 2.9]];
        let rows: Vec<CellRow> =
            (0..3).flat_map(|i| (0..3).map(move |j| (i, j))).map(|(i, j)| row(i + 1, j + 1, w[i][j])).collect();
        let got: Vec<(u32, u32)> =
            minima(&rows, Curve::W, 1e-3).iter().map(|r| (r.key.nf, r.key.more.inputs()[0].nf as u32)).collect();
        assert_eq!(got, vec![(2, 2)]);
        // One input: the curve's minima, as before.
        let one: Vec<CellRow> = [3.0, 2.0, 2.5, 1.0]
            .iter()
            .enumerate()
            .map(|(i, &w)| {
                let mut r = row(1, 1, w);
                r.key = RowKey::huber(&Structure::siso(1, i + 1, 0), 0);
                r
            })
            .collect();
        let got: Vec<u32> = minima(&one, Curve::W, 1e-3).iter().map(|r| r.key.nf).collect();
        assert_eq!(got, vec![2, 4]);
    }
}
