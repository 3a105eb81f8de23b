//! Variable projection (METHOD.md 12): the inner problem of the separable solver.
//!
//! For a fixed F the OE predictor is linear in beta = [b, c]:
//!
//! ```text
//! yhat = Phi(F) beta,   Phi columns: xu[t - d - i] (i < nB), 1 (offset),   xu = (1/F) u
//! ```
//!
//! so the criterion can be minimised over F alone, with beta(F) = argmin_beta V(F, beta)
//! solved inside (Golub-Pereyra). The outer Levenberg-Marquardt step (in
//! [`super::solver::minimise`] with `method = separable`) uses the full normal equations at
//! (F, beta(F)) and damps only the F block: eliminating the undamped beta block leaves
//! `(S + lambda D_F) delta_F = g_F - H_FL H_LL^-1 g_L` with S the Schur complement of H_LL,
//! which is Kaufman's approximation of the projected Jacobian's Gauss-Newton step (its
//! gradient term vanishes at the inner optimum, g_L = 0). The trial F is then evaluated at
//! its own inner optimum, warm-started from the linearised beta of the full step.
//!
//! The inner problem is convex. Least squares: one Newton step from the warm start is the
//! exact solution. Huber: Newton steps with the Gauss-Newton weights of the L2 set
//! (1 on |e| <= gamma, 0 beyond), each followed by a backtracking search along the step,
//! which is cheap because yhat is linear in beta: `V(beta + s delta)` needs only `Phi delta`
//! once. It stops when a step no longer lowers W by more than [`INNER_FTOL`] (relative), or
//! after [`INNER_MAX`] steps; the outer solver accepts a trial only when its W decreased, so
//! an inexact inner solution costs iterations, never correctness.
//!
//! Normal equations of the inner problem are those of an OE model with nF = 0 over xu
//! ([`NormalEquations::build`] with that layout), so the weighting rules (the correction
//! for few reweighted rows, the direct sum for many) have one home.
//!
//! Buffers: the caller's xu, yhat and two N-length scratch vectors (r, w: free during a
//! trial, see [`super::solver::minimise`]), the inner normal equations' row list and weights
//! (1.5 N-length); the rest is (nB + 1)^2-sized.

use super::huber::Loss;
use super::linalg::{cholesky, cholesky_solve};
use super::normal::{Layout, NormalEquations};
use super::problem::Problem;

/// Newton steps of a Huber inner problem at most (each warm-started from the linearised beta
/// of the outer step). The inner problem changes only its L2 set between steps, which settles
/// in 2-4 steps near a solution; the cap bounds the cost of an outer trial far from one, where
/// the outer solver's acceptance test (W must decrease) guards the result anyway.
pub const INNER_MAX: usize = 6;
/// A Huber inner step lowering W by less than this (relative) ends the inner solve: two
/// orders below the solver's `ftol` (1e-10), so the inner solve never limits the outer
/// convergence test.
pub const INNER_FTOL: f64 = 1e-12;

/// Small buffers of the inner problem, reused across calls.
#[derive(Default, Debug)]
pub struct Inner {
    h: Vec<f64>,
    a: Vec<f64>,
    g: Vec<f64>,
    delta: Vec<f64>,
    /// b part of beta or of a step, for the FIR pass.
    b: Vec<f64>,
    ne: NormalEquations,
}

/// The inner linear parameters' count: nB, plus one with an offset.
fn linear_dim(prob: &Problem) -> usize {
    prob.one().nb + usize::from(prob.offset)
}

/// `theta`'s beta = [b, c] (b first, c last in theta; F untouched) as one vector view.
fn beta_get(prob: &Problem, theta: &[f64], i: usize) -> f64 {
    if i < prob.one().nb { theta[i] } else { theta[prob.one().nb + prob.one().nf] }
}

fn beta_add(prob: &Problem, theta: &mut [f64], i: usize, v: f64) {
    if i < prob.one().nb {
        theta[i] += v;
    } else {
        theta[prob.one().nb + prob.one().nf] += v;
    }
}

/// `out = Phi beta` for the linear part `beta` (b then c) over `xu`.
fn predict(prob: &Problem, beta: impl Fn(usize) -> f64, b_scratch: &mut [f64], xu: &[f64], out: &mut [f64]) {
    for (i, v) in b_scratch.iter_mut().enumerate() {
        *v = beta(i);
    }
    prob.delayed_fir(b_scratch, xu, out, &mut Vec::new());
    if prob.offset {
        let c = beta(prob.one().nb);
        if c != 0.0 {
            out.iter_mut().for_each(|v| *v += c);
        }
    }
}

/// Projects `theta` onto the inner optimum of its F: `xu = (1/F) u`, beta(F) written into
/// theta's b (and c), `yhat = Phi beta` (offset included); returns the criterion there.
/// `r` and `w` are N-length scratch.
#[allow(clippy::too_many_arguments)]
pub fn project(
    prob: &Problem,
    loss: Loss,
    theta: &mut [f64],
    xu: &mut [f64],
    yhat: &mut [f64],
    r: &mut [f64],
    w: &mut [f64],
    inner: &mut Inner,
) -> f64 {
    let n = prob.n();
    let (nb, nl) = (prob.one().nb, linear_dim(prob));
    let lay = Layout::siso(nb, 0, prob.one().delay);
    inner.h.resize(nl * nl, 0.0);
    inner.a.resize(nl * nl, 0.0);
    inner.g.resize(nl, 0.0);
    inner.delta.resize(nl, 0.0);
    inner.b.resize(nb, 0.0);
    xu.copy_from_slice(prob.u);
    prob.inv_f(prob.split(theta).1, xu);
    let th: &[f64] = theta;
    predict(prob, |i| beta_get(prob, th, i), &mut inner.b, xu, yhat);
    let mut crit = loss.criterion(prob.y, yhat);
    if nl == 0 || !crit.is_finite() {
        return crit;
    }
    let steps = if matches!(loss, Loss::LeastSquares) { 1 } else { INNER_MAX };
    for _ in 0..steps {
        // Gauss-Newton weights (exact Newton on the piecewise quadratic W); when they leave
        // too few L2 rows for a definite system (a start far off, every residual beyond
        // gamma), IRLS weights gamma/|e| on the L1 rows, which keep it definite.
        let mut solved = false;
        for irls in [false, true] {
            let weights = match loss {
                Loss::LeastSquares => {
                    for ((r, &y), &yh) in r.iter_mut().zip(prob.y).zip(yhat.iter()) {
                        *r = y - yh;
                    }
                    None
                }
                Loss::Huber { gamma } => {
                    let rows = r.iter_mut().zip(w.iter_mut()).zip(prob.y.iter().zip(yhat.iter()));
                    for ((r, w), (&y, &yh)) in rows {
                        let e = y - yh;
                        *r = e.clamp(-gamma, gamma);
                        *w = if e.abs() <= gamma {
                            1.0
                        } else if irls {
                            gamma / e.abs()
                        } else {
                            0.0
                        };
                    }
                    Some(&w[..])
                }
            };
            // xu stands in for the unused xy of an nF = 0 layout.
            inner.ne.build_all(&lay, prob.offset, prob.seams, xu, xu, weights, r, &mut inner.h, &mut inner.g);
            solved = solve_ridged(&inner.h, &mut inner.a, &inner.g, &mut inner.delta[..nl], nl);
            if solved || weights.is_none() {
                break;
            }
        }
        if !solved {
            break;
        }
        // v = Phi delta (into r, free now): yhat(beta + s delta) = yhat + s v.
        let delta = &inner.delta[..nl];
        if delta.iter().all(|v| *v == 0.0) {
            break;
        }
        predict(prob, |i| delta[i], &mut inner.b, xu, r);
        if matches!(loss, Loss::LeastSquares) {
            // The exact minimiser: no search.
            for (yh, v) in yhat.iter_mut().zip(r.iter()) {
                *yh += v;
            }
            for (i, &dv) in delta.iter().enumerate() {
                beta_add(prob, theta, i, dv);
            }
            crit = loss.criterion(prob.y, yhat);
            break;
        }
        let mut s = 1.0;
        let mut accepted = None;
        for _ in 0..SEARCH_HALVINGS {
            let c = shifted_criterion(loss, prob.y, yhat, r, s);
            if c.is_finite() && c < crit {
                accepted = Some(c);
                break;
            }
            s *= 0.5;
        }
        let Some(new_crit) = accepted else { break };
        for (yh, v) in yhat.iter_mut().zip(r.iter()) {
            *yh += s * v;
        }
        for (i, &dv) in delta.iter().enumerate() {
            beta_add(prob, theta, i, s * dv);
        }
        let decrease = crit - new_crit;
        crit = new_crit;
        if decrease <= INNER_FTOL * crit {
            break;
        }
    }
    debug_assert_eq!(yhat.len(), n);
    // yhat was updated incrementally; the criterion is of that yhat.
    crit
}

/// Step halvings of the Huber inner search before it gives up: a step shortened 256-fold that
/// still does not lower W points the wrong way (the L2 set changed under it), and the outer
/// step's own damping is the better remedy.
const SEARCH_HALVINGS: usize = 8;

/// `V(y - yhat - s v)`.
fn shifted_criterion(loss: Loss, y: &[f64], yhat: &[f64], v: &[f64], s: f64) -> f64 {
    let n = y.len() as f64;
    let mut acc = [0.0; 4];
    let (cy, rest_y) = (y.chunks_exact(4), y.len() / 4 * 4);
    for ((a, b), c) in cy.zip(yhat.chunks_exact(4)).zip(v.chunks_exact(4)) {
        for k in 0..4 {
            acc[k] += loss.rho(a[k] - b[k] - s * c[k]);
        }
    }
    let tail: f64 = (rest_y..y.len()).map(|t| loss.rho(y[t] - yhat[t] - s * v[t])).sum();
    (acc[0] + acc[1] + acc[2] + acc[3] + tail) / n
}

/// Ridges of [`solve_ridged`], relative to the largest diagonal entry: none first (the inner
/// problem of [b, c] is a linear least-squares problem, well posed unless the L1 set swallows
/// most rows), then from rounding level up to 1e-6, where the shrinkage of the linear
/// parameters is still below the solver's tolerances' effect on the outer criterion.
const INNER_RIDGES: [f64; 4] = [0.0, 1e-12, 1e-9, 1e-6];

/// Solves `(h + ridge) x = g` by Cholesky with the smallest ridge (relative to the largest
/// diagonal entry) that makes it positive definite; false when none does (a degenerate
/// inner problem: every row in the L1 set, or a zero input).
fn solve_ridged(h: &[f64], a: &mut [f64], g: &[f64], x: &mut [f64], d: usize) -> bool {
    if h.iter().chain(g).any(|v| !v.is_finite()) {
        return false;
    }
    let hmax = (0..d).map(|i| h[i * d + i]).fold(0.0, f64::max);
    if hmax <= 0.0 {
        return false;
    }
    for ridge in INNER_RIDGES {
        a.copy_from_slice(h);
        for i in 0..d {
            a[i * d + i] += ridge * hmax;
        }
        if cholesky(a, d) {
            x.copy_from_slice(g);
            cholesky_solve(a, d, x);
            return x.iter().all(|v| v.is_finite());
        }
    }
    false
}
