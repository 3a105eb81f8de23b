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

/// Regressor matrix with columns `[s1_{t-d-i+1}]_{i=1..nb}` and `[-s2_{t-j}]_{j=1..nf}`.
fn regressors(u: &[f64], s2: &[f64], nb: usize, nf: usize, delay: usize) -> Mat<f64> {
    let n = u.len();
    Mat::from_fn(n, nb + nf, |t, c| {
        if c < nb {
            let lag = delay + c;
            if t >= lag { u[t - lag] } else { 0.0 }
        } else {
            let lag = c - nb + 1;
            if t >= lag { -s2[t - lag] } else { 0.0 }
        }
    })
}

fn finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// ARX least-squares estimate (via QR), F stabilised. None when the regression is degenerate.
pub fn arx(prob: &Problem) -> Option<Vec<f64>> {
    crate::faer_sequential();
    let phi = regressors(prob.u, prob.y, prob.nb, prob.nf, prob.delay);
    let rhs = Mat::from_fn(prob.n(), 1, |t, _| prob.y[t]);
    let sol = phi.col_piv_qr().solve_lstsq(&rhs);
    let mut theta: Vec<f64> = (0..prob.dim()).map(|i| sol[(i, 0)]).collect();
    if !finite(&theta) {
        return None;
    }
    oe::reflect_unstable(&mut theta[prob.nb..]);
    Some(theta)
}

/// One IV pass with instruments simulated from `theta`.
fn iv_step(prob: &Problem, theta: &[f64]) -> Option<Vec<f64>> {
    crate::faer_sequential();
    let (nb, nf) = (prob.nb, prob.nf);
    let x = oe::simulate_vec(&theta[..nb], &theta[nb..], prob.delay, prob.u);
    if !finite(&x) {
        return None;
    }
    let phi = regressors(prob.u, prob.y, nb, nf, prob.delay);
    let z = regressors(prob.u, &x, nb, nf, prob.delay);
    let zt_phi = z.transpose() * &phi;
    let zt_y = z.transpose() * Mat::from_fn(prob.n(), 1, |t, _| prob.y[t]);
    let sol = zt_phi.partial_piv_lu().solve(&zt_y);
    let mut th: Vec<f64> = (0..prob.dim()).map(|i| sol[(i, 0)]).collect();
    if !finite(&th) {
        return None;
    }
    oe::reflect_unstable(&mut th[nb..]);
    Some(th)
}

/// Start points for the L2 phase: ARX and its IV refinement (two passes), each with F
/// stable. Least-squares OE fits have local minima (METHOD.md 8), and neither start is
/// reliably the better basin, so the L2 phase runs from each and keeps the lower criterion.
/// Falls back to `b = 0, F = 1` when the regressions are degenerate.
///
/// With an output offset ([`Problem::offset`]) the regressions run on the output less its
/// mean, and each guess gets the offset that centres its residuals.
pub fn initial_guesses(prob: &Problem) -> Vec<Vec<f64>> {
    if prob.offset {
        let mean = prob.y.iter().sum::<f64>() / prob.n() as f64;
        let centred: Vec<f64> = prob.y.iter().map(|v| v - mean).collect();
        let plain = Problem { y: &centred, offset: false, ..*prob };
        return initial_guesses(&plain)
            .into_iter()
            .map(|mut g| {
                let sim = oe::simulate_vec(&g[..prob.nb], &g[prob.nb..], prob.delay, prob.u);
                let c = prob.y.iter().zip(&sim).map(|(y, s)| y - s).sum::<f64>() / prob.n() as f64;
                g.push(if c.is_finite() { c } else { mean });
                g
            })
            .collect();
    }
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
