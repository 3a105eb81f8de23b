//! Huber's mixed L2-L1 criterion (METHOD.md section 3).
//!
//! ```text
//! rho_g(x) = x^2/2             |x| <= g      (L2 set)
//!          = g|x| - g^2/2      |x| >  g      (L1 set)
//! W_{N,g}  = (1/N) sum_t rho_g(e_t)
//! psi_g(x) = x on L2, g sign(x) on L1        (influence function)
//! L1C      = (1/N) #{t : |e_t| > g}          (L1-contribution, METHOD.md 6)
//! ```
//! The plain least-squares criterion is the limit g -> infinity: `(1/N) sum e^2/2`.

/// The loss a fit minimises.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Loss {
    /// `(1/N) sum e_t^2 / 2`.
    LeastSquares,
    /// `W_{N,gamma}`.
    Huber { gamma: f64 },
}

impl Loss {
    #[inline(always)]
    pub fn rho(self, x: f64) -> f64 {
        match self {
            Loss::LeastSquares => 0.5 * x * x,
            Loss::Huber { gamma } => rho(gamma, x),
        }
    }

    #[inline(always)]
    pub fn psi(self, x: f64) -> f64 {
        match self {
            Loss::LeastSquares => x,
            Loss::Huber { gamma } => x.clamp(-gamma, gamma),
        }
    }

    /// Mean loss over residuals `y - yhat`.
    pub fn criterion(self, y: &[f64], yhat: &[f64]) -> f64 {
        self.total(y, yhat) / y.len() as f64
    }

    /// Summed loss over residuals `y - yhat` (a record with missing outputs sums its observed
    /// runs: [`super::Problem::criterion`]).
    pub fn total(self, y: &[f64], yhat: &[f64]) -> f64 {
        crate::kernels::loss_total(y, yhat, self.gamma())
    }

    /// Huber's gamma; None for least squares.
    pub fn gamma(self) -> Option<f64> {
        match self {
            Loss::LeastSquares => None,
            Loss::Huber { gamma } => Some(gamma),
        }
    }
}

/// `rho_g(x)`: defined beside the kernels that sum it ([`crate::kernels::huber_rho`]).
pub use crate::kernels::huber_rho as rho;

/// L1-contribution: the share of residuals beyond gamma, over the observed outputs (a missing
/// output's NaN residual is never beyond gamma; `observed` is their count).
pub fn l1_contribution(y: &[f64], yhat: &[f64], gamma: f64, observed: usize) -> f64 {
    let c = y.iter().zip(yhat).filter(|(a, b)| (*a - *b).abs() > gamma).count();
    c as f64 / observed as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rho_is_continuous_and_psi_is_its_derivative() {
        let g = 0.7;
        for &x in &[-3.0, -0.7, -0.3, 0.0, 0.2, 0.7, 1.5] {
            let h = 1e-6;
            let d = (rho(g, x + h) - rho(g, x - h)) / (2.0 * h);
            assert!((d - Loss::Huber { gamma: g }.psi(x)).abs() < 1e-6, "x={x}");
        }
        assert!((rho(g, g) - 0.5 * g * g).abs() < 1e-15);
    }
}
