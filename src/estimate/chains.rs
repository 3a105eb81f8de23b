//! Continuation chains along k: the Huber phase of one order pair under the `chains` start
//! strategy (docs/METHOD.md 5.5). [`walk_pair`] is the whole phase of a pair: the up walk of
//! [`Chains`] over increasing k, the backward pass of [`ChainWalk`], and per cell the fit that
//! won and where it started ([`StartKind`]). The sweep only schedules pairs and turns the
//! outcomes into rows.

pub use super::fit::PairProblem;
use super::fit::{HuberFit, Judge, LsFit, StartKind, huber_from_solution, judged};
use super::huber::Loss;
use super::least_squares::exploration_head;
use super::options::{SolverOptions, Termination};
use super::problem::{Problem, Solution};
use super::solver;
use super::workspace::Workspace;
use crate::profile::Role;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

/// Continuation chains along k for one order pair (METHOD.md 5.5).
///
/// One chain per start (theta_LS, then the pair's alternative starts). The cells are fitted in
/// increasing k: each chain starts the next cell from its own solution at the previous k. Small
/// k comes first because there the Huber minima are farthest from theta_LS and the starts most
/// often end in different basins; moving up in k then tracks each basin (measured against the
/// scipy peer: no worse in 96 % of cells, against 91 % going down from theta_LS). Chains
/// that reach the same criterion (relative [`Chains::MERGE`]) at the same parameters
/// ([`Chains::MERGE_THETA`]) have found the same minimum and merge into the earlier one, so
/// most pairs soon run a single chain. A losing chain that ran
/// out of iterations, or took [`Chains::SLOW_ITERATIONS`] or more (creeping along the
/// stability boundary), continues on a small iteration budget ([`Chains::CREEP_ITERATIONS`])
/// and is fitted only every [`Chains::CREEP_PERIOD`]-th cell until it wins a cell or merges.
#[derive(Clone, Debug)]
pub struct Chains {
    /// Current point of each chain (None: merged into an earlier chain).
    points: Vec<Option<Vec<f64>>>,
    /// The points are minima at the previous k (after the first step), not cold starts.
    warm: bool,
    /// Per chain: it runs on the creeping budget (see [`Chains::step`]).
    creeping: Vec<bool>,
    /// Steps taken so far (cells fitted).
    steps: usize,
    /// Per chain: the step and log k at which its point was found, and the point it had
    /// before with that point's step and log k (for [`Chains::predict`]).
    found: Vec<Option<(usize, f64)>>,
    before: Vec<Option<(usize, f64, Vec<f64>)>>,
}

impl Chains {
    /// Relative criterion difference below which two chains count as one minimum: two
    /// solvers (or two starts) end on the same minimum within ~1e-6 (the Huber tolerance is
    /// 1e-8 on steps that creep along ill-conditioned directions), while distinct local minima
    /// of OE models differ from 1e-4 up (METHOD.md 8).
    pub const MERGE: f64 = 1e-6;
    /// Iteration budget of a chain creeping along the stability boundary: enough to follow a
    /// minimum that moves with k, too little to spend a cell's cost on a chain that loses.
    pub const CREEP_ITERATIONS: usize = 10;
    /// A losing fit this long counts as creeping even when it converged (see [`Chains::step`]):
    /// on OE(12,13) of the paper grid one losing chain took 130-277 iterations at almost every
    /// k and stopped just under the iteration cap, so a budget for capped fits alone never
    /// applied; 50 is about three times a converging warm fit (issue 19, commit 1dbd529).
    pub const SLOW_ITERATIONS: usize = 50;
    /// A creeping chain is fitted only at the steps whose index (from 0, the first cell) is a
    /// multiple of this, and holds its point in between (see [`Chains::step`]): creeping
    /// iterations 10 419 -> 3 576 on the paper grid with the same quality against the peer
    /// (issue 19, commit 0de824f); no other period was measured.
    pub const CREEP_PERIOD: usize = 4;
    /// Two chains at the same criterion merge only when their parameters also agree to this
    /// share of the larger parameter magnitude (at least 1): over-parameterised pairs have
    /// distinct minima whose criteria agree to 1e-7 at one k and part by 1e-4 a few k later.
    /// On the paper grid's OE(12,15) a chain in the scipy peer's basin (max pole radius 0.989)
    /// merged at k = 0.055 into one at radius 0.9987, a relative 1.6e-7 lower, and from
    /// k = 0.156 on every cell sat up to 3e-4 above the peer. Whole grid against the peer
    /// (benches/compare_table.py, same gamma): Huber cells no worse at a relative 1e-6 3631 ->
    /// 3672 of 3840, at 1e-4 3795 -> 3802; iterations 92 081 -> 95 813 (+4 %). 1e-3 gave the
    /// same counts (3673, 3802) for 96 771 iterations.
    pub const MERGE_THETA: f64 = 1e-2;

    /// Chains from `theta_ls` (chain 0) and each of `alternatives`.
    pub fn new(theta_ls: &[f64], alternatives: &[Vec<f64>]) -> Self {
        let points: Vec<_> = std::iter::once(theta_ls.to_vec()).chain(alternatives.iter().cloned()).map(Some).collect();
        let creeping = vec![false; points.len()];
        let n = points.len();
        Chains { points, warm: false, creeping, steps: 0, found: vec![None; n], before: vec![None; n] }
    }

    /// Chains still running.
    pub fn live(&self) -> usize {
        self.points.iter().flatten().count()
    }

    /// Chains running on the creeping budget [`Chains::CREEP_ITERATIONS`].
    pub fn creeping(&self) -> usize {
        self.points.iter().zip(&self.creeping).filter(|(p, c)| p.is_some() && **c).count()
    }

    /// The current point of chain `i` (None once merged).
    pub fn point(&self, i: usize) -> Option<&[f64]> {
        self.points.get(i)?.as_deref()
    }

    /// The secant predictor of continuation methods (Allgower and Georg 1990, ch. 2): chain
    /// `i`'s minimum at log k extrapolated linearly from its minima at the two previous steps,
    /// `theta + (theta - theta_before) (log k - log k_1) / (log k_1 - log k_0)`. None (start at
    /// the point itself) unless the chain was fitted at both previous steps. [`Chains::step`]
    /// starts from it only when [`lower_start`] says so. On the paper grid (issue 30, `run --profile`):
    /// the chains' iterations 56 943 -> 45 335, all minimisations' 104 825 -> 92 081; 3522 of
    /// 3840 cells within a relative 1e-6 of the walk without it, 16 higher and 17 lower by more
    /// than 1e-4 (the chains reach other basins, both ways); the same picks; against the scipy
    /// peer's 8-k grid 761/768 Huber cells no worse either way. Unguarded, 18 609 instead of
    /// 17 827 reported iterations on that grid and the same count against the peer.
    fn predict(&self, i: usize, step: usize, log_k: f64) -> Option<Vec<f64>> {
        let point = self.points[i].as_ref()?;
        let (s1, lk1) = self.found[i]?;
        let (s0, lk0, before) = self.before[i].as_ref()?;
        if s1 + 1 != step || s0 + 1 != s1 || lk1 <= *lk0 {
            return None;
        }
        let t = (log_k - lk1) / (lk1 - lk0);
        Some(point.iter().zip(before).map(|(p, b)| p + t * (p - b)).collect())
    }

    /// The cell at tuning constant `k` (larger than at the previous call): one fit per live
    /// chain, the lowest criterion wins (ties: the earlier chain). Returns the fit and the
    /// index of the chain's start (0 = theta_LS).
    pub fn step(&mut self, pair: &PairProblem, k: f64, ws: &mut Workspace) -> (HuberFit, usize) {
        let PairProblem { prob, sigma, judge, opts } = *pair;
        let loss = Loss::Huber { gamma: k * sigma };
        let opts = &if self.warm { opts.huber_warm() } else { opts.huber() };
        self.warm = true;
        let mut sols: Vec<Option<Solution>> = Vec::with_capacity(self.points.len());
        let budget = SolverOptions { max_iterations: Self::CREEP_ITERATIONS.min(opts.max_iterations), ..opts.clone() };
        // Between its periodic fits a creeping chain holds its point, as long as another chain
        // runs to win the cell. On the paper grid this took the creeping chains' iterations
        // from ~10 400 to ~3 600 (6 % of the sweep's); a creeping chain that wins a cell when it
        // runs again is a jump, and the backward pass walks down from it through the cells it
        // skipped (against the scipy peer the same quality: 761 and 763 of 768 Huber cells no
        // worse on the bundled and held-out records, with the top cell's cold fit below).
        let period_step = self.steps.is_multiple_of(Self::CREEP_PERIOD);
        let step = self.steps;
        self.steps += 1;
        let log_k = k.ln();
        let runner = self.points.iter().zip(&self.creeping).any(|(p, &c)| p.is_some() && !c);
        for (i, (point, &creeping)) in self.points.iter().zip(&self.creeping).enumerate() {
            if creeping && runner && !period_step {
                sols.push(None);
                continue;
            }
            let opts = if creeping { &budget } else { opts };
            ws.role = if creeping { Role::Creep } else { Role::Chain };
            let predicted = match (creeping, point) {
                (false, Some(p)) => self.predict(i, step, log_k).and_then(|c| lower_start(prob, loss, c, p, ws)),
                _ => None,
            };
            let start = predicted.as_deref().or(point.as_deref());
            sols.push(start.map(|p| solver::minimise(prob, loss, p, opts, ws)));
        }
        let last = sols.iter().rposition(Option::is_some);
        // Criteria this small are rounding noise of an exact fit, equal whatever their ratio.
        let floor = 1e-20 * prob.mean_square_output();
        let mut best: Option<usize> = None;
        for (i, sol) in sols.iter().enumerate() {
            let Some(sol) = sol else { continue };
            if !sol.usable() {
                // A chain that broke down keeps its last point (the next k may recover).
                continue;
            }
            let merged = sols[..i].iter().enumerate().any(|(j, other)| {
                self.points[j].is_some()
                    && other.as_ref().is_some_and(|o| {
                        o.criterion.is_finite()
                            && (o.criterion - sol.criterion).abs() <= Self::MERGE * sol.criterion.abs() + floor
                            && same_point(&o.theta, &sol.theta)
                    })
            });
            let old = std::mem::replace(&mut self.points[i], (!merged).then(|| sol.theta.clone()));
            self.before[i] = old.zip(self.found[i]).map(|(p, (s, lk))| (s, lk, p));
            self.found[i] = Some((step, log_k));
            if best.is_none_or(|b| sol.criterion < sols[b].as_ref().expect("live").criterion) {
                best = Some(i);
            }
        }
        // No usable chain: report chain 0's (non-finite) attempt as the cell's failure.
        let which = best.unwrap_or(0);
        // A losing chain whose fit ran out of iterations is creeping along the stability
        // boundary: nearly every step leaves the unit circle and is reflected back for a
        // decrease of ~1e-5, the minimum of its basin lying outside. Walked on, it repeats
        // that at every k (on the paper grid such steps never won a cell, yet took a quarter
        // of the Huber iterations), so it runs on a budget of CREEP_ITERATIONS per cell:
        // enough for a warm start whose basin has turned interior (2-5 iterations), and the
        // chain stays in the race. The same for a losing fit of SLOW_ITERATIONS or more that
        // converged: from a theta_LS on the boundary a chain can creep 130-280 iterations per
        // cell and stop on the criterion tolerance just under the cap, cell after cell (paper
        // grid with nested least-squares starts, OE(12,13)). The budget holds until the chain
        // wins a cell: such a chain often converges within it at one k (a tiny step along the
        // boundary meets the tolerance) and creeps 170-230 iterations at the next, and ending
        // the budget on convergence paid that every other cell (on the paper grid, a third of
        // the losing chains' iterations; the quality against the peer stayed the same).
        for (i, sol) in sols.iter().enumerate() {
            self.creeping[i] = best.is_some()
                && i != which
                && (self.creeping[i]
                    || sol.as_ref().is_some_and(|s| {
                        s.termination == Termination::MaxIterations || s.iterations >= Self::SLOW_ITERATIONS
                    }));
        }
        let sol = sols[which].as_ref().or(sols.iter().flatten().next()).expect("at least one chain");
        let fit = huber_from_solution(prob, sigma, k, sol, judge, ws, Some(which) != last);
        (fit, which)
    }
}

/// The cells of one order pair along its k grid (increasing k), as [`Chains`] left them, and
/// the backward pass over them ([`ChainWalk::walk_back`]).
///
/// Walking up in k, a chain follows its minimum until that minimum ceases to exist (a fold:
/// the basin merges into another one as gamma grows); the chain then falls into the other
/// basin, which may have been the lower one at the smaller k too, unseen because every start
/// was elsewhere. On the paper grid this happened in 62 of 3840 cells (up to 12 % lower W,
/// e.g. OE(8,4) at k = 0.0875: 1.795 against the 1.586 that the scipy peer found, and that is
/// the continuation of the k = 0.1 minimum downwards). So where the up walk jumped (the
/// winning chain changed, or its warm fit needed [`ChainWalk::JUMP_ITERATIONS`] or more) the
/// pass walks down from that cell, warm start by warm start, as long as each fit lowers the
/// criterion of the cell below; a cell keeps the better of the two. Never worse than the up
/// walk; on the paper grid it added ~9 % to the Huber iterations and 2-3 % to the wall time.
///
/// The pass also fits the top cell (largest k) from theta_LS, as an independent solver that
/// starts every cell there would: that is where the Huber minimum lies nearest theta_LS, while
/// the chains arrive from below, possibly in another basin. A lower fit is walked down like a
/// jump. Against the scipy peer's 8-k grid this took the Huber cells no worse from 744 to 761
/// of 768 on the bundled record and from 753 to 763 on a held-out one, for one fit per pair.
#[derive(Clone, Debug, Default)]
pub struct ChainWalk {
    /// Per k: the cell's fit and where it came from (the winning chain, or the backward
    /// pass); None for a cell that failed outright (a panic), which a walk does not cross.
    pub cells: Vec<Option<(HuberFit, StartKind)>>,
}

impl ChainWalk {
    /// A warm fit this long has likely left its basin (warm fits converge in 2-5 iterations).
    pub const JUMP_ITERATIONS: usize = 15;

    /// The backward pass; `ks[i]` is the tuning constant of `cells[i]`. Returns the time spent
    /// per cell (seconds), to be added to its own. Deterministic, like the up walk.
    pub fn walk_back(&mut self, pair: &PairProblem, ks: &[f64], theta_ls: &[f64], ws: &mut Workspace) -> Vec<f64> {
        let PairProblem { prob, sigma, judge, opts } = *pair;
        let n = self.cells.len();
        assert_eq!(ks.len(), n);
        let mut seconds = vec![0.0; n];
        // The triggers are those of the up walk, fixed before any cell changes.
        let jumped: Vec<bool> = (0..n)
            .map(|i| {
                i > 0
                    && match (&self.cells[i], &self.cells[i - 1]) {
                        (Some((fit, which)), Some((_, below))) => {
                            which != below || fit.iterations >= Self::JUMP_ITERATIONS
                        }
                        _ => false,
                    }
            })
            .collect();
        for i in (1..n).rev().filter(|&i| jumped[i]) {
            self.walk_down(pair, ks, i, ws, &mut seconds);
        }
        // Last, so that it only adds to what the passes above found: the top cell from theta_LS,
        // as an independent solver starts every cell. At the largest k the Huber minimum lies
        // nearest theta_LS, and the chains, arriving from below, may sit in another basin.
        // With the warm settings: theta_LS is next to that minimum (at k = 2 nearly every
        // residual is in the L2 region), and near Gauss-Newton first steps stay in its basin
        // where the cold damping's gradient-like ones wander (against the scipy peer, bundled
        // record: 761 against 757 of 768 Huber cells no worse; held-out: 763 either way). And
        // with the cold settings too, as the peer starts every cell, keeping the lower: each
        // finds minima the other misses (bundled record 760 -> 761, held-out 763 either way,
        // for 2 % more iterations on the paper grid).
        if let Some(Some((top, _))) = self.cells.last() {
            let incumbent = top.criterion;
            let t = std::time::Instant::now();
            let loss = Loss::Huber { gamma: ks[n - 1] * sigma };
            ws.role = Role::Top;
            let cold = solver::minimise(prob, loss, theta_ls, &opts.huber(), ws);
            let warm = solver::minimise(prob, loss, theta_ls, &opts.huber_warm(), ws);
            let cold_lower = cold.usable() && (!warm.usable() || cold.criterion < warm.criterion);
            let sol = if cold_lower { cold } else { warm };
            let lower = sol.usable() && (!incumbent.is_finite() || sol.criterion < incumbent * (1.0 - Chains::MERGE));
            if lower {
                // The workspace holds the warm fit's simulation, the last to run.
                let fit = huber_from_solution(prob, sigma, ks[n - 1], &sol, judge, ws, cold_lower);
                self.cells[n - 1] = Some((fit, StartKind::Ls { start: 0 }));
            }
            seconds[n - 1] += t.elapsed().as_secs_f64();
            if lower {
                self.walk_down(pair, ks, n - 1, ws, &mut seconds);
            }
        }
        super::boundary::probe(&mut self.cells, pair, ks, ws, &mut seconds);
        seconds
    }

    /// Warm fits down from cell `i`, each from the one above, as long as each is lower than
    /// the cell it would replace.
    fn walk_down(&mut self, pair: &PairProblem, ks: &[f64], i: usize, ws: &mut Workspace, seconds: &mut [f64]) {
        let PairProblem { prob, sigma, judge, opts } = *pair;
        let opts = opts.huber_warm();
        let mut j = i;
        while j > 0 {
            let (Some((from, _)), Some((below, _))) = (&self.cells[j], &self.cells[j - 1]) else { break };
            let start = from.theta();
            let incumbent = below.criterion;
            let t = std::time::Instant::now();
            let loss = Loss::Huber { gamma: ks[j - 1] * sigma };
            ws.role = Role::Back;
            let sol = solver::minimise(prob, loss, &start, &opts, ws);
            let lower = sol.usable() && (!incumbent.is_finite() || sol.criterion < incumbent * (1.0 - Chains::MERGE));
            if lower {
                let fit = huber_from_solution(prob, sigma, ks[j - 1], &sol, judge, ws, false);
                self.cells[j - 1] = Some((fit, StartKind::ChainBack));
            }
            seconds[j - 1] += t.elapsed().as_secs_f64();
            if !lower {
                break;
            }
            j -= 1;
        }
    }
}

/// One cell of a walked pair.
#[derive(Debug)]
pub enum CellOutcome {
    /// The cell's fit, where it started, and the seconds spent on it (its share of the up walk
    /// and of the backward pass).
    Fit { fit: Box<HuberFit>, start: StartKind, seconds: f64 },
    /// The fit panicked (a bug in the numerics): the reason, for a failed row.
    Panicked(String),
}

/// The whole Huber phase of one pair: its cells at `ks` (k index, k), in increasing k, chains
/// from `theta_ls` and `alternatives`. On a record at least four times `solver.explore_rows` long the walk
/// (chains and backward pass) runs on the record's first `explore_rows` samples
/// ([`exploration_head`]), and each cell is then one warm fit on the whole record from the
/// head's solution, moved by the previous cell's head-to-whole shift where that keeps F stable
/// ([`polish_start`]; METHOD.md 5.5): the losing chains and the backward pass cost a head's
/// worth per iteration. On a 131 072-sample record (`benches/long_record.sh`) every one of the
/// 640 cells came out within 1e-6 of the whole-record walk, the same picks, for 11.8 -> 9.8 s
/// of Huber time. The chains carry state from cell to cell that the rows
/// do not hold, so a pair with unfinished cells is walked again from its first cell: the walk
/// is deterministic, so the cells an earlier run finished (`done[i]`) come out bit for bit the
/// same, and only the others are returned (with their k index). Each cell is guarded on its
/// own: a panic becomes that cell's outcome and the chains go on from their last points. A
/// pair's outcomes are final only when the backward pass is done: when `stopped()` turns true
/// before an unfinished cell, the walk ends with None (the pair is redone on resume).
pub fn walk_pair(
    pair: &PairProblem,
    theta_ls: &[f64],
    alternatives: &[Vec<f64>],
    ks: &[(usize, f64)],
    done: &[bool],
    stopped: &dyn Fn() -> bool,
    ws: &mut Workspace,
) -> Option<Vec<(usize, CellOutcome)>> {
    let (nb, nf) = (pair.prob.one().nb, pair.prob.one().nf);
    // A long record walks on its head (`solver.explore_rows`), judged by nothing but its own
    // criterion, and each cell is then minimised on the whole record from there.
    let whole = pair;
    let head = exploration_head(pair.prob, pair.opts);
    let on_head = head.is_some();
    // The walk fits for the criterion only, and each cell's final fit is judged once at the end
    // (`judged`): the backward pass, the top cell and the boundary probe replace cells.
    let walk_judge = Judge { criterion_only: true, ..Judge::default() };
    let walk_pair = match &head {
        Some(prob) => PairProblem { prob, judge: &walk_judge, ..*pair },
        None => PairProblem { judge: &walk_judge, ..*pair },
    };
    let pair = &walk_pair;
    let mut chains = Chains::new(theta_ls, alternatives);
    let mut walk = ChainWalk::default();
    let mut seconds = Vec::with_capacity(ks.len());
    let mut panics: Vec<Option<String>> = Vec::with_capacity(ks.len());
    for (&(ki, k), &was_done) in ks.iter().zip(done) {
        if !was_done && stopped() {
            return None;
        }
        let t = Instant::now();
        let run = catch_unwind(AssertUnwindSafe(|| {
            crate::failpoint::before_cell(nb, nf, ki);
            chains.step(pair, k, ws)
        }));
        seconds.push(t.elapsed().as_secs_f64());
        match run {
            Ok((fit, which)) => {
                walk.cells.push(Some((fit, StartKind::Chain { start: which })));
                panics.push(None);
            }
            Err(e) => {
                walk.cells.push(None);
                panics.push(Some(format!("Huber fit panicked: {}", panic_message(e))));
            }
        }
    }
    let k_values: Vec<f64> = ks.iter().map(|&(_, k)| k).collect();
    // The pass replaces a cell only by a complete, lower fit, so after a panic in it every cell
    // is still a valid fit (of the up walk or of the pass).
    let extra = catch_unwind(AssertUnwindSafe(|| walk.walk_back(pair, &k_values, theta_ls, ws)))
        .unwrap_or_else(|_| vec![0.0; ks.len()]);
    let mut out = Vec::new();
    // On a long record, how far the whole record's minimum lay from the head's at the previous
    // cell (see `polish_start`); cells an earlier run finished are polished again for it when a
    // later cell needs it, so that a resumed pair starts each cell from the same point.
    let mut shift: Option<Vec<f64>> = None;
    for (i, (cell, panic)) in walk.cells.into_iter().zip(panics).enumerate() {
        let needed_later = on_head && done[i + 1..].iter().any(|d| !d);
        if done[i] && !needed_later {
            continue;
        }
        let outcome = match cell {
            Some((fit, start)) if on_head => {
                let t = Instant::now();
                let polished = catch_unwind(AssertUnwindSafe(|| {
                    let loss = Loss::Huber { gamma: fit.k * whole.sigma };
                    let head_theta = fit.theta();
                    let from = polish_start(whole.prob, &head_theta, shift.as_deref());
                    ws.role = Role::Polish;
                    let sol = solver::minimise(whole.prob, loss, &from, &whole.opts.huber_warm(), ws);
                    shift = sol.usable().then(|| sol.theta.iter().zip(&head_theta).map(|(a, b)| a - b).collect());
                    huber_from_solution(whole.prob, whole.sigma, fit.k, &sol, whole.judge, ws, false)
                }));
                let seconds = seconds[i] + extra[i] + t.elapsed().as_secs_f64();
                match polished {
                    Ok(fit) => CellOutcome::Fit { fit: Box::new(fit), start, seconds },
                    Err(e) => CellOutcome::Panicked(format!("Huber fit panicked: {}", panic_message(e))),
                }
            }
            Some((fit, start)) => {
                let t = Instant::now();
                let fit = catch_unwind(AssertUnwindSafe(|| judged(whole.prob, fit, whole.judge, ws)));
                let seconds = seconds[i] + extra[i] + t.elapsed().as_secs_f64();
                match fit {
                    Ok(fit) => CellOutcome::Fit { fit: Box::new(fit), start, seconds },
                    Err(e) => CellOutcome::Panicked(format!("Huber fit panicked: {}", panic_message(e))),
                }
            }
            None => CellOutcome::Panicked(panic.unwrap_or_else(|| "Huber fit panicked".into())),
        };
        if !done[i] {
            out.push((ks[i].0, outcome));
        }
    }
    Some(out)
}

/// Where a long record's cell is minimised on the whole record: from the head's solution
/// `head_theta` moved by `shift` (the whole record's minimum minus the head's at the previous
/// cell: the two differ by the head's sampling error, which changes little from one k to the
/// next), or from `head_theta` itself when there is no shift or the moved F is unstable.
///
/// Unlike the chains' predictor along k, the shifted start is not first compared with the plain
/// one ([`lower_start`]): that took two simulations of the whole record per cell, 6-8 % of a
/// long-record run (`benches/long_record.sh`), for a choice that changes the cell by less than
/// the fit's tolerance. On that 131 072-sample record (seed 7) it never chose the plain start
/// (the same table bit for bit without it); with seed 8 it did for 11 of 640 cells, and without
/// it every criterion came out within a relative 1.3e-8 (10 lower, 16 higher), the same picks,
/// in 2390 instead of 2412 iterations.
fn polish_start(prob: &Problem, head_theta: &[f64], shift: Option<&[f64]>) -> Vec<f64> {
    if let Some(s) = shift {
        let moved: Vec<f64> = head_theta.iter().zip(s).map(|(a, s)| a + s).collect();
        if prob.is_stable(&moved) {
            return moved;
        }
    }
    head_theta.to_vec()
}

/// Two chains' points are one minimum ([`Chains::MERGE_THETA`]).
fn same_point(a: &[f64], b: &[f64]) -> bool {
    let scale = b.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= Chains::MERGE_THETA * scale)
}

/// The rule of the chains' predictor along k (`Chains::predict`): a predicted start
/// `candidate` replaces the plain one, `point`, only when its F is stable and its criterion
/// lower (one simulation of each into the workspace's trial output; the solver's buffers are
/// untouched). A prediction can overshoot where the minimum's path bends; the point is then
/// the better start.
fn lower_start(prob: &Problem, loss: Loss, candidate: Vec<f64>, point: &[f64], ws: &mut Workspace) -> Option<Vec<f64>> {
    if !prob.is_stable(&candidate) {
        return None;
    }
    ws.trial_yhat.resize(prob.n(), 0.0);
    prob.simulate(&candidate, &mut ws.trial_yhat);
    let at_candidate = prob.criterion(loss, &ws.trial_yhat);
    prob.simulate(point, &mut ws.trial_yhat);
    (at_candidate < prob.criterion(loss, &ws.trial_yhat)).then_some(candidate)
}

/// The message of a caught panic.
pub fn panic_message(e: Box<dyn std::any::Any + Send>) -> String {
    if let Some(s) = e.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = e.downcast_ref::<String>() {
        s.clone()
    } else {
        "unknown panic".to_string()
    }
}

/// Step 3 from theta_LS and from each of `ls.alternatives`, keeping the lowest criterion (ties:
/// the earlier start). Returns the fit and the index of the winning start (0 = theta_LS).
/// Least-squares OE fits have several minima (METHOD.md 8) and the Huber fit inherits its
/// start's basin; this multi-start is what keeps oesweep no worse than an independent solver.
pub fn fit_huber_multi(
    prob: &Problem,
    ls: &LsFit,
    k: f64,
    judge: &Judge,
    opts: &SolverOptions,
    ws: &mut Workspace,
) -> (HuberFit, usize) {
    fit_huber_starts(prob, ls.sigma, k, &ls.theta(), &ls.alternatives, judge, opts, ws)
}

/// [`fit_huber_multi`] from its parts: `theta_ls` first, then `alternatives`.
#[allow(clippy::too_many_arguments)]
pub fn fit_huber_starts(
    prob: &Problem,
    sigma: f64,
    k: f64,
    theta_ls: &[f64],
    alternatives: &[Vec<f64>],
    judge: &Judge,
    opts: &SolverOptions,
    ws: &mut Workspace,
) -> (HuberFit, usize) {
    // One step of fresh chains is exactly this: every start once, the lowest W wins.
    Chains::new(theta_ls, alternatives).step(&PairProblem { prob, sigma, judge, opts }, k, ws)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chains_at_one_criterion_but_apart_in_the_parameters_are_two_minima() {
        let a = [0.5, -1.9, 0.95];
        assert!(same_point(&a, &a));
        // Within 1e-2 of the largest magnitude (1.9): the same minimum to the solver's precision.
        assert!(same_point(&[0.51, -1.9, 0.95], &a));
        // A pole pair moved from radius 0.989 to 0.9987 moves F by ~2e-2: another basin.
        assert!(!same_point(&[0.5, -1.88, 0.93], &a));
        // The scale is at least 1: tiny parameters compare absolutely.
        assert!(same_point(&[1e-3, 0.0], &[5e-3, 0.0]));
    }
}
