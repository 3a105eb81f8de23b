//! The output-error model OE(nB, nF) with delay d (METHOD.md section 2).
//!
//! ```text
//! y_t    = q^-d B(q^-1)/F(q^-1) u_t + e_t
//! B      = b_1 + b_2 q^-1 + ... + b_nB q^-(nB-1)
//! F      = 1 + f_1 q^-1 + ... + f_nF q^-nF          (monic)
//! yhat_t = sum_i b_i u_{t-d-i+1} - sum_j f_j yhat_{t-j}   (zero initial conditions)
//! ```
//!
//! Indices here are 0-based (`t = 0..N`); samples before the record are zero.
//! The predictor gradient needs only two `1/F` passes (METHOD.md 2):
//! `d yhat_t/d b_i = [(1/F) u]_{t-d-i+1}`, `d yhat_t/d f_j = -[(1/F) yhat]_{t-j}`.
//!
//! The `1/F` recursion is the innermost loop of every solver: it lives in [`crate::kernels`],
//! specialised on the filter order (state in registers) and built with and without FMA.

use crate::kernels;
pub use crate::structure::{MAX_INPUTS, Orders, Structure};
use faer::Mat;

/// Apply `1/F` in place: `x_t <- x_t - sum_j f_j x_{t-j}` (zero initial conditions).
pub fn inv_f_in_place(f: &[f64], x: &mut [f64]) {
    kernels::inv_f(f, x)
}

/// FIR part of the model: `out_t = sum_i b_i u_{t-d-i+1}`.
pub fn delayed_fir(b: &[f64], delay: usize, u: &[f64], out: &mut [f64]) {
    kernels::fir(b, delay, u, out)
}

/// The simulation and the two Jacobian signals in one pass: `xu = (1/F) u`,
/// `yhat = q^-d B xu`, `xy = (1/F) yhat` ([`kernels::simulate_filtered`]).
pub fn simulate_filtered(
    b: &[f64],
    f: &[f64],
    delay: usize,
    u: &[f64],
    xu: &mut [f64],
    yhat: &mut [f64],
    xy: &mut [f64],
) {
    kernels::simulate_filtered(b, f, delay, u, xu, yhat, xy)
}

/// Simulated output (= one-step predictor of an OE model), zero initial conditions.
pub fn simulate(b: &[f64], f: &[f64], delay: usize, u: &[f64], yhat: &mut [f64]) {
    delayed_fir(b, delay, u, yhat);
    inv_f_in_place(f, yhat);
}

/// Convenience wrapper of [`simulate`] that allocates its output.
pub fn simulate_vec(b: &[f64], f: &[f64], delay: usize, u: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; u.len()];
    simulate(b, f, delay, u, &mut y);
    y
}

/// Frequency response `G(e^{jw}) = e^{-jwd} B(e^{-jw}) / F(e^{-jw})` at normalised angular
/// frequency `w = 2 pi f Ts` (rad/sample). Returns (re, im).
pub fn freq_response(b: &[f64], f: &[f64], delay: usize, w: f64) -> (f64, f64) {
    use cplx::*;
    // Horner in q = e^{-jw} (|q| = 1, so no growth): one sine and cosine per frequency
    // instead of one per coefficient (the band fit of every cell evaluates hundreds of bins).
    let q = (w.cos(), -w.sin());
    let horner = |c: &[f64], last: C| c.iter().rev().fold(last, |acc, &ci| add(mul(acc, q), (ci, 0.0)));
    // B(q) = sum_i b_i q^i; F(q) = 1 + sum_j f_j q^j = 1 + q (f_1 + f_2 q + ...).
    let bq = horner(b, (0.0, 0.0));
    let fq = add((1.0, 0.0), mul(q, horner(f, (0.0, 0.0))));
    let shift = ((w * delay as f64).cos(), -(w * delay as f64).sin());
    div(mul(shift, bq), fq)
}

/// Schur-Cohn (step-down) test: true when every root of `1 + f_1 z^-1 + ... + f_n z^-n` lies
/// strictly inside the unit circle. O(n^2), no allocation for n <= 64.
pub fn is_stable(f: &[f64]) -> bool {
    let n = f.len();
    if n == 0 {
        return true;
    }
    if f.iter().any(|v| !v.is_finite()) {
        return false;
    }
    let mut stack = [0.0; 65];
    let mut heap;
    let a: &mut [f64] = if n < 65 {
        &mut stack[..=n]
    } else {
        heap = vec![0.0; n + 1];
        &mut heap
    };
    a[0] = 1.0;
    a[1..].copy_from_slice(f);
    for m in (1..=n).rev() {
        let k = a[m];
        if k.abs() >= 1.0 {
            return false;
        }
        let den = 1.0 - k * k;
        // a_i <- (a_i - k a_{m-i}) / (1 - k^2), i = 1..m-1, done in pairs to stay in place.
        let (mut i, mut j) = (1, m - 1);
        while i < j {
            let (ai, aj) = (a[i], a[j]);
            a[i] = (ai - k * aj) / den;
            a[j] = (aj - k * ai) / den;
            i += 1;
            j -= 1;
        }
        if i == j {
            a[i] = (a[i] - k * a[i]) / den;
        }
    }
    true
}

/// Roots of `z^n + f_1 z^{n-1} + ... + f_n` (the poles of the model) as (re, im) pairs. Empty
/// when they cannot be computed (non-finite coefficients, or both root finders failed).
///
/// Aberth-Ehrlich iteration first: the solver reflects unstable trial steps (every reflection
/// needs the poles, and lightly damped piezo modes put a third of the trial steps outside
/// the circle), and for these small degrees it is ~10x faster than a general eigen solver
/// call. When it does not converge (e.g. multiple roots), the eigenvalues of the companion
/// matrix.
pub fn poles(f: &[f64]) -> Vec<(f64, f64)> {
    let n = f.len();
    if n == 0 {
        return Vec::new();
    }
    if f.iter().any(|v| !v.is_finite()) {
        return Vec::new();
    }
    aberth_roots(f).unwrap_or_else(|| companion_eigenvalues(f))
}

/// Eigenvalues of the companion matrix of `z^n + f_1 z^{n-1} + ... + f_n`; empty on failure.
fn companion_eigenvalues(f: &[f64]) -> Vec<(f64, f64)> {
    let n = f.len();
    let c = Mat::<f64>::from_fn(n, n, |i, j| {
        if i == 0 {
            -f[j]
        } else if i == j + 1 {
            1.0
        } else {
            0.0
        }
    });
    crate::dense::eigenvalues(c.as_ref()).unwrap_or_default()
}

/// Complex arithmetic on (re, im) pairs: what the root finder and the continuous equivalent's
/// factors (`export::continuous`) need.
pub(crate) mod cplx {
    pub type C = (f64, f64);
    #[inline]
    pub fn add(a: C, b: C) -> C {
        (a.0 + b.0, a.1 + b.1)
    }
    #[inline]
    pub fn sub(a: C, b: C) -> C {
        (a.0 - b.0, a.1 - b.1)
    }
    #[inline]
    pub fn mul(a: C, b: C) -> C {
        (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
    }
    #[inline]
    pub fn div(a: C, b: C) -> C {
        // Smith's algorithm: no overflow for large |b|.
        if b.0.abs() >= b.1.abs() {
            let r = b.1 / b.0;
            let d = b.0 + b.1 * r;
            ((a.0 + a.1 * r) / d, (a.1 - a.0 * r) / d)
        } else {
            let r = b.0 / b.1;
            let d = b.0 * r + b.1;
            ((a.0 * r + a.1) / d, (a.1 * r - a.0) / d)
        }
    }
    /// |a| without libm's hypot (slow): the roots here are of modest size, no overflow.
    #[inline]
    pub fn abs(a: C) -> f64 {
        (a.0 * a.0 + a.1 * a.1).sqrt()
    }
}

/// Roots of the monic `z^n + f_1 z^{n-1} + ... + f_n` by the Aberth-Ehrlich iteration
/// (simultaneous Newton steps, each deflated by the other roots; Gauss-Seidel updates), from
/// points on a circle of the roots' geometric mean radius. None unless every correction fell
/// to rounding level within the iteration cap.
fn aberth_roots(f: &[f64]) -> Option<Vec<(f64, f64)>> {
    let mut z = vec![(0.0, 0.0); f.len()];
    let mut done = vec![false; f.len()];
    aberth_into(f, &mut z, &mut done).then_some(z)
}

/// [`aberth_roots`] into `z` (one entry per root) with `done` as scratch (as long as `z`);
/// false when it did not converge. Allocates nothing.
fn aberth_into(f: &[f64], z: &mut [(f64, f64)], done: &mut [bool]) -> bool {
    use cplx::*;
    const MAX_ITERATIONS: usize = 100;
    let n = f.len();
    assert!(z.len() == n && done.len() == n);
    let radius = f[n - 1].abs().powf(1.0 / n as f64).clamp(0.1, 10.0);
    for (k, zk) in z.iter_mut().enumerate() {
        // An angle offset keeps the start off the real axis and off conjugate symmetry.
        let a = std::f64::consts::TAU * k as f64 / n as f64 + 0.4;
        *zk = (radius * a.cos(), radius * a.sin());
    }
    done.fill(false);
    for _ in 0..MAX_ITERATIONS {
        let mut all_done = true;
        for k in 0..n {
            if done[k] {
                continue;
            }
            let zk = z[k];
            // p(zk) and p'(zk) by Horner, and the bound sum |c_i| |zk|^(n-i) of the rounding
            // error of p(zk).
            let (mut p, mut dp): (C, C) = ((1.0, 0.0), (0.0, 0.0));
            let (r, mut bound) = (abs(zk), 1.0);
            for &c in f {
                dp = add(mul(dp, zk), p);
                p = add(mul(p, zk), (c, 0.0));
                bound = bound * r + c.abs();
            }
            if abs(p) == 0.0 {
                done[k] = true;
                continue;
            }
            // |p| at rounding level: zk is a root as far as the coefficients define one; the
            // correction below is its last.
            let at_rounding = abs(p) <= 4.0 * (n + 1) as f64 * f64::EPSILON * bound;
            let ratio = div(p, dp);
            let mut sum: C = (0.0, 0.0);
            for (j, &zj) in z.iter().enumerate() {
                if j != k {
                    sum = add(sum, div((1.0, 0.0), sub(zk, zj)));
                }
            }
            let w = div(ratio, sub((1.0, 0.0), mul(ratio, sum)));
            if !(w.0.is_finite() && w.1.is_finite()) {
                return false;
            }
            z[k] = sub(zk, w);
            if at_rounding || abs(w) <= 4.0 * f64::EPSILON * abs(z[k]).max(f64::MIN_POSITIVE) {
                done[k] = true;
            } else {
                all_done = false;
            }
        }
        if all_done {
            return true;
        }
    }
    false
}

/// Largest pole radius of `F` (0 for nF = 0, infinity when the poles cannot be computed).
pub fn max_pole_radius(f: &[f64]) -> f64 {
    if f.is_empty() {
        return 0.0;
    }
    let p = poles(f);
    if p.is_empty() {
        return f64::INFINITY;
    }
    p.iter().map(|&(re, im)| re.hypot(im)).fold(0.0, f64::max)
}

/// Monic real polynomial `[f_1..f_n]` from its roots (complex roots in conjugate pairs).
pub fn poly_from_roots(roots: &[(f64, f64)]) -> Vec<f64> {
    let mut c = vec![(0.0, 0.0); roots.len() + 1];
    poly_from_roots_into(roots, &mut c);
    c[1..].iter().map(|z| z.0).collect()
}

/// Monic real polynomial `[f_1..f_n]` with the poles `r e^(+-j a)` of each (radius, angle) pair
/// in `pairs` and the real poles `real`: how the tests and benchmarks write a system down.
pub fn poly_from_poles(pairs: &[(f64, f64)], real: &[f64]) -> Vec<f64> {
    let mut roots = Vec::new();
    for &(r, a) in pairs {
        roots.push((r * a.cos(), r * a.sin()));
        roots.push((r * a.cos(), -r * a.sin()));
    }
    roots.extend(real.iter().map(|&p| (p, 0.0)));
    poly_from_roots(&roots)
}

/// The complex coefficients of `prod (z - r)`, highest power first, into `c` (one longer than
/// `roots`), multiplying in one root at a time in place. Allocates nothing.
fn poly_from_roots_into(roots: &[(f64, f64)], c: &mut [(f64, f64)]) {
    assert_eq!(c.len(), roots.len() + 1);
    c[0] = (1.0, 0.0);
    for (m, &(rr, ri)) in roots.iter().enumerate() {
        // Degree m -> m + 1: c_k <- c_k - r c_{k-1}, from the top down so c_{k-1} is still old.
        c[m + 1] = (0.0, 0.0);
        for k in (1..=m + 1).rev() {
            let (cr, ci) = c[k - 1];
            c[k].0 += -(rr * cr - ri * ci);
            c[k].1 += -(rr * ci + ri * cr);
        }
    }
}

/// Reflect the poles outside (or on) the unit circle to `1/conj(p)`, keeping `F` monic and
/// real. Roots exactly on the circle are pulled to radius `1 - 1e-6` so the result is
/// strictly stable. Returns true when something changed.
pub fn reflect_unstable(f: &mut [f64]) -> bool {
    if is_stable(f) {
        return false;
    }
    if f.iter().any(|v| !v.is_finite()) {
        // Nothing to reflect: fall back to F = 1 (the shrinking below would never end).
        f.fill(0.0);
        return true;
    }
    // A third of the solver's trial steps can need this (lightly damped modes): for the
    // orders of a sweep it runs in stack buffers.
    let n = f.len();
    if n <= STACK_ORDER {
        let mut z = [(0.0, 0.0); STACK_ORDER];
        let mut done = [false; STACK_ORDER];
        let mut c = [(0.0, 0.0); STACK_ORDER + 1];
        let mut g = [0.0; STACK_ORDER];
        reflect_with(f, &mut z[..n], &mut done[..n], &mut c[..=n], &mut g[..n]);
    } else {
        let (mut z, mut done) = (vec![(0.0, 0.0); n], vec![false; n]);
        let (mut c, mut g) = (vec![(0.0, 0.0); n + 1], vec![0.0; n]);
        reflect_with(f, &mut z, &mut done, &mut c, &mut g);
    }
    true
}

/// Orders up to which [`reflect_unstable`] allocates nothing (its root buffers live on the
/// stack). A job's orders are capped below it ([`crate::job::MAX_ORDER`]) so that no fit of a
/// sweep allocates in its iteration loop (tests/no_allocation.rs).
pub const STACK_ORDER: usize = 64;

/// [`reflect_unstable`] of an unstable, finite `f` in the given buffers (roots `z`, scratch
/// `done`, coefficients `c` and `g`).
fn reflect_with(f: &mut [f64], z: &mut [(f64, f64)], done: &mut [bool], c: &mut [(f64, f64)], g: &mut [f64]) {
    if !aberth_into(f, z, done) {
        // The rare polynomial the iteration does not settle: the eigen solver (allocates).
        let p = companion_eigenvalues(f);
        if p.len() != f.len() {
            // Eigen solver failed: shrink towards F = 1, which is always stable.
            let mut scale = 0.5;
            while !is_stable(f) {
                for (j, v) in f.iter_mut().enumerate() {
                    *v *= f64::powi(scale, j as i32 + 1);
                }
                scale *= 0.5;
            }
            return;
        }
        z.copy_from_slice(&p);
    }
    const RMAX: f64 = 1.0 - 1e-6;
    for z in z.iter_mut() {
        let r = z.0.hypot(z.1);
        if r >= 1.0 {
            let target = if r > 1.0 + 1e-6 { 1.0 / r } else { RMAX };
            let s = target / r;
            *z = (z.0 * s, z.1 * s);
        }
    }
    poly_from_roots_into(z, c);
    for (gj, cj) in g.iter_mut().zip(&c[1..]) {
        *gj = cj.0;
    }
    f.copy_from_slice(g);
    if !is_stable(f) {
        // Rounding left a root on the circle, or inaccurate roots of a clustered high-order F
        // left some outside: contract all poles, by 1e-6 at first and doubling the step each
        // time, so even a root far outside is pulled in within ~60 tries.
        let (mut s, mut step) = (RMAX, 1e-6f64);
        while !is_stable(f) {
            for (j, v) in f.iter_mut().enumerate() {
                *v = g[j] * s.powi(j as i32 + 1);
            }
            step = (2.0 * step).min(0.5);
            s *= 1.0 - step;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulate_matches_difference_equation() {
        let b = [0.5, -0.2, 0.1];
        let f = [-1.2, 0.5];
        let u: Vec<f64> = (0..50).map(|t| if (t / 3) % 2 == 0 { 1.0 } else { -1.0 }).collect();
        for d in 0..3 {
            let y = simulate_vec(&b, &f, d, &u);
            for t in 0..u.len() {
                let mut r = 0.0;
                for i in 0..3 {
                    if t >= d + i {
                        r += b[i] * u[t - d - i];
                    }
                }
                for j in 0..2 {
                    if t > j {
                        r -= f[j] * y[t - 1 - j];
                    }
                }
                assert!((r - y[t]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn stability_test_agrees_with_poles() {
        let cases: &[&[f64]] = &[&[-1.5, 0.7], &[-2.5, 1.0], &[0.5], &[-1.0], &[-1.8, 0.81], &[-1.9, 0.99, -0.2]];
        for f in cases {
            let r = max_pole_radius(f);
            assert_eq!(is_stable(f), r < 1.0 - 1e-12, "{f:?} radius {r}");
        }
    }

    #[test]
    fn reflection_of_a_non_finite_f_ends_at_f_equal_one() {
        for bad in [[f64::NAN, 0.2], [0.5, f64::INFINITY]] {
            let mut f = bad;
            assert!(reflect_unstable(&mut f));
            assert_eq!(f, [0.0, 0.0]);
        }
    }

    #[test]
    fn reflection_moves_poles_inside() {
        let mut f = vec![-2.5, 1.0]; // roots 2 and 0.5
        assert!(reflect_unstable(&mut f));
        assert!((f[0] + 1.0).abs() < 1e-12 && (f[1] - 0.25).abs() < 1e-12, "{f:?}");
        let mut g = vec![-2.0, 1.0]; // double root at 1
        reflect_unstable(&mut g);
        assert!(is_stable(&g));
    }

    #[test]
    fn reflection_ends_stable_for_clustered_and_wild_polynomials() {
        // A 12-fold root outside the circle: its computed eigenvalues scatter by ~eps^(1/12).
        let mut f = poly_from_roots(&[(1.5, 0.0); 12]);
        assert!(reflect_unstable(&mut f) && is_stable(&f), "{f:?}");
        // Extrapolated parameter vectors can be anything: every one must end stable, fast.
        let mut state = 7u64;
        for _ in 0..200 {
            let mut f: Vec<f64> = (0..15)
                .map(|_| {
                    state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 40.0
                })
                .collect();
            reflect_unstable(&mut f);
            assert!(is_stable(&f), "{f:?}");
        }
    }

    /// The Aberth roots are the companion-matrix eigenvalues: random real polynomials of
    /// degrees 1..24 with roots inside, on and outside the circle, lightly damped clusters
    /// like the piezo's modes, and a double root (where Aberth may give up: then `poles`
    /// falls back to the eigenvalues).
    #[test]
    fn aberth_roots_are_the_companion_eigenvalues() {
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut cases: Vec<Vec<(f64, f64)>> = Vec::new();
        for n in 1..=24 {
            for _ in 0..20 {
                let mut roots = Vec::new();
                while roots.len() + 2 <= n {
                    let (r, a) = (0.2 + 1.0 * rnd(), std::f64::consts::PI * rnd());
                    roots.push((r * a.cos(), r * a.sin()));
                    roots.push((r * a.cos(), -r * a.sin()));
                }
                if roots.len() < n {
                    roots.push((2.0 * rnd() - 1.0, 0.0));
                }
                cases.push(roots);
            }
        }
        // Resonances at radius 0.995-0.9995, some within 0.01 rad of each other.
        let mut lightly_damped = Vec::new();
        for (r, a) in [(0.999, 0.30), (0.9995, 0.31), (0.995, 0.8), (0.998, 1.5), (0.997, 2.2)] {
            lightly_damped.push((r * f64::cos(a), r * f64::sin(a)));
            lightly_damped.push((r * f64::cos(a), -r * f64::sin(a)));
        }
        cases.push(lightly_damped);
        for roots in &cases {
            let f = poly_from_roots(roots);
            let got = poles(&f);
            let want = companion_eigenvalues(&f);
            assert_eq!(got.len(), f.len());
            // Each true root is found about as accurately as by the eigen solver: both are
            // limited by how well the rounded coefficients determine it.
            let nearest = |set: &[(f64, f64)], w: (f64, f64)| {
                set.iter().map(|g| (g.0 - w.0).hypot(g.1 - w.1)).fold(f64::INFINITY, f64::min)
            };
            for &w in roots {
                let (a, e) = (nearest(&got, w), nearest(&want, w));
                assert!(a <= 10.0 * e + 1e-12, "{f:?}: root {w:?}: Aberth {a:e} away, eigen solver {e:e}");
            }
        }
        let double = poly_from_roots(&[(0.5, 0.0), (0.5, 0.0), (-0.3, 0.2), (-0.3, -0.2)]);
        let p = poles(&double);
        assert_eq!(p.len(), 4);
        assert!(p.iter().filter(|z| (z.0 - 0.5).hypot(z.1) < 1e-6).count() == 2, "{p:?}");
    }

    #[test]
    fn poly_roundtrip() {
        let f = [-1.6, 1.2, -0.4, 0.05];
        let g = poly_from_roots(&poles(&f));
        for (a, b) in f.iter().zip(&g) {
            assert!((a - b).abs() < 1e-10);
        }
    }

    #[test]
    fn freq_response_at_dc() {
        let (re, im) = freq_response(&[0.2, 0.1], &[-0.5], 1, 0.0);
        assert!((re - 0.6).abs() < 1e-12 && im.abs() < 1e-12);
    }

    /// Horner in e^{-jw} against the defining sums, term by term.
    #[test]
    fn freq_response_is_the_defining_sum() {
        let b = [0.5, -0.2, 0.1, 0.05];
        let f = [-1.2, 0.5, 0.1];
        for delay in [0, 1, 3] {
            for w in [0.0, 0.01, 0.7, 2.0, std::f64::consts::PI] {
                let (mut br, mut bi, mut fr, mut fi) = (0.0, 0.0, 1.0, 0.0);
                for (i, c) in b.iter().enumerate() {
                    let ph = -w * (delay + i) as f64;
                    br += c * ph.cos();
                    bi += c * ph.sin();
                }
                for (j, c) in f.iter().enumerate() {
                    let ph = -w * (j + 1) as f64;
                    fr += c * ph.cos();
                    fi += c * ph.sin();
                }
                let den = fr * fr + fi * fi;
                let want = ((br * fr + bi * fi) / den, (bi * fr - br * fi) / den);
                let got = freq_response(&b, &f, delay, w);
                assert!(
                    (got.0 - want.0).abs() < 1e-12 && (got.1 - want.1).abs() < 1e-12,
                    "{delay} {w}: {got:?} {want:?}"
                );
            }
        }
    }
}
