//! Initial guess for the prediction-error fit (METHOD.md 5, step 1).
//!
//! ARX least squares regresses `y_t` on `phi_t = [u_{t-d}, .., u_{t-d-nB+1}, -y_{t-1}, .., -y_{t-nF}]`.
//! With output-error noise the `-y` regressors are correlated with the equation error, so ARX
//! is biased, badly so on finely sampled data. The instrumental-variable (IV) refinement
//! replaces `-y` by `-x` in the instruments, `x` the noise-free output simulated from the
//! previous estimate, and solves `(Z^T Phi) theta = Z^T y`. Two IV passes are made; F is made
//! stable by root reflection after each, and the candidate with the lowest least-squares
//! output-error criterion is returned.

use super::solver::Problem;
use crate::oe;
use faer::Mat;
use faer::prelude::*;

/// Regressor matrix with columns `[s1_{t-d-i+1}]_{i=1..nb}` and `[-s2_{t-j}]_{j=1..nf}`, and
/// with an output offset a column of ones: `F (y - c) = B u` is `y = B u - sum f_j y_{t-j} +
/// F(1) c`, linear in `F(1) c`.
fn regressors(prob: &Problem, s2: &[f64]) -> Mat<f64> {
    let (u, nb, nf, delay) = (prob.u, prob.nb, prob.nf, prob.delay);
    let n = u.len();
    Mat::from_fn(n, prob.dim(), |t, c| {
        if c < nb {
            let lag = delay + c;
            if t >= lag { u[t - lag] } else { 0.0 }
        } else if c < nb + nf {
            let lag = c - nb + 1;
            if t >= lag { -s2[t - lag] } else { 0.0 }
        } else {
            1.0
        }
    })
}

/// The regression's last coefficient `F(1) c` as the offset c (F is stable, so F(1) > 0).
fn offset_from_regression(prob: &Problem, theta: &mut [f64]) {
    if prob.offset {
        let f1 = 1.0 + theta[prob.nb..prob.nb + prob.nf].iter().sum::<f64>();
        theta[prob.nb + prob.nf] /= f1;
    }
}

fn finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// ARX least-squares estimate (via QR), F stabilised. None when the regression is degenerate.
pub fn arx(prob: &Problem) -> Option<Vec<f64>> {
    crate::faer_sequential();
    let phi = regressors(prob, prob.y);
    let rhs = Mat::from_fn(prob.n(), 1, |t, _| prob.y[t]);
    let sol = phi.col_piv_qr().solve_lstsq(&rhs);
    let mut theta: Vec<f64> = (0..prob.dim()).map(|i| sol[(i, 0)]).collect();
    if !finite(&theta) {
        return None;
    }
    oe::reflect_unstable(prob.f_mut(&mut theta));
    offset_from_regression(prob, &mut theta);
    Some(theta)
}

/// One IV pass with instruments simulated from `theta`.
fn iv_step(prob: &Problem, theta: &[f64]) -> Option<Vec<f64>> {
    crate::faer_sequential();
    // Instruments from the noise-free output, offset included.
    let x = prob.simulate_vec(theta);
    if !finite(&x) {
        return None;
    }
    let phi = regressors(prob, prob.y);
    let z = regressors(prob, &x);
    let zt_phi = z.transpose() * &phi;
    let zt_y = z.transpose() * Mat::from_fn(prob.n(), 1, |t, _| prob.y[t]);
    let sol = zt_phi.partial_piv_lu().solve(&zt_y);
    let mut th: Vec<f64> = (0..prob.dim()).map(|i| sol[(i, 0)]).collect();
    if !finite(&th) {
        return None;
    }
    oe::reflect_unstable(prob.f_mut(&mut th));
    offset_from_regression(prob, &mut th);
    Some(th)
}

/// Start points for the L2 phase: ARX and its IV refinement (two passes), each with F
/// stable. Least-squares OE fits have local minima (METHOD.md 8), and neither start is
/// reliably the better basin, so the L2 phase runs from each and keeps the lower criterion.
/// Falls back to `b = 0, F = 1` when the regressions are degenerate.
///
/// With an output offset ([`Problem::offset`]) the regressions carry a constant column.
pub fn initial_guesses(prob: &Problem) -> Vec<Vec<f64>> {
    let mut out = Vec::new();
    if let Some(a) = arx(prob) {
        let mut cur = a.clone();
        out.push(a);
        if prob.nf > 0 {
            let mut refined = None;
            for _ in 0..2 {
                match iv_step(prob, &cur) {
                    Some(next) => {
                        cur = next.clone();
                        refined = Some(next);
                    }
                    None => break,
                }
            }
            out.extend(refined);
        }
    }
    if out.is_empty() {
        out.push(vec![0.0; prob.dim()]);
    }
    out
}
