//! Initial guess for the prediction-error fit (METHOD.md 5, step 1).
//!
//! ARX least squares regresses `y_t` on `phi_t = [u_{t-d}, .., u_{t-d-nB+1}, -y_{t-1}, .., -y_{t-nF}]`.
//! With output-error noise the `-y` regressors are correlated with the equation error, so ARX
//! is biased, badly so on finely sampled data. The instrumental-variable (IV) refinement
//! replaces `-y` by `-x` in the instruments, `x` the noise-free output simulated from the
//! previous estimate, and solves `(Z^T Phi) theta = Z^T y`. Two IV passes are made; F is made
//! stable by root reflection after each, and the candidate with the lowest least-squares
//! output-error criterion is returned.
//!
//! Missing outputs (METHOD.md 21.3): a regression row whose target `y_t` or one of its output
//! lags `y_{t-1} .. y_{t-nF}` is missing is left out ([`kept_rows`]): the row's equation needs
//! those outputs, and taking them as zero would be a wrong equation. The rows kept are those of
//! the stretches of observed outputs (`data::observed_ranges`), less the first nF of a stretch
//! that a gap (not its experiment's start) begins; the input lags may reach back across a gap
//! (the inputs are complete), never across a seam.

use super::problem::Problem;
use faer::prelude::ReborrowMut;
use faer::{Mat, MatMut};

/// What column `c` of the regressor matrix holds: columns `[u_{t-d-i+1}]_{i=1..nb}` and
/// `[-s2_{t-j}]_{j=1..nf}`, and with an output offset a column of ones: `F (y - c) = B u` is
/// `y = B u - sum f_j y_{t-j} + F(1) c`, linear in `F(1) c`. Column `dim` is `y_t` itself
/// (the right-hand side rides along as one more column). A lagged column is zero where its lag
/// reaches back across the start of the experiment t belongs to.
enum Column<'s> {
    /// `sign * src[t - lag]`.
    Lagged {
        src: &'s [f64],
        lag: usize,
        negate: bool,
    },
    Ones,
    Target,
}

fn column<'s>(prob: &Problem<'s>, s2: &'s [f64], c: usize) -> Column<'s> {
    let (nb, nf, delay) = (prob.one().nb, prob.one().nf, prob.one().delay);
    if c < nb {
        Column::Lagged { src: prob.u, lag: delay + c, negate: false }
    } else if c < nb + nf {
        Column::Lagged { src: s2, lag: c - nb + 1, negate: true }
    } else if c < prob.dim() {
        Column::Ones
    } else {
        Column::Target
    }
}

/// Entry (t, c) of the regressor matrix ([`Column`]).
pub(super) fn regressor(prob: &Problem, s2: &[f64], t: usize, c: usize) -> f64 {
    match column(prob, s2, c) {
        Column::Lagged { src, lag, negate } => {
            if t >= prob.experiment_start(t) + lag {
                if negate { -src[t - lag] } else { src[t - lag] }
            } else {
                0.0
            }
        }
        Column::Ones => 1.0,
        Column::Target => prob.y[t],
    }
}

/// Rows per block of the streamed products below: the regressions never hold more than this
/// many rows, so their memory does not grow with N (a whole N x d regressor matrix, and the
/// packing buffers faer's blocked QR keeps per thread for it, took 80 MB per worker at
/// N = 131 072).
const BLOCK: usize = 256;

/// The triangular factor R of the n x `cols` matrix `A` (`R^T R = A^T A`), by QR of
/// `[R; next block of rows]` block after block; `a(t0, block)` writes rows `t0..` of `A` into
/// the zeroed `block`.
fn r_factor(n: usize, cols: usize, a: impl Fn(usize, MatMut<'_, f64>)) -> Mat<f64> {
    let mut r = Mat::<f64>::zeros(0, cols);
    for t0 in (0..n).step_by(BLOCK) {
        let m = BLOCK.min(n - t0);
        let k = r.nrows();
        let mut stacked = Mat::<f64>::zeros(k + m, cols);
        stacked.as_mut().get_mut(..k, ..).copy_from(r.as_ref());
        a(t0, stacked.as_mut().get_mut(k.., ..));
        r = crate::dense::qr_r(stacked.as_ref());
    }
    r
}

/// `Z^T A` for the n-row matrices `Z` (`zc` columns) and `A` (`ac` columns), summed block by
/// block; `z(t0, block)` and `a(t0, block)` write rows `t0..` into the zeroed `block`.
pub(super) fn cross_product(
    n: usize,
    zc: usize,
    ac: usize,
    z: impl Fn(usize, MatMut<'_, f64>),
    a: impl Fn(usize, MatMut<'_, f64>),
) -> Mat<f64> {
    let mut out = Mat::<f64>::zeros(zc, ac);
    for t0 in (0..n).step_by(BLOCK) {
        let m = BLOCK.min(n - t0);
        let mut zb = Mat::<f64>::zeros(m, zc);
        z(t0, zb.as_mut());
        let mut ab = Mat::<f64>::zeros(m, ac);
        a(t0, ab.as_mut());
        out += crate::dense::mul(zb.transpose(), ab.as_ref());
    }
    out
}

/// Rows `t0 .. t0 + block.nrows()` of the regressor matrix ([`kept_regressor`]: `keep`, `s2`)
/// into the zeroed `block` (its first `block.ncols()` columns), column by column. Where the
/// rows lie in one experiment and every row is kept (a complete record), a column is its
/// signal shifted by its lag (negated for the output lags), zero before the lag reaches into
/// the experiment: the values of [`regressor`] entry by entry, copied as slices (filling
/// the blocks entry by entry, an experiment lookup per entry, was half the time of the initial
/// guesses, 4 % of the paper grid's). Elsewhere entry by entry.
fn regressor_rows(prob: &Problem, keep: Option<&[bool]>, s2: &[f64], t0: usize, mut block: MatMut<'_, f64>) {
    let m = block.nrows();
    let start = prob.experiment_start(t0);
    if keep.is_some() || m == 0 || prob.experiment_start(t0 + m - 1) != start {
        for c in 0..block.ncols() {
            for i in 0..m {
                block[(i, c)] = kept_regressor(prob, keep, s2, t0 + i, c);
            }
        }
        return;
    }
    for c in 0..block.ncols() {
        let col =
            block.rb_mut().col_mut(c).try_as_col_major_mut().expect("a column of a column-major block").as_slice_mut();
        match column(prob, s2, c) {
            Column::Lagged { src, lag, negate } => {
                // Rows t >= start + lag take the signal at t - lag; the rows before stay zero.
                let first = (start + lag).saturating_sub(t0).min(m);
                for (i, v) in col.iter_mut().enumerate().skip(first) {
                    let x = src[t0 + i - lag];
                    *v = if negate { -x } else { x };
                }
            }
            Column::Ones => col.fill(1.0),
            Column::Target => col.copy_from_slice(&prob.y[t0..t0 + m]),
        }
    }
}

/// The regression rows kept on a record with missing outputs (see the module doc): every row of
/// a stretch of observed outputs that begins at its experiment's start (its lags before the
/// start are zero, as a complete record's), the rest of a stretch from its (nF+1)-th row on.
/// None for a complete record: every row, the code path of before.
fn kept_rows(prob: &Problem) -> Option<Vec<bool>> {
    if prob.missing.is_empty() {
        return None;
    }
    let lags = prob.structure.inputs().iter().map(|o| o.nf).max().unwrap_or(0);
    let mut keep = vec![false; prob.n()];
    for r in crate::data::observed_ranges(prob.n(), prob.seams, prob.missing) {
        let first = if prob.experiment_start(r.start) == r.start { r.start } else { (r.start + lags).min(r.end) };
        keep[first..r.end].fill(true);
    }
    Some(keep)
}

/// [`regressor`] of the rows kept (`keep` of [`kept_rows`]), a zero row for the others: a zero
/// row adds nothing to `R^T R` or `Z^T A`, so the streamed products below are those of the
/// kept rows alone.
fn kept_regressor(prob: &Problem, keep: Option<&[bool]>, s2: &[f64], t: usize, c: usize) -> f64 {
    if keep.is_none_or(|k| k[t]) { regressor(prob, s2, t, c) } else { 0.0 }
}

/// The regression's last coefficient `F(1) c` as the offset c (F is stable, so F(1) > 0).
fn offset_from_regression(prob: &Problem, theta: &mut [f64]) {
    if prob.offset {
        let f1 = 1.0 + theta[prob.one().nb..prob.one().nb + prob.one().nf].iter().sum::<f64>();
        theta[prob.one().nb + prob.one().nf] /= f1;
    }
}

fn finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// ARX least-squares estimate, F stabilised. None when the regression is degenerate. The
/// streamed factor R of `[Phi | y]` turns the N-row problem into the equivalent (d+1)-row
/// one `min ||R_Phi theta - r_y||`, which column-pivoted QR solves (rank-revealing, as the
/// whole regression would be).
pub fn arx(prob: &Problem) -> Option<Vec<f64>> {
    let d = prob.dim();
    let keep = kept_rows(prob);
    let keep = keep.as_deref();
    let r = r_factor(prob.n(), d + 1, |t0, block| regressor_rows(prob, keep, prob.y, t0, block));
    let rows = r.nrows();
    let lhs = Mat::from_fn(rows, d, |i, c| r[(i, c)]);
    let rhs = Mat::from_fn(rows, 1, |i, _| r[(i, d)]);
    let sol = crate::dense::lstsq(lhs.as_ref(), rhs.as_ref());
    let mut theta: Vec<f64> = (0..d).map(|i| sol[(i, 0)]).collect();
    if !finite(&theta) {
        return None;
    }
    prob.reflect_unstable(&mut theta);
    offset_from_regression(prob, &mut theta);
    Some(theta)
}

/// One IV pass with instruments simulated from `theta`.
fn iv_step(prob: &Problem, theta: &[f64]) -> Option<Vec<f64>> {
    // Instruments from the noise-free output, offset included.
    let x = prob.simulate_vec(theta);
    if !finite(&x) {
        return None;
    }
    let d = prob.dim();
    let keep = kept_rows(prob);
    let keep = keep.as_deref();
    // Z^T [Phi | y]: the system and its right-hand side in one product.
    let zt = cross_product(
        prob.n(),
        d,
        d + 1,
        |t0, block| regressor_rows(prob, keep, &x, t0, block),
        |t0, block| regressor_rows(prob, keep, prob.y, t0, block),
    );
    let zt_phi = Mat::from_fn(d, d, |i, c| zt[(i, c)]);
    let zt_y = Mat::from_fn(d, 1, |i, _| zt[(i, d)]);
    let sol = crate::dense::Lu::new(zt_phi.as_ref()).solve(zt_y.as_ref());
    let mut th: Vec<f64> = (0..d).map(|i| sol[(i, 0)]).collect();
    if !finite(&th) {
        return None;
    }
    prob.reflect_unstable(&mut th);
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
    if prob.m() > 1 {
        return vec![backfit(prob)];
    }
    let mut out = Vec::new();
    if let Some(a) = arx(prob) {
        let mut cur = a.clone();
        out.push(a);
        if prob.one().nf > 0 {
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

/// Backfitting rounds of [`backfit`]: the peer's count (`../shared/peer/peer_miso.py`); the
/// least-squares fit that follows does the rest.
const BACKFIT_ROUNDS: usize = 3;

/// The start of several inputs: each input's one-input start (the best of ARX and IV by its
/// output error) fitted to the output less the other inputs' current contributions, input
/// after input, [`BACKFIT_ROUNDS`] times. A common ARX denominator of every input need not
/// factor into the F_i; this gives every F_i a stable start of its own. The offset is the
/// last input's fit's.
fn backfit(prob: &Problem) -> Vec<f64> {
    let (n, m) = (prob.n(), prob.m());
    let mut theta = vec![0.0; prob.dim()];
    let mut contribution = vec![vec![0.0; n]; m];
    let mut target = vec![0.0; n];
    for _ in 0..BACKFIT_ROUNDS {
        for i in 0..m {
            for (t, v) in target.iter_mut().enumerate() {
                *v = prob.y[t] - (0..m).filter(|&j| j != i).map(|j| contribution[j][t]).sum::<f64>();
            }
            let o = prob.structure.inputs()[i];
            let one = Problem {
                u: prob.input(i),
                y: &target,
                structure: crate::oe::Structure::siso(o.nb, o.nf, o.delay),
                offset: prob.offset,
                seams: prob.seams,
                missing: prob.missing,
            };
            // Over the observed outputs (a missing one is NaN in the target; elsewhere a NaN is
            // a diverged simulation's, which makes the start's error infinite).
            let sse = |th: &[f64]| {
                let e: f64 = one
                    .simulate_vec(th)
                    .iter()
                    .zip(&target)
                    .filter(|(_, b)| one.missing.is_empty() || !b.is_nan())
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum();
                if e.is_finite() { e } else { f64::INFINITY }
            };
            let Some(best) = initial_guesses(&one).into_iter().min_by(|a, b| sse(a).total_cmp(&sse(b))) else {
                continue;
            };
            let (b, f, c) = one.split(&best);
            theta[prob.structure.b_range(i)].copy_from_slice(b);
            theta[prob.structure.f_range(i)].copy_from_slice(f);
            if prob.offset {
                theta[prob.structure.dim()] = c;
            }
            let plain = Problem { offset: false, ..one };
            plain.simulate(&crate::estimate::theta_of(b, f, None), &mut contribution[i]);
        }
    }
    theta
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::Structure;

    /// The blocks written column by column hold [`kept_regressor`]'s values bit for bit, on a
    /// complete record, on one of several experiments (blocks that span a seam, lags cut at
    /// it) and on one with missing outputs, with and without an offset, at every block start.
    #[test]
    fn regressor_blocks_are_the_entries() {
        let n = 700;
        let u: Vec<f64> = (0..n).map(|t| ((t * 37 % 11) as f64 - 5.0) * 0.3 + t as f64 * 1e-3).collect();
        let y: Vec<f64> = (0..n).map(|t| ((t * 13 % 7) as f64 - 3.0) * 0.7 - t as f64 * 2e-3).collect();
        let s2: Vec<f64> = y.iter().map(|v| v * 0.5 + 0.25).collect();
        let seams = [250, 256, 300];
        let mut y_missing = y.clone();
        let missing = [3, 255, 411];
        for &t in &missing {
            y_missing[t] = f64::NAN;
        }
        for (seams, missing, y) in
            [(&[][..], &[][..], &y), (&seams[..], &[][..], &y), (&[][..], &missing[..], &y_missing)]
        {
            for offset in [false, true] {
                let prob = Problem { u: &u, y, structure: Structure::siso(4, 3, 2), offset, seams, missing };
                let keep = kept_rows(&prob);
                let cols = prob.dim() + 1;
                for t0 in [0, 1, 5, 240, 256, 299, 500, 690] {
                    let m = 16.min(n - t0);
                    let mut block = Mat::<f64>::zeros(m, cols);
                    regressor_rows(&prob, keep.as_deref(), &s2, t0, block.as_mut());
                    for i in 0..m {
                        for c in 0..cols {
                            let want = kept_regressor(&prob, keep.as_deref(), &s2, t0 + i, c);
                            let got = block[(i, c)];
                            assert!(
                                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                                "seams {seams:?} missing {missing:?} offset {offset} row {} column {c}: {got} != {want}",
                                t0 + i
                            );
                        }
                    }
                }
            }
        }
    }
}
