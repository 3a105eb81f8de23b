//! Small dense linear algebra of the solver's normal equations (d x d, d = nB + nF (+ 1) <= 121),
//! in place on the workspace's buffers: faer's routines would allocate per call.

/// In-place Cholesky of the d x d row-major SPD matrix `a` (lower factor); false if not SPD.
pub(crate) fn cholesky(a: &mut [f64], d: usize) -> bool {
    // Row slices instead of indices: the same sums in the same order, without a bounds check
    // per multiply-add (this runs at least once per solver iteration).
    let a = &mut a[..d * d];
    for j in 0..d {
        let (head, tail) = a.split_at_mut((j + 1) * d);
        let row_j = &mut head[j * d..];
        let mut s = row_j[j];
        for &v in &row_j[..j] {
            s -= v * v;
        }
        if s.is_nan() || s <= 0.0 || s.is_infinite() {
            return false;
        }
        let l = s.sqrt();
        row_j[j] = l;
        let row_j = &row_j[..j];
        // Four rows at a time: each row's sum is its own chain of dependent subtractions, in
        // the same order as one row alone; four chains side by side keep the adder busy
        // through their latency (one at a time, the chains of the rows below overlapped
        // only as far as the out-of-order window reached).
        let mut rows = tail.chunks_exact_mut(4 * d);
        for four in &mut rows {
            let (r0, rest) = four.split_at_mut(d);
            let (r1, rest) = rest.split_at_mut(d);
            let (r2, r3) = rest.split_at_mut(d);
            let mut s = [r0[j], r1[j], r2[j], r3[j]];
            for (k, &y) in row_j.iter().enumerate() {
                s[0] -= r0[k] * y;
                s[1] -= r1[k] * y;
                s[2] -= r2[k] * y;
                s[3] -= r3[k] * y;
            }
            r0[j] = s[0] / l;
            r1[j] = s[1] / l;
            r2[j] = s[2] / l;
            r3[j] = s[3] / l;
        }
        for row_i in rows.into_remainder().chunks_exact_mut(d) {
            let mut s = row_i[j];
            for (&x, &y) in row_i[..j].iter().zip(row_j) {
                s -= x * y;
            }
            row_i[j] = s / l;
        }
    }
    true
}

/// Solves `L L^T x = b` in place (`x` holds b) with the factor of [`cholesky`].
pub(crate) fn cholesky_solve(l: &[f64], d: usize, x: &mut [f64]) {
    let (l, x) = (&l[..d * d], &mut x[..d]);
    for (i, row) in l.chunks_exact(d).enumerate() {
        let (done, rest) = x.split_at_mut(i);
        let mut s = rest[0];
        for (&a, &b) in row[..i].iter().zip(done.iter()) {
            s -= a * b;
        }
        rest[0] = s / row[i];
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

    /// Uniform numbers in [-1/2, 1/2) from a linear congruential generator.
    fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// `A = M M^T + ridge I` (d x d, row-major) for a random M: symmetric positive definite.
    fn spd(d: usize, rnd: &mut impl FnMut() -> f64, ridge: f64) -> Vec<f64> {
        let m: Vec<f64> = (0..d * d).map(|_| rnd()).collect();
        (0..d * d)
            .map(|k| {
                let (i, j) = (k / d, k % d);
                (0..d).map(|l| m[i * d + l] * m[j * d + l]).sum::<f64>() + if i == j { ridge } else { 0.0 }
            })
            .collect()
    }

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

    /// The rows four at a time give the bits of one row at a time (the plain Cholesky-Crout
    /// loop below), every size up to 30.
    #[test]
    fn four_rows_at_a_time_are_the_bits_of_one() {
        let mut rnd = uniform(11);
        for d in 1..=30 {
            let a0 = spd(d, &mut rnd, 0.1);
            let mut want = a0.clone();
            for j in 0..d {
                let mut s = want[j * d + j];
                for k in 0..j {
                    s -= want[j * d + k] * want[j * d + k];
                }
                let l = s.sqrt();
                want[j * d + j] = l;
                for i in j + 1..d {
                    let mut s = want[i * d + j];
                    for k in 0..j {
                        s -= want[i * d + k] * want[j * d + k];
                    }
                    want[i * d + j] = s / l;
                }
            }
            let mut got = a0.clone();
            assert!(cholesky(&mut got, d));
            assert!(got.iter().zip(&want).all(|(a, b)| a.to_bits() == b.to_bits()), "d = {d}");
        }
    }

    /// Every size up to 30: L L^T is A, the solve's residual is at rounding level, and the
    /// upper triangle is left as it was (the solver reads only the lower factor).
    #[test]
    fn cholesky_factors_and_solves_every_size() {
        let mut rnd = uniform(5);
        for d in 1..=30 {
            let a0 = spd(d, &mut rnd, d as f64);
            let mut a = a0.clone();
            assert!(cholesky(&mut a, d), "d = {d}");
            for i in 0..d {
                for j in 0..d {
                    if j > i {
                        assert_eq!(a[i * d + j], a0[i * d + j], "upper ({i},{j}) touched");
                        continue;
                    }
                    let llt: f64 = (0..=j).map(|k| a[i * d + k] * a[j * d + k]).sum();
                    assert!((llt - a0[i * d + j]).abs() < 1e-12 * d as f64, "d = {d} ({i},{j})");
                }
            }
            let b: Vec<f64> = (0..d).map(|_| rnd()).collect();
            let mut x = b.clone();
            cholesky_solve(&a, d, &mut x);
            for i in 0..d {
                let r: f64 = (0..d).map(|j| a0[i * d + j] * x[j]).sum();
                assert!((r - b[i]).abs() < 1e-12 * d as f64, "d = {d} row {i}");
            }
        }
    }
}
