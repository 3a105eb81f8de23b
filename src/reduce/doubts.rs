//! Warnings that say when a pick is doubtful (METHOD.md 7.2), for the lead rule's and the
//! paper's picks: a pick on the grid's edge (the
//! largest nB or nF searched, or an edge delay: the data may want a model the grid did not
//! offer) and picks on the stability boundary (a pole at radius >= 0.999: the plant looks
//! integrating or unstable, and an output-error model forces a stable one onto it). The
//! spectral sign of an integrating plant is a property of the data and is found where the
//! records are read ([`crate::job::read_inputs`]).

use super::{Rule, Selection};
use crate::estimate::least_squares::BOUNDARY;
use std::collections::BTreeMap;

/// The searched ranges, inclusive: (smallest, largest).
#[derive(Clone, Copy, Debug)]
pub struct GridBounds {
    pub nb: (u32, u32),
    pub nf: (u32, u32),
    pub delay: (u32, u32),
}

/// The warnings about the picks of the lead rule and the paper's two rules, one per model,
/// naming the rules that picked it. (The other rules are reported, not led with: AIC-type
/// rules over-fit and would put a warning about the grid's largest model on most runs.)
pub fn pick_warnings(sel: &Selection, grid: &GridBounds) -> Vec<String> {
    // model (delay, nb, nf) -> (rules, max pole radius)
    let mut models: BTreeMap<(u32, u32, u32), (Vec<Rule>, f64)> = BTreeMap::new();
    let watched = |r: &Rule| *r == sel.rule || matches!(r, Rule::PaperM1 | Rule::PaperM2);
    for (rule, pick) in sel.picks.iter().filter(|(r, _)| watched(r)) {
        if let Some(m) = &pick.model {
            let e = models.entry((m.key.delay, m.key.nb, m.key.nf)).or_insert((Vec::new(), 0.0));
            e.0.push(*rule);
            e.1 = e.1.max(m.fit.max_pole_radius.unwrap_or(0.0));
        }
    }
    let mut out = Vec::new();
    for ((delay, nb, nf), (rules, radius)) in models {
        let names = rules.iter().map(|r| r.as_str()).collect::<Vec<_>>().join(", ");
        let model = format!("OE({nb},{nf}) delay {delay} (picked by {names})");
        let mut edges = Vec::new();
        if nb == grid.nb.1 && grid.nb.0 < grid.nb.1 {
            edges.push("the largest nB");
        }
        if nf == grid.nf.1 && grid.nf.0 < grid.nf.1 {
            edges.push("the largest nF");
        }
        if grid.delay.0 < grid.delay.1 && (delay == grid.delay.1 || (delay == grid.delay.0 && delay > 0)) {
            edges.push("an edge delay");
        }
        if !edges.is_empty() {
            out.push(format!(
                "{model} has {} of the grid: the data may want a model the grid did not offer; widen the grid",
                edges.join(" and ")
            ));
        }
        if radius >= BOUNDARY {
            out.push(format!(
                "{model} has a pole at radius {radius:.4}, on the stability boundary: the plant looks integrating \
                 or unstable, and an output-error model forces a stable model onto it (identify from the \
                 differenced output, or in closed loop)"
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reduce::{FitBasis, ReduceOptions, select};
    use crate::table::{CellRow, FitKind, RowKey, Status};

    fn row(nb: u32, nf: u32, fit: f64, radius: f64) -> CellRow {
        let key = RowKey { kind: FitKind::Huber, delay: 1, nb, nf, k_index: Some(0) };
        let mut r = CellRow::failed(key, Some(0.5), String::new());
        r.status = Status::Ok;
        r.reason = None;
        (r.fit.sigma, r.fit.gamma, r.fit.criterion, r.fit.l1c) = (Some(1.0), Some(0.5), Some(1.0), Some(0.1));
        (r.fit.fit, r.fit.fit_val, r.fit.max_pole_radius) = (Some(fit), Some(fit), Some(radius));
        r
    }

    #[test]
    fn a_pick_on_the_edge_or_the_boundary_is_named_once_with_its_rules() {
        let grid = GridBounds { nb: (1, 3), nf: (1, 3), delay: (1, 1) };
        let rows = vec![row(2, 2, 80.0, 0.5), row(3, 3, 95.0, 0.9995)];
        let sel = select(&rows, &ReduceOptions::new(FitBasis::Validation));
        let w = pick_warnings(&sel, &grid);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(w[0].contains("OE(3,3)") && w[0].contains("the largest nB and the largest nF"), "{}", w[0]);
        assert!(w[0].contains("paper_m1, paper_m2"), "{}", w[0]);
        assert!(w[1].contains("stability boundary"), "{}", w[1]);
        // Inside the grid and well inside the unit circle: nothing to say.
        let rows = vec![row(2, 2, 95.0, 0.5), row(3, 3, 80.0, 0.5)];
        let sel = select(&rows, &ReduceOptions::new(FitBasis::Validation));
        assert!(pick_warnings(&sel, &grid).is_empty());
        // A grid of one nB has no edge in nB.
        let one = GridBounds { nb: (3, 3), nf: (1, 4), delay: (0, 2) };
        assert!(
            pick_warnings(&select(&[row(3, 3, 95.0, 0.5)], &ReduceOptions::new(FitBasis::Validation)), &one).is_empty()
        );
    }
}
