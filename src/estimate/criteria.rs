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
//! **Robust criteria of a Huber fit** (METHOD.md 14.1). The fit minimised W = (1/N) sum
//! rho_gamma(e_t) with gamma = k sigma; that makes it the maximum-likelihood fit under the density
//! `f(e) = exp(-rho_gamma(e) / tau^2) / Z(gamma, tau)` for every tau, Huber's least favourable
//! density with scale tau and tuning constant `kappa = gamma / tau`:
//! `Z = tau C(kappa)`, `C(kappa) = sqrt(2 pi) (2 Phi(kappa) - 1) + 2 exp(-kappa^2/2) / kappa`. With
//! tau profiled out (its likelihood equation `2 W / tau^2 = 1 + 2 exp(-kappa^2/2) / (kappa C(kappa))`
//! has one root):
//!
//! ```text
//! -2 log L = 2 N (W / tau^2 + log tau + log C(gamma/tau))
//! RAIC     = -2 log L + 2 np mean(psi_gamma(e)^2) / (tau^2 (1 - L1C))   Ronchetti (1985)
//! RBIC     = -2 log L + np log N                                        Machado (1993)
//! ```
//!
//! For gamma -> infinity both become the Gaussian AIC and BIC above.

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

/// Bisection steps on log kappa: the bracket [1e-8, 1e8] shrinks below 1e-12 relative.
const SCALE_STEPS: usize = 100;

/// The robust criteria of a Huber fit with threshold `gamma`, residuals `y - yhat` (over the
/// observed outputs) and `np` estimated parameters.
pub fn robust(y: &[f64], yhat: &[f64], gamma: f64, np: usize) -> Robust {
    let undefined = Robust { raic: f64::NAN, rbic: f64::NAN };
    // A missing output (NaN in y, METHOD.md 21.2) is no sample of the likelihood.
    let seen = || y.iter().zip(yhat).filter(|(a, _)| !a.is_nan());
    let n = seen().count();
    if n == 0 || !(gamma.is_finite() && gamma > 0.0) {
        return undefined;
    }
    let (mut w, mut psi2, mut inside) = (0.0, 0.0, 0usize);
    for e in seen().map(|(a, b)| a - b) {
        w += super::huber::rho(gamma, e);
        let p = e.clamp(-gamma, gamma);
        psi2 += p * p;
        inside += usize::from(e.abs() <= gamma);
    }
    let nf = n as f64;
    let (w, psi2, share) = (w / nf, psi2 / nf, (inside as f64).max(1.0) / nf);
    let Some(kappa) = profiled_kappa(w, gamma) else { return undefined };
    let tau = gamma / kappa;
    let minus_2_log_l = 2.0 * nf * (w / (tau * tau) + tau.ln() + c(kappa).ln());
    let p = np as f64;
    Robust { raic: minus_2_log_l + 2.0 * p * psi2 / (tau * tau * share), rbic: minus_2_log_l + p * nf.ln() }
}

/// The normalising constant of Huber's density with tuning constant `kappa` and unit scale.
fn c(kappa: f64) -> f64 {
    (2.0 * std::f64::consts::PI).sqrt() * erf(kappa / std::f64::consts::SQRT_2)
        + 2.0 * (-0.5 * kappa * kappa).exp() / kappa
}

/// kappa = gamma / tau of the profiled scale: the root of
/// `2 W kappa^2 / gamma^2 - 1 - 2 exp(-kappa^2/2) / (kappa C(kappa))`, which rises from -2 at
/// kappa -> 0 to +infinity (the second term falls from 2 to 1), by bisection on log kappa.
fn profiled_kappa(w: f64, gamma: f64) -> Option<f64> {
    if !(w.is_finite() && w > 0.0) {
        return None;
    }
    let h = |kappa: f64| {
        2.0 * w * kappa * kappa / (gamma * gamma) - 1.0 - 2.0 * (-0.5 * kappa * kappa).exp() / (kappa * c(kappa))
    };
    let (mut lo, mut hi) = (1e-8f64.ln(), 1e8f64.ln());
    if !(h(lo.exp()) < 0.0 && h(hi.exp()) > 0.0) {
        return None;
    }
    for _ in 0..SCALE_STEPS {
        let mid = 0.5 * (lo + hi);
        if h(mid.exp()) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some((0.5 * (lo + hi)).exp())
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
    fn robust_criteria_become_the_gaussian_ones_for_large_gamma() {
        let e = gaussian_quantiles(4000, 0.3);
        let zero = vec![0.0; e.len()];
        let v = e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64;
        let ls = least_squares(v, e.len(), 5);
        let r = robust(&e, &zero, 50.0, 5);
        assert!((r.raic - ls.aic).abs() < 1e-6, "{} vs {}", r.raic, ls.aic);
        assert!((r.rbic - ls.bic).abs() < 1e-6, "{} vs {}", r.rbic, ls.bic);
    }

    #[test]
    fn the_profiled_scale_maximises_the_likelihood() {
        // -2 log L / 2N as a function of tau, minimised at the profiled tau.
        let (w, gamma) = (0.37, 0.4);
        let kappa = profiled_kappa(w, gamma).unwrap();
        let nll = |tau: f64| w / (tau * tau) + tau.ln() + c(gamma / tau).ln();
        let tau = gamma / kappa;
        for f in [0.9, 0.99, 1.01, 1.1] {
            assert!(nll(tau * f) > nll(tau), "tau x {f}");
        }
        // C is the integral of exp(-rho_kappa(x)).
        let kappa = 0.7;
        let dx = 1e-3;
        let integral: f64 =
            (-60_000..60_000).map(|i| (-crate::estimate::huber::rho(kappa, (i as f64 + 0.5) * dx)).exp() * dx).sum();
        assert!((integral - c(kappa)).abs() < 1e-6, "{integral} vs {}", c(kappa));
    }

    #[test]
    fn the_penalty_is_one_per_parameter_when_the_density_fits() {
        // tr(M^-1 Q) per parameter, E psi^2 / (tau^2 E psi'), is 1 when the residuals follow the
        // density (the information identity) and grows with the misfit: on Gaussian residuals
        // with gamma = 1.345 sd, E psi^2 = 0.710 sd^2, E psi' = 0.821 and tau^2 = 0.80 sd^2
        // give 1.08.
        let e = gaussian_quantiles(20000, 2.0);
        let zero = vec![0.0; e.len()];
        let factor = |gamma: f64| (robust(&e, &zero, gamma, 1).raic - robust(&e, &zero, gamma, 0).raic) / 2.0;
        assert!((factor(1.345 * 2.0) - 1.08).abs() < 0.01, "{}", factor(2.69));
        assert!((factor(100.0) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn robust_criteria_ignore_spikes_that_mislead_the_gaussian_ones() {
        // A better model removes a small structured error; spikes on 1 in 7 samples swamp V but
        // not the robust likelihood.
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
        let good_r = robust(&good, &zero, 0.15, 6);
        let bad_r = robust(&bad, &zero, 0.15, 5);
        assert!(good_r.rbic < bad_r.rbic && good_r.raic < bad_r.raic, "{good_r:?} vs {bad_r:?}");
        // The Gaussian BIC prefers the worse, smaller model: the spikes swamp V.
        let v = |x: &[f64]| x.iter().map(|e| e * e).sum::<f64>() / x.len() as f64;
        assert!(least_squares(v(&bad), 2000, 5).bic < least_squares(v(&good), 2000, 6).bic);
        // Undefined on zero residuals.
        assert!(robust(&zero, &zero, 0.5, 3).raic.is_nan());
    }
}
