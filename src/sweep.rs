//! Running a plan: rayon workers estimate the cells; the only module that knows about threads.
//!
//! Two stages. (1) The least-squares phase (initial guess, L2 fit, sigma) of every order pair,
//! in parallel over pairs. (2) The Huber cells: with the `ls` start every cell is independent
//! and runs in parallel over cells; with `neighbour`/`best` the k values of a pair form a
//! continuation chain (largest k first) and run in parallel over pairs. Each task is
//! sequential and deterministic, so the table does not depend on the thread count. One
//! [`Workspace`] per worker (`map_init`). A panic inside a fit is caught and becomes a failed
//! row; the sweep goes on.

use crate::data::Record;
use crate::estimate::{self, Judge, LsFit, Problem, SolverOptions, Workspace};
use crate::job::StartStrategy;
use crate::plan::{Cell, Plan};
use crate::progress::Progress;
use crate::spectral::SpectralEstimate;
use crate::table::{CellRow, Method};
use rayon::prelude::*;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

/// Everything a cell needs besides its orders and k.
pub struct Context<'a> {
    pub est: &'a Record,
    pub val: Option<&'a Record>,
    pub band: Option<(&'a SpectralEstimate, &'a [usize])>,
    pub solver: SolverOptions,
}

impl Context<'_> {
    fn judge(&self) -> Judge<'_> {
        Judge { validation: self.val.map(|v| (&v.u[..], &v.y[..])), band: self.band }
    }
}

fn panic_message(e: Box<dyn std::any::Any + Send>) -> String {
    if let Some(s) = e.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = e.downcast_ref::<String>() {
        s.clone()
    } else {
        "unknown panic".to_string()
    }
}

/// Result of a sweep: rows sorted by (method, nb, nf, k_index), `ls` rows first.
pub struct Outcome {
    pub rows: Vec<CellRow>,
    pub seconds: f64,
}

impl Outcome {
    pub fn failed_cells(&self) -> usize {
        self.rows.iter().filter(|r| r.method == Method::Huber && !r.ok()).count()
    }
}

/// Run every cell of `plan` on `threads` workers (0 = all cores).
pub fn run(plan: &Plan, ctx: &Context, threads: usize, progress: &Progress) -> Outcome {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    let t0 = Instant::now();
    let mut rows = pool.install(|| run_in_pool(plan, ctx, progress));
    rows.sort_by(|a, b| {
        (a.method != Method::Ls, a.nb, a.nf, a.k_index).cmp(&(b.method != Method::Ls, b.nb, b.nf, b.k_index))
    });
    Outcome { rows, seconds: t0.elapsed().as_secs_f64() }
}

fn run_in_pool(plan: &Plan, ctx: &Context, progress: &Progress) -> Vec<CellRow> {
    let judge = ctx.judge();
    let delay = plan.delay;
    progress.message("least-squares phase");
    let ls: Vec<(Option<LsFit>, CellRow)> = plan
        .pairs
        .par_iter()
        .map_init(Workspace::new, |ws, pair| {
            let prob = Problem { u: &ctx.est.u, y: &ctx.est.y, nb: pair.nb, nf: pair.nf, delay };
            let t = Instant::now();
            match catch_unwind(AssertUnwindSafe(|| estimate::fit_ls(&prob, &judge, &ctx.solver, ws))) {
                Ok(fit) => {
                    let row = CellRow::from_ls(&fit, t.elapsed().as_secs_f64());
                    (fit.ok().then_some(fit), row)
                }
                Err(e) => {
                    let reason = format!("least-squares phase panicked: {}", panic_message(e));
                    (None, CellRow::failed(Method::Ls, pair.nb, pair.nf, delay, None, reason))
                }
            }
        })
        .collect();
    progress.message("Huber phase");

    let huber_rows: Vec<CellRow> = match plan.start {
        StartStrategy::Ls => plan
            .cells()
            .par_iter()
            .map_init(Workspace::new, |ws, cell| {
                let row = huber_cell(plan, ctx, &judge, &ls[cell.pair], *cell, None, ws);
                progress.inc(1);
                row.0
            })
            .collect(),
        StartStrategy::Neighbour | StartStrategy::Best => (0..plan.pairs.len())
            .into_par_iter()
            .map_init(Workspace::new, |ws, p| {
                let mut out = Vec::with_capacity(plan.ks.len());
                let mut prev: Option<Vec<f64>> = None;
                for ki in plan.k_chain() {
                    let (row, theta) =
                        huber_cell(plan, ctx, &judge, &ls[p], Cell { pair: p, k_index: ki }, prev.as_deref(), ws);
                    prev = theta.or(prev);
                    out.push(row);
                    progress.inc(1);
                }
                out
            })
            .flatten()
            .collect(),
    };
    let mut rows: Vec<CellRow> = ls.into_iter().map(|(_, r)| r).collect();
    rows.extend(huber_rows);
    rows
}

/// One Huber cell; returns its row and (when ok) its parameters for the next cell of a chain.
fn huber_cell(
    plan: &Plan,
    ctx: &Context,
    judge: &Judge,
    ls: &(Option<LsFit>, CellRow),
    cell: Cell,
    neighbour: Option<&[f64]>,
    ws: &mut Workspace,
) -> (CellRow, Option<Vec<f64>>) {
    let pair = plan.pairs[cell.pair];
    let k = plan.ks[cell.k_index];
    let failed = |reason: String| {
        (CellRow::failed(Method::Huber, pair.nb, pair.nf, plan.delay, Some((cell.k_index, k)), reason), None)
    };
    let Some(lsfit) = &ls.0 else {
        return failed(format!(
            "no least-squares fit for this order pair: {}",
            ls.1.reason.as_deref().unwrap_or("it failed")
        ));
    };
    let prob = Problem { u: &ctx.est.u, y: &ctx.est.y, nb: pair.nb, nf: pair.nf, delay: plan.delay };
    let t = Instant::now();
    let run = catch_unwind(AssertUnwindSafe(|| {
        let mut fit_from = |start: &[f64]| estimate::fit_huber(&prob, lsfit.sigma, k, start, judge, &ctx.solver, ws);
        let theta_ls = lsfit.theta();
        match (plan.start, neighbour) {
            (StartStrategy::Ls, _) | (_, None) => (fit_from(&theta_ls), "ls"),
            (StartStrategy::Neighbour, Some(nb)) => (fit_from(nb), "neighbour"),
            (StartStrategy::Best, Some(nb)) => {
                let a = fit_from(&theta_ls);
                let b = fit_from(nb);
                // Ties keep the paper's start.
                if b.criterion < a.criterion { (b, "neighbour") } else { (a, "ls") }
            }
        }
    }));
    match run {
        Ok((fit, start)) => {
            let row = CellRow::from_huber(&fit, lsfit, cell.k_index, start, t.elapsed().as_secs_f64());
            let theta = row.ok().then(|| [&fit.b[..], &fit.f[..]].concat());
            (row, theta)
        }
        Err(e) => failed(format!("Huber fit panicked: {}", panic_message(e))),
    }
}
