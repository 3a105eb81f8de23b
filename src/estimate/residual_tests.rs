//! The residual tests that come with a fitted model (METHOD.md 10), on its robust residuals
//! `psi_g(e)` so that a spike does not dominate (Ljung 1999, 16.6):
//! - whiteness: the portmanteau statistic `Q = N (N+2) sum_{k=1}^{M} rho_k^2 / (N-k)` of their
//!   autocorrelations `rho_k`, chi-squared with M degrees of freedom (Ljung-Box);
//! - independence from past inputs: the cross-correlations `r_k` of the residuals with the
//!   input at lags `k = 0..M`; under independence `sqrt(N) r` is normal with covariance
//!   `sigma_e^2 R_u` (the input's Toeplitz autocovariance), so
//!   `zeta = N r^T R_u^-1 r / sigma_e^2` is chi-squared with M + 1 degrees of freedom.
//!
//! Both as p-values (`resid_white_p`, `resid_indep_p`), M = 25, their lagged products taken
//! within each experiment of a record (`seams`) and in one pass over the record
//! ([`residual_correlations`]). The report's correlation plot ([`correlation_functions`])
//! shows the same correlations.
//!
//! Missing outputs (METHOD.md 21.3): the residuals are centred over the observed samples O and
//! set to 0 at a missing one ([`centre_observed`]), so a lagged product counts only where the
//! residuals it pairs are observed. `N = N_O` throughout. Whiteness: `rho_k = sum_{pairs} e_s
//! e_{s+k} / sum_O e^2` over the `n_k` pairs with both residuals observed within one experiment
//! ([`observed_pairs`]); under whiteness its variance is `n_k / N_O^2`, so `Q = N_O (N_O + 2)
//! sum_k rho_k^2 / n_k` (a complete record: `n_k = N - k`, Ljung-Box's). Independence: `r_k =
//! sum_{t in O} e_t u_{t-k}` has covariance `sigma_e^2 C`, `C = sum_{t in O} v_t v_t^T` with
//! `v_t = (u_t, .., u_{t-M})`; C is the input's Toeplitz autocorrelation less the missing
//! samples' `v_t v_t^T` ([`missing_rows_gram`]), and `zeta = r^T C^-1 r / sigma_e^2`.

use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::kernels;

/// Largest lag of the residual tests.
pub const MAX_LAG: usize = 25;

/// [`kernels::lagged_dots2`] over the pairs within one experiment (`seams` as in
/// [`crate::estimate::Problem::seams`]; empty: the kernel itself): `out_a[L] = sum_s a[s] c[s + L]`,
/// `out_b[L] = sum_s b[s] c[s + L]`, no product pairing samples of two experiments.
pub(super) fn lagged_dots2_within(
    a: &[f64],
    b: &[f64],
    c: &[f64],
    seams: &[usize],
    out_a: &mut [f64],
    out_b: &mut [f64],
) {
    if seams.is_empty() {
        kernels::lagged_dots2(a, b, c, out_a, out_b);
        return;
    }
    let lags = out_a.len();
    out_a.fill(0.0);
    out_b.fill(0.0);
    let (mut pa, mut pb) = ([0.0; MAX_LAG + 1], [0.0; MAX_LAG + 1]);
    for x in crate::data::experiment_ranges(c.len(), seams) {
        let m = lags.min(x.len());
        kernels::lagged_dots2(&a[x.clone()], &b[x.clone()], &c[x], &mut pa[..m], &mut pb[..m]);
        for (o, p) in out_a.iter_mut().zip(&pa[..m]) {
            *o += p;
        }
        for (o, p) in out_b.iter_mut().zip(&pb[..m]) {
            *o += p;
        }
    }
}

/// The residuals' autocorrelation `ree[L] = sum_s e[s] e[s + L]` and their cross-correlation
/// with the input `reu[L] = sum_s u[s] e[s + L]` at lags `0..ree.len()`, within each
/// experiment, in one pass over the record.
pub(super) fn residual_correlations(e: &[f64], u: &[f64], seams: &[usize], ree: &mut [f64], reu: &mut [f64]) {
    lagged_dots2_within(e, u, e, seams, ree, reu);
}

/// Ljung-Box p-value of `n` centred residuals over lags 1..=m from their autocorrelation
/// `acf` at lags 0..=m ([`residual_correlations`]); `pairs` are the observed pairs per lag of a
/// record with missing outputs ([`observed_pairs`]; empty: `n - k`).
pub(super) fn whiteness_p(acf: &[f64], n: usize, pairs: &[f64]) -> f64 {
    let m = acf.len() - 1;
    if m == 0 {
        return f64::NAN;
    }
    if acf[0] <= 0.0 {
        return f64::NAN;
    }
    let nf = n as f64;
    let count = |k: usize| if pairs.is_empty() { nf - k as f64 } else { pairs[k] };
    let q = nf * (nf + 2.0) * (1..=m).map(|k| (acf[k] / acf[0]).powi(2) / count(k)).sum::<f64>();
    chi2_sf(q, m)
}

/// p-value of the independence of `n` centred residuals from the input at lags 0..=m, from
/// their cross-correlation with the centred input `reu` and their sum of squares `see`
/// ([`residual_correlations`]); `ruu` is the input's autocorrelation at lags 0..=m, `less` the
/// missing outputs' correction of its Toeplitz matrix ([`missing_rows_gram`]; empty: none).
pub(super) fn independence_p(reu: &[f64], see: f64, n: usize, ruu: &[f64], less: &[f64]) -> f64 {
    let m = ruu.len() - 1;
    // r_k = (1/N) sum_t e_t u_{t-k} = (1/N) sum_s u_s e_{s+k}.
    let nf = n as f64;
    let sigma2 = see / nf;
    if !(sigma2 > 0.0 && ruu[0] > 0.0) {
        return f64::NAN;
    }
    let k = m + 1;
    let toeplitz = faer::Mat::<f64>::from_fn(k, k, |i, j| {
        if less.is_empty() { ruu[i.abs_diff(j)] / nf } else { (ruu[i.abs_diff(j)] - less[i * k + j]) / nf }
    });
    let rhs = faer::Mat::<f64>::from_fn(k, 1, |i, _| reu[i] / nf);
    let Some(chol) = crate::dense::Llt::new(toeplitz.as_ref()) else { return f64::NAN };
    let x = chol.solve(rhs.as_ref());
    let zeta = nf * (0..k).map(|i| rhs[(i, 0)] * x[(i, 0)]).sum::<f64>() / sigma2;
    chi2_sf(zeta, k)
}

/// The correlation functions the tests are made of (MATLAB's `resid` plots): the
/// autocorrelation of the residuals `r` at lags 0..=[`MAX_LAG`] and their cross-correlation
/// with the input, `sum_t r_t u_{t-k} / sqrt(sum r^2 sum u^2)`, at lags 0..=MAX_LAG (means
/// removed). Under the tests' null hypotheses each is within `2.58 / sqrt(N)` with
/// probability 0.99 (for the cross-correlation, when the residuals are white). The lagged
/// products stay within each experiment (`seams` as in [`Problem::seams`]), as the tests' own,
/// and with missing outputs (`missing`, as [`Problem::missing`]) over the observed residuals:
/// every sum over t is over the observed samples, and N is their count.
pub fn correlation_functions(r: &[f64], u: &[f64], seams: &[usize], missing: &[usize]) -> (Vec<f64>, Vec<f64>) {
    let m = MAX_LAG.min((r.len() - missing.len().min(r.len())).saturating_sub(2));
    let mut e = Vec::new();
    centre_observed(r, missing, &mut e);
    let u = centred(u);
    let (mut ree, mut ruu, mut reu) = (vec![0.0; m + 1], vec![0.0; 1], vec![0.0; m + 1]);
    residual_correlations(&e, &u, seams, &mut ree, &mut reu);
    if missing.is_empty() {
        kernels::lagged_dots(&u, &u, &mut ruu);
    } else {
        // The input's power over the observed samples, the residuals' own.
        ruu[0] = u.iter().map(|v| v * v).sum::<f64>() - missing.iter().map(|&t| u[t] * u[t]).sum::<f64>();
    }
    let norm = (ree[0] * ruu[0]).sqrt();
    (ree.iter().map(|v| v / ree[0]).collect(), reu.iter().map(|v| v / norm).collect())
}

fn centred(x: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    centre_into(x, &mut out);
    out
}

/// `out = x - mean(x)` over the samples not in `missing` (sorted), and 0 at those: a missing
/// residual then adds nothing to any lagged product. A complete record: [`centre_into`].
pub(super) fn centre_observed(x: &[f64], missing: &[usize], out: &mut Vec<f64>) {
    if missing.is_empty() {
        return centre_into(x, out);
    }
    out.clear();
    out.extend_from_slice(x);
    for &t in missing {
        out[t] = 0.0;
    }
    let mean = out.iter().sum::<f64>() / (x.len() - missing.len()) as f64;
    out.iter_mut().for_each(|v| *v -= mean);
    for &t in missing {
        out[t] = 0.0;
    }
}

/// `C_ij = sum_{t in missing} v_t[i] v_t[j]` (i, j in 0..=m, row-major in `out`), `v_t[i] =
/// u[t - i]` within t's experiment (0 before its start): what the missing samples' rows add to
/// the input's Toeplitz autocorrelation, which [`independence_p`] takes out. Empty `out` for
/// a complete record.
pub(super) fn missing_rows_gram(u: &[f64], seams: &[usize], missing: &[usize], m: usize, out: &mut Vec<f64>) {
    out.clear();
    if missing.is_empty() {
        return;
    }
    let k = m + 1;
    out.resize(k * k, 0.0);
    let mut v = vec![0.0; k];
    for &t in missing {
        let start = match seams.partition_point(|&s| s <= t) {
            0 => 0,
            i => seams[i - 1],
        };
        for (i, vi) in v.iter_mut().enumerate() {
            *vi = if t >= start + i { u[t - i] } else { 0.0 };
        }
        for i in 0..k {
            for j in 0..k {
                out[i * k + j] += v[i] * v[j];
            }
        }
    }
}

/// `n_k`, k in 0..=m: the pairs (s, s + k) within one experiment whose outputs are both
/// observed (`missing` sorted), by inclusion and exclusion over the missing samples. Empty for
/// a complete record (the tests then take Ljung-Box's `N - k`).
pub(super) fn observed_pairs(n: usize, seams: &[usize], missing: &[usize], m: usize) -> Vec<f64> {
    if missing.is_empty() {
        return Vec::new();
    }
    let mut out = vec![0.0; m + 1];
    for e in crate::data::experiment_ranges(n, seams) {
        let miss = &missing[missing.partition_point(|&t| t < e.start)..missing.partition_point(|&t| t < e.end)];
        for (k, o) in out.iter_mut().enumerate() {
            if e.len() <= k {
                continue;
            }
            let first = miss.iter().filter(|&&t| t + k < e.end).count();
            let second = miss.iter().filter(|&&t| t >= e.start + k).count();
            let both = miss.iter().filter(|&&t| t + k < e.end && miss.binary_search(&(t + k)).is_ok()).count();
            *o += (e.len() - k + both - first - second) as f64;
        }
    }
    out
}

/// `out = x - mean(x)`.
pub(super) fn centre_into(x: &[f64], out: &mut Vec<f64>) {
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    out.clear();
    out.extend(x.iter().map(|v| v - mean));
}

/// `P(X > q)` for X chi-squared with `dof` degrees of freedom.
fn chi2_sf(q: f64, dof: usize) -> f64 {
    match ChiSquared::new(dof as f64) {
        Ok(dist) if q.is_finite() => dist.sf(q.max(0.0)),
        _ => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The report's correlation functions are the residual tests' ones: no lagged product
    /// pairs samples of two experiments (checked against the sum over pairs written out).
    #[test]
    fn correlation_functions_keep_lags_within_experiments() {
        let n = 900;
        let u: Vec<f64> = (0..n).map(|t| ((t * 37 % 23) as f64 - 11.0) * 0.1).collect();
        // Residuals that repeat the input one sample later: every cross-correlation lag but 1
        // is small, and lag 1 across a seam would pair two experiments' samples.
        let r: Vec<f64> =
            (0..n).map(|t| if t == 0 { 0.0 } else { u[t - 1] } + ((t * 11 % 7) as f64 - 3.0) * 0.01).collect();
        let seams = [300, 650];
        let (acf, ccf) = correlation_functions(&r, &u, &seams, &[]);
        let centred = |x: &[f64]| {
            let m = x.iter().sum::<f64>() / x.len() as f64;
            x.iter().map(|v| v - m).collect::<Vec<f64>>()
        };
        let (e, uc) = (centred(&r), centred(&u));
        let experiment = |t: usize| seams.iter().filter(|&&s| s <= t).count();
        let within = |a: &[f64], b: &[f64], lag: usize| {
            (0..n - lag).filter(|&s| experiment(s) == experiment(s + lag)).map(|s| a[s] * b[s + lag]).sum::<f64>()
        };
        let (ee0, uu0) = (within(&e, &e, 0), within(&uc, &uc, 0));
        assert_eq!(acf.len(), MAX_LAG + 1);
        for lag in 0..=MAX_LAG {
            let want_acf = within(&e, &e, lag) / ee0;
            let want_ccf = within(&uc, &e, lag) / (ee0 * uu0).sqrt();
            assert!((acf[lag] - want_acf).abs() <= 1e-12, "acf lag {lag}: {} vs {want_acf}", acf[lag]);
            assert!((ccf[lag] - want_ccf).abs() <= 1e-12, "ccf lag {lag}: {} vs {want_ccf}", ccf[lag]);
        }
        // Across the seams the answer differs: the test above can tell the two apart.
        let (_, ccf_joined) = correlation_functions(&r, &u, &[], &[]);
        assert!((ccf_joined[1] - ccf[1]).abs() > 1e-6);
    }

    #[test]
    fn white_noise_passes_and_a_moving_average_fails() {
        let mut s = 99u64;
        let mut normal = || {
            let mut u = || {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((s >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        let e: Vec<f64> = (0..4000).map(|_| normal()).collect();
        let u: Vec<f64> = (0..4000).map(|_| normal()).collect();
        // (whiteness p, independence p) of residuals x against the input u (as long as x).
        let tests = |x: &[f64], u: &[f64]| {
            let (x, u) = (centred(x), centred(&u[..x.len()]));
            let (mut ree, mut reu, mut ruu) = (vec![0.0; MAX_LAG + 1], vec![0.0; MAX_LAG + 1], vec![0.0; MAX_LAG + 1]);
            residual_correlations(&x, &u, &[], &mut ree, &mut reu);
            kernels::lagged_dots(&u, &u, &mut ruu);
            (whiteness_p(&ree, x.len(), &[]), independence_p(&reu, ree[0], x.len(), &ruu, &[]))
        };
        let (white, indep) = tests(&e, &u);
        assert!(white > 0.001, "{white}");
        assert!(indep > 0.001, "{indep}");
        let ma: Vec<f64> = e.windows(2).map(|w| w[1] + 0.5 * w[0]).collect();
        assert!(tests(&ma, &u).0 < 1e-6);
        // Residuals that carry the input at lag 3.
        let leak: Vec<f64> = (0..4000).map(|t| e[t] + if t >= 3 { 0.2 * u[t - 3] } else { 0.0 }).collect();
        assert!(tests(&leak, &u).1 < 1e-6);
    }
}
