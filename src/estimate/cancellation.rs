//! Pole-zero pairs that cancel within their confidence region (METHOD.md 10.1): the sign of an
//! over-fitted model that does not depend on how it is parameterised, as engineers read
//! MATLAB's `pzmap` with confidence regions.
//!
//! The zeros are the roots r of `P(z) = b_1 z^(nB-1) + ... + b_nB`, the poles the roots p of
//! `Q(z) = z^nF + f_1 z^(nF-1) + ... + f_nF`. To first order a root moves with the
//! coefficients as
//!
//! ```text
//! dr/db_i = -r^(nB-i) / P'(r),      dp/df_j = -p^(nF-j) / Q'(p)
//! ```
//!
//! so the difference `delta = p - r` of a pole and a zero has the gradient `w` (complex, one
//! entry per parameter) and the 2 x 2 covariance `S` of `(Re delta, Im delta)` from the
//! parameters' covariance C: `S = [Re w, Im w]^T C [Re w, Im w]`. The pair cancels when delta = 0
//! lies in the 95 % region: `delta^T S^-1 delta <= chi2_2(0.95) = 5.99` for a complex pair, and
//! `delta^2 / S_11 <= chi2_1(0.95) = 3.84` when both roots are real.

use crate::oe;

/// chi-squared quantiles at 0.95 with one and two degrees of freedom.
const CHI2_95_1: f64 = 3.841_458_820_694_124;
const CHI2_95_2: f64 = 5.991_464_547_107_979;
/// Below this |imaginary part| relative to the modulus a root is taken as real.
const REAL: f64 = 1e-9;

/// The number of zeros that cancel a pole within the 95 % confidence region of their
/// difference (a conjugate pair counts once); `cov` is the d x d covariance of `[b, f(, c)]`.
/// None when the roots cannot be computed (b_1 = 0, non-finite coefficients).
pub fn cancelling_pairs(b: &[f64], f: &[f64], cov: &[f64], d: usize) -> Option<u32> {
    if b.len() < 2 || f.is_empty() {
        return Some(0);
    }
    if !(b[0] != 0.0 && b.iter().chain(f).all(|v| v.is_finite())) {
        return None;
    }
    let monic: Vec<f64> = b[1..].iter().map(|v| v / b[0]).collect();
    let zeros = oe::poles(&monic);
    let poles = oe::poles(f);
    if zeros.len() != b.len() - 1 || poles.len() != f.len() {
        return None;
    }
    // Each root's gradient w (re and im parts as d-vectors, zero outside its polynomial) and
    // C w once, so that a pair's 2 x 2 covariance is a few dot products:
    // S(p - r) = w_p^T C w_p + w_r^T C w_r - w_p^T C w_r - w_r^T C w_p, per part.
    let lift = |grad: Vec<(f64, f64)>, at: usize| -> Parts {
        let mut re = vec![0.0; d];
        let mut im = vec![0.0; d];
        for (i, g) in grad.into_iter().enumerate() {
            re[at + i] = g.0;
            im[at + i] = g.1;
        }
        let times = |v: &[f64]| (0..d).map(|i| (0..d).map(|j| cov[i * d + j] * v[j]).sum()).collect();
        Parts { c_re: times(&re), c_im: times(&im), re, im }
    };
    let pole_parts: Vec<Parts> = poles.iter().map(|&p| lift(root_gradient_monic(f, p), b.len())).collect();
    let mut count = 0;
    for &r in zeros.iter().filter(|r| r.1 >= -REAL * r.0.hypot(r.1)) {
        let zr = lift(root_gradient(b, r), 0);
        let cancels = poles.iter().zip(&pole_parts).any(|(&p, pp)| {
            let s = |a: fn(&Parts) -> (&[f64], &[f64]), c: fn(&Parts) -> (&[f64], &[f64])| {
                let dot = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(u, v)| u * v).sum::<f64>();
                dot(a(pp).0, c(pp).1) + dot(a(&zr).0, c(&zr).1) - dot(a(pp).0, c(&zr).1) - dot(a(&zr).0, c(pp).1)
            };
            let (s11, s12, s22) = (
                s(|q| (&q.re, &q.c_re), |q| (&q.re, &q.c_re)),
                s(|q| (&q.re, &q.c_im), |q| (&q.re, &q.c_im)),
                s(|q| (&q.im, &q.c_im), |q| (&q.im, &q.c_im)),
            );
            let delta = (p.0 - r.0, p.1 - r.1);
            let both_real = r.1.abs() <= REAL * r.0.hypot(r.1) && p.1.abs() <= REAL * p.0.hypot(p.1);
            if both_real {
                s11 > 0.0 && delta.0 * delta.0 <= CHI2_95_1 * s11
            } else {
                let det = s11 * s22 - s12 * s12;
                det > 0.0
                    && (s22 * delta.0 * delta.0 - 2.0 * s12 * delta.0 * delta.1 + s11 * delta.1 * delta.1) / det
                        <= CHI2_95_2
            }
        });
        count += u32::from(cancels);
    }
    Some(count)
}

/// A root's gradient (real and imaginary parts over the parameters) and the covariance times
/// each.
struct Parts {
    re: Vec<f64>,
    im: Vec<f64>,
    c_re: Vec<f64>,
    c_im: Vec<f64>,
}

/// `dr/db_i` of a root r of `b_1 z^(n-1) + ... + b_n` (n = `b.len()`).
fn root_gradient(b: &[f64], r: (f64, f64)) -> Vec<(f64, f64)> {
    let n = b.len();
    let powers = powers(r, n);
    // P'(r) = sum_i b_i (n-i) r^(n-i-1), i from 1.
    let mut dp = (0.0, 0.0);
    for (i, bi) in b.iter().enumerate().take(n - 1) {
        let e = n - 1 - i;
        dp = add(dp, scale(powers[e - 1], bi * e as f64));
    }
    (0..n).map(|i| neg(div(powers[n - 1 - i], dp))).collect()
}

/// `dp/df_j` of a root p of `z^n + f_1 z^(n-1) + ... + f_n` (n = `f.len()`).
fn root_gradient_monic(f: &[f64], p: (f64, f64)) -> Vec<(f64, f64)> {
    let n = f.len();
    let powers = powers(p, n + 1);
    let mut dq = scale(powers[n - 1], n as f64);
    for (j, fj) in f.iter().enumerate().take(n - 1) {
        let e = n - 1 - j;
        dq = add(dq, scale(powers[e - 1], fj * e as f64));
    }
    (0..n).map(|j| neg(div(powers[n - 1 - j], dq))).collect()
}

type C = (f64, f64);

/// `z^0 .. z^(m-1)`.
fn powers(z: C, m: usize) -> Vec<C> {
    let mut out = Vec::with_capacity(m);
    let mut acc = (1.0, 0.0);
    for _ in 0..m {
        out.push(acc);
        acc = (acc.0 * z.0 - acc.1 * z.1, acc.0 * z.1 + acc.1 * z.0);
    }
    out
}
fn add(a: C, b: C) -> C {
    (a.0 + b.0, a.1 + b.1)
}
fn scale(a: C, s: f64) -> C {
    (a.0 * s, a.1 * s)
}
fn neg(a: C) -> C {
    (-a.0, -a.1)
}
fn div(a: C, b: C) -> C {
    let den = b.0 * b.0 + b.1 * b.1;
    ((a.0 * b.0 + a.1 * b.1) / den, (a.1 * b.0 - a.0 * b.1) / den)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The root gradients against central differences of the roots.
    #[test]
    fn root_gradients_match_finite_differences() {
        let b = [0.5, -0.3, 0.2];
        let f = [-1.1, 0.6, -0.1];
        let roots_b = |b: &[f64]| oe::poles(&b[1..].iter().map(|v| v / b[0]).collect::<Vec<_>>());
        for (k, r) in roots_b(&b).into_iter().enumerate() {
            let g = root_gradient(&b, r);
            for i in 0..b.len() {
                let (mut bp, mut bm) = (b, b);
                bp[i] += 1e-7;
                bm[i] -= 1e-7;
                let (rp, rm) = (roots_b(&bp)[k], roots_b(&bm)[k]);
                let fd = ((rp.0 - rm.0) / 2e-7, (rp.1 - rm.1) / 2e-7);
                assert!((fd.0 - g[i].0).abs() < 1e-5 && (fd.1 - g[i].1).abs() < 1e-5, "{fd:?} vs {:?}", g[i]);
            }
        }
        for (k, p) in oe::poles(&f).into_iter().enumerate() {
            let g = root_gradient_monic(&f, p);
            for j in 0..f.len() {
                let (mut fp, mut fm) = (f, f);
                fp[j] += 1e-7;
                fm[j] -= 1e-7;
                let (pp, pm) = (oe::poles(&fp)[k], oe::poles(&fm)[k]);
                let fd = ((pp.0 - pm.0) / 2e-7, (pp.1 - pm.1) / 2e-7);
                assert!((fd.0 - g[j].0).abs() < 1e-5 && (fd.1 - g[j].1).abs() < 1e-5, "{fd:?} vs {:?}", g[j]);
            }
        }
    }

    #[test]
    fn a_near_cancelling_pair_cancels_only_when_uncertain_enough() {
        // Zero at 0.5, poles at 0.52 and 0.9: B = 1 - 0.5 z^-1, F = (1 - 0.52 z^-1)(1 - 0.9 z^-1).
        let b = [1.0, -0.5];
        let f = [-1.42, 0.468];
        let d = 4;
        let diag = |v: f64| (0..d * d).map(|ij| if ij / d == ij % d { v } else { 0.0 }).collect::<Vec<_>>();
        assert_eq!(cancelling_pairs(&b, &f, &diag(1e-2), d), Some(1));
        assert_eq!(cancelling_pairs(&b, &f, &diag(1e-8), d), Some(0));
        // No zeros, nothing to cancel; b_1 = 0 has no roots to speak of.
        assert_eq!(cancelling_pairs(&[1.0], &f, &diag(1.0), 3), Some(0));
        assert_eq!(cancelling_pairs(&[0.0, 1.0], &f, &diag(1.0), d), None);
    }
}
