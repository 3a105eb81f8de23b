//! What the report draws differently for a model of several inputs (issue 46): the grid seen one
//! input at a time, each input's coefficients, and a table row's output on a record of several
//! inputs.
//!
//! The grid of several inputs is a product of the inputs' order grids, too many dimensions for
//! one picture. The report draws it one input at a time: the rows whose other inputs have the
//! lead pick's orders (and input i the lead pick's delay), keyed as one input's (nB_i, nF_i)
//! rows, so the one-input heat maps and W/L1C curves draw them unchanged. That slice holds the
//! lead pick; another pick is outlined on it only where it lies on it. How the picks move with
//! k is one figure per input: the rules applied to every row of each k (the whole grid, not the
//! slice), that input's orders drawn.

use super::figures::{self, Picked};
use super::html::{Section, esc};
use super::{Review, figure};
use crate::data::Record;
use crate::error::Result;
use crate::estimate::InitialState;
use crate::estimate::initial_state;
use crate::oe::{self, Structure};
use crate::reduce::{Candidate, Curve};
use crate::table::{CellRow, RowKey};

/// The rows of input `i`'s slice through `lead` (module docs), keyed as one input's rows.
pub(super) fn slice(rows: &[CellRow], lead: &RowKey, i: usize) -> Vec<CellRow> {
    rows.iter().filter_map(|r| on_slice(r, lead, i)).collect()
}

/// `r` keyed as input `i`'s one-input row, when it lies on input `i`'s slice through `lead`.
fn on_slice(r: &CellRow, lead: &RowKey, i: usize) -> Option<CellRow> {
    let (mine, theirs) = (r.key.structure(), lead.structure());
    if mine.m() != theirs.m() {
        return None;
    }
    let same = mine
        .inputs()
        .iter()
        .zip(theirs.inputs())
        .enumerate()
        .all(|(j, (a, b))| if j == i { a.delay == b.delay } else { a == b });
    let o = mine.inputs()[i];
    same.then(|| CellRow {
        key: RowKey::siso(r.key.kind, o.nb as u32, o.nf as u32, o.delay as u32, r.key.k_index),
        ..r.clone()
    })
}

/// A pick on input `i`'s slice through `lead`, keyed as one input's (None: it is not on it).
fn candidate_on_slice(c: &Candidate, lead: &RowKey, i: usize) -> Option<Candidate> {
    on_slice(&c.row, lead, i).map(|row| Candidate { row, score: c.score })
}

/// Input `i`'s block of a covariance over theta `[b_1, f_1, ..., b_m, f_m]` (+ an offset):
/// the rows and columns of its b_i and f_i (None when the covariance does not fit `s`).
pub(super) fn input_block(cov: &[f64], s: &Structure, i: usize) -> Option<Vec<f64>> {
    let n = (cov.len() as f64).sqrt().round() as usize;
    if n * n != cov.len() || n < s.dim() {
        return None;
    }
    let range = s.b_range(i).start..s.f_range(i).end;
    Some(range.clone().flat_map(|r| range.clone().map(move |c| cov[r * n + c])).collect())
}

/// A table row's output on a record of several inputs, in the data's units: the sum of each
/// input's `q^-d_i B_i/F_i (u_i - u0_i)` and the offset, from zero initial conditions, plus the
/// fitted free response with [`InitialState::Estimate`] (each experiment on its own, as the
/// sweep judges the fits).
pub(super) fn output_of_row(r: &CellRow, rec: &Record, u0s: &[f64], is: InitialState) -> Vec<f64> {
    let s = r.key.structure();
    let (b, f) = (s.split_b(&r.fit.b), s.split_f(&r.fit.f));
    let mut out = Vec::with_capacity(rec.len());
    for e in rec.experiments() {
        let mut yhat = vec![r.fit.offset.unwrap_or(0.0); e.len()];
        for (i, o) in s.inputs().iter().enumerate() {
            let u0 = u0s.get(i).copied().unwrap_or(0.0);
            let centred: Vec<f64> = rec.input(i)[e.clone()].iter().map(|v| v - u0).collect();
            let part = oe::simulate_vec(&b[i], &f[i], o.delay, &centred);
            yhat.iter_mut().zip(&part).for_each(|(a, p)| *a += p);
        }
        if is == InitialState::Estimate {
            let theta = crate::estimate::theta_in(&s, &r.fit.b, &r.fit.f, None);
            let (common, past) = initial_state::common_denominator(&s, &theta);
            initial_state::add_free_response(&common, past + 1, 0, &rec.y[e.clone()], &mut yhat);
        }
        out.extend(yhat);
    }
    out
}

/// Per input's orders: the W and L1C curves over nF_i and the heat maps over (nB_i, nF_i) on
/// the input's slice through the lead pick (module docs).
pub(super) fn grid_section(
    s: &Review,
    lead: Option<Picked>,
    m1: Option<Picked>,
    m2: Option<Picked>,
) -> Result<Section> {
    let sel = &s.selection;
    let mut figs = Vec::new();
    let mut notes = Vec::new();
    let Some(lead) = lead else {
        notes.push("No pick: no slice of the grid to draw.".into());
        return Ok(section(String::new(), figs, notes));
    };
    let lead_key = lead.model.key;
    for i in 0..s.job.m {
        let rows = slice(&s.rows, &lead_key, i);
        let projected: Vec<(Picked, Candidate)> = [Some(lead), m1, m2]
            .into_iter()
            .flatten()
            .filter_map(|p| candidate_on_slice(p.model, &lead_key, i).map(|c| (p, c)))
            .collect();
        let on_slice = |name: &str| projected.iter().find(|(p, _)| p.name == name);
        let picked = |name: &str| on_slice(name).map(|(p, c)| Picked { name: p.name, model: c, colour: p.colour });
        let scope = format!(", input {} (the other inputs at the {} pick's orders)", s.input_name(i), lead.name);
        let u = i + 1;
        for (curve, pick, file) in [
            (Curve::W, picked("M1").or(picked(lead.name)), format!("report-w-nf-u{u}.svg")),
            (Curve::L1c, picked("M2").or(picked(lead.name)), format!("report-l1c-nf-u{u}.svg")),
        ] {
            let ki = pick.map_or(lead.model.k_index(), |p| p.model.k_index());
            let drawn = figures::curve_figure(&rows, curve, (ki, s.k_of(ki)), sel.min_tolerance, pick, &scope, &file);
            figs.push(figure(&s.folder, &file, drawn)?);
        }
        let ki = lead.model.k_index();
        // Each pick once (the lead is M1 or M2 when those rules lead).
        let mut outlined: Vec<Picked> = Vec::new();
        for name in ["M1", "M2", lead.name] {
            if let Some(p) = picked(name).filter(|p| !outlined.iter().any(|q| q.name == p.name)) {
                outlined.push(p);
            }
        }
        let file = format!("report-heat-u{u}.svg");
        let drawn = figures::heat_figure(&rows, ki, s.k_of(ki), sel.basis, &outlined, &scope, &file);
        figs.push(figure(&s.folder, &file, drawn)?);
        // The rules on every row of each k (not the slice): the picks as the whole grid gives
        // them, input i's orders drawn.
        let file = format!("report-picks-k-u{u}.svg");
        let name = s.input_name(i);
        let drawn = figures::picks_by_k_figure(&s.rows, &s.job.ks, sel, Some((i, &name)), &file);
        figs.push(figure(&s.folder, &file, drawn)?);
    }
    let intro = format!(
        "<p>A grid of {} inputs is the product of the inputs' order grids. Each input's figures show its \
         slice through the {} pick ({}): the other inputs held at that pick's orders, this input's nB and nF \
         varied at its delay, at the pick's k. A pick is outlined where it lies on the slice. How the picks move \
         with k is drawn per input too: the pick rules applied to every row of each k alone, that input's \
         orders.</p>\n",
        s.job.m,
        lead.name,
        esc(&lead.label())
    );
    Ok(section(intro, figs, notes))
}

fn section(intro_html: String, figures: Vec<figures::Figure>, notes: Vec<String>) -> Section {
    Section { id: "maps", heading: "The grid, one input at a time".into(), intro_html, figures, notes }
}

/// The picks' coefficients, one table per input (b_i, f_i with their standard deviations).
pub(super) fn parameter_tables(s: &Review, title: &str, m: &Candidate) -> String {
    let structure = m.key.structure();
    let (b, f) = (structure.split_b(&m.fit.b), structure.split_f(&m.fit.f));
    let (b_std, f_std) = (structure.split_b(&m.evidence.b_std), structure.split_f(&m.evidence.f_std));
    let mut h = String::new();
    for (i, o) in structure.inputs().iter().enumerate() {
        let head = format!("{title}, input {}: OE({},{}), d = {}", s.input_name(i), o.nb, o.nf, o.delay);
        h.push_str(&super::html::parameter_table(&head, (&b[i], &b_std[i]), (&f[i], &f_std[i])));
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::Orders;
    use crate::table::FitKind;

    fn row(orders: &[(usize, usize, usize)], k: Option<u32>) -> CellRow {
        let o: Vec<Orders> = orders.iter().map(|&(nb, nf, delay)| Orders { nb, nf, delay }).collect();
        let kind = if k.is_some() { FitKind::Huber } else { FitKind::Ls };
        CellRow::empty(RowKey::new(kind, &Structure::new(&o).unwrap(), k))
    }

    #[test]
    fn a_slice_holds_the_rows_whose_other_inputs_are_the_leads() {
        let lead = row(&[(2, 1, 1), (1, 1, 0)], Some(0)).key;
        let rows = vec![
            row(&[(1, 1, 1), (1, 1, 0)], Some(0)),
            row(&[(2, 2, 1), (1, 1, 0)], Some(1)),
            row(&[(2, 1, 1), (1, 2, 0)], Some(0)),
            row(&[(2, 1, 0), (1, 1, 0)], Some(0)),
        ];
        let first: Vec<(u32, u32, Option<u32>)> =
            slice(&rows, &lead, 0).iter().map(|r| (r.key.nb, r.key.nf, r.key.k_index)).collect();
        assert_eq!(first, vec![(1, 1, Some(0)), (2, 2, Some(1))], "input 1 varies at its delay; input 2 held");
        let second: Vec<(u32, u32)> = slice(&rows, &lead, 1).iter().map(|r| (r.key.nb, r.key.nf)).collect();
        assert_eq!(second, vec![(1, 2)]);
        assert!(slice(&rows, &lead, 1).iter().all(|r| r.key.m() == 1 && r.key.delay == 0));
    }

    #[test]
    fn an_inputs_block_of_the_covariance_is_its_b_and_f() {
        let s = Structure::new(&[Orders { nb: 1, nf: 1, delay: 0 }, Orders { nb: 1, nf: 0, delay: 0 }]).unwrap();
        // theta = [b_1, f_1, b_2, c]: 4 x 4 with entry (r, c) = 10 r + c.
        let cov: Vec<f64> = (0..16).map(|x| (10 * (x / 4) + x % 4) as f64).collect();
        assert_eq!(input_block(&cov, &s, 0).unwrap(), vec![0.0, 1.0, 10.0, 11.0]);
        assert_eq!(input_block(&cov, &s, 1).unwrap(), vec![22.0]);
        assert!(input_block(&cov[..4], &s, 0).is_none());
    }
}
