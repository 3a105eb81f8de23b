//! The inverse `(J_s^T J_s)^-1` of the covariance (METHOD.md 10) from the triangular factor of
//! the scaled Jacobian `J_s = Q R` when the formed Gram matrix is too ill-conditioned for its
//! own Cholesky inverse ([`super::evidence`]): `R^-1 R^-T`, whose rounding error grows with
//! `cond(J_s)` instead of `cond(J_s)^2`. `J_s` is the N x d Jacobian with column j divided by
//! `scale_j sqrt(N_O)` (unit column norms); its rows are built in blocks of [`ROWS`] from the
//! solver's signals `xu`, `xy`, never as one N x d matrix.
//!
//! **CholeskyQR2 first** (Yamamoto, Nakatsukasa, Yanagisawa, Fukaya, ETNA 44 (2015) 306-326):
//! the evidence has the Cholesky factor `L1` of `G1 = J_s^T J_s` already (its formed inverse was
//! too ill-conditioned, not impossible), so `Q1 = J L1^-T`, `G2 = Q1^T Q1`, `L = L1 chol(G2)`:
//! one pass over the record. Accepted when `||G2 - I||_F <= 1/2` ([`QR2_DEPARTURE`]): `Q1` is
//! then well-conditioned and the second step is as accurate as Householder's; otherwise (from
//! conditions of `G1` near 1e16, or without `L1`) shifted CholeskyQR3.
//!
//! **Shifted CholeskyQR3** (Fukaya, Kannan, Nakatsukasa, Yamamoto, Yanagisawa, SIAM J. Sci.
//! Comput. 42 (2020) A477-A503):
//!
//! ```text
//! 1. G1 = J^T J,     R1 = chol(G1 + s I),   s = 11 (N d + d (d + 1)) u ||J||_F^2
//! 2. Q1 = J R1^-1,   G2 = Q1^T Q1,          R2 = chol(G2)
//! 3. Q2 = Q1 R2^-1,  G3 = Q2^T Q2,          R3 = chol(G3);   R = R3 R2 R1
//! ```
//!
//! (u the unit roundoff, `||J||_F^2 = trace G1 >= ||J||_2^2`, which only enlarges the shift.)
//! `G1` is the unit-diagonal matrix `A` the evidence formed for its Cholesky inverse (from the
//! normal equations, METHOD.md 3: `J_s^T J_s` up to rounding well below the shift), so step 1
//! reads no row: two passes over the record, each building its blocks of `J_s` again.
//! The shift makes step 1's Cholesky succeed up to `cond(J) ~ 1/u`; `Q1` then has a condition
//! of at most ~`u^-1/2`, which the two unshifted steps (CholeskyQR2) orthogonalise to `O(u)`:
//! `R` is the factor of `J + dJ`, `||dJ|| = O(u) ||J||`, as Householder's is, so the inverse
//! moves by `O(u cond(J))` relative to its norm. Every step is a product, a triangular solve or
//! a d x d Cholesky (faer, [`crate::dense`]): 2 N d^2 flops per Gram matrix, N d^2 per
//! triangular solve (two Gram matrices, three solves), cheaper than faer's Householder QR
//! (2 N d^2 flops), which runs far below the rate of its products at this tall, narrow shape.
//!
//! When a Cholesky fails (`cond(J)` beyond ~`1/u`: parameters the data all but do not
//! determine), `R` is the Householder QR's of blocks of rows stacked under the R so far
//! (Golub and Van Loan, 5.3.7), as before shifted CholeskyQR3.
//!
//! Missing outputs (METHOD.md 21.3): a missing sample's row is zero (no equation, nothing added
//! to `R^T R`). No lag reaches back across a seam (METHOD.md 21): an experiment's first rows
//! of a lagged column are zero, as the record's first are.

use faer::prelude::*;
use faer::{Mat, MatMut, MatRef};

use super::problem::Problem;
use crate::dense::{self, Llt};

/// Rows of the scaled Jacobian per block.
const ROWS: usize = 1024;

/// The rows of the scaled Jacobian of `prob` at the signals `xu`, `xy` (the solver's).
struct ScaledJacobian<'a> {
    prob: &'a Problem<'a>,
    xu: &'a [f64],
    xy: &'a [f64],
    /// `1 / (scale_j sqrt(N_O))` per column.
    factor: Vec<f64>,
}

impl<'a> ScaledJacobian<'a> {
    fn new(prob: &'a Problem<'a>, xu: &'a [f64], xy: &'a [f64], scale: &[f64]) -> ScaledJacobian<'a> {
        let root_n = (prob.n_obs() as f64).sqrt();
        ScaledJacobian { prob, xu, xy, factor: scale.iter().map(|s| 1.0 / (s * root_n)).collect() }
    }

    fn rows(&self) -> usize {
        self.prob.n()
    }

    /// Rows `start..start + out.nrows()` into `out`.
    fn fill(&self, start: usize, mut out: MatMut<'_, f64>) {
        let prob = self.prob;
        let lay = prob.layout();
        let d0 = lay.dim();
        let m = out.nrows();
        let here = &prob.missing[prob.missing.partition_point(|&t| t < start)..];
        for (j, &factor) in self.factor.iter().enumerate() {
            let mut col = out.rb_mut().col_mut(j);
            let out = col.rb_mut().try_as_col_major_mut().expect("a column of a column-major block").as_slice_mut();
            if j < d0 {
                lay.column_into(self.xu, self.xy, j, start, factor, out);
                let lag = lay.lag(j);
                for &seam in prob.seams.iter().filter(|&&s| s + lag > start && s < start + m) {
                    for t in seam.max(start)..(seam + lag).min(start + m) {
                        out[t - start] = 0.0;
                    }
                }
            } else {
                out.fill(factor);
            }
            for &t in here.iter().take_while(|&&t| t < start + m) {
                out[t - start] = 0.0;
            }
        }
    }

    /// `sum_blocks B^T B` of the blocks `B` of rows, each first divided on the right by
    /// `L_1^T`, then `L_2^T`, ... (`Q = J R_1^-1 R_2^-1 ...`): one pass over the record.
    fn gram(&self, divide: &[&Llt], block: &mut Mat<f64>) -> Mat<f64> {
        let d = self.factor.len();
        let mut g = Mat::zeros(d, d);
        for start in (0..self.rows()).step_by(ROWS) {
            let m = ROWS.min(self.rows() - start);
            let mut b = block.as_mut().subrows_mut(0, m);
            self.fill(start, b.rb_mut());
            for l in divide {
                dense::solve_right_lower_transpose_in_place(b.rb_mut(), l.factor());
            }
            dense::gram_add(g.as_mut(), b.rb());
        }
        g
    }

    /// `L = R^T` by CholeskyQR2 from the Cholesky factor `l1` of `G1 = J_s^T J_s` (the
    /// evidence's, unshifted): `Q1 = J L1^-T`, `G2 = Q1^T Q1`, `L = L1 chol(G2)`, one pass over
    /// the rows. None when `Q1` is not close to orthogonal (`||G2 - I||_F > `[`QR2_DEPARTURE`]),
    /// or `G2`'s Cholesky fails: shifted CholeskyQR3 then.
    fn cholesky_qr2(&self, l1: &Llt) -> Option<Mat<f64>> {
        let d = self.factor.len();
        let mut block = Mat::zeros(ROWS.min(self.rows()), d);
        let g2 = self.gram(&[l1], &mut block);
        let departure: f64 = (0..d)
            .flat_map(|j| (j..d).map(move |i| (i, j)))
            .map(|(i, j)| {
                let e = g2[(i, j)] - if i == j { 1.0 } else { 0.0 };
                if i == j { e * e } else { 2.0 * e * e }
            })
            .sum::<f64>()
            .sqrt();
        // A NaN departure (a non-finite row) fails too.
        if departure.is_nan() || departure > QR2_DEPARTURE {
            return None;
        }
        let l2 = Llt::new(g2.as_ref())?;
        Some(dense::mul(l1.factor(), l2.factor()))
    }

    /// `L = R^T` by shifted CholeskyQR3 from `G1 = J_s^T J_s` (`g1`, lower triangle read);
    /// None when one of its Cholesky factorisations fails.
    fn cholesky_qr3(&self, g1: MatRef<'_, f64>) -> Option<Mat<f64>> {
        let d = self.factor.len();
        let n = self.rows();
        let norm2: f64 = (0..d).map(|i| g1[(i, i)]).sum();
        let shift = 11.0 * (n * d + d * (d + 1)) as f64 * (f64::EPSILON / 2.0) * norm2;
        let l1 = Llt::new(Mat::from_fn(d, d, |i, j| g1[(i, j)] + if i == j { shift } else { 0.0 }).as_ref())?;
        let mut block = Mat::zeros(ROWS.min(n), d);
        let l2 = Llt::new(self.gram(&[&l1], &mut block).as_ref())?;
        let l3 = Llt::new(self.gram(&[&l1, &l2], &mut block).as_ref())?;
        // R = R3 R2 R1, so L = R^T = L1 L2 L3.
        Some(dense::mul(dense::mul(l1.factor(), l2.factor()).as_ref(), l3.factor()))
    }

    /// `R` (upper, d x d; fewer rows when N < d) by blocks of rows stacked under the R so far,
    /// each stack factored by faer's blocked Householder QR.
    fn householder(&self) -> Mat<f64> {
        let d = self.factor.len();
        let n = self.rows();
        let mut stack = Mat::<f64>::zeros(d + ROWS, d);
        let mut r = Mat::<f64>::zeros(0, d);
        for start in (0..n).step_by(ROWS) {
            let m = ROWS.min(n - start);
            let k = r.nrows();
            stack.as_mut().subrows_mut(0, k).copy_from(&r);
            self.fill(start, stack.as_mut().subrows_mut(k, m));
            r = dense::qr_r(stack.as_ref().subrows(0, k + m));
        }
        r
    }
}

/// Largest `||G2 - I||_F` at which CholeskyQR2's `Q1` counts as close to orthogonal: its
/// singular values then lie within `sqrt(1 -/+ 1/2)`, so `Q1` has a condition below `sqrt(3)`
/// and the second step orthogonalises it to `O(u)`; the rows `Q1 L1^T` reproduce `J_s` to
/// `O(u) ||J_s||` since `||Q1|| ||L1|| <= 1.23 ||J_s||` (Yamamoto, Nakatsukasa, Yanagisawa,
/// Fukaya, ETNA 44 (2015) 306-326: CholeskyQR2 is as accurate as Householder once its first
/// `Q` is well-conditioned). `G2 - I` is `L1^-1 E L1^-T` for the rounding `E` of `G1` and its
/// factor, `~u cond(G1)` in size: the check passes up to a condition of some 1e14-1e15.
const QR2_DEPARTURE: f64 = 0.5;

/// `(J_s^T J_s)^-1` (d x d, row-major) of the Jacobian with columns scaled by
/// `1 / (scale sqrt(N_O))`, as `R^-1 R^-T`; `a` is `J_s^T J_s` as the normal equations formed
/// it (unit diagonal; lower triangle read) and `chol` its Cholesky factor when it has one
/// (CholeskyQR2 from it, one pass over the rows; else, or when its `Q` is not close to
/// orthogonal, shifted CholeskyQR3, two passes). None when R is singular.
pub(super) fn qr_inverse(
    prob: &Problem,
    xu: &[f64],
    xy: &[f64],
    scale: &[f64],
    a: MatRef<'_, f64>,
    chol: Option<&Llt>,
) -> Option<Vec<f64>> {
    let jac = ScaledJacobian::new(prob, xu, xy, scale);
    let l = chol
        .and_then(|l1| jac.cholesky_qr2(l1))
        .or_else(|| jac.cholesky_qr3(a))
        .unwrap_or_else(|| jac.householder().transpose().to_owned());
    inverse(l.as_ref(), prob.dim())
}

/// `L^-T L^-1` (d x d, row-major) of `L = R^T`; None when it has fewer than d columns (fewer
/// rows than parameters) or a zero or non-finite diagonal entry.
fn inverse(l: MatRef<'_, f64>, d: usize) -> Option<Vec<f64>> {
    if l.ncols() < d || (0..d).any(|i| !(l[(i, i)].is_finite() && l[(i, i)] != 0.0)) {
        return None;
    }
    // Householder's R may have negative diagonal entries: its L^-T L^-1 is the same.
    let inv = Llt::from_factor(l).inverse();
    Some((0..d * d).map(|ij| inv[(ij / d, ij % d)]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::fit::theta_of;
    use crate::estimate::normal::NormalEquations;
    use crate::oe::{self, Structure};

    /// A uniform (binary: its sign) input of the tests' LCG.
    fn input(n: usize, binary: bool) -> Vec<f64> {
        let mut s = 7u64;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let v = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
                if binary { v.signum() } else { v }
            })
            .collect()
    }

    /// The Jacobian signals of `prob` at `theta`, the columns' scale and the unit-diagonal Gram
    /// matrix, as `evidence` forms them.
    fn signals(prob: &Problem, theta: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>, Mat<f64>) {
        let n = prob.n();
        let (mut xu, mut yh, mut xy) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        prob.simulate_filtered(theta, &mut xu, &mut yh, &mut xy);
        let d = prob.dim();
        let w: Vec<f64> = (0..n).map(|t| if prob.missing.contains(&t) { 0.0 } else { 1.0 }).collect();
        let w = Some(&w[..]).filter(|_| !prob.missing.is_empty());
        let (mut h, mut g, r) = (vec![0.0; d * d], vec![0.0; d], vec![0.0; n]);
        NormalEquations::default().build_all(&prob.layout(), prob.offset, prob.seams, &xu, &xy, w, &r, &mut h, &mut g);
        let per_obs = n as f64 / prob.n_obs() as f64;
        let scale: Vec<f64> = (0..d).map(|i| (h[i * d + i] * per_obs).sqrt()).collect();
        let a = Mat::from_fn(d, d, |i, j| h[i * d + j] * per_obs / (scale[i] * scale[j]));
        (xu, xy, scale, a)
    }

    /// The largest absolute entry of `a - b` over that of `b`.
    fn max_rel_diff(a: &[f64], b: &[f64]) -> f64 {
        let big = b.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
        a.iter().zip(b).fold(0.0, |m: f64, (x, y)| m.max((x - y).abs())) / big
    }

    /// Both ways to R invert the same matrix as the Cholesky inverse of the formed Gram
    /// matrix, also on a record of several experiments with an offset and with missing
    /// outputs: the rows have no lag across a seam, as the summed normal equations have not
    /// (which `tests/experiments.rs` checks against an explicit Jacobian), and a missing
    /// output's row is left out, as the weighted normal equations leave it out; and where
    /// shifted CholeskyQR3 fails, the inverse is Householder's.
    #[test]
    fn the_qr_inverse_is_the_cholesky_inverse_across_seams() {
        let n = 3000;
        let u = input(n, false);
        let y = vec![0.0; n];
        let missing: Vec<usize> = (0..n).filter(|t| t % 37 == 5 || (1500..1540).contains(t)).collect();
        for (seams, missing) in [(vec![], &[][..]), (vec![700, 2100], &[][..]), (vec![700, 2100], &missing[..])] {
            let prob =
                Problem { u: &u, y: &y, structure: Structure::siso(2, 2, 1), offset: true, seams: &seams, missing };
            let (xu, xy, scale, a) = signals(&prob, &theta_of(&[1.0, 0.5], &[-0.6, 0.2], Some(0.0)));
            let d = prob.dim();
            let chol = Llt::new(a.as_ref()).expect("well conditioned").inverse();
            let chol: Vec<f64> = (0..d * d).map(|ij| chol[(ij / d, ij % d)]).collect();
            let jac = ScaledJacobian::new(&prob, &xu, &xy, &scale);
            let cq = jac.cholesky_qr3(a.as_ref()).expect("well conditioned");
            let l1 = Llt::new(a.as_ref()).expect("well conditioned");
            let cq2 = jac.cholesky_qr2(&l1).expect("well conditioned");
            for (method, l) in [
                ("CholeskyQR3", cq.clone()),
                ("CholeskyQR2", cq2.clone()),
                ("Householder", jac.householder().transpose().to_owned()),
            ] {
                let qr = inverse(l.as_ref(), d).expect("full rank");
                let diff = max_rel_diff(&qr, &chol);
                assert!(diff <= 1e-12, "seams {seams:?}, {} missing, {method}: {diff:e}", missing.len());
            }
            // With the Gram matrix's factor, CholeskyQR2; without, shifted CholeskyQR3.
            assert_eq!(qr_inverse(&prob, &xu, &xy, &scale, a.as_ref(), Some(&l1)), inverse(cq2.as_ref(), d));
            assert_eq!(qr_inverse(&prob, &xu, &xy, &scale, a.as_ref(), None), inverse(cq.as_ref(), d));
            // Where a Cholesky factorisation fails (here step 1's, of a matrix that is not
            // positive definite), R is Householder's.
            let householder = inverse(jac.householder().transpose(), d);
            assert_eq!(qr_inverse(&prob, &xu, &xy, &scale, (-&a).as_ref(), None), householder);
        }
    }

    /// Shifted CholeskyQR3, and CholeskyQR2 wherever its first `Q` passes the check, invert
    /// ill-conditioned Jacobians as accurately as Householder's QR: the lightly damped OE(12,12) of `tests/covariance_large.rs` and its sub-models with
    /// the first 1..6 pole pairs (radii as there and 1 % closer to the origin; B of the same
    /// order from its zeros) at their true parameters, white binary input, N = 5000: conditions
    /// of the unit-diagonal Gram matrix `A` from 1e2 to 2.5e18 (1e11..1e15: OE(8,8), OE(10,10)).
    /// Both factorisations are backward stable, so the inverse from either is off by
    /// `O(u cond(J_s))` relative to its largest entry (u = 2^-53, `cond(J_s) = cond(A)^1/2`,
    /// METHOD.md 10); the two agree to within `u (10 d + cond(J_s))` (observed: at most 0.02
    /// `u cond(J_s)` above `cond(A)` = 1e12, a few `d u` below).
    #[test]
    fn cholesky_qr3_inverts_ill_conditioned_jacobians_as_householder_does() {
        let n = 5000;
        let u = input(n, true);
        let y = vec![0.0; n];
        let zeros = |z: &[(f64, f64)], real: &[f64]| -> Vec<f64> {
            std::iter::once(1.0).chain(oe::poly_from_poles(z, real)).collect()
        };
        let pairs = [(0.99, 0.3), (0.98, 0.9), (0.97, 1.6), (0.8, 0.5), (0.7, 1.5), (0.6, 2.5)];
        let zero_pairs = [(0.9, 1.25), (0.85, 2.6)];
        let real_zeros = [-0.9, -0.6, -0.3, 0.2, 0.45, -1.5, 1.3];
        let mut systems: Vec<(Vec<f64>, Vec<f64>)> = Vec::new();
        for k in 1..=6 {
            for r in [0.99, 1.0] {
                let p: Vec<(f64, f64)> = pairs[..k].iter().map(|&(rad, w)| (rad * r, w)).collect();
                let zp = &zero_pairs[..(k / 2).min(2)];
                let nr = 2 * k - 1 - 2 * zp.len();
                systems.push((zeros(zp, &real_zeros[..nr]), oe::poly_from_poles(&p, &[])));
            }
        }
        let (mut worst, mut qr2_reach): (f64, f64) = (0.0, 0.0);
        for (b, f) in &systems {
            let prob = Problem {
                u: &u,
                y: &y,
                structure: Structure::siso(b.len(), f.len(), 1),
                offset: false,
                seams: &[],
                missing: &[],
            };
            let (xu, xy, scale, a) = signals(&prob, &theta_of(b, f, None));
            let d = prob.dim();
            let jac = ScaledJacobian::new(&prob, &xu, &xy, &scale);
            let cq = jac.cholesky_qr3(a.as_ref()).expect("shifted CholeskyQR3 up to cond(J_s) ~ 1/u");
            let cq = inverse(cq.as_ref(), d).expect("full rank");
            let hh = inverse(jac.householder().transpose(), d).expect("full rank");
            // CholeskyQR2 from the Gram matrix's own factor, where it has one and its Q1 is
            // close enough to orthogonal; what qr_inverse gives in either case.
            let l1 = Llt::new(a.as_ref());
            let cq2 =
                l1.as_ref().and_then(|l1| jac.cholesky_qr2(l1)).map(|l| inverse(l.as_ref(), d).expect("full rank"));
            let chosen = qr_inverse(&prob, &xu, &xy, &scale, a.as_ref(), l1.as_ref()).expect("full rank");
            assert_eq!(chosen, cq2.clone().unwrap_or_else(|| cq.clone()));
            let largest = |m: &Mat<f64>| dense::symmetric_eigen(m.as_ref()).expect("symmetric").0[d - 1];
            let cond = largest(&a) * largest(&Mat::from_fn(d, d, |i, j| hh[i * d + j]));
            let diff = max_rel_diff(&cq, &hh);
            let bound = f64::EPSILON / 2.0 * (10.0 * d as f64 + cond.sqrt());
            worst = worst.max(cond);
            let diff2 = cq2.as_ref().map(|c| max_rel_diff(c, &hh));
            if diff2.is_some() {
                qr2_reach = qr2_reach.max(cond);
            }
            eprintln!(
                "OE({}, {}): cond(A) {cond:.1e}, CholeskyQR3 vs Householder {diff:.1e}, CholeskyQR2 {diff2:?}, bound {bound:.1e}",
                b.len(),
                f.len()
            );
            assert!(diff <= bound, "OE({}, {}): cond(A) {cond:.1e}: {diff:e} > {bound:e}", b.len(), f.len());
            if let Some(diff2) = diff2 {
                assert!(
                    diff2 <= bound,
                    "OE({}, {}) CholeskyQR2: cond(A) {cond:.1e}: {diff2:e} > {bound:e}",
                    b.len(),
                    f.len()
                );
            }
        }
        assert!(worst > 1e15, "the Jacobians reach a condition of 1e15: {worst:e}");
        // CholeskyQR2 serves beyond the Gram matrix's own inverse (1e11, COND_LIMIT).
        assert!(qr2_reach > 1e12, "CholeskyQR2 up to a condition of {qr2_reach:e}");
    }
}
