//! The innermost loops (dot products, the `1/F` recursion, the FIR part of the model), compiled
//! twice: once for the baseline target and once with AVX2+FMA, chosen at run time.
//!
//! Why: per solver iteration these loops are nearly all of the work (METHOD.md 2: one `1/F`
//! pass over `u`, one over `yhat`, a simulation, and O(N (nB+nF)) lagged dot products). With
//! FMA the `1/F` recursion's critical path is one fused multiply-add per sample instead of a
//! multiply and a subtract, and the dot products run four lanes wide. The choice depends only
//! on the CPU, so a given machine gives the same numbers whatever the thread count.

#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    // mul_add without hardware FMA is a slow libm call, so it is used only in the FMA build.
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

#[inline(always)]
fn dot_impl<const FMA: bool>(a: &[f64], b: &[f64]) -> f64 {
    // 16 independent accumulators: enough to keep two FMA ports busy through their latency.
    const ACC: usize = 16;
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; ACC];
    let mut ca = a.chunks_exact(ACC);
    let mut cb = b.chunks_exact(ACC);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for k in 0..ACC {
            acc[k] = madd::<FMA>(x[k], y[k], acc[k]);
        }
    }
    let mut s = 0.0;
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        s = madd::<FMA>(*x, *y, s);
    }
    let mut w = ACC / 2;
    while w > 0 {
        for k in 0..w {
            acc[k] += acc[k + w];
        }
        w /= 2;
    }
    acc[0] + s
}

/// Samples per block of [`lagged_dots_impl`]: two blocks (plus the lags) stay in L1.
const LAG_BLOCK: usize = 1024;

/// Visit the terms of lagged sums `sum_{s + l < n} ...` block by block: for each block of
/// [`LAG_BLOCK`] samples and each lag `l < lags`, `f(l, s0, end)` with the block's terms
/// `s in [s0, end)`. Each block is read for all lags while it sits in L1.
#[inline(always)]
fn blocked_lags(n: usize, lags: usize, mut f: impl FnMut(usize, usize, usize)) {
    let mut s0 = 0;
    while s0 < n {
        let s1 = (s0 + LAG_BLOCK).min(n);
        for l in 0..lags {
            let end = s1.min(n.saturating_sub(l));
            if end <= s0 {
                break;
            }
            f(l, s0, end);
        }
        s0 = s1;
    }
}

/// `out[l] = sum_{s=0}^{n-1-l} a[s] b[s+l]` for `l = 0..out.len()`, n = common length.
///
/// Blocked over s: all lags of one block of `a` and `b` are taken while the block sits in L1.
/// Lag by lag over the whole record (as before) streamed both sequences from L2 once per
/// lag, and that bandwidth, not the multiply-adds, bounded the normal equations. (Sharing
/// loads of `a` between four lags, and a 512-bit build, both measured slower.)
#[inline(always)]
fn lagged_dots_impl<const FMA: bool>(a: &[f64], b: &[f64], out: &mut [f64]) {
    let n = a.len().min(b.len());
    out.fill(0.0);
    blocked_lags(n, out.len(), |l, s0, end| out[l] += dot_impl::<FMA>(&a[s0..end], &b[s0 + l..end + l]));
}

/// The six correlations of the normal equations at lags `0..out.len()`:
/// `out[l] = [R(u,u), R(y,y), R(u,y), R(y,u), R(u,r), R(y,r)](l)`, `R(a,b)(l) = sum_s a[s] b[s+l]`.
///
/// One pass: per step the five loads `u[s], y[s], u[s+l], y[s+l], r[s+l]` feed six
/// multiply-adds, where six separate dot products load twelve. Blocked over s like
/// [`lagged_dots_impl`].
#[inline(always)]
fn correlations_impl<const FMA: bool>(u: &[f64], y: &[f64], r: &[f64], out: &mut [[f64; 6]]) {
    const W: usize = 4;
    let n = u.len().min(y.len()).min(r.len());
    for o in out.iter_mut() {
        *o = [0.0; 6];
    }
    let lags = out.len();
    blocked_lags(n, lags, |l, s0, end| {
        let o = &mut out[l];
        {
            let len = end - s0;
            let (ua, ya) = (&u[s0..end], &y[s0..end]);
            let (ub, yb, rb) = (&u[s0 + l..end + l], &y[s0 + l..end + l], &r[s0 + l..end + l]);
            let mut acc = [[0.0f64; W]; 6];
            let chunks = len / W;
            let it = ua.chunks_exact(W).zip(ya.chunks_exact(W)).zip(ub.chunks_exact(W)).zip(yb.chunks_exact(W));
            for ((((a, b), p), q), z) in it.zip(rb.chunks_exact(W)) {
                for k in 0..W {
                    acc[0][k] = madd::<FMA>(a[k], p[k], acc[0][k]);
                    acc[1][k] = madd::<FMA>(b[k], q[k], acc[1][k]);
                    acc[2][k] = madd::<FMA>(a[k], q[k], acc[2][k]);
                    acc[3][k] = madd::<FMA>(b[k], p[k], acc[3][k]);
                    acc[4][k] = madd::<FMA>(a[k], z[k], acc[4][k]);
                    acc[5][k] = madd::<FMA>(b[k], z[k], acc[5][k]);
                }
            }
            for i in chunks * W..len {
                let (a, b) = (ua[i], ya[i]);
                let (p, q, z) = (ub[i], yb[i], rb[i]);
                acc[0][0] = madd::<FMA>(a, p, acc[0][0]);
                acc[1][0] = madd::<FMA>(b, q, acc[1][0]);
                acc[2][0] = madd::<FMA>(a, q, acc[2][0]);
                acc[3][0] = madd::<FMA>(b, p, acc[3][0]);
                acc[4][0] = madd::<FMA>(a, z, acc[4][0]);
                acc[5][0] = madd::<FMA>(b, z, acc[5][0]);
            }
            for (oj, aj) in o.iter_mut().zip(&acc) {
                *oj += (aj[0] + aj[2]) + (aj[1] + aj[3]);
            }
        }
    });
}

/// `h += alpha v v^T` on the upper triangle of the d x d row-major `h`.
#[inline(always)]
fn rank1_upper_impl<const FMA: bool>(h: &mut [f64], d: usize, v: &[f64], alpha: f64) {
    for i in 0..d {
        let a = alpha * v[i];
        if a == 0.0 {
            continue;
        }
        let row = &mut h[i * d + i..i * d + d];
        for (hij, vj) in row.iter_mut().zip(&v[i..d]) {
            *hij = madd::<FMA>(a, *vj, *hij);
        }
    }
}

/// `h[i d + j] += scale sum_k q[k dp + i] p[k dp + j]` for `i <= j < d`: the upper triangle
/// of `scale Q^T P` for two m x d matrices stored row by row with stride `dp >= d`.
#[inline(always)]
fn syrk_upper_impl<const FMA: bool>(h: &mut [f64], d: usize, p: &[f64], q: &[f64], dp: usize, m: usize, scale: f64) {
    for i in 0..d {
        for j in i..d {
            let mut s = 0.0;
            for k in 0..m {
                s = madd::<FMA>(q[k * dp + i], p[k * dp + j], s);
            }
            h[i * d + j] = madd::<FMA>(scale, s, h[i * d + j]);
        }
    }
}

/// [`compact`]: branch-free (write every t, advance past the kept ones), since which rows are
/// kept is unpredictable.
#[inline(always)]
fn compact_impl(w: &[f64], skip: f64, rows: &mut [u32], mut alpha: Option<&mut [f64]>) -> usize {
    let mut m = 0;
    for (t, &wt) in w.iter().enumerate() {
        rows[m] = t as u32;
        if let Some(a) = alpha.as_deref_mut() {
            a[m] = wt;
        }
        m += (wt != skip) as usize;
    }
    m
}

#[inline(always)]
fn inv_f_impl<const M: usize, const FMA: bool>(f: &[f64], x: &mut [f64]) {
    let mut a = [0.0; M];
    a.copy_from_slice(&f[..M]);
    // s[j] holds x_{t-1-j}: the last M outputs, newest first, kept in registers. (Re-reading
    // the history from x instead was slower: wide loads over just-stored scalars stall.)
    let mut s = [0.0; M];
    let mut neg = [0.0; M];
    for j in 0..M {
        neg[j] = -a[j];
    }
    for xt in x.iter_mut() {
        // One serial chain, oldest output first: output t-1-j enters 4(j+1) cycles (j+1 FMA
        // latencies) before output t is due, so every lag allows the one-FMA-per-sample pace
        // and the bound is the FMA ports (M per sample). Summing the older terms in a tree
        // instead put out(t-2) -> out(t) five operations apart, ~10 cycles per sample.
        let mut acc = *xt;
        for j in (0..M).rev() {
            acc = madd::<FMA>(neg[j], s[j], acc);
        }
        for j in (1..M).rev() {
            s[j] = s[j - 1];
        }
        s[0] = acc;
        *xt = acc;
    }
}

#[inline(always)]
fn fir_impl<const FMA: bool>(b: &[f64], delay: usize, u: &[f64], out: &mut [f64]) {
    fir_range_impl::<FMA>(b, delay, u, out, 0, u.len())
}

/// `out_t` of [`fir`] for `t` in `t0..t1` only (`u` must hold samples up to `t1 - delay`). Each
/// output sums its taps in the same order whatever the range, so the result does not depend
/// on how a signal is cut into ranges.
#[inline(always)]
fn fir_range_impl<const FMA: bool>(b: &[f64], delay: usize, u: &[f64], out: &mut [f64], t0: usize, t1: usize) {
    // Blocks of W outputs accumulate every tap in registers: one store per output instead of
    // a load and a store per output and tap (the tap-by-tap loop was store-bound).
    const W: usize = 8;
    let max_lag = delay + b.len().saturating_sub(1);
    let scalar = |t: usize| {
        let mut acc = 0.0;
        for (i, &bi) in b.iter().enumerate() {
            let lag = delay + i;
            if t >= lag {
                acc = madd::<FMA>(bi, u[t - lag], acc);
            }
        }
        acc
    };
    let head = max_lag.clamp(t0, t1);
    for (t, o) in out[t0..head].iter_mut().enumerate() {
        *o = scalar(t0 + t);
    }
    let mut t = head;
    while t + W <= t1 {
        let mut acc = [0.0; W];
        for (i, &bi) in b.iter().enumerate() {
            let start = t - delay - i;
            let x: &[f64; W] = u[start..start + W].try_into().expect("W samples");
            for k in 0..W {
                acc[k] = madd::<FMA>(bi, x[k], acc[k]);
            }
        }
        out[t..t + W].copy_from_slice(&acc);
        t += W;
    }
    for (t, o) in out[t..t1].iter_mut().enumerate().map(|(i, o)| (t + i, o)) {
        *o = scalar(t);
    }
}

fn inv_f_generic(f: &[f64], x: &mut [f64]) {
    for t in 0..x.len() {
        let mut acc = x[t];
        for (j, fj) in f.iter().enumerate().take(t) {
            acc -= fj * x[t - 1 - j];
        }
        x[t] = acc;
    }
}

macro_rules! inv_f_dispatch {
    ($fma:literal, $f:expr, $x:expr, $($n:literal)*) => {
        match $f.len() {
            0 => {}
            $($n => inv_f_impl::<$n, $fma>($f, $x),)*
            _ => inv_f_generic($f, $x),
        }
    };
}

mod base {
    pub fn compact(w: &[f64], skip: f64, rows: &mut [u32], alpha: Option<&mut [f64]>) -> usize {
        super::compact_impl(w, skip, rows, alpha)
    }
    pub fn dot(a: &[f64], b: &[f64]) -> f64 {
        super::dot_impl::<false>(a, b)
    }
    pub fn lagged_dots(a: &[f64], b: &[f64], out: &mut [f64]) {
        super::lagged_dots_impl::<false>(a, b, out)
    }
    pub fn rank1_upper(h: &mut [f64], d: usize, v: &[f64], alpha: f64) {
        super::rank1_upper_impl::<false>(h, d, v, alpha)
    }
    pub fn correlations(u: &[f64], y: &[f64], r: &[f64], out: &mut [[f64; 6]]) {
        super::correlations_impl::<false>(u, y, r, out)
    }
    pub fn syrk_upper(h: &mut [f64], d: usize, p: &[f64], q: &[f64], dp: usize, m: usize, scale: f64) {
        super::syrk_upper_impl::<false>(h, d, p, q, dp, m, scale)
    }
    pub fn inv_f(f: &[f64], x: &mut [f64]) {
        use super::*;
        inv_f_dispatch!(false, f, x, 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24);
    }
    pub fn fir(b: &[f64], delay: usize, u: &[f64], out: &mut [f64]) {
        super::fir_impl::<false>(b, delay, u, out)
    }
}

#[cfg(target_arch = "x86_64")]
mod fma {
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn dot(a: &[f64], b: &[f64]) -> f64 {
        super::dot_impl::<true>(a, b)
    }
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn lagged_dots(a: &[f64], b: &[f64], out: &mut [f64]) {
        super::lagged_dots_impl::<true>(a, b, out)
    }
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn rank1_upper(h: &mut [f64], d: usize, v: &[f64], alpha: f64) {
        super::rank1_upper_impl::<true>(h, d, v, alpha)
    }
    /// [`super::correlations_impl`] with explicit 256-bit vectors: left to itself the compiler
    /// vectorised the six interleaved sums only partly (half the lanes scalar).
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn correlations(u: &[f64], y: &[f64], r: &[f64], out: &mut [[f64; 6]]) {
        use std::arch::x86_64::*;
        let n = u.len().min(y.len()).min(r.len());
        for o in out.iter_mut() {
            *o = [0.0; 6];
        }
        let hsum = |v: __m256d| {
            let mut a = [0.0; 4];
            // SAFETY: a holds four f64.
            unsafe { _mm256_storeu_pd(a.as_mut_ptr(), v) };
            (a[0] + a[2]) + (a[1] + a[3])
        };
        let lags = out.len();
        super::blocked_lags(n, lags, |l, s0, end| {
            let o = &mut out[l];
            {
                let mut acc = [_mm256_setzero_pd(); 6];
                let mut i = s0;
                // SAFETY: i + 3 < end <= n - l, so every load below is inside its slice.
                unsafe {
                    let (pu, py, pr) = (u.as_ptr(), y.as_ptr(), r.as_ptr());
                    while i + 4 <= end {
                        let a = _mm256_loadu_pd(pu.add(i));
                        let b = _mm256_loadu_pd(py.add(i));
                        let p = _mm256_loadu_pd(pu.add(i + l));
                        let q = _mm256_loadu_pd(py.add(i + l));
                        let z = _mm256_loadu_pd(pr.add(i + l));
                        acc[0] = _mm256_fmadd_pd(a, p, acc[0]);
                        acc[1] = _mm256_fmadd_pd(b, q, acc[1]);
                        acc[2] = _mm256_fmadd_pd(a, q, acc[2]);
                        acc[3] = _mm256_fmadd_pd(b, p, acc[3]);
                        acc[4] = _mm256_fmadd_pd(a, z, acc[4]);
                        acc[5] = _mm256_fmadd_pd(b, z, acc[5]);
                        i += 4;
                    }
                }
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
        });
    }
    /// [`super::syrk_upper_impl`] in register tiles: 4 rows of Q (broadcast) times 4, 8 or
    /// 12 columns of P (vectors), 16 or fewer accumulators, for every tile touching the upper
    /// triangle. Rows i0.. are multiples of 4 and `dp` is too, so each tile's loads stay
    /// inside its padded row.
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
    /// [`super::compact_impl`] four rows at a time: a compare gives a 4-bit mask, a table
    /// the shuffle that packs the kept indices (and weights) to the front, and every store
    /// writes all four lanes, the slack past `m` being overwritten later. The scalar loop
    /// carried `m` through every row; this carries it through every fourth.
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
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn inv_f(f: &[f64], x: &mut [f64]) {
        use super::*;
        inv_f_dispatch!(true, f, x, 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24);
    }
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn fir(b: &[f64], delay: usize, u: &[f64], out: &mut [f64]) {
        super::fir_impl::<true>(b, delay, u, out)
    }

    use std::arch::x86_64::*;

    /// One sample of two `1/F` recursions with the same F, one per lane: the same fused
    /// multiply-adds in the same order as [`super::inv_f_impl`], so each lane is bit for bit
    /// that recursion, at the cost of one.
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
                    super::fir_range_impl::<true>(b, delay, xu, yhat, t0, t0 + len0);
                }
                t0 += L;
            }
        }
    }

    /// # Safety
    /// The CPU supports AVX2 and FMA; all four signals have the same length.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn simulate_filtered(
        f: &[f64],
        b: &[f64],
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
}

#[inline]
fn has_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `sum_i a_i b_i` over the common length.
#[inline]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if has_fma() {
        // SAFETY: the CPU supports the features the function is compiled for.
        return unsafe { fma::dot(a, b) };
    }
    base::dot(a, b)
}

/// `out[l] = sum_s a[s] b[s+l]` for `l = 0..out.len()` over the common length of a and b.
#[inline]
pub fn lagged_dots(a: &[f64], b: &[f64], out: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if has_fma() {
        // SAFETY: the CPU supports the features the function is compiled for.
        return unsafe { fma::lagged_dots(a, b, out) };
    }
    base::lagged_dots(a, b, out)
}

/// `out[l] = [R(u,u), R(y,y), R(u,y), R(y,u), R(u,r), R(y,r)](l)` for `l = 0..out.len()`,
/// `R(a,b)(l) = sum_s a[s] b[s+l]` over the common length.
#[inline]
pub fn correlations(u: &[f64], y: &[f64], r: &[f64], out: &mut [[f64; 6]]) {
    #[cfg(target_arch = "x86_64")]
    if has_fma() {
        // SAFETY: the CPU supports the features the function is compiled for.
        return unsafe { fma::correlations(u, y, r, out) };
    }
    base::correlations(u, y, r, out)
}

/// `h += alpha v v^T` on the upper triangle of the d x d row-major matrix `h`.
#[inline]
pub fn rank1_upper(h: &mut [f64], d: usize, v: &[f64], alpha: f64) {
    #[cfg(target_arch = "x86_64")]
    if has_fma() {
        // SAFETY: as above.
        return unsafe { fma::rank1_upper(h, d, v, alpha) };
    }
    base::rank1_upper(h, d, v, alpha)
}

/// `h[i d + j] += scale sum_k q[k dp + i] p[k dp + j]` for `i <= j < d`: the upper triangle of
/// `scale Q^T P` for two m x d matrices stored row by row with stride `dp` (a multiple of 4,
/// `dp >= d`; the padding columns may hold anything finite).
#[inline]
pub fn syrk_upper(h: &mut [f64], d: usize, p: &[f64], q: &[f64], dp: usize, m: usize, scale: f64) {
    assert!(dp.is_multiple_of(4) && dp >= d && p.len() >= m * dp && q.len() >= m * dp && h.len() >= d * d);
    #[cfg(target_arch = "x86_64")]
    if has_fma() {
        // SAFETY: as above; the shapes are checked.
        return unsafe { fma::syrk_upper(h, d, p, q, dp, m, scale) };
    }
    base::syrk_upper(h, d, p, q, dp, m, scale)
}

/// Indices `t` with `w[t] != skip` into `rows[..m]` and, if given, those `w[t]` into
/// `alpha[..m]`; returns m. `rows` (and `alpha`) need `w.len() + 3` slots: the entries past
/// `m` are scratch.
#[inline]
pub fn compact(w: &[f64], skip: f64, rows: &mut [u32], alpha: Option<&mut [f64]>) -> usize {
    assert!(rows.len() >= w.len() + 3 && alpha.as_ref().is_none_or(|a| a.len() >= w.len() + 3));
    #[cfg(target_arch = "x86_64")]
    if has_fma() {
        // SAFETY: as above; the lengths are checked.
        return unsafe { fma::compact(w, skip, rows, alpha) };
    }
    base::compact(w, skip, rows, alpha)
}

/// Apply `1/F` in place: `x_t <- x_t - sum_j f_j x_{t-j}` (zero initial conditions).
/// Orders up to 24 run a recursion specialised on the order (state in registers).
#[inline]
pub fn inv_f(f: &[f64], x: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if has_fma() {
        // SAFETY: as above.
        return unsafe { fma::inv_f(f, x) };
    }
    base::inv_f(f, x)
}

/// The simulation and both Jacobian signals of an OE model in one pass (METHOD.md 2):
/// `xu = (1/F) u`, `yhat = q^-d B xu`, `xy = (1/F) yhat`. Equal, bit for bit, to
/// [`inv_f`] on `u`, [`fir`], and [`inv_f`] on `yhat`: with FMA the two recursions share one
/// two-lane recursion (the second one block behind the first), which halves the cost of the
/// `1/F` passes, the innermost loop of every solver iteration.
pub fn simulate_filtered(
    f: &[f64],
    b: &[f64],
    delay: usize,
    u: &[f64],
    xu: &mut [f64],
    yhat: &mut [f64],
    xy: &mut [f64],
) {
    let n = u.len();
    assert!(xu.len() == n && yhat.len() == n && xy.len() == n, "signals of one length");
    #[cfg(target_arch = "x86_64")]
    // SAFETY: as above; the lengths are checked.
    if has_fma() && unsafe { fma::simulate_filtered(f, b, delay, u, xu, yhat, xy) } {
        return;
    }
    xu.copy_from_slice(u);
    inv_f(f, xu);
    fir(b, delay, xu, yhat);
    xy.copy_from_slice(yhat);
    inv_f(f, xy);
}

/// `out_t = sum_i b_i u_{t-d-i+1}`.
#[inline]
pub fn fir(b: &[f64], delay: usize, u: &[f64], out: &mut [f64]) {
    assert_eq!(u.len(), out.len());
    #[cfg(target_arch = "x86_64")]
    if has_fma() {
        // SAFETY: as above.
        return unsafe { fma::fir(b, delay, u, out) };
    }
    base::fir(b, delay, u, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_builds_agree_with_the_plain_recursion() {
        let x0: Vec<f64> = (0..300).map(|t| ((t * 37 % 11) as f64 - 5.0) * 0.3).collect();
        for n in 0..=30 {
            let f: Vec<f64> = (0..n).map(|j: i32| 0.5f64.powi(j + 1) * if j % 2 == 0 { -1.0 } else { 0.7 }).collect();
            let mut want = x0.clone();
            inv_f_generic(&f, &mut want);
            let mut a = x0.clone();
            base::inv_f(&f, &mut a);
            let mut b = x0.clone();
            inv_f(&f, &mut b);
            for ((p, q), w) in a.iter().zip(&b).zip(&want) {
                assert!((p - w).abs() <= 1e-12 * (1.0 + w.abs()), "n={n}");
                assert!((q - w).abs() <= 1e-12 * (1.0 + w.abs()), "n={n}");
            }
        }
        // 2100: lagged dots span blocks of LAG_BLOCK samples.
        for len in [0, 1, 15, 16, 17, 100, 1001, 2100] {
            let a: Vec<f64> = (0..len).map(|i| (i as f64 * 0.37).sin()).collect();
            let b: Vec<f64> = (0..len).map(|i| (i as f64 * 0.11).cos()).collect();
            let want: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
            assert!((dot(&a, &b) - want).abs() < 1e-10 && (base::dot(&a, &b) - want).abs() < 1e-10);
            for lags in [0, 1, 3, 4, 5, 9, 30] {
                let mut out = vec![f64::NAN; lags];
                lagged_dots(&a, &b, &mut out);
                let mut out2 = vec![f64::NAN; lags];
                base::lagged_dots(&a, &b, &mut out2);
                for l in 0..lags {
                    let want: f64 =
                        if l < len { a[..len - l].iter().zip(&b[l..]).map(|(x, y)| x * y).sum() } else { 0.0 };
                    assert!((out[l] - want).abs() < 1e-10 && (out2[l] - want).abs() < 1e-10, "len {len} lag {l}");
                }
            }
        }
    }

    #[test]
    fn syrk_tiles_agree_with_the_definition_and_leave_the_lower_triangle() {
        let mut s = 7u64;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        for d in [1usize, 3, 4, 5, 8, 11, 12, 13, 19, 24, 27, 29] {
            let dp = d.div_ceil(4) * 4;
            for m in [0usize, 1, 5, 64, 137] {
                let p: Vec<f64> = (0..m * dp).map(|_| next()).collect();
                let q: Vec<f64> = (0..m * dp).map(|_| next()).collect();
                let h0: Vec<f64> = (0..d * d).map(|_| next()).collect();
                let scale = -0.75;
                let mut want = h0.clone();
                for i in 0..d {
                    for j in i..d {
                        want[i * d + j] += scale * (0..m).map(|k| q[k * dp + i] * p[k * dp + j]).sum::<f64>();
                    }
                }
                let mut a = h0.clone();
                syrk_upper(&mut a, d, &p, &q, dp, m, scale);
                let mut b = h0.clone();
                base::syrk_upper(&mut b, d, &p, &q, dp, m, scale);
                for i in 0..d {
                    for j in 0..d {
                        let k = i * d + j;
                        if j < i {
                            assert_eq!(a[k], h0[k], "lower ({i},{j}) touched, d={d} m={m}");
                            assert_eq!(b[k], h0[k]);
                        } else {
                            assert!((a[k] - want[k]).abs() < 1e-12, "({i},{j}) d={d} m={m}: {} vs {}", a[k], want[k]);
                            assert!((b[k] - want[k]).abs() < 1e-12);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn compact_keeps_the_rows_off_the_skip_value_in_order() {
        for n in [0usize, 1, 3, 4, 5, 17, 1000] {
            for skip in [0.0, 1.0] {
                let w: Vec<f64> =
                    (0..n).map(|t| [1.0, 0.0, 0.5, 1.0, 0.0, f64::NAN, 1.0][(t * 7 + t / 3) % 7]).collect();
                let want: Vec<usize> = (0..n).filter(|&t| w[t] != skip).collect();
                for fast in [true, false] {
                    let mut rows = vec![0u32; n + 3];
                    let mut alpha = vec![0.0; n + 3];
                    let m = if fast {
                        compact(&w, skip, &mut rows, Some(&mut alpha))
                    } else {
                        base::compact(&w, skip, &mut rows, Some(&mut alpha))
                    };
                    assert_eq!(m, want.len(), "n={n} skip={skip}");
                    for (k, &t) in want.iter().enumerate() {
                        assert_eq!(rows[k] as usize, t);
                        assert_eq!(alpha[k].to_bits(), w[t].to_bits());
                    }
                    let mut rows2 = vec![0u32; n + 3];
                    assert_eq!(compact(&w, skip, &mut rows2, None), m);
                    assert_eq!(rows2[..m], rows[..m]);
                }
            }
        }
    }

    #[test]
    fn fused_correlations_agree_with_lagged_dots() {
        for len in [0, 3, 17, 1001, 2100] {
            let seq = |w: f64| (0..len).map(|i| (i as f64 * w).sin()).collect::<Vec<f64>>();
            let (u, y, r) = (seq(0.37), seq(0.11), seq(0.53));
            for lags in [0, 1, 5, 16] {
                let mut out = vec![[f64::NAN; 6]; lags];
                correlations(&u, &y, &r, &mut out);
                let mut out2 = vec![[f64::NAN; 6]; lags];
                base::correlations(&u, &y, &r, &mut out2);
                for (j, (a, b)) in [(&u, &u), (&y, &y), (&u, &y), (&y, &u), (&u, &r), (&y, &r)].into_iter().enumerate()
                {
                    let mut want = vec![0.0; lags];
                    lagged_dots(a, b, &mut want);
                    for l in 0..lags {
                        let tol = 1e-10 * (1.0 + want[l].abs());
                        assert!(
                            (out[l][j] - want[l]).abs() <= tol && (out2[l][j] - want[l]).abs() <= tol,
                            "{len} {j} {l}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn fir_blocks_agree_with_the_definition() {
        for len in [0, 1, 5, 8, 9, 30, 1003] {
            let u: Vec<f64> = (0..len).map(|i| (i as f64 * 0.23).sin() + 0.1).collect();
            for nb in [1, 2, 7, 12, 40] {
                let b: Vec<f64> = (0..nb).map(|i| 1.0 / (i as f64 + 1.5)).collect();
                for delay in [0, 1, 3] {
                    let want: Vec<f64> = (0..len)
                        .map(|t| (0..nb).filter(|i| t >= delay + i).map(|i| b[i] * u[t - delay - i]).sum())
                        .collect();
                    let (mut p, mut q) = (vec![f64::NAN; len], vec![f64::NAN; len]);
                    fir(&b, delay, &u, &mut p);
                    base::fir(&b, delay, &u, &mut q);
                    for t in 0..len {
                        let tol = 1e-12 * (1.0 + want[t].abs());
                        assert!(
                            (p[t] - want[t]).abs() <= tol && (q[t] - want[t]).abs() <= tol,
                            "{len} {nb} {delay} {t}"
                        );
                    }
                }
            }
        }
    }

    /// The fused pass is the three separate passes bit for bit, at every order (the two-lane
    /// kernels and the fallback), across block boundaries (256) and for short records.
    #[test]
    fn simulate_filtered_is_the_separate_passes_bit_for_bit() {
        for len in [0, 1, 7, 255, 256, 257, 600, 1003] {
            let u: Vec<f64> = (0..len).map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.3 + (i as f64 * 0.1).sin()).collect();
            for nf in [0, 1, 2, 5, 12, 24, 25, 30] {
                // A stable F: poles at radius 0.9 spread over angles.
                let mut roots = Vec::new();
                for j in 0..nf / 2 {
                    let a = 0.3 + 2.5 * j as f64 / nf as f64;
                    roots.push((0.9 * a.cos(), 0.9 * a.sin()));
                    roots.push((0.9 * a.cos(), -0.9 * a.sin()));
                }
                if nf % 2 == 1 {
                    roots.push((-0.5, 0.0));
                }
                let f = crate::oe::poly_from_roots(&roots);
                assert_eq!(f.len(), nf);
                for (nb, delay) in [(1, 0), (3, 1), (12, 1), (7, 4)] {
                    let b: Vec<f64> = (0..nb).map(|i| 1.0 / (i as f64 + 1.5)).collect();
                    let mut want_xu = u.clone();
                    inv_f(&f, &mut want_xu);
                    let mut want_yhat = vec![0.0; len];
                    fir(&b, delay, &want_xu, &mut want_yhat);
                    let mut want_xy = want_yhat.clone();
                    inv_f(&f, &mut want_xy);
                    let (mut xu, mut yhat, mut xy) = (vec![f64::NAN; len], vec![f64::NAN; len], vec![f64::NAN; len]);
                    simulate_filtered(&f, &b, delay, &u, &mut xu, &mut yhat, &mut xy);
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    let what = format!("len {len} nf {nf} nb {nb} delay {delay}");
                    assert_eq!(bits(&xu), bits(&want_xu), "xu, {what}");
                    assert_eq!(bits(&yhat), bits(&want_yhat), "yhat, {what}");
                    assert_eq!(bits(&xy), bits(&want_xy), "xy, {what}");
                }
            }
        }
    }
}
