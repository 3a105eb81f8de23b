//! Information criteria of a least-squares fit, as MATLAB's System Identification Toolbox
//! defines them (`aic`, `fpe`; METHOD.md 14), for one output:
//!
//! ```text
//! V    = (1/N) sum e_t^2                       (the estimation residuals, zero initial state)
//! AIC  = N log V + 2 np + N (log 2 pi + 1)      MATLAB's raw AIC
//! AICc = AIC + 2 np (np + 1) / (N - np - 1)     small-sample corrected
//! BIC  = N log V + N (log 2 pi + 1) + np log N
//! FPE  = V (1 + np/N) / (1 - np/N)
//! ```
//!
//! np counts every estimated parameter: nB + nF, and the offset when it is estimated.
//!
//! **Robust criteria of a Huber fit** (METHOD.md 14.1). The noise model behind Huber's
//! criterion is his least favourable density with scale s, `f(e) = exp(-rho_k(e/s)) / (s C_k)`,
//! `C_k = sqrt(2 pi) (2 Phi(k) - 1) + 2 exp(-k^2/2) / k`. With the fit's residuals and the scale
//! profiled out (`s_hat` solves `mean(psi_k(x) x) = 1`, x = e/s, the likelihood equation of s):
//!
//! ```text
//! -2 log L = 2 sum rho_k(e_t/s_hat) + 2 N log s_hat + 2 N log C_k
//! RAIC     = -2 log L + 2 np E[psi_k^2] / E[psi_k']     Ronchetti (1985), tr(M^-1 Q) for Huber
//! RBIC     = -2 log L + np log N                        Machado (1993)
//! ```
//!
//! For k -> infinity both become the Gaussian AIC and BIC above. E[psi'] = P(|x| <= k) is
//! estimated with a smoothed count (an integrated Epanechnikov kernel, Silverman's bandwidth):
//! at the paper's small k only a handful of residuals lie inside +/-k, and a raw count would
//! make the penalty jump between neighbouring cells.

use statrs::function::erf::erf;

/// The criteria of one fit; NaN where a formula is undefined (AICc with N <= np + 1, FPE with
/// N <= np, any of them with V = 0).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Criteria {
    pub aic: f64,
    pub aicc: f64,
    pub bic: f64,
    pub fpe: f64,
}

/// The criteria of a least-squares fit with mean squared residual `v` on `n` samples and `np`
/// estimated parameters.
pub fn least_squares(v: f64, n: usize, np: usize) -> Criteria {
    let (nf, p) = (n as f64, np as f64);
    let undefined = !(v.is_finite() && v > 0.0);
    let log_v = if undefined { f64::NAN } else { v.ln() };
    let gauss = nf * ((2.0 * std::f64::consts::PI).ln() + 1.0);
    let aic = nf * log_v + 2.0 * p + gauss;
    let aicc = if nf > p + 1.0 { aic + 2.0 * p * (p + 1.0) / (nf - p - 1.0) } else { f64::NAN };
    let bic = nf * log_v + gauss + p * nf.ln();
    let fpe = if nf > p && !undefined { v * (1.0 + p / nf) / (1.0 - p / nf) } else { f64::NAN };
    Criteria { aic, aicc, bic, fpe }
}

/// The robust criteria of one Huber fit; NaN where undefined (all residuals zero).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Robust {
    pub raic: f64,
    pub rbic: f64,
}

/// Largest Newton steps on log s before the profiled scale is taken as found.
const SCALE_STEPS: usize = 60;

/// The robust criteria of a Huber fit at tuning constant `k` with residuals `y - yhat` and
/// `np` estimated parameters.
pub fn robust(y: &[f64], yhat: &[f64], k: f64, np: usize) -> Robust {
    let undefined = Robust { raic: f64::NAN, rbic: f64::NAN };
    let n = y.len().min(yhat.len());
    let e = || y.iter().zip(yhat).map(|(a, b)| a - b);
    let mean_abs = e().map(f64::abs).sum::<f64>() / n as f64;
    if n == 0 || !(mean_abs.is_finite() && mean_abs > 0.0) || !(k.is_finite() && k > 0.0) {
        return undefined;
    }
    let Some(s) = profiled_scale(&e, n, k, mean_abs) else { return undefined };
    let nf = n as f64;
    let (mut sum_rho, mut sum_psi2) = (0.0, 0.0);
    for x in e().map(|v| v / s) {
        sum_rho += super::huber::rho(k, x);
        let p = x.clamp(-k, k);
        sum_psi2 += p * p;
    }
    let c_k = (2.0 * std::f64::consts::PI).sqrt() * erf(k / std::f64::consts::SQRT_2) + 2.0 * (-0.5 * k * k).exp() / k;
    let minus_2_log_l = 2.0 * sum_rho + 2.0 * nf * s.ln() + 2.0 * nf * c_k.ln();
    let slope = smoothed_share_inside(&e, n, k, s);
    let p = np as f64;
    Robust { raic: minus_2_log_l + 2.0 * p * (sum_psi2 / nf) / slope, rbic: minus_2_log_l + p * nf.ln() }
}

/// The scale s with `mean(psi_k(e/s) e/s) = 1`: `mean(min(x^2, k|x|))` falls strictly with s,
/// so the root is unique; Newton on log s from the least-absolute scale, kept inside a bracket.
fn profiled_scale<I: Iterator<Item = f64>>(e: &impl Fn() -> I, n: usize, k: f64, mean_abs: f64) -> Option<f64> {
    let nf = n as f64;
    // h(t) = mean(min(x^2, k|x|)) - 1 at s = exp(t), and its derivative in t.
    let h = |t: f64| {
        let s = t.exp();
        let (mut v, mut dv) = (0.0, 0.0);
        for a in e().map(|x| (x / s).abs()) {
            if a <= k {
                v += a * a;
                dv -= 2.0 * a * a;
            } else {
                v += k * a;
                dv -= k * a;
            }
        }
        (v / nf - 1.0, dv / nf)
    };
    // g(s) = mean(min(x^2, k|x|)) is at most mean(e^2)/s^2 and k mean|e|/s, so the root lies
    // below the smaller of sqrt(mean e^2) and k mean|e|; halving s from there finds a lower
    // end with g >= 1 (g grows like 1/s as s -> 0 because mean|e| > 0).
    let mean_sq = e().map(|v| v * v).sum::<f64>() / nf;
    let mut hi = mean_sq.sqrt().min(k * mean_abs).ln();
    let mut lo = hi;
    for _ in 0..SCALE_STEPS {
        if h(lo).0 >= 0.0 {
            break;
        }
        hi = lo;
        lo -= std::f64::consts::LN_2;
    }
    let mut t = 0.5 * (lo + hi);
    for _ in 0..SCALE_STEPS {
        let (v, dv) = h(t);
        if v > 0.0 {
            lo = t;
        } else {
            hi = t;
        }
        let newton = t - v / dv;
        let next = if newton.is_finite() && newton > lo && newton < hi { newton } else { 0.5 * (lo + hi) };
        if (next - t).abs() < 1e-12 {
            return Some(next.exp()).filter(|s| s.is_finite() && *s > 0.0);
        }
        t = next;
    }
    Some(t.exp()).filter(|s| s.is_finite() && *s > 0.0)
}

/// `P(|x| <= k)` of x = e/s, from the integrated Epanechnikov kernel with Silverman's
/// bandwidth `0.9 A N^-1/5`, A the smaller of the standard deviation and the Gaussian-scaled
/// mean absolute value of x (so spikes do not widen it); floored at 1/N.
fn smoothed_share_inside<I: Iterator<Item = f64>>(e: &impl Fn() -> I, n: usize, k: f64, s: f64) -> f64 {
    let nf = n as f64;
    let (mut sum, mut sum_sq, mut sum_abs) = (0.0, 0.0, 0.0);
    for x in e().map(|v| v / s) {
        sum += x;
        sum_sq += x * x;
        sum_abs += x.abs();
    }
    let sd = (sum_sq / nf - (sum / nf).powi(2)).max(0.0).sqrt();
    let spread = sd.min(sum_abs / nf * (std::f64::consts::PI / 2.0).sqrt());
    let h = 0.9 * spread * nf.powf(-0.2);
    // The kernel's CDF: 0 below -1, 1 above 1.
    let cdf = |u: f64| {
        let u = u.clamp(-1.0, 1.0);
        0.5 + 0.75 * u - 0.25 * u * u * u
    };
    let share = if h > 0.0 {
        e().map(|v| v / s).map(|x| cdf((k - x) / h) - cdf((-k - x) / h)).sum::<f64>() / nf
    } else {
        e().filter(|v| (v / s).abs() <= k).count() as f64 / nf
    };
    share.max(1.0 / nf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn criteria_match_the_formulas_and_rank_like_matlab() {
        let c = least_squares(0.25, 1000, 4);
        let g = 1000.0 * ((2.0 * std::f64::consts::PI).ln() + 1.0);
        assert!((c.aic - (1000.0 * 0.25f64.ln() + 8.0 + g)).abs() < 1e-9);
        assert!((c.aicc - (c.aic + 40.0 / 995.0)).abs() < 1e-9);
        assert!((c.bic - (1000.0 * 0.25f64.ln() + g + 4.0 * 1000f64.ln())).abs() < 1e-9);
        assert!((c.fpe - 0.25 * 1004.0 / 996.0).abs() < 1e-15);
        // One more parameter must buy a lower V to be preferred.
        assert!(least_squares(0.25, 1000, 5).aic > c.aic);
        assert!(least_squares(0.24, 1000, 5).aic < c.aic);
        // Undefined where the formulas are.
        assert!(least_squares(0.0, 1000, 4).aic.is_nan());
        assert!(least_squares(0.25, 5, 4).aicc.is_nan() && least_squares(0.25, 4, 4).fpe.is_nan());
    }

    /// Residuals of a known distribution (deterministic quantiles, so no sampling noise).
    fn gaussian_quantiles(n: usize, sd: f64) -> Vec<f64> {
        use statrs::distribution::{ContinuousCDF, Normal};
        let g = Normal::new(0.0, sd).unwrap();
        (0..n).map(|i| g.inverse_cdf((i as f64 + 0.5) / n as f64)).collect()
    }

    #[test]
    fn robust_criteria_become_the_gaussian_ones_for_large_k() {
        let e = gaussian_quantiles(4000, 0.3);
        let zero = vec![0.0; e.len()];
        let v = e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64;
        let ls = least_squares(v, e.len(), 5);
        let r = robust(&e, &zero, 50.0, 5);
        assert!((r.raic - ls.aic).abs() < 0.05, "{} vs {}", r.raic, ls.aic);
        assert!((r.rbic - ls.bic).abs() < 0.05, "{} vs {}", r.rbic, ls.bic);
    }

    #[test]
    fn profiled_scale_solves_its_equation_and_the_penalty_is_the_efficiency_loss() {
        let e = gaussian_quantiles(20000, 2.0);
        for k in [0.05, 0.3, 1.345, 2.0] {
            let mean_abs = e.iter().map(|v| v.abs()).sum::<f64>() / e.len() as f64;
            let s = profiled_scale(&|| e.iter().copied(), e.len(), k, mean_abs).unwrap();
            let m = e.iter().map(|v| (v / s).abs()).map(|a| if a <= k { a * a } else { k * a }).sum::<f64>()
                / e.len() as f64;
            assert!((m - 1.0).abs() < 1e-9, "k {k}: {m}");
            // On Gaussian residuals E psi^2 / E psi' is the asymptotic variance of the
            // M-estimator relative to least squares: pi/2 for k -> 0, 1.05 at k = 1.345.
            let r = robust(&e, &vec![0.0; e.len()], k, 1);
            let r0 = robust(&e, &vec![0.0; e.len()], k, 0);
            let factor = (r.raic - r0.raic) / 2.0;
            let expected = if k == 0.05 { std::f64::consts::FRAC_PI_2 } else { f64::NAN };
            if k == 0.05 {
                assert!((factor - expected).abs() < 0.1, "k {k}: {factor}");
            }
            if k == 1.345 {
                assert!((factor - 1.05).abs() < 0.03, "k {k}: {factor}");
            }
        }
    }

    #[test]
    fn robust_criteria_ignore_spikes_that_mislead_the_gaussian_ones() {
        // A better model removes a small structured error; spikes on 15 % of samples swamp V
        // but not the robust likelihood.
        let base = gaussian_quantiles(2000, 0.1);
        let spiky = |x: &[f64]| -> Vec<f64> {
            x.iter()
                .enumerate()
                .map(|(t, v)| if t % 7 == 3 { v + 5.0 * if t % 2 == 0 { 1.0 } else { -1.0 } } else { *v })
                .collect()
        };
        let worse: Vec<f64> = base.iter().enumerate().map(|(t, v)| v + 0.06 * (t as f64 * 0.9).sin()).collect();
        let (good, bad) = (spiky(&base), spiky(&worse));
        let zero = vec![0.0; 2000];
        let good_r = robust(&good, &zero, 0.5, 6);
        let bad_r = robust(&bad, &zero, 0.5, 5);
        assert!(good_r.rbic < bad_r.rbic && good_r.raic < bad_r.raic, "{good_r:?} vs {bad_r:?}");
        // The Gaussian BIC prefers the worse, smaller model: the spikes swamp V.
        let v = |x: &[f64]| x.iter().map(|e| e * e).sum::<f64>() / x.len() as f64;
        assert!(least_squares(v(&bad), 2000, 5).bic < least_squares(v(&good), 2000, 6).bic);
        // Undefined on zero residuals.
        assert!(robust(&zero, &zero, 0.5, 3).raic.is_nan());
    }
}
