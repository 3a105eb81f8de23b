//! faer's dense routines as oesweep uses them, with `Par::Seq` passed explicitly. faer's
//! high-level API (`Mat * Mat`, `llt`, `qr`, `eigenvalues`, ...) reads the process-wide
//! parallelism instead: a host program that disables it makes those calls panic, and one whose
//! faer has `rayon` (cargo unifies the feature into ours) and sets it would run them on its
//! pool. oesweep parallelises across cells and leaves that setting to the host, so every
//! factorisation here is sequential by construction, with faer's default parameters: the
//! same operations, in the same order, as the high-level calls on one thread.

use faer::diag::Diag;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg;
use faer::perm::Perm;
use faer::prelude::{Reborrow, ReborrowMut};
use faer::{Accum, Conj, Mat, MatMut, MatRef, Par};

const SEQ: Par = Par::Seq;

/// `a b`.
pub fn mul(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let mut out = Mat::zeros(a.nrows(), b.ncols());
    linalg::matmul::matmul(out.as_mut(), Accum::Replace, a, b, 1.0, SEQ);
    out
}

/// The factors of `a` (m >= n, or square) packed by faer's LU and QR: the unit lower
/// trapezoid (m x n) and the upper triangle (n x n).
fn split(mut packed: Mat<f64>) -> (Mat<f64>, Mat<f64>) {
    let upper = split_in_place(packed.as_mut());
    (packed, upper)
}

/// [`split`] without a copy of the packed factors: `packed` becomes the unit lower trapezoid;
/// returns the upper triangle.
fn split_in_place(mut packed: MatMut<'_, f64>) -> Mat<f64> {
    let n = packed.ncols();
    let mut upper = Mat::zeros(n, n);
    upper.copy_from_triangular_upper(packed.rb().get(..n, ..n));
    for j in 0..n {
        for i in 0..j.min(packed.nrows()) {
            packed[(i, j)] = 0.0;
        }
        if j < packed.nrows() {
            packed[(j, j)] = 1.0;
        }
    }
    upper
}

/// `dst += a^T a`.
pub fn gram_add(dst: MatMut<'_, f64>, a: MatRef<'_, f64>) {
    linalg::matmul::matmul(dst, Accum::Add, a.transpose(), a, 1.0, SEQ);
}

/// `a <- a L^-T` for a lower triangular `L` (the rows of `a` solved against `L^T`: `a`'s
/// transpose against `L`).
pub fn solve_right_lower_transpose_in_place(a: MatMut<'_, f64>, l: MatRef<'_, f64>) {
    linalg::triangular_solve::solve_lower_triangular_in_place(l, a.transpose_mut(), SEQ);
}

/// LU of a square matrix with partial pivoting.
pub struct Lu {
    l: Mat<f64>,
    u: Mat<f64>,
    p: Perm<usize>,
}

impl Lu {
    pub fn new(a: MatRef<'_, f64>) -> Lu {
        let (m, n) = a.shape();
        assert_eq!(m, n, "LU of a square matrix");
        let mut lu = a.to_owned();
        let (mut fwd, mut bwd) = (vec![0usize; m], vec![0usize; m]);
        let scratch =
            linalg::lu::partial_pivoting::factor::lu_in_place_scratch::<usize, f64>(m, n, SEQ, Default::default());
        linalg::lu::partial_pivoting::factor::lu_in_place(
            lu.as_mut(),
            &mut fwd,
            &mut bwd,
            SEQ,
            MemStack::new(&mut MemBuffer::new(scratch)),
            Default::default(),
        );
        let (l, u) = split(lu);
        // SAFETY: faer's LU wrote a permutation and its inverse.
        let p = unsafe { Perm::new_unchecked(fwd.into_boxed_slice(), bwd.into_boxed_slice()) };
        Lu { l, u, p }
    }

    /// `a^-1 rhs`.
    pub fn solve(&self, rhs: MatRef<'_, f64>) -> Mat<f64> {
        let mut out = rhs.to_owned();
        let scratch =
            linalg::lu::partial_pivoting::solve::solve_in_place_scratch::<usize, f64>(self.l.nrows(), rhs.ncols(), SEQ);
        linalg::lu::partial_pivoting::solve::solve_in_place_with_conj(
            self.l.as_ref(),
            self.u.as_ref(),
            self.p.as_ref(),
            Conj::No,
            out.as_mut(),
            SEQ,
            MemStack::new(&mut MemBuffer::new(scratch)),
        );
        out
    }

    /// `a^-1`.
    pub fn inverse(&self) -> Mat<f64> {
        let n = self.l.nrows();
        let mut out = Mat::zeros(n, n);
        let scratch = linalg::lu::partial_pivoting::inverse::inverse_scratch::<usize, f64>(n, SEQ);
        linalg::lu::partial_pivoting::inverse::inverse(
            out.as_mut(),
            self.l.as_ref(),
            self.u.as_ref(),
            self.p.as_ref(),
            SEQ,
            MemStack::new(&mut MemBuffer::new(scratch)),
        );
        out
    }
}

/// Cholesky factor `L` (`a = L L^T`) of a symmetric matrix given by its lower triangle; None
/// when `a` is not positive definite.
pub struct Llt {
    l: Mat<f64>,
}

impl Llt {
    pub fn new(a: MatRef<'_, f64>) -> Option<Llt> {
        let n = a.nrows();
        assert_eq!(n, a.ncols(), "Cholesky of a square matrix");
        let mut l = Mat::zeros(n, n);
        l.copy_from_triangular_lower(a);
        let scratch = linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f64>(n, SEQ, Default::default());
        linalg::cholesky::llt::factor::cholesky_in_place(
            l.as_mut(),
            Default::default(),
            SEQ,
            MemStack::new(&mut MemBuffer::new(scratch)),
            Default::default(),
        )
        .ok()?;
        for j in 0..n {
            for i in 0..j {
                l[(i, j)] = 0.0;
            }
        }
        Some(Llt { l })
    }

    /// The Cholesky factor of `l l^T`: `l` lower triangular with a nonzero diagonal (its
    /// upper part is not read).
    pub fn from_factor(l: MatRef<'_, f64>) -> Llt {
        let n = l.nrows();
        Llt { l: Mat::from_fn(n, n, |i, j| if i >= j { l[(i, j)] } else { 0.0 }) }
    }

    /// `L`.
    pub fn factor(&self) -> MatRef<'_, f64> {
        self.l.as_ref()
    }

    /// `a^-1 rhs`.
    pub fn solve(&self, rhs: MatRef<'_, f64>) -> Mat<f64> {
        let mut out = rhs.to_owned();
        let scratch = linalg::cholesky::llt::solve::solve_in_place_scratch::<f64>(self.l.nrows(), rhs.ncols(), SEQ);
        linalg::cholesky::llt::solve::solve_in_place_with_conj(
            self.l.as_ref(),
            Conj::No,
            out.as_mut(),
            SEQ,
            MemStack::new(&mut MemBuffer::new(scratch)),
        );
        out
    }

    /// `a^-1` (both triangles).
    pub fn inverse(&self) -> Mat<f64> {
        let n = self.l.nrows();
        let mut out = Mat::zeros(n, n);
        let scratch = linalg::cholesky::llt::inverse::inverse_scratch::<f64>(n, SEQ);
        linalg::cholesky::llt::inverse::inverse(
            out.as_mut(),
            self.l.as_ref(),
            SEQ,
            MemStack::new(&mut MemBuffer::new(scratch)),
        );
        for j in 0..n {
            for i in 0..j {
                out[(i, j)] = out[(j, i)];
            }
        }
        out
    }
}

/// The upper trapezoid `R` (min(m, n) x n) of the QR factorisation of `a`.
pub fn qr_r(a: MatRef<'_, f64>) -> Mat<f64> {
    let (m, n) = a.shape();
    let size = m.min(n);
    let mut qr = a.to_owned();
    let block = linalg::qr::no_pivoting::factor::recommended_block_size::<f64>(m, n);
    let mut coeff = Mat::zeros(block, size);
    let scratch = linalg::qr::no_pivoting::factor::qr_in_place_scratch::<f64>(m, n, block, SEQ, Default::default());
    linalg::qr::no_pivoting::factor::qr_in_place(
        qr.as_mut(),
        coeff.as_mut(),
        SEQ,
        MemStack::new(&mut MemBuffer::new(scratch)),
        Default::default(),
    );
    Mat::from_fn(size, n, |i, j| if j >= i { qr[(i, j)] } else { 0.0 })
}

/// The least-squares solution of `a x = b` (`a` with at least as many rows as columns) by
/// QR with column pivoting.
pub fn lstsq(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    lstsq_in_place(a.to_owned().as_mut(), b)
}

/// [`lstsq`] that factors `a` where it is (it holds the unit lower factor afterwards): no copy
/// of a large `a`, the same operations and result.
pub fn lstsq_in_place(a: MatMut<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let (m, n) = a.shape();
    assert!(m >= n && b.nrows() == m, "least squares of a tall matrix");
    let mut qr = a;
    let (mut fwd, mut bwd) = (vec![0usize; n], vec![0usize; n]);
    let block = linalg::qr::no_pivoting::factor::recommended_block_size::<f64>(m, n);
    let mut coeff = Mat::zeros(block, n.min(m));
    let scratch =
        linalg::qr::col_pivoting::factor::qr_in_place_scratch::<usize, f64>(m, n, block, SEQ, Default::default());
    linalg::qr::col_pivoting::factor::qr_in_place(
        qr.rb_mut(),
        coeff.as_mut(),
        &mut fwd,
        &mut bwd,
        SEQ,
        MemStack::new(&mut MemBuffer::new(scratch)),
        Default::default(),
    );
    let r = split_in_place(qr.rb_mut());
    let basis = qr.rb();
    // SAFETY: faer's QR wrote a permutation and its inverse.
    let p = unsafe { Perm::new_unchecked(fwd.into_boxed_slice(), bwd.into_boxed_slice()) };
    let mut out = b.to_owned();
    let scratch =
        linalg::qr::col_pivoting::solve::solve_lstsq_in_place_scratch::<usize, f64>(m, n, block, b.ncols(), SEQ);
    linalg::qr::col_pivoting::solve::solve_lstsq_in_place_with_conj(
        basis,
        coeff.as_ref(),
        r.as_ref(),
        p.as_ref(),
        Conj::No,
        out.as_mut(),
        SEQ,
        MemStack::new(&mut MemBuffer::new(scratch)),
    );
    out.truncate(n, b.ncols());
    out
}

/// The eigenvalues (re, im) of a real square matrix; None when the iteration fails.
pub fn eigenvalues(a: MatRef<'_, f64>) -> Option<Vec<(f64, f64)>> {
    let n = a.nrows();
    assert_eq!(n, a.ncols(), "eigenvalues of a square matrix");
    let (mut re, mut im) = (Diag::<f64>::zeros(n), Diag::<f64>::zeros(n));
    let no = linalg::evd::ComputeEigenvectors::No;
    let scratch = linalg::evd::evd_scratch::<f64>(n, no, no, SEQ, Default::default());
    linalg::evd::evd_real(
        a,
        re.as_mut(),
        im.as_mut(),
        None,
        None,
        SEQ,
        MemStack::new(&mut MemBuffer::new(scratch)),
        Default::default(),
    )
    .ok()?;
    Some(re.column_vector().iter().zip(im.column_vector().iter()).map(|(&r, &i)| (r, i)).collect())
}

/// Eigenvalues (ascending) and eigenvectors (columns) of a symmetric matrix given by its lower
/// triangle; None when the iteration fails.
pub fn symmetric_eigen(a: MatRef<'_, f64>) -> Option<(Vec<f64>, Mat<f64>)> {
    let n = a.nrows();
    assert_eq!(n, a.ncols(), "eigenvalues of a square matrix");
    let (mut s, mut u) = (Diag::<f64>::zeros(n), Mat::zeros(n, n));
    let yes = linalg::evd::ComputeEigenvectors::Yes;
    let scratch = linalg::evd::self_adjoint_evd_scratch::<f64>(n, yes, SEQ, Default::default());
    linalg::evd::self_adjoint_evd(
        a,
        s.as_mut(),
        Some(u.as_mut()),
        SEQ,
        MemStack::new(&mut MemBuffer::new(scratch)),
        Default::default(),
    )
    .ok()?;
    Some((s.column_vector().iter().copied().collect(), u))
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::linalg::solvers::{DenseSolveCore, Solve, SolveLstsq};

    /// The explicit sequential calls give faer's high-level results bit for bit (the global
    /// setting is sequential in this build, so the two must agree exactly).
    #[test]
    fn same_bits_as_the_high_level_calls() {
        let a = Mat::<f64>::from_fn(5, 5, |i, j| ((i * 7 + j * 3) % 11) as f64 + if i == j { 9.0 } else { 0.3 });
        let sym = Mat::<f64>::from_fn(5, 5, |i, j| a[(i, j)] + a[(j, i)]);
        let tall = Mat::<f64>::from_fn(9, 4, |i, j| ((i * 5 + j * 13) % 7) as f64 - 2.5 + 0.1 * i as f64);
        let b = Mat::<f64>::from_fn(5, 2, |i, j| (i + 2 * j) as f64 - 1.5);
        let tb = Mat::<f64>::from_fn(9, 1, |i, _| (i as f64 * 0.7).sin());
        let bits = |m: &Mat<f64>| -> Vec<u64> {
            (0..m.ncols()).flat_map(|j| (0..m.nrows()).map(move |i| (i, j))).map(|(i, j)| m[(i, j)].to_bits()).collect()
        };
        assert_eq!(bits(&mul(a.as_ref(), b.as_ref())), bits(&(&a * &b)));
        assert_eq!(bits(&mul(tall.transpose(), tall.as_ref())), bits(&(tall.transpose() * &tall)));
        let lu = Lu::new(a.as_ref());
        assert_eq!(bits(&lu.solve(b.as_ref())), bits(&a.partial_piv_lu().solve(&b)));
        assert_eq!(bits(&lu.inverse()), bits(&a.partial_piv_lu().inverse()));
        let llt = Llt::new(sym.as_ref()).unwrap();
        let chol = sym.llt(faer::Side::Lower).unwrap();
        assert_eq!(bits(&llt.solve(b.as_ref())), bits(&chol.solve(&b)));
        assert_eq!(bits(&llt.inverse()), bits(&chol.inverse()));
        assert!(Llt::new((-&sym).as_ref()).is_none());
        assert_eq!(bits(&qr_r(tall.as_ref())), bits(&tall.qr().thin_R().to_owned()));
        assert_eq!(bits(&lstsq(tall.as_ref(), tb.as_ref())), bits(&tall.col_piv_qr().solve_lstsq(&tb)));
        let ev: Vec<(u64, u64)> = a.eigenvalues().unwrap().iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect();
        let mine: Vec<(u64, u64)> =
            eigenvalues(a.as_ref()).unwrap().iter().map(|z| (z.0.to_bits(), z.1.to_bits())).collect();
        assert_eq!(mine, ev);
        let (vals, vecs) = symmetric_eigen(sym.as_ref()).unwrap();
        let eig = sym.self_adjoint_eigen(faer::Side::Lower).unwrap();
        assert_eq!(
            vals.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            eig.S().column_vector().iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(bits(&vecs), bits(&eig.U().to_owned()));
    }
}
