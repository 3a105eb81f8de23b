//! The AVX2+FMA build of the kernels, compiled with `#[target_feature(enable = "avx2,fma")]`
//! and called only after the CPU was seen to support both ([`super::has_fma`]).
//!
//! # Safety
//! Every function here is `unsafe` for one shared reason: it may only run on a CPU with AVX2
//! and FMA. Where a function also reads or writes through raw pointers or unchecked indices,
//! its own `# Safety` section states what the caller must guarantee on top.

/// [`super::dot`].
///
/// # Safety
/// The CPU supports AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn dot(a: &[f64], b: &[f64]) -> f64 {
    super::generic::dot_impl::<true>(a, b)
}
/// [`super::generic::loss_total_impl`] with explicit 256-bit vectors: accumulators 0-3 in one
/// register, 4-7 in another, and its reduction `((0 + 4) + (1 + 5)) + ((2 + 6) + (3 + 7))`, so
/// the same bits. Left to itself the compiler kept the eight sums in 128-bit halves and
/// shuffled every vector into them.
///
/// # Safety
/// The CPU supports AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn loss_total(y: &[f64], yhat: &[f64], gamma: Option<f64>) -> f64 {
    let n = y.len().min(yhat.len());
    let full = n / 8 * 8;
    let (mut lo, mut hi) = (_mm256_setzero_pd(), _mm256_setzero_pd());
    // SAFETY: i + 8 <= full <= n, so every load is inside its slice.
    unsafe {
        let (py, ph) = (y.as_ptr(), yhat.as_ptr());
        let e = |i: usize| _mm256_sub_pd(_mm256_loadu_pd(py.add(i)), _mm256_loadu_pd(ph.add(i)));
        match gamma {
            None => {
                let mut i = 0;
                while i < full {
                    let (a, b) = (e(i), e(i + 4));
                    lo = _mm256_add_pd(lo, _mm256_mul_pd(a, a));
                    hi = _mm256_add_pd(hi, _mm256_mul_pd(b, b));
                    i += 8;
                }
            }
            Some(g) => {
                // rho(g, x) = m (|x| - m/2), m = min(|x|, g); f64::min gives g for a NaN |x|,
                // as vminpd does with g second.
                let (gv, half, sign) = (_mm256_set1_pd(g), _mm256_set1_pd(0.5), _mm256_set1_pd(-0.0));
                let rho = |x: __m256d| {
                    let a = _mm256_andnot_pd(sign, x);
                    let m = _mm256_min_pd(a, gv);
                    _mm256_mul_pd(m, _mm256_sub_pd(a, _mm256_mul_pd(half, m)))
                };
                let mut i = 0;
                while i < full {
                    lo = _mm256_add_pd(lo, rho(e(i)));
                    hi = _mm256_add_pd(hi, rho(e(i + 4)));
                    i += 8;
                }
            }
        }
    }
    let mut s = [0.0; 4];
    // SAFETY: s holds four f64.
    unsafe { _mm256_storeu_pd(s.as_mut_ptr(), _mm256_add_pd(lo, hi)) };
    let rest = y[full..n].iter().zip(&yhat[full..n]).map(|(a, b)| a - b);
    let tail: f64 = match gamma {
        None => rest.map(|e| e * e).sum(),
        Some(g) => rest.map(|e| super::huber_rho(g, e)).sum(),
    };
    let sum = ((s[0] + s[1]) + (s[2] + s[3])) + tail;
    if gamma.is_none() { sum * 0.5 } else { sum }
}
/// [`super::influence`].
///
/// # Safety
/// The CPU supports AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn influence(y: &[f64], yhat: &[f64], gamma: Option<f64>, irls: bool, r: &mut [f64], w: &mut [f64]) {
    super::generic::influence_impl(y, yhat, gamma, irls, r, w)
}
/// [`super::pack_rows`]: the baseline's copies, four lags at a time reversed by a lane permute (the
/// reversed scalar copies were 4 % of the paper grid's samples, a third of the packed product's).
///
/// # Safety
/// The CPU supports AVX2 and FMA.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma")]
pub unsafe fn pack_rows(
    xu: &[f64],
    xy: &[f64],
    rows: &[u32],
    nb: usize,
    nf: usize,
    delay: usize,
    dp: usize,
    packed: &mut [f64],
) {
    let d = nb + nf;
    for (row, &t) in packed.chunks_exact_mut(dp).zip(rows) {
        let t = t as usize;
        // The baseline's slices, so a row whose lags leave the record panics as there.
        let su = &xu[t + 1 - delay - nb..=t - delay];
        let sy = &xy[t - nf..t];
        let (ru, rest) = row.split_at_mut(nb);
        let (ry, pad) = rest.split_at_mut(d - nb);
        // SAFETY: this function is compiled with AVX2; each pair has one length.
        unsafe {
            reversed::<false>(su, ru);
            reversed::<true>(sy, ry);
        }
        pad.fill(0.0);
    }
}

/// `dst[i] = src[len - 1 - i]` (negated when `NEG`: a flip of the sign bit, as `-v` is), four
/// at a time by a reversing lane permute; `src` and `dst` have one length.
#[inline(always)]
unsafe fn reversed<const NEG: bool>(src: &[f64], dst: &mut [f64]) {
    let n = src.len();
    assert_eq!(n, dst.len());
    // SAFETY: called from pack_rows (AVX2); the vector at dst[i..i + 4] reads
    // src[n - i - 4..n - i], both inside their slices while i + 4 <= n.
    unsafe {
        let sign = _mm256_set1_pd(-0.0);
        let mut i = 0;
        while i + 4 <= n {
            let v = _mm256_loadu_pd(src.as_ptr().add(n - i - 4));
            let mut r = _mm256_permute4x64_pd::<0b00_01_10_11>(v);
            if NEG {
                r = _mm256_xor_pd(r, sign);
            }
            _mm256_storeu_pd(dst.as_mut_ptr().add(i), r);
            i += 4;
        }
        for k in i..n {
            let v = src[n - 1 - k];
            dst[k] = if NEG { -v } else { v };
        }
    }
}
/// [`super::lagged_dots`].
///
/// # Safety
/// The CPU supports AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn lagged_dots(a: &[f64], b: &[f64], out: &mut [f64]) {
    super::generic::lagged_dots_impl::<true>(a, b, out)
}
/// [`super::lagged_dots2`].
///
/// # Safety
/// The CPU supports AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn lagged_dots2(a: &[f64], b: &[f64], c: &[f64], out_a: &mut [f64], out_b: &mut [f64]) {
    let n = a.len().min(b.len()).min(c.len());
    out_a.fill(0.0);
    out_b.fill(0.0);
    super::generic::blocked_lags(n, out_a.len(), |l, s0, end| {
        // SAFETY: this function's own contract.
        let (x, y) = unsafe { dot2(&a[s0..end], &b[s0..end], &c[s0 + l..end + l]) };
        out_a[l] += x;
        out_b[l] += y;
    });
}

/// [`super::generic::dot2_impl`] with explicit 256-bit vectors, in its operation order (lane k
/// of vector j is its accumulator 4 j + k): left to itself the compiler kept the 32
/// accumulators partly scalar, and the fused pass ran slower than the two separate ones.
///
/// # Safety
/// The CPU supports AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
unsafe fn dot2(a: &[f64], b: &[f64], c: &[f64]) -> (f64, f64) {
    use std::arch::x86_64::*;
    let n = a.len().min(b.len()).min(c.len());
    let full = n / 16 * 16;
    let mut acc_a = [_mm256_setzero_pd(); 4];
    let mut acc_b = [_mm256_setzero_pd(); 4];
    // SAFETY: i + 16 <= full <= n, so every load is inside its slice.
    unsafe {
        let (pa, pb, pc) = (a.as_ptr(), b.as_ptr(), c.as_ptr());
        let mut i = 0;
        while i < full {
            for j in 0..4 {
                let z = _mm256_loadu_pd(pc.add(i + 4 * j));
                acc_a[j] = _mm256_fmadd_pd(_mm256_loadu_pd(pa.add(i + 4 * j)), z, acc_a[j]);
                acc_b[j] = _mm256_fmadd_pd(_mm256_loadu_pd(pb.add(i + 4 * j)), z, acc_b[j]);
            }
            i += 16;
        }
    }
    let (mut sa, mut sb) = (0.0f64, 0.0f64);
    for i in full..n {
        sa = a[i].mul_add(c[i], sa);
        sb = b[i].mul_add(c[i], sb);
    }
    // The tree of dot_impl: accumulators k += k + 8, then k += k + 4, k += k + 2, k += k + 1.
    let reduce = |acc: [__m256d; 4]| {
        let v01 = _mm256_add_pd(acc[0], acc[2]);
        let v23 = _mm256_add_pd(acc[1], acc[3]);
        let v = _mm256_add_pd(v01, v23);
        let mut l = [0.0; 4];
        // SAFETY: l holds four f64.
        unsafe { _mm256_storeu_pd(l.as_mut_ptr(), v) };
        (l[0] + l[2]) + (l[1] + l[3])
    };
    (reduce(acc_a) + sa, reduce(acc_b) + sb)
}
/// [`super::rank1_upper`].
///
/// # Safety
/// The CPU supports AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn rank1_upper(h: &mut [f64], d: usize, v: &[f64], alpha: f64) {
    super::generic::rank1_upper_impl::<true>(h, d, v, alpha)
}
pub use super::avx2_correlations::correlations;

/// [`super::generic::syrk_upper_impl`] in register tiles: 4 rows of Q (broadcast) times 4, 8 or
/// 12 columns of P (vectors), 16 or fewer accumulators, for every tile touching the upper
/// triangle. Rows i0.. are multiples of 4 and `dp` is too, so each tile's loads stay
/// inside its padded row.
///
/// # Safety
/// The CPU supports AVX2 and FMA. (The shapes are asserted here, as [`super::syrk_upper`]
/// documents them.)
#[target_feature(enable = "avx2,fma")]
pub unsafe fn syrk_upper(h: &mut [f64], d: usize, p: &[f64], q: &[f64], dp: usize, m: usize, scale: f64) {
    assert!(dp.is_multiple_of(4) && dp >= d && p.len() >= m * dp && q.len() >= m * dp && h.len() >= d * d);
    let mut i0 = 0;
    while i0 < d {
        let mut j0 = i0;
        while j0 < d {
            let w = (dp - j0).min(12) / 4;
            // SAFETY: rows i0..i0+4 and columns j0..j0+4w lie inside the padded stride dp.
            unsafe {
                match w {
                    3 => syrk_tile::<3>(h, d, p, q, dp, m, scale, i0, j0),
                    2 => syrk_tile::<2>(h, d, p, q, dp, m, scale, i0, j0),
                    _ => syrk_tile::<1>(h, d, p, q, dp, m, scale, i0, j0),
                }
            }
            j0 += 4 * w;
        }
        i0 += 4;
    }
}

/// One register tile of [`syrk_upper`]: rows `i0..i0+4` of Q times columns `j0..j0+4W` of P.
///
/// # Safety
/// The CPU supports AVX2 and FMA; `i0 + 4 <= dp`, `j0 + 4 W <= dp`, `p` and `q` hold `m`
/// rows of stride `dp`, and `h` holds `d * d` entries.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn syrk_tile<const W: usize>(
    h: &mut [f64],
    d: usize,
    p: &[f64],
    q: &[f64],
    dp: usize,
    m: usize,
    scale: f64,
    i0: usize,
    j0: usize,
) {
    // SAFETY (whole body): the caller guarantees i0 + 4 <= dp and j0 + 4W <= dp, and
    // p, q hold m rows of dp.
    unsafe {
        let mut acc = [[_mm256_setzero_pd(); W]; 4];
        let (pp, pq) = (p.as_ptr(), q.as_ptr());
        for k in 0..m {
            let rp = pp.add(k * dp + j0);
            let rq = pq.add(k * dp + i0);
            let mut v = [_mm256_setzero_pd(); W];
            for (x, vx) in v.iter_mut().enumerate() {
                *vx = _mm256_loadu_pd(rp.add(4 * x));
            }
            for (r, accr) in acc.iter_mut().enumerate() {
                let b = _mm256_broadcast_sd(&*rq.add(r));
                for (a, &vx) in accr.iter_mut().zip(&v) {
                    *a = _mm256_fmadd_pd(b, vx, *a);
                }
            }
        }
        for (r, accr) in acc.iter().enumerate() {
            let i = i0 + r;
            if i >= d {
                break;
            }
            let mut buf = [0.0; 12];
            for (x, &a) in accr.iter().enumerate() {
                _mm256_storeu_pd(buf.as_mut_ptr().add(4 * x), a);
            }
            for (c, &s) in buf[..4 * W].iter().enumerate() {
                let j = j0 + c;
                if j >= i && j < d {
                    h[i * d + j] = scale.mul_add(s, h[i * d + j]);
                }
            }
        }
    }
}
/// [`super::generic::compact_impl`] four rows at a time: a compare gives a 4-bit mask, a table
/// the shuffle that packs the kept indices (and weights) to the front, and every store
/// writes all four lanes, the slack past `m` being overwritten later. The scalar loop
/// carried `m` through every row; this carries it through every fourth.
///
/// # Safety
/// The CPU supports AVX2 and FMA. (The lengths are asserted here, as [`super::compact`]
/// documents them.)
#[target_feature(enable = "avx2,fma")]
pub unsafe fn compact(w: &[f64], skip: f64, rows: &mut [u32], alpha: Option<&mut [f64]>) -> usize {
    // Lane order of the kept elements of each 4-bit mask, as 32-bit lane pairs for doubles.
    const fn table() -> ([[u32; 4]; 16], [[u32; 8]; 16]) {
        let mut idx = [[0u32; 4]; 16];
        let mut pairs = [[0u32; 8]; 16];
        let mut mask = 0;
        while mask < 16 {
            let mut k = 0;
            let mut lane = 0;
            while lane < 4 {
                if mask & (1 << lane) != 0 {
                    idx[mask][k] = lane as u32;
                    pairs[mask][2 * k] = 2 * lane as u32;
                    pairs[mask][2 * k + 1] = 2 * lane as u32 + 1;
                    k += 1;
                }
                lane += 1;
            }
            mask += 1;
        }
        (idx, pairs)
    }
    const TABLE: ([[u32; 4]; 16], [[u32; 8]; 16]) = table();
    let n = w.len();
    assert!(rows.len() >= n + 3 && alpha.as_ref().is_none_or(|a| a.len() >= n + 3));
    let n4 = n / 4 * 4;
    let mut m = 0;
    // SAFETY: loads read w[t..t+4] with t + 4 <= n4 <= n; stores write rows[m..m+4] and
    // alpha[m..m+4] with m <= t < n4, inside the n + 3 checked above.
    unsafe {
        let sk = _mm256_set1_pd(skip);
        let pr = rows.as_mut_ptr();
        let pa = alpha.map(|a| a.as_mut_ptr());
        let mut t = 0;
        while t < n4 {
            let v = _mm256_loadu_pd(w.as_ptr().add(t));
            let mask = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_NEQ_UQ>(v, sk)) as usize;
            let order = _mm_loadu_si128(TABLE.0[mask].as_ptr() as *const __m128i);
            let idx = _mm_add_epi32(_mm_set1_epi32(t as i32), order);
            _mm_storeu_si128(pr.add(m) as *mut __m128i, idx);
            if let Some(pa) = pa {
                let perm = _mm256_loadu_si256(TABLE.1[mask].as_ptr() as *const __m256i);
                let packed = _mm256_permutevar8x32_ps(_mm256_castpd_ps(v), perm);
                _mm256_storeu_pd(pa.add(m), _mm256_castps_pd(packed));
            }
            m += mask.count_ones() as usize;
            t += 4;
        }
        for (t, &wt) in w.iter().enumerate().skip(n4) {
            *pr.add(m) = t as u32;
            if let Some(pa) = pa {
                *pa.add(m) = wt;
            }
            m += (wt != skip) as usize;
        }
    }
    m
}
/// [`super::inv_f`].
///
/// # Safety
/// The CPU supports AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn inv_f(f: &[f64], x: &mut [f64]) {
    use super::generic::*;
    inv_f_dispatch!(true, f, x, 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24);
}
/// [`super::fir`].
///
/// # Safety
/// The CPU supports AVX2 and FMA; `u` and `out` have the same length.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn fir(b: &[f64], delay: usize, u: &[f64], out: &mut [f64]) {
    super::generic::fir_impl::<true>(b, delay, u, out)
}

use std::arch::x86_64::*;

/// One sample of two `1/F` recursions with the same F, one per lane: the same fused
/// multiply-adds in the same order as [`super::generic::inv_f_impl`], so each lane is bit for bit
/// that recursion, at the cost of one.
///
/// # Safety
/// Only called from functions compiled with AVX2 and FMA, on a CPU that has them.
#[inline(always)]
unsafe fn two_lane_step<const M: usize>(neg: &[__m128d; M], s: &mut [__m128d; M], x: __m128d) -> __m128d {
    let mut acc = x;
    for j in (0..M).rev() {
        // SAFETY: only called from functions compiled with FMA.
        acc = unsafe { _mm_fmadd_pd(neg[j], s[j], acc) };
    }
    for j in (1..M).rev() {
        s[j] = s[j - 1];
    }
    s[0] = acc;
    acc
}

/// [`super::simulate_filtered`] for `nF = M`: lane 0 runs `(1/F) u` block by block, the FIR
/// turns each finished block into `yhat`, and lane 1 runs `(1/F) yhat` one block behind.
///
/// # Safety
/// The CPU supports AVX2 and FMA; `f.len() == M`; `u`, `xu`, `yhat` and `xy` have one length
/// (the unchecked accesses rely on it).
#[inline(always)]
unsafe fn simulate_filtered_impl<const M: usize>(
    f: &[f64],
    b: &[f64],
    delay: usize,
    u: &[f64],
    xu: &mut [f64],
    yhat: &mut [f64],
    xy: &mut [f64],
) {
    // SAFETY: called with AVX2 and FMA; t0 + i < n and p0 + i < n in the unchecked accesses
    // (i < both <= len0, len1), and xu, yhat, xy have length n.
    unsafe {
        const L: usize = 256;
        let n = u.len();
        let mut neg = [_mm_setzero_pd(); M];
        for j in 0..M {
            neg[j] = _mm_set1_pd(-f[j]);
        }
        // Lane 1 is fed zeros during the first block: with zero state it stays exactly zero,
        // i.e. starts on yhat_0 with the zero initial conditions. Lane 0 is fed zeros past
        // the end; its outputs there are dropped.
        let mut s = [_mm_setzero_pd(); M];
        let mut t0 = 0;
        while t0 < n + L {
            let len0 = n.saturating_sub(t0).min(L);
            let p0 = t0.wrapping_sub(L);
            let len1 = if t0 >= L { (n - p0).min(L) } else { 0 };
            let both = len0.min(len1);
            for i in 0..both {
                let x = _mm_set_pd(*yhat.get_unchecked(p0 + i), *u.get_unchecked(t0 + i));
                let y = two_lane_step(&neg, &mut s, x);
                *xu.get_unchecked_mut(t0 + i) = _mm_cvtsd_f64(y);
                *xy.get_unchecked_mut(p0 + i) = _mm_cvtsd_f64(_mm_unpackhi_pd(y, y));
            }
            for i in both..len0 {
                let y = two_lane_step(&neg, &mut s, _mm_set_pd(0.0, u[t0 + i]));
                xu[t0 + i] = _mm_cvtsd_f64(y);
            }
            for i in both..len1 {
                let y = two_lane_step(&neg, &mut s, _mm_set_pd(yhat[p0 + i], 0.0));
                xy[p0 + i] = _mm_cvtsd_f64(_mm_unpackhi_pd(y, y));
            }
            if len0 > 0 {
                super::generic::fir_range_impl::<true>(b, delay, xu, yhat, t0, t0 + len0);
            }
            t0 += L;
        }
    }
}

/// [`super::simulate_filtered`] for `nF <= 24`; returns false (and does nothing) for larger
/// orders, which the caller then runs as separate passes.
///
/// # Safety
/// The CPU supports AVX2 and FMA; all four signals have the same length.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn simulate_filtered(
    b: &[f64],
    f: &[f64],
    delay: usize,
    u: &[f64],
    xu: &mut [f64],
    yhat: &mut [f64],
    xy: &mut [f64],
) -> bool {
    macro_rules! dispatch {
        ($($m:literal)*) => {
            match f.len() {
                $($m => simulate_filtered_impl::<$m>(f, b, delay, u, xu, yhat, xy),)*
                _ => return false,
            }
        };
    }
    // SAFETY: this function's own contract.
    unsafe {
        dispatch!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24);
    }
    true
}
