//! A discrete model's continuous-time equivalent for control design (`oesweep export
//! --continuous zoh|tustin`, the Python package's `Model.to_continuous`); METHOD.md 18.
//!
//! The model is `G(z) = num(z)/den(z)` with sample time `Ts` ([`super::model::ModelOut::num_den`]).
//! Its poles at `z = 0` that the relative degree allows are the delay: `G(z) = z^-k H(z)`, where
//! `k` is the number of poles at the origin, but no more than `deg den - deg num` so that `H` stays
//! proper. The delay leaves as a dead time `k Ts` (an input delay), never as poles; `H` goes
//! through one of two maps:
//!
//! - ZOH: the continuous system whose zero-order-hold sampling is `H`. With `(A, B, C, D)` the
//!   controllable canonical form of `H`, `[[A, B], [0, 1]] = exp([[Ac, Bc], [0, 0]] Ts)`, so
//!   `[[Ac, Bc], [0, 0]] Ts` is the principal matrix logarithm of the left side, and `C`, `D`
//!   stay. The logarithm is real only when no eigenvalue of `A` (pole of `H`) is on the closed
//!   negative real axis: a pole at or near `z = 0` (ln 0 = -inf: no continuous system samples
//!   to it) or on the negative real axis (a real continuous pole samples to a positive real one,
//!   a pair to a pair) has no equivalent and is an error that names it.
//! - Tustin: the bilinear map `s = (2/Ts)(z - 1)/(z + 1)`, by substituting
//!   `z = (1 + s Ts/2)/(1 - s Ts/2)` in `num` and `den`; a pole at `z = -1` maps to `s = inf`
//!   and is an error.
//!
//! Both work in the scaled variable `x = s Ts`, where the matrices and coefficients are of order
//! one, and scale the coefficients to `s` at the end. A ZOH-sampled system with a fractional
//! dead time `(k + a) Ts`, 0 < a < 1, has one more pole at the origin and a numerator of full
//! degree: it comes back as `k + 1` samples of dead time and a biproper `H` (a direct
//! feedthrough), which samples to the same `G(z)`; the fraction `a` is not estimated.

use crate::oe::{poles, poly_from_roots};
use faer::Mat;

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

/// `Gc(s) = exp(-input_delay s) num(s)/den(s)`.
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
        "the model has a pole at {0} on the negative real axis: no real continuous system samples to \
         it under the ZOH (its logarithm is complex); Tustin maps it"
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
    #[error("the matrix logarithm did not converge (poles too close to the origin or to each other)")]
    NoLogarithm,
}

/// A pole closer than this to `z = 0` (or `z = -1` under Tustin) counts as being there; a real
/// negative pole is one whose angle is within this of pi.
const NEAR: f64 = 1e-8;

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
    let roots = poles(&den[1..]);
    if n > 0 && roots.len() != n {
        return Err(NoEquivalent::NotFinite);
    }
    let (num_x, den_x) = match method {
        Method::Zoh => {
            // Roots exactly at the origin are known without a root finder (which may leave a
            // multiple one at ~1e-8).
            if den.last() == Some(&0.0) {
                return Err(NoEquivalent::PoleAtOrigin(Pole(0.0, 0.0)));
            }
            for &(re, im) in &roots {
                if re.hypot(im) < NEAR {
                    return Err(NoEquivalent::PoleAtOrigin(Pole(re, im)));
                }
                if re < 0.0 && im.abs() <= NEAR * re.abs() {
                    return Err(NoEquivalent::PoleOnNegativeAxis(Pole(re, 0.0)));
                }
            }
            zoh_inverse(&num, &den, &roots)?
        }
        Method::Tustin => {
            if let Some(&(re, im)) = roots.iter().find(|&&(re, im)| (re + 1.0).hypot(im) < NEAR) {
                return Err(NoEquivalent::PoleAtMinusOne(Pole(re, im)));
            }
            tustin_inverse(&num, &den)
        }
    };
    let (num, den) = scale_to_s(num_x, den_x, ts);
    Ok(ContinuousModel { method, num, den, input_delay: k as f64 * ts, delay_samples: k })
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

/// The ZOH inverse of `num/den` (monic `den` without roots at the origin, `roots` its roots) in
/// `x = s Ts`: numerator and monic denominator.
fn zoh_inverse(num: &[f64], den: &[f64], roots: &[(f64, f64)]) -> Result<(Vec<f64>, Vec<f64>), NoEquivalent> {
    let n = den.len() - 1;
    if n == 0 {
        return Ok((num.to_vec(), vec![1.0]));
    }
    let mut padded = vec![0.0; n + 1 - num.len()];
    padded.extend_from_slice(num);
    let d = padded[0];
    // The strictly proper part c(z)/den(z), c of degree n - 1.
    let c: Vec<f64> = (0..n).map(|i| padded[i + 1] - d * den[i + 1]).collect();
    // [[A, B], [0, 1]] with A the companion of den (first row -den[1..], ones below the
    // diagonal) and B = e1: C (zI - A)^-1 B = c(z)/den(z).
    let m = Mat::<f64>::from_fn(n + 1, n + 1, |i, j| match (i, j) {
        (0, j) if j < n => -den[j + 1],
        (0, _) => 1.0,
        (i, j) if i == n && j == n => 1.0,
        (i, _) if i == n => 0.0,
        (i, j) if i == j + 1 => 1.0,
        _ => 0.0,
    });
    let l = logm(&m).ok_or(NoEquivalent::NoLogarithm)?;
    let ac = Mat::<f64>::from_fn(n, n, |i, j| l[(i, j)]);
    let bc: Vec<f64> = (0..n).map(|i| l[(i, n)]).collect();
    // The eigenvalues of Ac are the logarithms of the poles: the denominator from them, exact
    // to rounding; the numerator as det(xI - Ac + Bc C) - det(xI - Ac) + D det(xI - Ac).
    let logs: Vec<(f64, f64)> = roots.iter().map(|&(re, im)| (re.hypot(im).ln(), im.atan2(re))).collect();
    let den_x: Vec<f64> = std::iter::once(1.0).chain(poly_from_roots(&logs)).collect();
    let closed = Mat::<f64>::from_fn(n, n, |i, j| ac[(i, j)] - bc[i] * c[j]);
    let zeros = eigenvalues(&closed).ok_or(NoEquivalent::NoLogarithm)?;
    let char_closed: Vec<f64> = std::iter::once(1.0).chain(poly_from_roots(&zeros)).collect();
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

/// Eigenvalues of a real square matrix as (re, im) pairs; None when the solver fails.
fn eigenvalues(a: &Mat<f64>) -> Option<Vec<(f64, f64)>> {
    let ev = crate::dense::eigenvalues(a.as_ref())?;
    ev.iter().all(|z| z.0.is_finite() && z.1.is_finite()).then_some(ev)
}

fn norm1(a: &Mat<f64>) -> f64 {
    (0..a.ncols()).map(|j| (0..a.nrows()).map(|i| a[(i, j)].abs()).sum::<f64>()).fold(0.0, f64::max)
}

fn minus_identity(a: &Mat<f64>) -> Mat<f64> {
    Mat::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)] - if i == j { 1.0 } else { 0.0 })
}

fn inverse(a: &Mat<f64>) -> Option<Mat<f64>> {
    let inv = crate::dense::Lu::new(a.as_ref()).inverse();
    (0..inv.nrows()).all(|i| (0..inv.ncols()).all(|j| inv[(i, j)].is_finite())).then_some(inv)
}

/// Principal square root by the product form of the Denman-Beavers iteration (Higham,
/// Functions of Matrices, 6.29): stable, and it needs no Schur form. None without convergence.
fn sqrtm(a: &Mat<f64>) -> Option<Mat<f64>> {
    let n = a.nrows();
    let (mut m, mut y) = (a.clone(), a.clone());
    for _ in 0..100 {
        let mi = inverse(&m)?;
        let half = Mat::from_fn(n, n, |i, j| 0.5 * (if i == j { 1.0 } else { 0.0 } + mi[(i, j)]));
        y = crate::dense::mul(y.as_ref(), half.as_ref());
        m = Mat::from_fn(n, n, |i, j| 0.5 * (if i == j { 1.0 } else { 0.0 } + 0.5 * (m[(i, j)] + mi[(i, j)])));
        if norm1(&minus_identity(&m)) <= 1e-15 * n as f64 {
            return Some(y);
        }
    }
    None
}

/// Principal matrix logarithm by inverse scaling and squaring: square roots until
/// `||T - I||_1 <= 1/4`, then `log(I + X)` by the 8-point Gauss-Legendre rule for
/// `int_0^1 X (I + tX)^-1 dt`, which is the [8/8] Padé approximant, accurate to rounding for
/// `||X|| <= 0.367` (Higham 2001, theta_8), times `2^s`. The matrix must have no eigenvalue on
/// the closed negative real axis (the caller checks the poles). None without convergence.
pub(crate) fn logm(a: &Mat<f64>) -> Option<Mat<f64>> {
    const NODES: [f64; 4] =
        [0.183_434_642_495_649_8, 0.525_532_409_916_329, 0.796_666_477_413_626_7, 0.960_289_856_497_536_3];
    const WEIGHTS: [f64; 4] =
        [0.362_683_783_378_362, 0.313_706_645_877_887_3, 0.222_381_034_453_374_5, 0.101_228_536_290_376_3];
    let n = a.nrows();
    let mut t = a.clone();
    let mut s = 0;
    while norm1(&minus_identity(&t)) > 0.25 {
        if s == 64 {
            return None;
        }
        t = sqrtm(&t)?;
        s += 1;
    }
    let x = minus_identity(&t);
    let mut log = Mat::<f64>::zeros(n, n);
    for (node, weight) in NODES.iter().zip(WEIGHTS) {
        for sign in [-1.0, 1.0] {
            // Nodes and weights on [0, 1] from those on [-1, 1].
            let tj = 0.5 * (1.0 + sign * node);
            let wj = 0.5 * weight;
            let shifted = Mat::from_fn(n, n, |i, j| tj * x[(i, j)] + if i == j { 1.0 } else { 0.0 });
            let term = crate::dense::mul(x.as_ref(), inverse(&shifted)?.as_ref());
            log = Mat::from_fn(n, n, |i, j| log[(i, j)] + wj * term[(i, j)]);
        }
    }
    let scale = 2f64.powi(s);
    Some(Mat::from_fn(n, n, |i, j| scale * log[(i, j)]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `exp(a)` by scaling and squaring with a degree-20 Taylor sum (`||a / 2^s|| <= 1/2`):
    /// the forward map of the tests, independent of [`logm`].
    fn expm(a: &Mat<f64>) -> Mat<f64> {
        let n = a.nrows();
        let s = norm1(a).log2().ceil().max(0.0) as i32 + 1;
        let b = Mat::from_fn(n, n, |i, j| a[(i, j)] / 2f64.powi(s));
        let mut sum = Mat::<f64>::identity(n, n);
        let mut term = Mat::<f64>::identity(n, n);
        for k in 1..=20 {
            let next = &term * &b;
            term = Mat::from_fn(n, n, |i, j| next[(i, j)] / k as f64);
            sum = Mat::from_fn(n, n, |i, j| sum[(i, j)] + term[(i, j)]);
        }
        for _ in 0..s {
            sum = &sum * &sum;
        }
        sum
    }

    /// c2d of `exp(-delay s) num(s)/den(s)` (monic den): num, den in z of the form
    /// `ModelOut::num_den` gives (equal length, the delay as poles at the origin).
    fn c2d(c: &ContinuousModel, ts: f64) -> (Vec<f64>, Vec<f64>) {
        let n = c.den.len() - 1;
        // To x = s Ts: the coefficient of s^(n-i) times Ts^-(n-i), over Ts^-n.
        let to_x = |p: &[f64]| -> Vec<f64> {
            let mut q = vec![0.0; n + 1 - p.len()];
            q.extend_from_slice(p);
            q.iter().enumerate().map(|(i, v)| v * ts.powi(i as i32)).collect()
        };
        let (num, den) = (to_x(&c.num), to_x(&c.den));
        let (mut nz, mut dz) = match c.method {
            Method::Zoh => {
                let d = num[0];
                let cc: Vec<f64> = (0..n).map(|i| num[i + 1] - d * den[i + 1]).collect();
                let m = Mat::from_fn(n + 1, n + 1, |i, j| match (i, j) {
                    (0, j) if j < n => -den[j + 1],
                    (0, j) if j == n => 1.0,
                    (i, _) if i == n => 0.0,
                    (i, j) if i == j + 1 => 1.0,
                    _ => 0.0,
                });
                let e = expm(&m);
                let ad = Mat::from_fn(n, n, |i, j| e[(i, j)]);
                let closed = Mat::from_fn(n, n, |i, j| e[(i, j)] - e[(i, n)] * cc[j]);
                let dz: Vec<f64> = std::iter::once(1.0).chain(poly_from_roots(&eigenvalues(&ad).unwrap())).collect();
                let cz: Vec<f64> =
                    std::iter::once(1.0).chain(poly_from_roots(&eigenvalues(&closed).unwrap())).collect();
                ((0..=n).map(|i| cz[i] - dz[i] + d * dz[i]).collect::<Vec<_>>(), dz)
            }
            Method::Tustin => {
                // x = 2 (z - 1)/(z + 1): c x^(n-j) -> c 2^(n-j) (z - 1)^(n-j) (z + 1)^j.
                let map = |p: &[f64]| -> Vec<f64> {
                    let mut out = vec![0.0; n + 1];
                    for (j, &cf) in p.iter().enumerate() {
                        let mut term = vec![cf * 2f64.powi((n - j) as i32)];
                        for _ in 0..n - j {
                            term = poly_mul(&term, &[1.0, -1.0]);
                        }
                        for _ in 0..j {
                            term = poly_mul(&term, &[1.0, 1.0]);
                        }
                        out.iter_mut().zip(&term).for_each(|(o, t)| *o += t);
                    }
                    out
                };
                let (nz, dz) = (map(&num), map(&den));
                (nz.iter().map(|v| v / dz[0]).collect(), dz.iter().map(|v| v / dz[0]).collect())
            }
        };
        let k = c.delay_samples as usize;
        nz.splice(0..0, std::iter::repeat_n(0.0, k));
        dz.resize(dz.len() + k, 0.0);
        (nz, dz)
    }

    fn close(what: &str, got: &[f64], want: &[f64], tol: f64) {
        assert_eq!(got.len(), want.len(), "{what}: {got:?} vs {want:?}");
        let scale = want.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() <= tol * scale, "{what}: {got:?} vs {want:?}");
        }
    }

    /// a/(z - p) with p = exp(-Ts/tau) and a = K (1 - p) is the ZOH sampling of K/(tau s + 1):
    /// the inverse gives back (K/tau)/(s + 1/tau), and a delay of d samples (the model's `nk`)
    /// gives d - 1 samples of dead time: the hold's own sample belongs to the system.
    #[test]
    fn a_first_order_lag_comes_back_exactly() {
        let (ts, tau, gain) = (0.1f64, 0.5, 2.0);
        let p = (-ts / tau).exp();
        for delay in [1usize, 3] {
            let mut num = vec![0.0; delay + 1];
            num[delay] = gain * (1.0 - p);
            let mut den = vec![0.0; delay + 1];
            den[0] = 1.0;
            den[1] = -p;
            let c = to_continuous(&num, &den, ts, Method::Zoh).unwrap();
            close("num", &c.num, &[gain / tau], 1e-13);
            close("den", &c.den, &[1.0, 1.0 / tau], 1e-13);
            assert_eq!(c.delay_samples, delay as u32 - 1);
            assert!((c.input_delay - (delay - 1) as f64 * ts).abs() < 1e-15);
        }
        // Tustin: a/(z - p) -> a (1 - x/2) / ((1 + x/2) - p (1 - x/2)), x = s Ts.
        let c = to_continuous(&[0.0, 1.0], &[1.0, -0.5], 0.2, Method::Tustin).unwrap();
        // (1 - 0.1 s)/(0.5 + 0.15 s) = (-2/3 s + 20/3)/(s + 10/3).
        close("tustin num", &c.num, &[-2.0 / 3.0, 20.0 / 3.0], 1e-14);
        close("tustin den", &c.den, &[1.0, 10.0 / 3.0], 1e-14);
    }

    /// A lightly damped 4th-order model (two modes at 0.99 and 0.95 radius) with a delay of 3
    /// (two samples of dead time and the hold's one): c2d(d2c(G)) is G to 1e-9, by both maps;
    /// and an integrator (a pole at z = 1) maps too.
    #[test]
    fn c2d_after_d2c_is_the_model() {
        let f = crate::oe::poly_from_poles(&[(0.99, 0.3), (0.95, 1.1)], &[]);
        let b = [0.02, -0.011, 0.004, 0.007];
        let m = super::super::model::ModelOut {
            name: String::new(),
            delay: 3,
            k: None,
            ts: 1e-3,
            b: b.to_vec(),
            f: f.clone(),
            offset: None,
            input_level: 0.0,
            covariance: None,
            parameters: Vec::new(),
            noise_variance: None,
        };
        let (num, den) = m.num_den();
        for method in [Method::Zoh, Method::Tustin] {
            let c = to_continuous(&num, &den, m.ts, method).unwrap();
            assert_eq!(c.delay_samples, 2, "{method}: {c:?}");
            assert_eq!(c.den.len(), 5);
            let (nz, dz) = c2d(&c, m.ts);
            close(&format!("{method} num"), &nz, &num, 1e-9);
            close(&format!("{method} den"), &dz, &den, 1e-9);
        }
        // Order 8: three resonances and two real poles, delay 1, a short sample time.
        let f = crate::oe::poly_from_poles(&[(0.985, 0.45), (0.97, 1.3), (0.9, 2.2)], &[0.8, 0.5]);
        let b = [0.02, 0.05, -0.03, 0.04, 0.01, -0.02, 0.03, 0.015];
        let num: Vec<f64> = std::iter::once(0.0).chain(b).collect();
        let den: Vec<f64> = std::iter::once(1.0).chain(f).collect();
        for method in [Method::Zoh, Method::Tustin] {
            let c = to_continuous(&num, &den, 1e-4, method).unwrap();
            let (nz, dz) = c2d(&c, 1e-4);
            close(&format!("order 8 {method} num"), &nz, &num, 1e-9);
            close(&format!("order 8 {method} den"), &dz, &den, 1e-9);
        }
        // A pole at z = 1 and one at 0.5, with a direct feedthrough (delay 0).
        let (num, den) = (vec![0.3, 0.1, -0.05], vec![1.0, -1.5, 0.5]);
        let c = to_continuous(&num, &den, 0.5, Method::Zoh).unwrap();
        assert!(c.den.last().unwrap().abs() < 1e-12, "an integrator: {c:?}");
        let (nz, dz) = c2d(&c, 0.5);
        close("integrator num", &nz, &num, 1e-9);
        close("integrator den", &dz, &den, 1e-9);
    }

    /// A fractional dead time: the ZOH of exp(-0.4 Ts s)/(s + 1) is z^-1 (b1 z + b2)/(z - p),
    /// an OE(2,1) with delay 1: it comes back as one sample of dead time and a biproper system
    /// that samples to the same model.
    #[test]
    fn a_fractional_delay_comes_back_as_a_whole_sample_and_a_feedthrough() {
        let (ts, a) = (0.1f64, 0.4);
        let p = (-ts).exp();
        let (b1, b2) = (1.0 - (-(1.0 - a) * ts).exp(), (-(1.0 - a) * ts).exp() - p);
        let (num, den) = (vec![0.0, b1, b2], vec![1.0, -p, 0.0]);
        let c = to_continuous(&num, &den, ts, Method::Zoh).unwrap();
        assert_eq!(c.delay_samples, 1);
        assert_eq!(c.den.len(), 2);
        assert_eq!(c.num.len(), 2, "biproper: {c:?}");
        let (nz, dz) = c2d(&c, ts);
        close("num", &nz, &num, 1e-12);
        close("den", &dz, &den, 1e-12);
    }

    #[test]
    fn poles_without_an_equivalent_are_named() {
        // A pole on the negative real axis.
        let e = to_continuous(&[0.0, 1.0], &[1.0, 0.5], 1.0, Method::Zoh).unwrap_err();
        assert_eq!(e, NoEquivalent::PoleOnNegativeAxis(Pole(-0.5, 0.0)));
        assert!(e.to_string().contains("z = -0.500000 on the negative real axis"), "{e}");
        assert!(to_continuous(&[0.0, 1.0], &[1.0, 0.5], 1.0, Method::Tustin).is_ok());
        // Near the origin.
        let e = to_continuous(&[0.0, 1.0], &[1.0, -1e-12], 1.0, Method::Zoh).unwrap_err();
        assert!(matches!(e, NoEquivalent::PoleAtOrigin(_)), "{e}");
        // At the origin beyond the delay: OE(2,1) with F = 1 + 0 q^-1, G = (b1 z + b2)/z^2.
        let e = to_continuous(&[0.0, 1.0, 0.5], &[1.0, 0.0, 0.0], 1.0, Method::Zoh).unwrap_err();
        assert_eq!(e, NoEquivalent::PoleAtOrigin(Pole(0.0, 0.0)));
        // Exactly at the origin and within the delay: an FIR gain with dead time.
        let c = to_continuous(&[0.0, 0.0, 2.0], &[1.0, 0.0, 0.0], 0.1, Method::Zoh).unwrap();
        assert_eq!((c.num, c.den, c.delay_samples), (vec![2.0], vec![1.0], 2));
        // Tustin: z = -1.
        let e = to_continuous(&[0.0, 1.0], &[1.0, 1.0], 1.0, Method::Tustin).unwrap_err();
        assert!(e.to_string().contains("s = infinity"), "{e}");
        // Not a model.
        assert_eq!(to_continuous(&[0.0, 0.0], &[1.0, 0.5], 1.0, Method::Zoh), Err(NoEquivalent::ZeroGain));
        assert_eq!(to_continuous(&[1.0], &[1.0], 0.0, Method::Zoh), Err(NoEquivalent::BadSampleTime(0.0)));
        assert_eq!(to_continuous(&[f64::NAN], &[1.0], 1.0, Method::Zoh), Err(NoEquivalent::NotFinite));
    }

    /// The logarithm inverts the exponential on matrices with eigenvalues far from 1.
    #[test]
    fn logm_inverts_expm() {
        let a = Mat::from_fn(3, 3, |i, j| [[-3.0, 1.0, 0.5], [0.2, -0.1, 2.0], [0.0, -2.0, -0.4]][i][j]);
        let l = logm(&expm(&a)).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((l[(i, j)] - a[(i, j)]).abs() < 1e-12, "{i},{j}: {} vs {}", l[(i, j)], a[(i, j)]);
            }
        }
    }
}
