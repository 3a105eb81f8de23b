//! Small dense linear algebra of the solver's normal equations (d x d, d = nB + nF (+ 1) <= 121),
//! in place on the workspace's buffers: faer's routines would allocate per call.

/// In-place Cholesky of the d x d row-major SPD matrix `a` (lower factor); false if not SPD.
pub(crate) fn cholesky(a: &mut [f64], d: usize) -> bool {
    for j in 0..d {
        let mut s = a[j * d + j];
        for k in 0..j {
            s -= a[j * d + k] * a[j * d + k];
        }
        if s.is_nan() || s <= 0.0 || s.is_infinite() {
            return false;
        }
        let l = s.sqrt();
        a[j * d + j] = l;
        for i in j + 1..d {
            let mut s = a[i * d + j];
            for k in 0..j {
                s -= a[i * d + k] * a[j * d + k];
            }
            a[i * d + j] = s / l;
        }
    }
    true
}

/// Solves `L L^T x = b` in place (`x` holds b) with the factor of [`cholesky`].
pub(crate) fn cholesky_solve(l: &[f64], d: usize, x: &mut [f64]) {
    for i in 0..d {
        let mut s = x[i];
        for k in 0..i {
            s -= l[i * d + k] * x[k];
        }
        x[i] = s / l[i * d + i];
    }
    for i in (0..d).rev() {
        let mut s = x[i];
        for k in i + 1..d {
            s -= l[k * d + i] * x[k];
        }
        x[i] = s / l[i * d + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_spd_system() {
        let a0 = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let mut a = a0;
        assert!(cholesky(&mut a, 3));
        let mut x = [1.0, 2.0, 3.0];
        cholesky_solve(&a, 3, &mut x);
        for i in 0..3 {
            let r: f64 = (0..3).map(|j| a0[i * 3 + j] * x[j]).sum();
            assert!((r - [1.0, 2.0, 3.0][i]).abs() < 1e-12);
        }
        let mut b = [1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky(&mut b, 2));
    }
}
