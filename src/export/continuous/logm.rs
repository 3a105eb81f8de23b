//! The principal matrix logarithm of the ZOH inverse (METHOD.md 18) and the few dense-matrix
//! helpers it needs.

use faer::Mat;

/// Eigenvalues of a real square matrix as (re, im) pairs; None when the solver fails.
pub(super) fn eigenvalues(a: &Mat<f64>) -> Option<Vec<(f64, f64)>> {
    let ev = crate::dense::eigenvalues(a.as_ref())?;
    ev.iter().all(|z| z.0.is_finite() && z.1.is_finite()).then_some(ev)
}

pub(super) fn norm1(a: &Mat<f64>) -> f64 {
    (0..a.ncols()).map(|j| (0..a.nrows()).map(|i| a[(i, j)].abs()).sum::<f64>()).fold(0.0, f64::max)
}

fn minus_identity(a: &Mat<f64>) -> Mat<f64> {
    Mat::from_fn(a.nrows(), a.ncols(), |i, j| a[(i, j)] - if i == j { 1.0 } else { 0.0 })
}

fn inverse(a: &Mat<f64>) -> Option<Mat<f64>> {
    let inv = crate::dense::Lu::new(a.as_ref()).inverse();
    (0..inv.nrows()).all(|i| (0..inv.ncols()).all(|j| inv[(i, j)].is_finite())).then_some(inv)
}

/// Principal square root of a 2 x 2 block without eigenvalues on the closed negative real
/// axis: `(T + sqrt(det T) I)/sqrt(tr T + 2 sqrt(det T))` (Higham, Functions of Matrices,
/// 6.7). That cancels for a pair near the negative real axis; in the modal form `[[a, b],
/// [-b, a]]` (eigenvalues `a +- ib`) the root is `[[alpha, beta], [-beta, alpha]]` with
/// `alpha + i beta = sqrt(a + i b)`, which `beta = sqrt((|λ| - a)/2)`, `alpha = b/(2 beta)`
/// give without cancelling when `a < 0`.
fn sqrt2(t: [[f64; 2]; 2]) -> Option<[[f64; 2]; 2]> {
    let [[a, b], [c, d]] = t;
    if a == d && b == -c && a < 0.0 && b != 0.0 {
        let beta = ((a.hypot(b) - a) / 2.0).sqrt().copysign(b);
        let alpha = b / (2.0 * beta);
        return Some([[alpha, beta], [-beta, alpha]]);
    }
    let (tr, det) = (a + d, a * d - b * c);
    // Real eigenvalues at or below zero, or a negative determinant (one of each sign).
    if det <= 0.0 || (tr <= 0.0 && tr * tr >= 4.0 * det) {
        return None;
    }
    let delta = det.sqrt();
    let tau = (tr + 2.0 * delta).sqrt();
    Some([[(a + delta) / tau, b / tau], [c / tau, (d + delta) / tau]])
}

/// Principal square root of a block lower triangular matrix whose diagonal blocks have the
/// sizes `blocks` (1 or 2): the diagonal blocks' roots, then each block below from
/// `R_ii X + X R_jj = T_ij - sum_k R_ik R_kj` (Björck and Hammarling's recurrence, Higham
/// 6.2), well-conditioned as long as no two roots sum to about zero, which principal roots of
/// matrices without eigenvalues on the closed negative real axis do not. A square root of a
/// companion matrix by an iteration instead loses digits to its non-normality, most near the
/// negative real axis. None for an eigenvalue on the closed negative real axis.
fn sqrtm(t: &Mat<f64>, blocks: &[usize]) -> Option<Mat<f64>> {
    let n = t.nrows();
    let starts: Vec<usize> = blocks.iter().scan(0, |at, &b| Some(std::mem::replace(at, *at + b))).collect();
    let mut r = Mat::<f64>::zeros(n, n);
    for (&s, &b) in starts.iter().zip(blocks) {
        if b == 1 {
            if t[(s, s)] <= 0.0 {
                return None;
            }
            r[(s, s)] = t[(s, s)].sqrt();
        } else {
            let root = sqrt2([[t[(s, s)], t[(s, s + 1)]], [t[(s + 1, s)], t[(s + 1, s + 1)]]])?;
            for (i, row) in root.iter().enumerate() {
                for (j, v) in row.iter().enumerate() {
                    r[(s + i, s + j)] = *v;
                }
            }
        }
    }
    // Below the diagonal, column block by column block from the last, each from the top.
    for jb in (0..blocks.len()).rev() {
        let (sj, qj) = (starts[jb], blocks[jb]);
        for ib in jb + 1..blocks.len() {
            let (si, pi) = (starts[ib], blocks[ib]);
            // The right side, p x q, and the p q x p q system for X by columns.
            let rhs = Mat::<f64>::from_fn(pi * qj, 1, |k, _| {
                let (i, j) = (si + k % pi, sj + k / pi);
                t[(i, j)] - (sj + qj..si).map(|m| r[(i, m)] * r[(m, j)]).sum::<f64>()
            });
            let system = Mat::<f64>::from_fn(pi * qj, pi * qj, |row, col| {
                let (i, j, k, l) = (row % pi, row / pi, col % pi, col / pi);
                // (R_ii X)_ij = sum_k R_ii[i][k] X[k][j]; (X R_jj)_ij = sum_l X[i][l] R_jj[l][j].
                (if j == l { r[(si + i, si + k)] } else { 0.0 }) + if i == k { r[(sj + l, sj + j)] } else { 0.0 }
            });
            let x = crate::dense::Lu::new(system.as_ref()).solve(rhs.as_ref());
            for k in 0..pi * qj {
                r[(si + k % pi, sj + k / pi)] = x[(k, 0)];
            }
        }
    }
    (0..n).all(|i| (0..n).all(|j| r[(i, j)].is_finite())).then_some(r)
}

/// Principal matrix logarithm by inverse scaling and squaring: square roots until
/// `||T - I||_1 <= 1/4`, then `log(I + X)` by the 8-point Gauss-Legendre rule for
/// `int_0^1 X (I + tX)^-1 dt`, which is the [8/8] Padé approximant, accurate to rounding for
/// `||X|| <= 0.367` (Higham 2001, theta_8), times `2^s`. The matrix is block lower triangular
/// with diagonal blocks of the sizes `blocks` ([`sqrtm`]), as are its roots. None for an
/// eigenvalue on the closed negative real axis, or without convergence.
pub(super) fn logm(a: &Mat<f64>, blocks: &[usize]) -> Option<Mat<f64>> {
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
        t = sqrtm(&t, blocks)?;
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
