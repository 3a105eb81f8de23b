//! Judging a model with its initial state fitted (METHOD.md 9.2), as MATLAB's `compare` does.
//!
//! The estimation fits start from zero initial conditions (METHOD.md 2). Judged the same way,
//! a lightly damped model on a short validation record spends the record on the transient of
//! the unknown past and scores a few percent although it is right. The past enters the
//! difference equation `F y = q^-d B u` only in its first `n = max(nF, nB + d - 1)` equations,
//! as an unknown sequence `v` supported on `t < n`, so the free response is
//!
//! ```text
//! y_free = (1/F) v = sum_{j<n} x_j h[t - j],    h = (1/F) delta (impulse response of 1/F)
//! ```
//!
//! and the judged output is `yhat0 + y_free` with `x` the least-squares fit of `y - yhat0`
//! (`yhat0`: zero initial conditions, offset included). The basis is `n` shifts of one
//! sequence, so its Gram matrix and right-hand side are lagged dot products of `h` (O(n L),
//! `L` = where `h` has decayed to rounding), and the small system is solved by Cholesky with a
//! tiny ridge: an inexact `x` only makes the judged fit lower, never flattering.

use super::linalg::{cholesky, cholesky_solve};
use crate::{kernels, oe};

/// The initial state a fitted model is judged with (the job's `initial_state`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InitialState {
    /// Fitted by least squares on the record being judged (the default).
    #[default]
    Estimate,
    /// Zero, as in the estimation (the paper's).
    Zero,
}

crate::names::names!(InitialState { Estimate = "estimate", Zero = "zero" });

/// A fitted model's output on a record (u, y) in the data's units: `q^-d B/F (u - u0) +
/// offset` from zero initial conditions, plus the free response of the fitted initial state
/// with [`InitialState::Estimate`] (the report's simulated outputs; the sweep's judged fits
/// are the same on records with the levels taken out).
#[allow(clippy::too_many_arguments)]
pub fn model_output(
    b: &[f64],
    f: &[f64],
    delay: usize,
    offset: Option<f64>,
    u0: f64,
    u: &[f64],
    y: &[f64],
    initial_state: InitialState,
) -> Vec<f64> {
    let centred: Vec<f64> = u.iter().map(|v| v - u0).collect();
    let mut yhat = oe::simulate_vec(b, f, delay, &centred);
    if let Some(c) = offset {
        yhat.iter_mut().for_each(|v| *v += c);
    }
    if initial_state == InitialState::Estimate {
        add_free_response(f, b.len(), delay, y, &mut yhat);
    }
    yhat
}

/// `yhat` (the model's output from zero initial conditions on a record with output `y`) plus
/// the free response of the initial state that fits `y` best, in place. `f` and `delay`, `nb`
/// are the model's denominator, delay and numerator length.
pub fn add_free_response(f: &[f64], nb: usize, delay: usize, y: &[f64], yhat: &mut [f64]) {
    add_free_response_in(f, nb, delay, y, yhat, &mut Scratch::default())
}

/// The free response of several inputs' filters (METHOD.md 9.2): input i's past enters
/// `F_i y_i = q^-d_i B_i u_i` in its first `n_i = max(nF_i, nB_i + d_i - 1)` equations, so the
/// sum of their free responses is `(1/F) v` with `F = prod_i F_i` and `v` supported on the
/// first `max_i (n_i + sum_{j != i} nF_j)` samples. Returns F's coefficients after the leading
/// 1 and that count; [`add_free_response_in`] with `nb = count + 1`, `delay = 0` fits it.
pub fn common_denominator(s: &crate::oe::Structure, theta: &[f64]) -> (Vec<f64>, usize) {
    let mut f = vec![1.0];
    for i in 0..s.m() {
        let fi = &theta[s.f_range(i)];
        let mut next = vec![0.0; f.len() + fi.len()];
        for (a, &x) in f.iter().enumerate() {
            next[a] += x;
            for (j, &y) in fi.iter().enumerate() {
                next[a + j + 1] += x * y;
            }
        }
        f = next;
    }
    let nf_total: usize = s.inputs().iter().map(|o| o.nf).sum();
    let past =
        s.inputs().iter().map(|o| o.nf.max((o.nb + o.delay).saturating_sub(1)) + nf_total - o.nf).max().unwrap_or(0);
    f.remove(0);
    (f, past)
}

/// Buffers of [`add_free_response_in`], one per worker: the impulse response of 1/F and the
/// residual, each only as long as the impulse response takes to decay (not the record).
#[derive(Default, Debug)]
pub struct Scratch {
    h: Vec<f64>,
    r: Vec<f64>,
}

/// Length of the first stretch of the impulse response computed; each further stretch doubles
/// it (see [`impulse_response`]).
const FIRST_STRETCH: usize = 4096;

/// The impulse response of 1/F into `h`, cut where it has decayed below rounding of its peak
/// (1e-16 of it; at least one sample); None when it is not finite. Computed on a prefix of the
/// record that doubles until its last quarter is all below that level: the recursion is causal,
/// so every sample is the one a whole-record pass gives, and a lightly damped F decays within
/// a few thousand samples, where the whole record may be a million.
fn impulse_response(f: &[f64], n_obs: usize, h: &mut Vec<f64>) -> Option<usize> {
    let mut m = FIRST_STRETCH.min(n_obs);
    loop {
        h.clear();
        h.resize(m, 0.0);
        h[0] = 1.0;
        oe::inv_f_in_place(f, h);
        if h.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let peak = h.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let len = h.iter().rposition(|v| v.abs() > 1e-16 * peak).map_or(1, |i| i + 1);
        if m == n_obs || len <= m - m / 4 {
            return Some(len);
        }
        m = (2 * m).min(n_obs);
    }
}

/// [`add_free_response`] with its buffers in `s`.
pub fn add_free_response_in(f: &[f64], nb: usize, delay: usize, y: &[f64], yhat: &mut [f64], s: &mut Scratch) {
    let n_obs = y.len();
    let n = f.len().max((nb + delay).saturating_sub(1)).min(n_obs);
    if n == 0 {
        return;
    }
    let Some(len) = impulse_response(f, n_obs, &mut s.h) else { return };
    let h = &s.h[..len];
    // The residual where the basis reaches: the first n - 1 + len samples.
    let reach = (n - 1 + len).min(n_obs);
    s.r.clear();
    s.r.extend(y[..reach].iter().zip(&yhat[..reach]).map(|(a, b)| a - b));
    // A missing output (NaN in y, METHOD.md 21.2) is no equation of the least squares: its
    // residual leaves the right-hand side here and its row the Gram matrix below.
    let missing: Vec<usize> = (0..reach).filter(|&t| y[t].is_nan()).collect();
    for &t in &missing {
        s.r[t] = 0.0;
    }
    let r = &s.r;
    // rhs_j = sum_t h[t - j] r[t];  G_ij = sum_{s <= N-1-max(i,j)} h[s] h[s + |i-j|], which is
    // the lag's full product R(lag) = sum_{s < len - lag} h[s] h[s + lag] less at most j end
    // terms where the record ends before h has decayed (vectorised dot products: O(n L)).
    let rhs: Vec<f64> = (0..n)
        .map(|j| {
            let m = (n_obs - j).min(len);
            kernels::dot(&h[..m], &r[j..j + m])
        })
        .collect();
    let full: Vec<f64> =
        (0..n).map(|lag| if lag < len { kernels::dot(&h[..len - lag], &h[lag..len]) } else { 0.0 }).collect();
    let mut g = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let lag = i - j;
            // s runs to min(N - 1 - i, len - 1 - lag); the terms beyond N - 1 - i are the tail.
            let tail: f64 = (n_obs - i..len.saturating_sub(lag)).map(|s| h[s] * h[s + lag]).sum();
            let v = full[lag] - tail;
            g[i * n + j] = v;
            g[j * n + i] = v;
        }
    }
    for &t in &missing {
        // Row t of the basis: h[t - j] for the columns j <= t within h's reach.
        let cols = t.saturating_sub(len - 1)..(t + 1).min(n);
        for i in cols.clone() {
            for j in cols.clone() {
                g[i * n + j] -= h[t - i] * h[t - j];
            }
        }
    }
    let Some(x) = solve_ridged(&g, &rhs, n) else { return };
    for (j, &xj) in x.iter().enumerate() {
        if xj == 0.0 {
            continue;
        }
        let m = (n_obs - j).min(len);
        for (out, &hv) in yhat[j..j + m].iter_mut().zip(&h[..m]) {
            *out += xj * hv;
        }
    }
}

/// First ridge of [`solve_ridged`], relative to the mean diagonal: at rounding level, so a
/// well-posed system is solved as it is.
const RIDGE_FIRST: f64 = 1e-12;
/// Ridges tried, each a thousandfold the last (1e-12 .. 1e3 of the mean diagonal): the free
/// response's Gram matrix is singular when F has (near) common roots with the record's start,
/// and the last ridge turns the solve into a shrunk estimate rather than a failure.
const RIDGE_TRIES: usize = 6;

/// Solves the symmetric positive semi-definite `g x = b` by Cholesky with a ridge of
/// [`RIDGE_FIRST`] of the mean diagonal, raised a thousandfold until the factorisation succeeds.
fn solve_ridged(g: &[f64], b: &[f64], n: usize) -> Option<Vec<f64>> {
    let scale = (0..n).map(|i| g[i * n + i]).sum::<f64>() / n as f64;
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    let mut ridge = RIDGE_FIRST * scale;
    for _ in 0..RIDGE_TRIES {
        let mut l = g.to_vec();
        for i in 0..n {
            l[i * n + i] += ridge;
        }
        if cholesky(&mut l, n) {
            let mut x = b.to_vec();
            cholesky_solve(&l, n, &mut x);
            return x.iter().all(|v| v.is_finite()).then_some(x);
        }
        ridge *= 1e3;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The impulse response computed on doubling prefixes is the whole-record one, cut at the
    /// same sample, for a quickly and a slowly decaying F (the second needs several doublings).
    #[test]
    fn impulse_response_is_the_whole_records_cut() {
        for radius in [0.9, 0.9995] {
            let f = oe::poly_from_roots(&[
                (radius * 0.2f64.cos(), radius * 0.2f64.sin()),
                (radius * 0.2f64.cos(), -radius * 0.2f64.sin()),
            ]);
            let n_obs = 200_000;
            let mut whole = vec![0.0; n_obs];
            whole[0] = 1.0;
            oe::inv_f_in_place(&f, &mut whole);
            let peak = whole.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let want = whole.iter().rposition(|v| v.abs() > 1e-16 * peak).unwrap() + 1;
            let mut h = Vec::new();
            let len = impulse_response(&f, n_obs, &mut h).unwrap();
            assert_eq!(len, want, "radius {radius}");
            assert!(len > FIRST_STRETCH || radius < 0.99, "radius {radius}: {len}");
            assert_eq!(&h[..len], &whole[..len]);
        }
    }

    /// The tail of a record simulated from zero is the full model's output; judged from zero
    /// on the tail alone it is wrong at the start, with the fitted state it is exact.
    #[test]
    fn free_response_recovers_the_tail() {
        let b = [0.3, -0.1, 0.05];
        let f = oe::poly_from_roots(&[
            (0.99 * 0.3f64.cos(), 0.99 * 0.3f64.sin()),
            (0.99 * 0.3f64.cos(), -0.99 * 0.3f64.sin()),
            (0.5, 0.0),
        ]);
        let u: Vec<f64> = (0..600).map(|t| if (t * 7919 % 13) < 6 { 1.0 } else { -1.0 }).collect();
        for delay in [0, 1, 4] {
            let y = oe::simulate_vec(&b, &f, delay, &u);
            let (ut, yt) = (&u[400..], &y[400..]);
            let mut yhat = oe::simulate_vec(&b, &f, delay, ut);
            let before: f64 = yt.iter().zip(&yhat).map(|(a, b)| (a - b).powi(2)).sum();
            add_free_response(&f, b.len(), delay, yt, &mut yhat);
            let after: f64 = yt.iter().zip(&yhat).map(|(a, b)| (a - b).powi(2)).sum();
            assert!(before > 1e-3, "{before}");
            assert!(after < 1e-14 * before.max(1.0), "delay {delay}: {after:e} (from {before:e})");
        }
    }
}
