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
}
