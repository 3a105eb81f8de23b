//! Warnings that say when a pick is doubtful (METHOD.md 7.2), for the lead rule's and the
//! paper's picks: a pick on the grid's edge (the largest nB or nF searched, or an edge delay)
//! and picks on the stability boundary (a pole at radius >= 0.999: the plant looks integrating
//! or unstable, and an output-error model forces a stable one onto it). The record's
//! integrating-plant test runs where the records are read ([`crate::job::read_inputs`]) and is
//! judged against these picks' residuals after the sweep (`engine::uncertainty`, METHOD.md 7.3).
//!
//! An edge pick says "widen the grid" only where the evidence says the data want more: the
//! size-penalising rule (`rbic`) picks on the edge too and the model just beyond that edge,
//! fitted from its pick ([`Beyond`]), has a lower RBIC still; or no model off the edges has
//! residuals independent of the input. Otherwise the edge pick is named as what it most likely
//! is: a rule whose basis grows with the orders (the estimation fit) picking the largest model,
//! or RBIC's minimum that happens to lie on the edge; widening the grid would not help.

use super::rules::INDEPENDENCE_LEVEL;
use super::{FitBasis, Rule, Selection, takes_part};
use crate::estimate::least_squares::BOUNDARY;
use crate::oe::Structure;
use crate::table::{CellRow, FitKind, RowKey};
use std::collections::BTreeMap;

/// The searched ranges, inclusive: (smallest, largest); of every input, or of one input
/// ([`pick_warnings_per_input`]).
#[derive(Clone, Copy, Debug)]
pub struct GridBounds {
    pub nb: (u32, u32),
    pub nf: (u32, u32),
    pub delay: (u32, u32),
}

/// The searched ranges of every input: one [`GridBounds`] for all inputs, or one per input.
#[derive(Clone, Copy, Debug)]
struct Grid<'a>(&'a [GridBounds]);

impl Grid<'_> {
    /// The edges of the grid a model sits on, as words; for several inputs per input, naming
    /// it: "input 2's largest nF".
    fn edges(&self, key: &RowKey) -> Vec<String> {
        let orders = key.orders();
        let mut edges = Vec::new();
        for (i, &(delay, nb, nf)) in orders.iter().enumerate() {
            let g = if self.0.len() == 1 { self.0.first() } else { self.0.get(i) };
            let Some(g) = g else { continue };
            let whose = if orders.len() == 1 { "the".to_string() } else { format!("input {}'s", i + 1) };
            if nb == g.nb.1 && g.nb.0 < g.nb.1 {
                edges.push(format!("{whose} largest nB"));
            }
            if nf == g.nf.1 && g.nf.0 < g.nf.1 {
                edges.push(format!("{whose} largest nF"));
            }
            if g.delay.0 < g.delay.1 && (delay == g.delay.1 || (delay == g.delay.0 && delay > 0)) {
                edges.push(if orders.len() == 1 { "an edge delay".into() } else { format!("{whose} edge delay") });
            }
        }
        edges
    }
}

/// A model one step beyond the grid's edge, fitted warm from RBIC's pick on that edge
/// (`engine::beyond`), with its RBIC.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beyond {
    pub structure: Structure,
    pub rbic: f64,
}

/// What the table (and the look beyond the edge) says about a larger model.
enum Evidence {
    /// The data want more, and why.
    More(String),
    /// RBIC picks on the edge, but the models just beyond it have a higher RBIC: why not.
    Enough(String),
    None,
}

/// Whether the data want a larger model than the grid offers: RBIC picks on the edge and a
/// model just beyond it has a lower RBIC still (or nothing beyond it was fitted), or no model
/// off the edges is independent of the input.
fn wants_more(sel: &Selection, rows: &[CellRow], grid: Grid, beyond: &[Beyond]) -> Evidence {
    let rbic = sel.picks.get(&Rule::Rbic).and_then(|p| p.model.as_ref().map(|m| (m, p.value)));
    if let Some((m, Some(v))) = rbic.filter(|(m, _)| !grid.edges(&m.key).is_empty()) {
        let pick = m.key.label();
        let listed = |bs: &[&Beyond]| {
            bs.iter().map(|b| format!("{} ({:+.1})", b.structure.label(), b.rbic - v)).collect::<Vec<_>>().join(", ")
        };
        let lower: Vec<&Beyond> = beyond.iter().filter(|b| b.rbic < v).collect();
        return if !lower.is_empty() {
            Evidence::More(format!(
                "rbic picks {pick} on the edge too, and beyond the edge {} has a lower RBIC still",
                listed(&lower)
            ))
        } else if beyond.is_empty() {
            Evidence::More(format!("rbic picks {pick} on the edge too (the models beyond it were not fitted)"))
        } else {
            Evidence::Enough(format!(
                "rbic picks {pick} on the edge too, but one step beyond it {} has a higher RBIC: {pick} is \
                 RBIC's minimum in that direction",
                listed(&beyond.iter().collect::<Vec<_>>())
            ))
        };
    }
    let (tested, independent) = independent_inside(rows, grid);
    if tested > 0 && independent == 0 {
        return Evidence::More(format!(
            "none of the {tested} models off the edges has residuals independent of the input at {} %",
            INDEPENDENCE_LEVEL * 100.0
        ));
    }
    Evidence::None
}

/// The Huber models off the grid's edges: how many have an independence test, and how many
/// pass it.
fn independent_inside(rows: &[CellRow], grid: Grid) -> (usize, usize) {
    let inside = rows.iter().filter(|r| takes_part(r) && grid.edges(&r.key).is_empty());
    inside.fold((0, 0), |(tested, passed), r| match r.evidence.resid_indep_p {
        Some(p) => (tested + 1, passed + usize::from(p >= INDEPENDENCE_LEVEL)),
        None => (tested, passed),
    })
}

/// Does a rule rank by a measure that grows with the orders on this selection?
fn grows_with_orders(rule: Rule, basis: FitBasis) -> bool {
    match rule {
        Rule::PaperM1 | Rule::PaperM2 | Rule::Validation | Rule::Evidence => basis != FitBasis::Validation,
        Rule::Aic | Rule::Aicc | Rule::Fpe | Rule::Raic => true,
        Rule::Bic | Rule::Rbic => false,
    }
}

/// The warnings about the picks of the lead rule and the paper's two rules, one per model,
/// naming the rules that picked it. (The other rules are reported, not led with: AIC-type
/// rules over-fit and would put a warning about the grid's largest model on most runs.)
///
/// `beyond`: the models just beyond the edge RBIC's pick sits on, fitted from it
/// (`engine::beyond`; empty when the records could not be read).
pub fn pick_warnings(sel: &Selection, rows: &[CellRow], grid: &GridBounds, beyond: &[Beyond]) -> Vec<String> {
    pick_warnings_per_input(sel, rows, std::slice::from_ref(grid), beyond)
}

/// [`pick_warnings`] with one [`GridBounds`] per input (a job whose inputs have grids of
/// their own), or one for every input.
pub fn pick_warnings_per_input(
    sel: &Selection,
    rows: &[CellRow],
    grids: &[GridBounds],
    beyond: &[Beyond],
) -> Vec<String> {
    let grid = Grid(grids);
    // model (its structure as a key: by input (delay, nb, nf)) -> (rules, max pole radius)
    let mut models: BTreeMap<RowKey, (Vec<Rule>, f64)> = BTreeMap::new();
    let watched = |r: &Rule| *r == sel.rule || matches!(r, Rule::PaperM1 | Rule::PaperM2);
    for (rule, pick) in sel.picks.iter().filter(|(r, _)| watched(r)) {
        if let Some(m) = &pick.model {
            let model = RowKey::new(FitKind::Huber, &m.key.structure(), None);
            let e = models.entry(model).or_insert((Vec::new(), 0.0));
            e.0.push(*rule);
            e.1 = e.1.max(m.fit.max_pole_radius.unwrap_or(0.0));
        }
    }
    let more = wants_more(sel, rows, grid, beyond);
    let mut out = Vec::new();
    for (key, (rules, radius)) in models {
        let names = rules.iter().map(|r| r.as_str()).collect::<Vec<_>>().join(", ");
        let model = format!("{} (picked by {names})", key.label());
        let edges = grid.edges(&key);
        if !edges.is_empty() {
            let edges = edges.join(" and ");
            out.push(match &more {
                Evidence::More(why) => format!(
                    "{model} has {edges} of the grid and {why}: the data may want a model the grid did not \
                     offer; widen the grid"
                ),
                Evidence::Enough(why) => {
                    format!("{model} has {edges} of the grid; {why}: nothing says the data want a larger model")
                }
                Evidence::None => {
                    let basis = if rules.iter().all(|r| grows_with_orders(*r, sel.basis)) {
                        format!(" (its measure grows with the orders: the {} ranks it)", sel.basis.describe())
                    } else {
                        String::new()
                    };
                    let rbic = sel
                        .picks
                        .get(&Rule::Rbic)
                        .and_then(|p| p.model.as_ref())
                        .map_or(String::new(), |m| format!("; rbic picks {} inside the grid", m.key.label()));
                    let (_, independent) = independent_inside(rows, grid);
                    let independent = if independent > 0 {
                        format!(", and {independent} models off the edges have residuals independent of the input")
                    } else {
                        String::new()
                    };
                    format!(
                        "{model} has {edges} of the grid, but nothing else says the data want more{rbic}{independent}: \
                         the pick is likely over-fitted{basis}, not a sign that the grid is too small"
                    )
                }
            });
        }
        if radius >= BOUNDARY {
            out.push(format!(
                "{model} has a pole at radius {radius:.4}, on the stability boundary: the plant looks integrating \
                 or unstable, and an output-error model forces a stable model onto it (identify from the \
                 differenced output, or in closed loop); its reported standard deviations are local and may \
                 understate the uncertainty (METHOD.md 17)"
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
        let key = RowKey::siso(FitKind::Huber, nb, nf, 1, Some(0));
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
        let w = pick_warnings(&sel, &rows, &grid, &[]);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(w[0].contains("OE(3,3)") && w[0].contains("the largest nB and the largest nF"), "{}", w[0]);
        assert!(w[0].contains("paper_m1, paper_m2"), "{}", w[0]);
        assert!(w[1].contains("stability boundary"), "{}", w[1]);
        // Inside the grid and well inside the unit circle: nothing to say.
        let rows = vec![row(2, 2, 95.0, 0.5), row(3, 3, 80.0, 0.5)];
        let sel = select(&rows, &ReduceOptions::new(FitBasis::Validation));
        assert!(pick_warnings(&sel, &rows, &grid, &[]).is_empty());
        // A grid of one nB has no edge in nB.
        let one = GridBounds { nb: (3, 3), nf: (1, 4), delay: (0, 2) };
        assert!(
            pick_warnings(&select(&[row(3, 3, 95.0, 0.5)], &ReduceOptions::new(FitBasis::Validation)), &[], &one, &[])
                .is_empty()
        );
    }

    #[test]
    fn an_edge_pick_says_widen_only_where_the_evidence_says_the_data_want_more() {
        let grid = GridBounds { nb: (1, 3), nf: (1, 3), delay: (1, 1) };
        // One record: the estimation fit grows with the orders, RBIC is smallest at (2,2).
        let mut rows = vec![row(1, 1, 60.0, 0.5), row(2, 2, 90.0, 0.5), row(3, 3, 91.0, 0.5)];
        for (r, rbic) in rows.iter_mut().zip([10.0, 1.0, 5.0]) {
            r.fit.rbic = Some(rbic);
            r.evidence.resid_indep_p = Some(if r.key.nb == 1 { 1e-6 } else { 0.4 });
        }
        let sel = select(&rows, &ReduceOptions::new(FitBasis::Estimation));
        assert_eq!(sel.rule, Rule::Rbic, "{}", sel.rule_why);
        let w = pick_warnings(&sel, &rows, &grid, &[]);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("OE(3,3)") && w[0].contains("paper_m1, paper_m2"), "{}", w[0]);
        assert!(!w[0].contains("widen the grid") && w[0].contains("over-fitted"), "{}", w[0]);
        assert!(w[0].contains("rbic picks OE(2,2)") && w[0].contains("estimation fit"), "{}", w[0]);
        assert!(w[0].contains("1 models off the edges have residuals independent"), "{}", w[0]);

        // RBIC on the edge too: the data want more.
        rows[2].fit.rbic = Some(0.5);
        let sel = select(&rows, &ReduceOptions::new(FitBasis::Estimation));
        let w = pick_warnings(&sel, &rows, &grid, &[]);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("widen the grid") && w[0].contains("rbic picks OE(3,3)"), "{}", w[0]);
        assert!(w[0].contains("paper_m1, paper_m2, rbic"), "{}", w[0]);

        // Beyond the edge RBIC rises: the edge pick is RBIC's minimum, no widening.
        let up = [
            Beyond { structure: Structure::siso(3, 4, 1), rbic: 2.0 },
            Beyond { structure: Structure::siso(4, 3, 1), rbic: 0.7 },
        ];
        let w = pick_warnings(&sel, &rows, &grid, &up);
        assert!(w.len() == 1 && !w[0].contains("widen the grid"), "{w:?}");
        assert!(w[0].contains("OE(3,4) delay 1 (+1.5), OE(4,3) delay 1 (+0.2) has a higher RBIC"), "{}", w[0]);
        // ... and where one falls, it says so.
        let down = [up[0], Beyond { rbic: 0.2, ..up[1] }];
        let w = pick_warnings(&sel, &rows, &grid, &down);
        assert!(w.len() == 1 && w[0].contains("widen the grid") && w[0].contains("OE(4,3) delay 1 (-0.3)"), "{w:?}");

        // RBIC inside, but no model off the edges is independent of the input.
        rows[2].fit.rbic = Some(5.0);
        rows[1].evidence.resid_indep_p = Some(1e-4);
        let sel = select(&rows, &ReduceOptions::new(FitBasis::Estimation));
        let w = pick_warnings(&sel, &rows, &grid, &[]);
        assert!(w.len() == 1 && w[0].contains("widen the grid") && w[0].contains("none of the 2 models"), "{w:?}");
    }
}
