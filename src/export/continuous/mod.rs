//! A discrete model's continuous-time equivalent for control design (`oesweep export
//! --continuous zoh|tustin`, the Python package's `Model.to_continuous`); METHOD.md 18.
//!
//! The model is `G(z) = num(z)/den(z)` with sample time `Ts` ([`super::model::ModelOut::num_den`]).
//! Its poles at `z = 0` that the relative degree allows are the delay: `G(z) = z^-k H(z)`, where
//! `k` is the number of poles at the origin, but no more than `deg den - deg num` so that `H` stays
//! proper. The delay leaves as a dead time `k Ts` (an input delay), never as poles; `H` goes
//! through one of two maps:
//!
//! - ZOH: the continuous system whose zero-order-hold sampling is `H`. With `(A, B, C, D)` a
//!   realisation of `H`, `[[A, B], [0, 1]] = exp([[Ac, Bc], [0, 0]] Ts)`, so
//!   `[[Ac, Bc], [0, 0]] Ts` is the principal matrix logarithm of the left side ([`logm`]), and
//!   `C`, `D` stay; the realisation is `H`'s sections ([`zpk::realise`]). A real logarithm of
//!   the companion matrix of `H` exists only when no pole is on the closed negative real axis
//!   (Culver 1966: every Jordan block of a negative eigenvalue would have to occur twice, and a
//!   companion matrix has one block per distinct pole): a pole at or near `z = 0` (ln 0 = -inf)
//!   or on the negative real axis, single or repeated, has no real equivalent of the model's
//!   order and is an error that names it. A repeated pole comes out of the root finder split by
//!   about `eps^(1/m)` (`1.5e-8` for a double one), often as a complex pair: a pair within
//!   [`AXIS`] of the axis, or one whose real part is a root of `den` to within [`ROUNDING`] of
//!   its coefficients, counts as on it.
//! - Tustin: the bilinear map `s = (2/Ts)(z - 1)/(z + 1)`, by substituting
//!   `z = (1 + s Ts/2)/(1 - s Ts/2)` in `num` and `den`; a pole at `z = -1` maps to `s = inf`
//!   and is an error. The factor `(1 - s Ts/2)^r` that clears the fractions stays in the
//!   numerator when `H` has relative degree `r`: `r` zeros at `s = +2/Ts`.
//!
//! Both work in the scaled variable `x = s Ts`, where the matrices and coefficients are of order
//! one, and scale the coefficients to `s` at the end. A ZOH-sampled system with a fractional
//! dead time `(k + a) Ts`, 0 < a < 1, has one more pole at the origin and a numerator of full
//! degree: it comes back as `k + 1` samples of dead time and a biproper `H` (a direct
//! feedthrough), which samples to the same `G(z)`; the fraction `a` is not estimated.
//!
//! The coefficients in `s` span about `Ts^-n` and are ill-conditioned at high orders and short
//! sample times; [`zpk`] gives the same system as zeros, poles and gain, and as a state space of
//! scaled second-order sections, both well-conditioned.

mod logm;
mod zpk;

use crate::oe::{poles, poly_from_roots};
use faer::Mat;
pub use zpk::StateSpace;

/// How the discrete model is mapped to continuous time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// The inverse of the zero-order hold: the continuous system that samples to the model.
    Zoh,
    /// The inverse of the bilinear (Tustin) map.
    Tustin,
}

crate::names::names!(Method { Zoh = "zoh", Tustin = "tustin" });

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Method::from_name(s).ok_or_else(|| format!("method {s:?}: expected {}", Method::NAMES.join(" or ")))
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// `Gc(s) = exp(-input_delay s) num(s)/den(s) = exp(-input_delay s) gain prod(s - zeros)/prod(s - poles)`.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ContinuousModel {
    pub method: Method,
    /// Numerator in descending powers of s (no leading zeros).
    pub num: Vec<f64>,
    /// Denominator in descending powers of s, monic.
    pub den: Vec<f64>,
    /// Dead time in seconds: `delay_samples` times the sample time.
    pub input_delay: f64,
    /// The discrete model's delay that left as dead time (module docs).
    pub delay_samples: u32,
    /// The zeros in rad/s as (re, im): complex ones in conjugate pairs, the upper one first.
    pub zeros: Vec<(f64, f64)>,
    /// The poles in rad/s, as the zeros.
    pub poles: Vec<(f64, f64)>,
    /// The factor in front of the zeros' and poles' product.
    pub gain: f64,
    /// A realisation of the same transfer function (without the dead time).
    pub state_space: StateSpace,
}

/// A pole as it is printed in an error: `z = -0.5` or `z = 0.3+0.2i`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pole(pub f64, pub f64);

impl std::fmt::Display for Pole {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.1 == 0.0 { write!(f, "z = {:.6}", self.0) } else { write!(f, "z = {:.6}{:+.6}i", self.0, self.1) }
    }
}

/// Why a model has no continuous equivalent (or was not a model).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum NoEquivalent {
    #[error(
        "the model has a pole at {0} (at or near the origin, beyond what its delay holds): the ZOH \
         has no continuous equivalent (ln 0 = -inf); Tustin maps it"
    )]
    PoleAtOrigin(Pole),
    #[error(
        "the model has a pole at {0} on the negative real axis (single or repeated, or a pair within \
         1e-4 rad of it): the ZOH has no real continuous equivalent of the model's order (the \
         logarithm of a negative pole is complex; a pair near the axis maps to a resonance at the \
         Nyquist frequency whose gain is ill-conditioned); Tustin maps it"
    )]
    PoleOnNegativeAxis(Pole),
    #[error("the model has a pole at {0}: the Tustin map sends z = -1 to s = infinity")]
    PoleAtMinusOne(Pole),
    #[error("the model's numerator is zero: there is no transfer function to map")]
    ZeroGain,
    #[error("the model is not a proper transfer function (numerator of higher degree than the denominator)")]
    NotProper,
    #[error("the sample time {0} is not a positive number")]
    BadSampleTime(f64),
    #[error("the model's coefficients are not all finite")]
    NotFinite,
    #[error(
        "the matrix logarithm did not converge: the model's pole at {0} is the nearest to the negative \
         real axis, where the ZOH has no equivalent"
    )]
    NoLogarithm(Pole),
}

/// A pole closer than this to `z = 0` (or `z = -1` under Tustin) counts as being there.
const NEAR: f64 = 1e-8;

/// Under the ZOH, a pole whose angle is within this of pi counts as on the negative real axis.
/// A pair at angle `pi - e` has the equivalent `(ln r +- i(pi - e))/Ts`, a resonance `e/Ts`
/// below the Nyquist frequency with residues of order `1/e`, and the equivalent's response
/// carries the error of the computed poles (`eps/e` for a pair `e` apart) times `1/e`: about
/// `1e-16/e^2`, 1e-8 at this bound. It also holds the copies of a double or triple pole, which
/// a root finder splits by up to `eps^(1/3)` = 6e-6.
const AXIS: f64 = 1e-4;

/// A point `a` is a root of `den` to within rounding when `|den(a)|` is at most this times
/// `sum |den_i| |a|^(n-i)`: a relative change of the coefficients this small (some hundreds of
/// roundings, far below any estimate's uncertainty) puts a root at `a`. The copies of a pole
/// of any multiplicity, however far the root finder splits them, pass this test at their mean.
const ROUNDING: f64 = 1e-13;

/// `den` (descending powers) is zero at the real point `a` to within [`ROUNDING`].
fn root_within_rounding(den: &[f64], a: f64) -> bool {
    let (value, size) = den.iter().fold((0.0, 0.0), |(v, s), &c| (v * a + c, s * a.abs() + c.abs()));
    value.abs() <= ROUNDING * size
}

/// The continuous equivalent of `num(z)/den(z)` (descending powers of z) sampled every `ts`
/// seconds, by `method` (module docs).
pub fn to_continuous(num: &[f64], den: &[f64], ts: f64, method: Method) -> Result<ContinuousModel, NoEquivalent> {
    if !(ts.is_finite() && ts > 0.0) {
        return Err(NoEquivalent::BadSampleTime(ts));
    }
    if num.iter().chain(den).any(|v| !v.is_finite()) {
        return Err(NoEquivalent::NotFinite);
    }
    let (num, den, k) = split_delay(num, den)?;
    let n = den.len() - 1;
    let roots = zpk::conjugate_pairs(poles(&den[1..]));
    if n > 0 && roots.len() != n {
        return Err(NoEquivalent::NotFinite);
    }
    let ((num_x, den_x), (zeros, poles, gain)) = match method {
        Method::Zoh => {
            zoh_obstacle(&den, &roots)?;
            // The poles' logarithms: exact to rounding, and the eigenvalues of `Ac`.
            let logs: Vec<(f64, f64)> = roots.iter().map(|&(re, im)| (re.hypot(im).ln(), im.atan2(re))).collect();
            let (num_x, den_x) = zoh_inverse(&num, &den, &roots, &logs)?;
            let factored = zpk::zoh(&num_x, &logs, ts).ok_or(NoEquivalent::NotFinite)?;
            ((num_x, den_x), factored)
        }
        Method::Tustin => {
            // z = -1 itself when den vanishes there to within rounding (the copies of a
            // repeated pole split around it), else a pole within NEAR of it.
            if n > 0 && root_within_rounding(&den, -1.0) {
                return Err(NoEquivalent::PoleAtMinusOne(Pole(-1.0, 0.0)));
            }
            if let Some(&(re, im)) = roots.iter().find(|p| (p.0 + 1.0).hypot(p.1) < NEAR) {
                return Err(NoEquivalent::PoleAtMinusOne(Pole(re, im)));
            }
            (tustin_inverse(&num, &den), zpk::tustin(&num, &roots, ts).ok_or(NoEquivalent::NotFinite)?)
        }
    };
    let (num, den) = scale_to_s(num_x, den_x, ts);
    let (state_space, _) = zpk::realise(&zeros, &poles, gain, zpk::reference_point(&poles, ts), false);
    Ok(ContinuousModel {
        method,
        num,
        den,
        input_delay: k as f64 * ts,
        delay_samples: k,
        zeros,
        poles,
        gain,
        state_space,
    })
}

/// Why the poles `roots` of the monic `den` have no ZOH equivalent, if they have none (module
/// docs). Roots exactly at the origin are known without a root finder (which may leave a
/// multiple one at ~1e-8). A pole on the negative real axis is named by the mean of the
/// roots within 1e-3 of it, on the axis: the copies of a repeated pole (split by up to ~1e-4
/// for four) read the same however the root finder split them.
fn zoh_obstacle(den: &[f64], roots: &[(f64, f64)]) -> Result<(), NoEquivalent> {
    if den.last() == Some(&0.0) {
        return Err(NoEquivalent::PoleAtOrigin(Pole(0.0, 0.0)));
    }
    for &(re, im) in roots {
        let modulus = re.hypot(im);
        if modulus < NEAR {
            return Err(NoEquivalent::PoleAtOrigin(Pole(re, im)));
        }
        if re < 0.0 && (im.abs() <= AXIS * modulus || root_within_rounding(den, re)) {
            let copies: Vec<f64> =
                roots.iter().filter(|p| (p.0 - re).hypot(p.1 - im) <= 1e-3 * modulus).map(|p| p.0).collect();
            return Err(NoEquivalent::PoleOnNegativeAxis(Pole(copies.iter().sum::<f64>() / copies.len() as f64, 0.0)));
        }
    }
    Ok(())
}

/// `G = z^-k H` (module docs): `H`'s numerator and monic denominator (no leading zeros) and `k`.
fn split_delay(num: &[f64], den: &[f64]) -> Result<(Vec<f64>, Vec<f64>, u32), NoEquivalent> {
    let trim = |p: &[f64]| -> Vec<f64> { p.iter().copied().skip_while(|&c| c == 0.0).collect() };
    let (mut num, mut den) = (trim(num), trim(den));
    if num.is_empty() {
        return Err(NoEquivalent::ZeroGain);
    }
    if den.is_empty() {
        return Err(NoEquivalent::NotProper);
    }
    // Common factors z cancel.
    while num.len() > 1 && den.len() > 1 && num.last() == Some(&0.0) && den.last() == Some(&0.0) {
        num.pop();
        den.pop();
    }
    if num.len() > den.len() {
        return Err(NoEquivalent::NotProper);
    }
    let at_origin = den.iter().rev().take_while(|&&c| c == 0.0).count();
    let k = at_origin.min(den.len() - num.len());
    den.truncate(den.len() - k);
    let lead = den[0];
    num.iter_mut().for_each(|c| *c /= lead);
    den.iter_mut().for_each(|c| *c /= lead);
    Ok((num, den, k as u32))
}

/// `num(x)/den(x)` in `x = s Ts` to descending powers of `s`: the coefficient of `x^j` times
/// `Ts^j`, over the denominator's leading one; the numerator's leading zeros dropped.
fn scale_to_s(mut num: Vec<f64>, mut den: Vec<f64>, ts: f64) -> (Vec<f64>, Vec<f64>) {
    let n = den.len() - 1;
    let lead = den[0];
    // Equal lengths, so the same power of Ts goes with the same index from the top.
    let mut padded = vec![0.0; den.len().saturating_sub(num.len())];
    padded.append(&mut num);
    let scale = |p: &mut Vec<f64>| {
        for (i, c) in p.iter_mut().enumerate() {
            // x^(n-i) Ts^(n-i) s^(n-i), divided by Ts^n for a monic denominator in s.
            *c = *c / lead * ts.powi(-(i as i32));
        }
    };
    scale(&mut padded);
    scale(&mut den);
    let first = padded.iter().position(|&c| c != 0.0).unwrap_or(n);
    (padded.split_off(first), den)
}

/// The ZOH inverse of `num/den` (monic `den` without roots at the origin, `roots` its roots,
/// `logs` their logarithms) in `x = s Ts`: numerator and monic denominator.
fn zoh_inverse(
    num: &[f64],
    den: &[f64],
    roots: &[(f64, f64)],
    logs: &[(f64, f64)],
) -> Result<(Vec<f64>, Vec<f64>), NoEquivalent> {
    let n = den.len() - 1;
    if n == 0 {
        return Ok((num.to_vec(), vec![1.0]));
    }
    // H in scaled sections (`zpk::realise`), its pairs left of the imaginary axis in the
    // modal form: the block is block lower triangular, so the logarithm takes its square
    // roots block by block (`logm`), exactly for a pair near the negative real axis, where
    // the roots of a companion matrix lose digits to its non-normality.
    let zeros = zpk::roots_of(num).ok_or(NoEquivalent::NotFinite)?;
    let (ss, sections) = zpk::realise(&zeros, roots, num[0], (0.0, 1.0), true);
    let (d, c) = (ss.d, &ss.c);
    // [[1, 0], [B, A]]: the hold's state first, so the block stays lower triangular.
    let m = Mat::<f64>::from_fn(n + 1, n + 1, |i, j| match (i, j) {
        (0, 0) => 1.0,
        (0, _) => 0.0,
        (i, 0) => ss.b[i - 1],
        (i, j) => ss.a[i - 1][j - 1],
    });
    let blocks: Vec<usize> = std::iter::once(1).chain(sections).collect();
    // Where the logarithm fails, the pole nearest the negative real axis is the likely cause.
    let no_logarithm = || {
        let nearest = roots.iter().max_by(|a, b| a.1.atan2(a.0).abs().total_cmp(&b.1.atan2(b.0).abs()));
        NoEquivalent::NoLogarithm(nearest.map_or(Pole(0.0, 0.0), |&(re, im)| Pole(re, im)))
    };
    let l = logm::logm(&m, &blocks).ok_or_else(no_logarithm)?;
    let ac = Mat::<f64>::from_fn(n, n, |i, j| l[(i + 1, j + 1)]);
    let bc: Vec<f64> = (0..n).map(|i| l[(i + 1, 0)]).collect();
    // The eigenvalues of Ac are the logarithms of the poles: the denominator from them, exact
    // to rounding; the numerator as det(xI - Ac + Bc C) - det(xI - Ac) + D det(xI - Ac).
    let den_x: Vec<f64> = std::iter::once(1.0).chain(poly_from_roots(logs)).collect();
    let closed = Mat::<f64>::from_fn(n, n, |i, j| ac[(i, j)] - bc[i] * c[j]);
    let closed_roots = logm::eigenvalues(&closed).ok_or_else(no_logarithm)?;
    let char_closed: Vec<f64> = std::iter::once(1.0).chain(poly_from_roots(&closed_roots)).collect();
    let num_x = (0..=n).map(|i| char_closed[i] - den_x[i] + d * den_x[i]).collect::<Vec<_>>();
    // The x^n coefficient of a strictly proper part is 1 - 1: exactly zero.
    Ok((num_x, den_x))
}

/// `num(z)/den(z)` with `z = (1 + x/2)/(1 - x/2)`, times `(1 - x/2)^n / (1 - x/2)^n`.
fn tustin_inverse(num: &[f64], den: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = den.len() - 1;
    let map = |p: &[f64]| -> Vec<f64> {
        let mut padded = vec![0.0; n + 1 - p.len()];
        padded.extend_from_slice(p);
        let mut out = vec![0.0; n + 1];
        for (j, &c) in padded.iter().enumerate() {
            // c z^(n-j) -> c (1 + x/2)^(n-j) (1 - x/2)^j.
            let mut term = vec![c];
            for _ in 0..n - j {
                term = poly_mul(&term, &[0.5, 1.0]);
            }
            for _ in 0..j {
                term = poly_mul(&term, &[-0.5, 1.0]);
            }
            out.iter_mut().zip(&term).for_each(|(o, t)| *o += t);
        }
        out
    };
    (map(num), map(den))
}

/// Product of two polynomials in descending powers.
fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

#[cfg(test)]
mod tests;
