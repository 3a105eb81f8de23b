//! [`super::correlations`] in the AVX2+FMA build (split from [`super::avx2`] for its length),
//! two lags at a time. Called only after the CPU was seen to support AVX2 and FMA.
//!
//! # Safety
//! As in [`super::avx2`]: every function here may only run on a CPU with AVX2 and FMA; their
//! own `# Safety` sections state what else they need.

use std::arch::x86_64::*;

/// [`super::generic::correlations_impl`] with explicit 256-bit vectors: left to itself the compiler
/// vectorised the six interleaved sums only partly (half the lanes scalar).
///
/// Two lags at a time ([`corr_lag_pair`]): one lag's six sums are six chains of 4-cycle
/// multiply-adds, one per 4 samples, so a lag alone runs at 1.5 multiply-adds per cycle where
/// the two FMA ports take 2; two lags give twelve independent chains and share the loads of
/// `u[s]` and `y[s]`. Each sum still runs over the same terms in the same order as one lag
/// alone ([`corr_lag`]), so the result is that of lag by lag, bit for bit.
///
/// # Safety
/// The CPU supports AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn correlations(u: &[f64], y: &[f64], r: &[f64], out: &mut [[f64; 6]]) {
    let n = u.len().min(y.len()).min(r.len());
    for o in out.iter_mut() {
        *o = [0.0; 6];
    }
    let (u, y, r) = (&u[..n], &y[..n], &r[..n]);
    let lags = out.len();
    // The blocks of `generic::blocked_lags`, the lags of a block taken two by two.
    let mut s0 = 0;
    while s0 < n {
        let s1 = (s0 + super::generic::LAG_BLOCK).min(n);
        let end = |l: usize| s1.min(n.saturating_sub(l));
        let mut l = 0;
        while l < lags && end(l) > s0 {
            if l + 1 < lags && end(l + 1) > s0 {
                let (lo, hi) = out.split_at_mut(l + 1);
                // SAFETY: s0 < end(l + 1) <= end(l) <= n - l, as corr_lag_pair asks.
                unsafe { corr_lag_pair(u, y, r, l, s0, end(l), end(l + 1), &mut lo[l], &mut hi[0]) };
                l += 2;
            } else {
                // SAFETY: s0 < end(l) <= n - l.
                unsafe { corr_lag(u, y, r, l, s0, end(l), &mut out[l]) };
                l += 1;
            }
        }
        s0 = s1;
    }
}

/// Horizontal sum of a 256-bit vector in the order every kernel here uses: (0 + 2) + (1 + 3).
#[inline(always)]
fn hsum(v: __m256d) -> f64 {
    let mut a = [0.0; 4];
    // SAFETY: a holds four f64.
    unsafe { _mm256_storeu_pd(a.as_mut_ptr(), v) };
    (a[0] + a[2]) + (a[1] + a[3])
}

/// The six products of one step of one lag: u[s] and y[s] (`a`, `b`) against u, y and r at
/// s + l (`p`, `q`, `z`), each into its own accumulator.
#[inline(always)]
fn corr_step(acc: &mut [__m256d; 6], a: __m256d, b: __m256d, p: __m256d, q: __m256d, z: __m256d) {
    // SAFETY: only called from functions compiled with AVX2 and FMA.
    unsafe {
        acc[0] = _mm256_fmadd_pd(a, p, acc[0]);
        acc[1] = _mm256_fmadd_pd(b, q, acc[1]);
        acc[2] = _mm256_fmadd_pd(a, q, acc[2]);
        acc[3] = _mm256_fmadd_pd(b, p, acc[3]);
        acc[4] = _mm256_fmadd_pd(a, z, acc[4]);
        acc[5] = _mm256_fmadd_pd(b, z, acc[5]);
    }
}

/// One lag's block `s0..end` after its vector steps, which ended at `i`: the scalar tail, then
/// `o += hsum(acc) + tail`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn corr_finish(u: &[f64], y: &[f64], r: &[f64], l: usize, i: usize, end: usize, acc: &[__m256d; 6], o: &mut [f64; 6]) {
    let mut tail = [0.0; 6];
    for i in i..end {
        let (a, b, p, q, z) = (u[i], y[i], u[i + l], y[i + l], r[i + l]);
        tail[0] = a.mul_add(p, tail[0]);
        tail[1] = b.mul_add(q, tail[1]);
        tail[2] = a.mul_add(q, tail[2]);
        tail[3] = b.mul_add(p, tail[3]);
        tail[4] = a.mul_add(z, tail[4]);
        tail[5] = b.mul_add(z, tail[5]);
    }
    for j in 0..6 {
        o[j] += hsum(acc[j]) + tail[j];
    }
}

/// The six sums of lag `l` over the block `s0..end` into `o`.
///
/// # Safety
/// The CPU supports AVX2 and FMA; `s0 <= end` and `end + l` is at most the length of `u`, `y`
/// and `r`.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma")]
unsafe fn corr_lag(u: &[f64], y: &[f64], r: &[f64], l: usize, s0: usize, end: usize, o: &mut [f64; 6]) {
    let mut acc = [_mm256_setzero_pd(); 6];
    let mut i = s0;
    // SAFETY: i + 3 < end, and end + l <= the slices' length.
    unsafe {
        let (pu, py, pr) = (u.as_ptr(), y.as_ptr(), r.as_ptr());
        while i + 4 <= end {
            let (a, b) = (_mm256_loadu_pd(pu.add(i)), _mm256_loadu_pd(py.add(i)));
            let (p, q, z) =
                (_mm256_loadu_pd(pu.add(i + l)), _mm256_loadu_pd(py.add(i + l)), _mm256_loadu_pd(pr.add(i + l)));
            corr_step(&mut acc, a, b, p, q, z);
            i += 4;
        }
    }
    corr_finish(u, y, r, l, i, end, &acc, o);
}

/// [`corr_lag`] of lags `l` (block `s0..end0`, into `o0`) and `l + 1` (block `s0..end1`, into
/// `o1`) in one pass over their common steps; each lag's sums are those of [`corr_lag`] bit
/// for bit (the same vector steps in the same order, then the same tail).
///
/// # Safety
/// The CPU supports AVX2 and FMA; `s0 <= end1 <= end0` and `end0 + l` is at most the length
/// of `u`, `y` and `r`.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma")]
unsafe fn corr_lag_pair(
    u: &[f64],
    y: &[f64],
    r: &[f64],
    l: usize,
    s0: usize,
    end0: usize,
    end1: usize,
    o0: &mut [f64; 6],
    o1: &mut [f64; 6],
) {
    let (mut acc0, mut acc1) = ([_mm256_setzero_pd(); 6], [_mm256_setzero_pd(); 6]);
    let mut i = s0;
    // SAFETY: i + 3 < end1 <= end0 in the paired loop and i + 3 < end0 after it, with
    // end1 + l + 1 <= end0 + l <= the slices' length.
    let i1 = unsafe {
        let (pu, py, pr) = (u.as_ptr(), y.as_ptr(), r.as_ptr());
        while i + 4 <= end1 {
            let (a, b) = (_mm256_loadu_pd(pu.add(i)), _mm256_loadu_pd(py.add(i)));
            let (p, q, z) =
                (_mm256_loadu_pd(pu.add(i + l)), _mm256_loadu_pd(py.add(i + l)), _mm256_loadu_pd(pr.add(i + l)));
            corr_step(&mut acc0, a, b, p, q, z);
            let k = i + l + 1;
            let (p, q, z) = (_mm256_loadu_pd(pu.add(k)), _mm256_loadu_pd(py.add(k)), _mm256_loadu_pd(pr.add(k)));
            corr_step(&mut acc1, a, b, p, q, z);
            i += 4;
        }
        let i1 = i;
        while i + 4 <= end0 {
            let (a, b) = (_mm256_loadu_pd(pu.add(i)), _mm256_loadu_pd(py.add(i)));
            let (p, q, z) =
                (_mm256_loadu_pd(pu.add(i + l)), _mm256_loadu_pd(py.add(i + l)), _mm256_loadu_pd(pr.add(i + l)));
            corr_step(&mut acc0, a, b, p, q, z);
            i += 4;
        }
        i1
    };
    corr_finish(u, y, r, l, i, end0, &acc0, o0);
    corr_finish(u, y, r, l + 1, i1, end1, &acc1, o1);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two lags at a time give each lag's sums bit for bit as one lag alone, in every block
    /// (records shorter and longer than a block, lags running past the record's end, odd and
    /// even numbers of lags).
    #[test]
    fn paired_lags_are_one_lag_at_a_time_bit_for_bit() {
        if !super::super::has_fma() {
            return;
        }
        for len in [0, 1, 5, 17, 1023, 1024, 1029, 2100, 5000] {
            let seq = |w: f64, c: f64| (0..len).map(|i| (i as f64 * w).sin() + c).collect::<Vec<f64>>();
            let (u, y, r) = (seq(0.37, 0.1), seq(0.11, -0.2), seq(0.53, 0.0));
            for lags in [0, 1, 2, 3, 12, 31] {
                let mut paired = vec![[f64::NAN; 6]; lags];
                // SAFETY: the CPU has AVX2 and FMA (checked above).
                unsafe { correlations(&u, &y, &r, &mut paired) };
                let mut single = vec![[0.0; 6]; lags];
                super::super::generic::blocked_lags(len, lags, |l, s0, end| {
                    // SAFETY: blocked_lags gives s0 < end <= len - l.
                    unsafe { corr_lag(&u, &y, &r, l, s0, end, &mut single[l]) }
                });
                let bits = |v: &[[f64; 6]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&paired), bits(&single), "len {len} lags {lags}");
            }
        }
    }
}
