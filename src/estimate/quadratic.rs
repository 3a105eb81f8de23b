//! Is the criterion quadratic over the fit's own confidence region (METHOD.md 17)? The
//! sandwich covariance P of METHOD.md 10 is the curvature of the criterion at the estimate,
//! read as if the criterion were the quadratic it is near a well-identified minimum. Where it is
//! not (a flat valley, another basin within reach, the stability boundary), P says nothing of
//! the uncertainty, and the check below says so from the fit alone.
//!
//! With `P = V diag(lambda) V^T`, step to `theta +/- c sqrt(lambda_i) v_i` along every
//! eigen-direction (each step is c standard deviations of the combination `v_i^T theta`), and
//! compare the rise of the criterion with the rise the covariance implies. The sandwich is
//! `P = kappa (sum_t psi_t psi_t^T)^-1` with `kappa = mean(psi_g^2) / mean(psi_g')^2`, and
//! the Gauss-Newton Hessian of W it stands for is `H = mean(psi_g') (1/N) sum_t psi_t psi_t^T`,
//! so `delta^T H delta = s delta^T P^-1 delta / N` with `s = mean(psi_g^2) / mean(psi_g')`,
//! and along every direction the predicted rise is the same number:
//!
//! ```text
//! predicted = c^2 s / (2 N)          (least squares: c^2 sigma^2 / (2 N))
//! ratio_i   = (W(theta + d_i) + W(theta - d_i) - 2 W(theta)) / (2 predicted)
//! ```
//!
//! The two sides are averaged so that a gradient left by a solver that stopped short of the
//! minimum cancels. The fit is doubtful when some ratio lies below [`RATIO_BAND`] (the
//! criterion flatter than the std say), when a step lowers the criterion (a lower point within the region: another basin, or no minimum
//! here), or when a step leaves the stability region (F unstable: the region reaches the
//! boundary). `c` is [`STEP_STD`]: the marginal 95 % interval of each combination.

use super::evidence;
use super::huber::Loss;
use super::least_squares::BOUNDARY;
use super::problem::Problem;

/// Curvature ratios inside this band count as quadratic. A factor 2 in curvature is a factor
/// sqrt(2) in a standard deviation; wider means the reported std is wrong by more than that.
/// Only the lower end makes a doubt: a criterion that rises faster than the covariance
/// predicts (a curved model, steps of 2 std in lightly damped poles) has a smaller region
/// than the std say, which errs on the safe side; on the 24-parameter Monte Carlo of
/// METHOD.md 17.2 the upper end flagged fits that lay within 2 std of the truth.
pub const RATIO_BAND: (f64, f64) = (0.5, 2.0);

/// Steps of this many standard deviations along each eigen-direction (~the 95 % interval).
pub const STEP_STD: f64 = 2.0;

/// What [`check`] found.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct QuadraticCheck {
    /// Standard deviations stepped along each direction.
    pub step_std: f64,
    /// The smallest and largest curvature ratio over the directions (actual / predicted).
    pub min_ratio: f64,
    pub max_ratio: f64,
    /// The largest drop of the criterion below W(theta) at a step, in units of the predicted
    /// rise (0 when no step lowered it).
    pub drop: f64,
    /// Steps whose F is unstable (the confidence region crosses the stability boundary).
    pub unstable: usize,
}

impl QuadraticCheck {
    /// True when the local covariance cannot be trusted.
    pub fn doubtful(&self) -> bool {
        self.reason().is_some()
    }

    /// Why the local covariance cannot be trusted, as a clause of a warning (None: quadratic).
    pub fn reason(&self) -> Option<String> {
        let c = self.step_std;
        if self.unstable > 0 {
            Some(format!("its {c}-std confidence region crosses the stability boundary"))
        } else if self.drop > 0.0 {
            Some(format!(
                "the criterion is lower {c} std away than at the fit (by {:.2}x the rise the covariance predicts): \
                 the fit is not at the bottom of a quadratic basin",
                self.drop
            ))
        } else if self.min_ratio.is_nan() || self.min_ratio < RATIO_BAND.0 {
            Some(format!(
                "its criterion is far from quadratic over its 95 % confidence region (W rises {:.2}x the \
                 quadratic prediction along one direction)",
                self.min_ratio
            ))
        } else {
            None
        }
    }

    /// One line for a table.
    pub fn summary(&self) -> String {
        format!(
            "curvature ratio {:.2}..{:.2}  drop {:.2}  unstable {}{}",
            self.min_ratio,
            self.max_ratio,
            self.drop,
            self.unstable,
            if self.doubtful() { "  DOUBT" } else { "" }
        )
    }
}

/// The warning for a model (`model` names it, e.g. "OE(12,12) delay 1 (picked by paper_m2)")
/// whose local covariance cannot be trusted: on the stability boundary (largest pole radius
/// `radius` >= [`BOUNDARY`]) or doubtful by `check`; `remedy` names the bootstrap as the
/// caller offers it. None: nothing to say.
pub fn doubt(model: &str, radius: f64, check: Option<&QuadraticCheck>, remedy: &str) -> Option<String> {
    let why = if radius >= BOUNDARY {
        format!("it has a pole at radius {radius:.4}, on the stability boundary")
    } else {
        check?.reason()?
    };
    Some(format!(
        "{model}: {why}: the reported standard deviations are local and may understate the uncertainty; use {remedy}"
    ))
}

/// The check of METHOD.md 17 at `theta` (fitted with `loss`) with its covariance `cov` (d x d,
/// row-major, as [`evidence::covariance`] gives it). Costs 2 d + 1 simulations.
pub fn check(prob: &Problem, theta: &[f64], loss: Loss, cov: &[f64]) -> QuadraticCheck {
    let d = prob.dim();
    assert_eq!(cov.len(), d * d, "a covariance of theta");
    let mut yhat = vec![0.0; prob.n()];
    prob.simulate(theta, &mut yhat);
    let w0 = prob.criterion(loss, &yhat);
    let slope = evidence::slope(prob, loss, &yhat);
    // Over the observed outputs (a missing one is NaN in y, METHOD.md 21.2).
    let n = prob.n_obs();
    let s = prob.y.iter().zip(&yhat).filter(|(y, _)| !y.is_nan()).map(|(y, yh)| loss.psi(y - yh).powi(2)).sum::<f64>()
        / n as f64
        / slope;
    let predicted = STEP_STD * STEP_STD * s / (2.0 * n as f64);
    let p = faer::Mat::<f64>::from_fn(d, d, |i, j| 0.5 * (cov[i * d + j] + cov[j * d + i]));
    let eig = crate::dense::symmetric_eigen(p.as_ref());
    let mut out =
        QuadraticCheck { step_std: STEP_STD, min_ratio: f64::INFINITY, max_ratio: 0.0, drop: 0.0, unstable: 0 };
    let Some((vals, vecs)) = eig else {
        out.min_ratio = f64::NAN;
        return out;
    };
    let mut point = vec![0.0; d];
    for i in 0..d {
        let len = STEP_STD * vals[i].max(0.0).sqrt();
        let mut rise = [0.0; 2];
        for (side, sign) in [1.0, -1.0].into_iter().enumerate() {
            for (j, p) in point.iter_mut().enumerate() {
                *p = theta[j] + sign * len * vecs[(j, i)];
            }
            if !prob.is_stable(&point) {
                out.unstable += 1;
                rise[side] = f64::INFINITY;
                continue;
            }
            prob.simulate(&point, &mut yhat);
            rise[side] = prob.criterion(loss, &yhat) - w0;
            out.drop = out.drop.max(-rise[side] / predicted);
        }
        if rise.iter().all(|r| r.is_finite()) {
            let ratio = (rise[0] + rise[1]) / (2.0 * predicted);
            out.min_ratio = out.min_ratio.min(ratio);
            out.max_ratio = out.max_ratio.max(ratio);
        }
    }
    if out.min_ratio == f64::INFINITY {
        out.min_ratio = f64::NAN;
    }
    out
}
