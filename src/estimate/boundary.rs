//! Fits that ended on the stability boundary (largest pole radius >= [`BOUNDARY`]), and the
//! further starts that look for an interior fit as low (METHOD.md 5.5 "Boundary probe", 17.1).
//!
//! On the boundary a pole at radius ~1 gives 1/F an almost infinite memory: the fit creeps,
//! stops there, and every start of the least-squares phase (or every chain along k) may have led
//! there. A cell left there above an interior minimum has a criterion too high and a covariance
//! that means nothing. `oesweep fit` tries [`boundary_starts`] on such a fit
//! ([`super::single::off_the_boundary`]); the sweep's walk of a pair tries them once per pair
//! ([`probe`]) and carries a winner along k. Both keep a fit by one rule, [`replaces`].

use super::fit::{HuberFit, PairProblem, StartKind, huber_from_solution};
use super::huber::Loss;
use super::initial_guess::initial_guesses;
use super::least_squares::{BOUNDARY, contracted};
use super::problem::{Problem, Solution};
use super::solver;
use super::workspace::Workspace;
use crate::profile::Role;

/// The further starts of a boundary fit `theta`: itself with its poles pulled to
/// [`super::least_squares::CONTRACTED`], and the initial guesses (ARX, IV).
pub(crate) fn boundary_starts(prob: &Problem, theta: &[f64]) -> Vec<(Vec<f64>, &'static str)> {
    let mut starts = vec![(contracted(prob, theta), "contracted")];
    starts.extend(initial_guesses(prob).into_iter().map(|g| (g, "guess")));
    starts
}

/// True when `theta`'s largest pole radius is on the stability boundary ([`BOUNDARY`]).
pub(crate) fn on_edge(prob: &Problem, theta: &[f64]) -> bool {
    prob.max_pole_radius(theta) >= BOUNDARY
}

/// The rule of [`super::single::choose`] for two fits, given as (criterion, on the boundary):
/// `new` replaces `old` when it is lower by more than [`super::Chains::MERGE`] relative, or when
/// `old` is on the boundary, `new` inside, and `new` no higher than `old` plus that tolerance.
pub(crate) fn replaces(new: (f64, bool), old: (f64, bool)) -> bool {
    let ((w, edge), (w_old, old_edge)) = (new, old);
    if !w.is_finite() {
        return false;
    }
    if !w_old.is_finite() {
        return true;
    }
    let tol = super::Chains::MERGE * w_old.abs();
    w < w_old - tol || (old_edge && !edge && w <= w_old + tol)
}

/// The boundary probe of one pair's walked cells (`cells[i]` at `ks[i]`, increasing k; None: a
/// cell that failed): when a cell is on the boundary, the first such cell (smallest k) is also
/// fitted cold from [`boundary_starts`]; when the lowest interior one of those fits replaces the
/// cell by [`replaces`], its point is walked up and down in k, warm fit by warm fit, replacing
/// each cell it beats by the same rule until a cell it does not beat (start `probe`). One probe
/// per pair (three cold fits), not per cell: the walk carries a winning probe along k. Adds the
/// time spent to each cell's `seconds`.
pub(crate) fn probe(
    cells: &mut [Option<(HuberFit, StartKind)>],
    pair: &PairProblem,
    ks: &[f64],
    ws: &mut Workspace,
    seconds: &mut [f64],
) {
    let PairProblem { prob, sigma, judge, opts } = *pair;
    let edge = |theta: &[f64]| on_edge(prob, theta);
    let Some(i) = cells.iter().position(|c| c.as_ref().is_some_and(|(fit, _)| edge(&fit.theta()))) else {
        return;
    };
    let Some((cell, _)) = &cells[i] else { return };
    let incumbent = (cell.criterion, true);
    let t = std::time::Instant::now();
    let loss = Loss::Huber { gamma: ks[i] * sigma };
    ws.role = Role::Probe;
    let mut best: Option<Solution> = None;
    for (start, _) in boundary_starts(prob, &cell.theta()) {
        let sol = solver::minimise(prob, loss, &start, &opts.huber(), ws);
        if sol.usable() && !edge(&sol.theta) && best.as_ref().is_none_or(|b| sol.criterion < b.criterion) {
            best = Some(sol);
        }
    }
    seconds[i] += t.elapsed().as_secs_f64();
    let Some(sol) = best.filter(|s| replaces((s.criterion, false), incumbent)) else { return };
    // The workspace holds the last start's simulation, not necessarily the winner's.
    let fit = huber_from_solution(prob, sigma, ks[i], &sol, judge, ws, true);
    cells[i] = Some((fit, StartKind::Probe));
    for range in [(i + 1..ks.len()).collect::<Vec<_>>(), (0..i).rev().collect()] {
        let mut from = i;
        for j in range {
            let t = std::time::Instant::now();
            let replaced = probe_step(cells, pair, ks, from, j, ws);
            seconds[j] += t.elapsed().as_secs_f64();
            if !replaced {
                break;
            }
            from = j;
        }
    }
}

/// One warm fit of the probe's walk: cell `j` from cell `from`'s point, kept when it replaces
/// the cell ([`replaces`]).
fn probe_step(
    cells: &mut [Option<(HuberFit, StartKind)>],
    pair: &PairProblem,
    ks: &[f64],
    from: usize,
    j: usize,
    ws: &mut Workspace,
) -> bool {
    let PairProblem { prob, sigma, judge, opts } = *pair;
    let edge = |theta: &[f64]| on_edge(prob, theta);
    let (Some((start, _)), Some((cell, _))) = (&cells[from], &cells[j]) else { return false };
    let incumbent = (cell.criterion, edge(&cell.theta()));
    ws.role = Role::Probe;
    let sol = solver::minimise(prob, Loss::Huber { gamma: ks[j] * sigma }, &start.theta(), &opts.huber_warm(), ws);
    if !(sol.usable() && replaces((sol.criterion, edge(&sol.theta)), incumbent)) {
        return false;
    }
    let fit = huber_from_solution(prob, sigma, ks[j], &sol, judge, ws, false);
    cells[j] = Some((fit, StartKind::Probe));
    true
}
