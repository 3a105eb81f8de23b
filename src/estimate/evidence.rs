//! The evidence that comes with a fitted model (METHOD.md 10): the robust covariance of its
//! parameters and two residual tests.
//!
//! **Covariance.** For an M-estimator of a prediction-error model with influence function
//! `psi_g` (Huber: `clamp(e, -gamma, gamma)`; least squares: `e`), the asymptotic covariance is
//! the sandwich
//!
//! ```text
//! Cov(theta) = kappa (sum_t psi_t psi_t^T)^-1,   kappa = mean(psi_g(e)^2) / mean(psi_g'(e))^2
//! ```
//!
//! (Huber 1981, ch. 7; Ljung 1999, 9.3), `psi_t` the predictor gradient of METHOD.md 2 (and 1 for
//! an offset). For least squares `psi_g' = 1` and `kappa = mean(e^2) = sigma^2`. Reported as the
//! standard deviations `b_std`, `f_std`, `offset_std`, and `max_rel_std = max_i std_i / |theta_i|`
//! (infinite when the Gram matrix is singular: parameters the data do not determine).
//!
//! The inverse is the Cholesky inverse of the formed, diagonally scaled Gram matrix `A` (unit
//! diagonal) when `max_i (A^-1)_ii <= 1e11` ([`COND_LIMIT`]); above, forming `A` has squared a
//! condition that rounding no longer survives, and the inverse is `R^-1 R^-T` from the
//! triangular factor of the scaled Jacobian, `J_s = Q R` (CholeskyQR2 from `A`'s own Cholesky
//! factor, one pass over the rows, where its first `Q` is close to orthogonal; else shifted
//! CholeskyQR3 from `A`, two passes; Householder QR where that fails; O(N d^2)), whose rounding error
//! grows with `cond(J_s)` instead of `cond(J_s)^2` ([`super::jacobian_r`]).
//!
//! **Residual tests** (whiteness, independence from the input): [`super::residual_tests`].
//!
//! **Missing outputs** (METHOD.md 21.3): the sums run over the observed samples O only, `N_O =
//! |O|` in every mean: `kappa = (1/N_O) sum_O psi_g(e)^2 / ((1/N_O) #{t in O: |e_t| <= gamma})^2`
//! and `Cov = kappa (sum_O psi_t psi_t^T)^-1`. A missing sample's Jacobian row is left out (the
//! normal equations give it weight 0, the QR path a zero row); its prediction still depends on
//! theta, but no residual is there to be explained.

use super::huber::Loss;
use super::jacobian_r::qr_inverse;
use super::normal::NormalEquations;
use super::problem::Problem;
use super::residual_tests::{
    MAX_LAG, centre_into, centre_observed, independence_p, lagged_dots2_within, missing_rows_gram, observed_pairs,
    residual_correlations, whiteness_p,
};
use crate::oe;

/// Parameter uncertainty and residual tests of one fitted model.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Evidence {
    pub b_std: Vec<f64>,
    pub f_std: Vec<f64>,
    pub offset_std: Option<f64>,
    /// Largest std / |value| over the parameters (infinite: an undetermined parameter; None:
    /// not computed).
    pub max_rel_std: Option<f64>,
    /// p-values of the residual tests: whiteness, independence from the input (None: not
    /// computed).
    pub resid_white_p: Option<f64>,
    pub resid_indep_p: Option<f64>,
    /// Zeros that cancel a pole within the 95 % region of their difference
    /// ([`super::cancellation`]; None: not computed, or the covariance is singular).
    pub cancellations: Option<u32>,
}

/// Buffers of [`evidence`], one per worker (in the solver's [`super::Workspace`]): the robust
/// residuals, their centred copy, the Gram matrix, and the centred input with its
/// autocorrelation, which are the same for every model of a record and so computed once per
/// record.
#[derive(Default, Debug)]
pub struct Scratch {
    r: Vec<f64>,
    e: Vec<f64>,
    h: Vec<f64>,
    g: Vec<f64>,
    ne: NormalEquations,
    /// The input `uc` and `ruu` were computed from.
    input_of: Vec<f64>,
    seams_of: Vec<usize>,
    missing_of: Vec<usize>,
    uc: Vec<f64>,
    ruu: Vec<f64>,
    /// The missing samples' lag vectors' outer products, summed ([`missing_rows_gram`]).
    less: Vec<f64>,
    /// Row weights of the normal equations: 0 at a missing output, 1 elsewhere.
    w: Vec<f64>,
    /// The observed pairs per lag of the whiteness test ([`observed_pairs`]).
    pairs: Vec<f64>,
}

impl Scratch {
    /// The centred input and its autocorrelation at lags 0..=m, and with missing outputs their
    /// correction and the observed pairs, computed when `u` changed.
    fn input(&mut self, u: &[f64], seams: &[usize], missing: &[usize], m: usize) {
        // Compared by value (one pass, far cheaper than the m + 1 lagged products): a
        // record's buffer may be freed and its address reused by another record.
        if self.input_of == u && self.seams_of == seams && self.missing_of == missing && self.ruu.len() == m + 1 {
            return;
        }
        centre_into(u, &mut self.uc);
        self.ruu.resize(m + 1, 0.0);
        // The input's autocorrelation, by the residuals' kernel and seam rule (its second
        // output is the same sums again, once per record).
        let mut again = [0.0; MAX_LAG + 1];
        lagged_dots2_within(&self.uc, &self.uc, &self.uc, seams, &mut self.ruu, &mut again[..m + 1]);
        self.input_of.clear();
        self.input_of.extend_from_slice(u);
        self.seams_of.clear();
        self.seams_of.extend_from_slice(seams);
        self.missing_of.clear();
        self.missing_of.extend_from_slice(missing);
        missing_rows_gram(&self.uc, seams, missing, m, &mut self.less);
        self.pairs = observed_pairs(u.len(), seams, missing, m);
    }
}

/// The evidence of the model `theta` of `prob` fitted with `loss`; `yhat` is its output on the
/// estimation record (zero initial conditions, offset included), as the criterion saw it, and
/// `xu = (1/F) u`, `xy = (1/F) (yhat - c)` its Jacobian signals (the solver's, reused).
pub fn evidence(
    prob: &Problem,
    theta: &[f64],
    loss: Loss,
    yhat: &[f64],
    xu: &[f64],
    xy: &[f64],
    s: &mut Scratch,
) -> Evidence {
    let n = prob.n_obs();
    s.r.clear();
    s.r.extend(prob.y.iter().zip(yhat).map(|(y, yh)| loss.psi(y - yh)));
    // A missing output's residual (NaN) counts in no sum.
    for &t in prob.missing {
        s.r[t] = 0.0;
    }
    let slope = slope(prob, loss, yhat);
    let d = prob.dim();
    let cov = covariance_in(prob, xu, xy, slope, s);
    let cancellations = cov.as_ref().and_then(|c| cancellations(prob, theta, c));
    let std: Vec<f64> = match cov {
        Some(cov) => (0..d)
            .map(|i| {
                let v = cov[i * d + i];
                if v.is_finite() && v >= 0.0 { v.sqrt() } else { f64::INFINITY }
            })
            .collect(),
        None => vec![f64::INFINITY; d],
    };
    let (b, f) = super::problem::flat_parts(&prob.structure, &std);
    let c = &std[prob.structure.dim()..];
    let max_rel_std = std
        .iter()
        .zip(theta)
        .map(|(s, v)| if s.is_finite() { s / v.abs() } else { f64::INFINITY })
        .fold(0.0, |m: f64, v| if v.is_nan() { f64::INFINITY } else { m.max(v) });
    centre_observed(&s.r, prob.missing, &mut s.e);
    let m = MAX_LAG.min(n.saturating_sub(2));
    // Independence from every input; the least independent one is reported.
    let (mut ree, mut reu) = ([0.0; MAX_LAG + 1], [0.0; MAX_LAG + 1]);
    let (ree, reu) = (&mut ree[..m + 1], &mut reu[..m + 1]);
    let mut indep = f64::INFINITY;
    for i in 0..prob.m() {
        s.input(prob.input(i), prob.seams, prob.missing, m);
        residual_correlations(&s.e, &s.uc, prob.seams, ree, reu);
        indep = indep.min(independence_p(reu, ree[0], n, &s.ruu, &s.less));
    }
    Evidence {
        b_std: b,
        f_std: f,
        offset_std: c.first().copied(),
        // An infinite ratio (an undetermined parameter) is a finding; a NaN or a non-finite
        // p-value is not a number to report.
        max_rel_std: Some(max_rel_std).filter(|v| !v.is_nan()),
        resid_white_p: Some(whiteness_p(ree, n, &s.pairs)).filter(|v| v.is_finite()),
        resid_indep_p: Some(indep).filter(|v| v.is_finite()),
        cancellations,
    }
}

/// Pole-zero cancellations summed over the inputs, each input's B_i and F_i judged with their
/// own block of the covariance `cov` (d x d).
fn cancellations(prob: &Problem, theta: &[f64], cov: &[f64]) -> Option<u32> {
    let d = prob.dim();
    if prob.m() == 1 {
        let (b, f, _) = prob.split(theta);
        return super::cancellation::cancelling_pairs(b, f, cov, d);
    }
    let mut total = 0;
    for i in 0..prob.m() {
        let (b, f) = prob.input_parts(theta, i);
        let idx: Vec<usize> = prob.structure.b_range(i).chain(prob.structure.f_range(i)).collect();
        let k = idx.len();
        let block: Vec<f64> = idx.iter().flat_map(|&r| idx.iter().map(move |&c| cov[r * d + c])).collect();
        total += super::cancellation::cancelling_pairs(b, f, &block, k)?;
    }
    Some(total)
}

/// `mean psi_g'(e)` over the observed outputs: 1 for least squares, the share of the L2 set for
/// Huber (a missing output's NaN residual is in no set).
pub(crate) fn slope(prob: &Problem, loss: Loss, yhat: &[f64]) -> f64 {
    match loss {
        Loss::LeastSquares => 1.0,
        Loss::Huber { gamma } => {
            prob.y.iter().zip(yhat).filter(|(y, yh)| (**y - **yh).abs() <= gamma).count() as f64 / prob.n_obs() as f64
        }
    }
}

/// [`covariance_of`] with the residuals in `s.r` and the Gram matrix in `s`' buffers.
fn covariance_in(prob: &Problem, xu: &[f64], xy: &[f64], slope: f64, s: &mut Scratch) -> Option<Vec<f64>> {
    let d = prob.dim();
    s.h.resize(d * d, 0.0);
    s.g.resize(d, 0.0);
    let w = observed_weights(prob, &mut s.w);
    covariance_of(prob, xu, xy, &s.r, w, slope, &mut s.ne, &mut s.h, &mut s.g)
}

/// The normal equations' row weights of a record with missing outputs (0 at a missing one, 1
/// elsewhere) in `buf`; None for a complete record (the unweighted form, as before).
fn observed_weights<'b>(prob: &Problem, buf: &'b mut Vec<f64>) -> Option<&'b [f64]> {
    if prob.missing.is_empty() {
        return None;
    }
    buf.clear();
    buf.resize(prob.n(), 1.0);
    for &t in prob.missing {
        buf[t] = 0.0;
    }
    Some(&buf[..])
}

/// The covariance matrix of `theta` (d x d, row-major; d = `prob.dim()`) of the model fitted
/// with `loss`, whose output on the estimation record is `yhat`; None when the Gram matrix is
/// singular.
pub fn covariance(prob: &Problem, theta: &[f64], loss: Loss, yhat: &[f64]) -> Option<Vec<f64>> {
    let mut r: Vec<f64> = prob.y.iter().zip(yhat).map(|(y, yh)| loss.psi(y - yh)).collect();
    for &t in prob.missing {
        r[t] = 0.0;
    }
    let (n, m) = (prob.n(), prob.m());
    let (mut xu, mut yh, mut xy) = (vec![0.0; m * n], vec![0.0; n], vec![0.0; m * n]);
    prob.simulate_filtered(theta, &mut xu, &mut yh, &mut xy);
    let d = prob.dim();
    let (mut h, mut g) = (vec![0.0; d * d], vec![0.0; d]);
    let slope = slope(prob, loss, yhat);
    let mut w = Vec::new();
    let w = observed_weights(prob, &mut w);
    covariance_of(prob, &xu, &xy, &r, w, slope, &mut NormalEquations::default(), &mut h, &mut g)
}

/// `kappa / N h^-1` with `kappa = mean(r^2) / slope^2` and `h = (1/N) sum psi psi^T` from the
/// Jacobian signals `xu`, `xy` (`h`, `g`: d x d and d buffers); with missing outputs N is the
/// observed count, the sums are over the observed samples (`w`: 0 at a missing one) and `r`
/// is 0 at a missing sample.
#[allow(clippy::too_many_arguments)]
fn covariance_of(
    prob: &Problem,
    xu: &[f64],
    xy: &[f64],
    r: &[f64],
    w: Option<&[f64]>,
    slope: f64,
    ne: &mut NormalEquations,
    h: &mut [f64],
    g: &mut [f64],
) -> Option<Vec<f64>> {
    let d = prob.dim();
    let n = prob.n_obs();
    if slope <= 0.0 || n == 0 {
        return None;
    }
    let kappa = r.iter().map(|v| v * v).sum::<f64>() / n as f64 / (slope * slope);
    let lay = prob.layout();
    ne.build_all(&lay, prob.offset, prob.seams, xu, xy, w, r, h, g);
    if w.is_some() {
        // The normal equations average over all N rows: over the observed ones instead.
        let scale = prob.n() as f64 / n as f64;
        h[..d * d].iter_mut().for_each(|v| *v *= scale);
    }
    // The inverse from a Cholesky factor of the diagonally scaled matrix (OE Gram matrices
    // span many decades).
    let scale: Vec<f64> = (0..d).map(|i| h[i * d + i].sqrt()).collect();
    if scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        return None;
    }
    let a = faer::Mat::<f64>::from_fn(d, d, |i, j| h[i * d + j] / (scale[i] * scale[j]));
    let chol = crate::dense::Llt::new(a.as_ref());
    let inv = chol.as_ref().map(|chol| chol.inverse());
    let inv: Vec<f64> = match inv {
        // A unit-diagonal matrix has max_i inv_ii >= 1/(d lambda_min) and <= 1/lambda_min:
        // the diagonal of the inverse bounds the condition the Cholesky inverse had to face.
        Some(inv) if (0..d).all(|i| inv[(i, i)] <= COND_LIMIT) => (0..d * d).map(|ij| inv[(ij / d, ij % d)]).collect(),
        _ => qr_inverse(prob, xu, xy, &scale, a.as_ref(), chol.as_ref())?,
    };
    Some((0..d * d).map(|ij| inv[ij] / (scale[ij / d] * scale[ij % d]) * kappa / n as f64).collect())
}

/// Largest condition (as the largest diagonal entry of the inverse of the unit-diagonal Gram
/// matrix) at which the Cholesky inverse of the formed Gram matrix is kept. Forming `J^T J`
/// squares the condition of `J`: its rounding (relative 1e-16 per product, summed over N rows)
/// perturbs the smallest eigenvalues by ~1e-14 of the largest, which at a condition of 1e11
/// moves the covariance by ~1e-3 relative (a std by half that) and near 1e15 by more than
/// itself (the lightly damped OE(12,12) of `tests/covariance_large.rs`, condition 6e15: the
/// factorisation failed in 59 of 100 realisations and the std was otherwise a median 0.48 of
/// the spread, METHOD.md 10). Below the limit the numbers are those of the formed matrix, as
/// before, and `tests/same_table.rs` keeps its numbers bit for bit. At 1e8 the QR path ran for
/// most high orders of the paper grid (`jobs/paper-grid.json`) and cost 28 % of its time; at
/// 1e11 it takes 1348 of the grid's 5164 evidence calls. Their cost, in interleaved runs of
/// an instrumented build on a loaded machine (2 threads): blocked Householder QR (785b7cd) 3.5
/// and 3.9 s, 2.6-2.9 ms a call; shifted CholeskyQR3 (2900eb1) 2.0 and 2.2 s, 1.5-1.6 ms.
const COND_LIMIT: f64 = 1e11;

/// `|G(e^{jw})|` of the model (b, f, delay) and its standard deviation from `cov` (of
/// `[b, f]`, or `[b, f, c]`: the offset does not enter G), to first order through the gradient
/// `dG/db_i = q^(d+i)/F`, `dG/df_j = -G q^j/F` (q = e^{-jw}), `d|G| = Re(conj(G) dG)/|G|`.
pub fn gain_std(b: &[f64], f: &[f64], delay: usize, cov: &[f64], w: f64) -> (f64, f64) {
    let d = (cov.len() as f64).sqrt().round() as usize;
    let (gr, gi) = oe::freq_response(b, f, delay, w);
    let mag = gr.hypot(gi);
    // 1/F at w: G / (q^d B), computed directly.
    let (mut fr, mut fi) = (1.0, 0.0);
    for (j, c) in f.iter().enumerate() {
        let ph = -w * (j + 1) as f64;
        fr += c * ph.cos();
        fi += c * ph.sin();
    }
    let den = fr * fr + fi * fi;
    let (ir, ii) = (fr / den, -fi / den);
    let mut grad = vec![0.0; d];
    for (i, gv) in grad.iter_mut().take(b.len()).enumerate() {
        let ph = -w * (delay + i) as f64;
        let (dr, di) = (ph.cos() * ir - ph.sin() * ii, ph.cos() * ii + ph.sin() * ir);
        *gv = (gr * dr + gi * di) / mag;
    }
    for j in 0..f.len() {
        let ph = -w * (j + 1) as f64;
        // -G q^j / F
        let (qr, qi) = (ph.cos(), ph.sin());
        let (tr, ti) = (gr * qr - gi * qi, gr * qi + gi * qr);
        let (dr, di) = (-(tr * ir - ti * ii), -(tr * ii + ti * ir));
        grad[b.len() + j] = (gr * dr + gi * di) / mag;
    }
    let var: f64 = (0..d).map(|i| (0..d).map(|k| grad[i] * cov[i * d + k] * grad[k]).sum::<f64>()).sum();
    (mag, var.max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The gradient of |G| in theta against central differences: with a covariance that has
    /// one parameter's variance only, the reported std is |d|G|/dtheta_i| times its std.
    #[test]
    fn gain_gradient_matches_finite_differences() {
        let (b, f) = ([0.3, -0.1, 0.05], [-1.2, 0.5]);
        let d = 5;
        for w in [0.05, 0.7, 2.5] {
            for i in 0..d {
                let mut cov = vec![0.0; d * d];
                cov[i * d + i] = 1e-4;
                let (mag, std) = gain_std(&b, &f, 2, &cov, w);
                let gain = |t: &[f64]| {
                    let (re, im) = oe::freq_response(&t[..3], &t[3..], 2, w);
                    re.hypot(im)
                };
                let theta: Vec<f64> = b.iter().chain(&f).copied().collect();
                let (mut tp, mut tm) = (theta.clone(), theta.clone());
                tp[i] += 1e-6;
                tm[i] -= 1e-6;
                let fd = (gain(&tp) - gain(&tm)) / 2e-6;
                assert!((gain(&theta) - mag).abs() < 1e-12);
                assert!(
                    (std - fd.abs() * 1e-2).abs() <= 1e-6 * (1.0 + fd.abs()),
                    "w {w}, theta {i}: {std} vs {}",
                    fd.abs() * 1e-2
                );
            }
        }
    }
}
